"""`eval` at scale: one query with `evaluate` against 100k queries with `evaluate_many`.

    python benchmarks/bench_eval.py [--samples 100] [--queries 100000]

A space of random samples over the turn-rate x speed axes is triangulated like a build does;
queries are spread over the axes (about a fifth fall outside the hull and go to its edge). The
run reports, in one process: scipy's `find_simplex` on the same queries (the floor: locating is
all it does), `evaluate` per query, `evaluate_many` per query with the document prepared once
(`BatchEvaluator`) and with preparation included, and the ratios between them. The issue's goals:
<= 5 us per query and 100k queries <= 0.5 s. Nothing here asserts a time.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from scipy.spatial import Delaunay

from blendspace_pipeline.space.document import BlendSpaceDocument
from blendspace_pipeline.space.evaluate import BatchEvaluator, evaluate, evaluate_many
from blendspace_pipeline.space.geometry import AxisRange, normalise
from blendspace_pipeline.space.triangulate import triangulate

AXES = (AxisRange(-180.0, 180.0), AxisRange(-3.0, 6.0))


def make_document(samples: int, rng: np.random.Generator) -> BlendSpaceDocument:
    positions = rng.uniform([-170.0, -2.5], [170.0, 5.5], size=(samples, 2))
    triangles = triangulate(normalise(positions, AXES)).triangles
    return BlendSpaceDocument.model_validate(
        {
            "schema_version": 1,
            "name": "bench",
            "axes": [
                {
                    "name": "x",
                    "feature": "turn_rate",
                    "min": -180,
                    "max": 180,
                    "divisions": 36,
                    "unit": "deg/s",
                },
                {"name": "y", "feature": "speed", "min": -3, "max": 6, "divisions": 36, "unit": "m/s"},
            ],
            "samples": [
                {
                    "name": f"clip_{i}",
                    "source": f"clips/clip_{i}.bvh",
                    "features": {"duration": 1.0 + (i % 7) * 0.1},
                    "position": [float(x), float(y)],
                }
                for i, (x, y) in enumerate(positions)
            ],
            "triangles": [list(t) for t in triangles],
        }
    )


def best_of(runs: int, action: object) -> float:
    """Best wall time of ``runs`` (the machine is shared: the minimum is the least disturbed)."""
    times = []
    for _ in range(runs):
        start = time.perf_counter()
        action()  # type: ignore[operator]
        times.append(time.perf_counter() - start)
    return min(times)


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--samples", type=int, default=100)
    parser.add_argument("--queries", type=int, default=100_000)
    parser.add_argument("--runs", type=int, default=3)
    args = parser.parse_args()
    rng = np.random.default_rng(1)
    doc = make_document(args.samples, rng)
    queries = rng.uniform([-180.0, -3.0], [180.0, 6.0], size=(args.queries, 2))
    mesh = Delaunay(normalise(np.array([s.position for s in doc.samples]), AXES))
    normalised = normalise(queries, AXES)
    floor = best_of(args.runs, lambda: mesh.find_simplex(normalised)) / args.queries
    singles = queries[:300]
    single = best_of(args.runs, lambda: [evaluate(doc, float(x), float(y)) for x, y in singles]) / len(
        singles
    )
    evaluator = BatchEvaluator(doc)
    batch = best_of(args.runs, lambda: evaluator(queries))
    cold = best_of(args.runs, lambda: evaluate_many(doc, queries))
    outside = float(evaluator(queries).outside_hull.mean())
    print(
        f"{args.samples} samples, {args.queries} queries ({outside:.0%} outside the hull); best of {args.runs}"
    )
    print(f"scipy find_simplex (floor)        {floor * 1e6:9.2f} us/query")
    print(f"evaluate, one query at a time     {single * 1e6:9.2f} us/query")
    print(
        f"evaluate_many, prepared evaluator {batch / args.queries * 1e6:9.2f} us/query   "
        f"{batch:.3f} s total   {single * args.queries / batch:8.0f}x faster than evaluate, "
        f"{batch / args.queries / floor:.1f}x the floor"
    )
    print(f"evaluate_many, preparation incl.  {cold / args.queries * 1e6:9.2f} us/query   {cold:.3f} s total")


if __name__ == "__main__":
    main()
