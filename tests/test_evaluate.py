"""The evaluator: barycentric weights checked against an independent computation, layers,
culling, merging, playback rates, and the `blendspace eval` command."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.spatial import ConvexHull, Delaunay

from blendspace_pipeline.cli import main
from blendspace_pipeline.errors import InputError
from blendspace_pipeline.motion.procedural import GaitSpec, generate
from blendspace_pipeline.pipeline.analysis import analyse
from blendspace_pipeline.pipeline.to_document import to_document
from blendspace_pipeline.space.document import BlendSpaceDocument
from blendspace_pipeline.space.evaluate import Evaluation, evaluate
from blendspace_pipeline.space.layers_doc import StyleLayerDoc, parse_layer_list, parse_layers
from blendspace_pipeline.writers.bvh import write_bvh_clip

TURN_SPEED = (("turn_rate", -180.0, 180.0, "deg/s"), ("speed", -3.0, 6.0, "m/s"))
UNIT_BOX = (("turn_rate", -1.0, 1.0, "deg/s"), ("speed", -1.0, 1.0, "m/s"))


def _normalised(points: np.ndarray, axes: tuple[tuple[str, float, float, str], ...]) -> np.ndarray:
    lows = np.array([axes[0][1], axes[1][1]])
    spans = np.array([axes[0][2] - axes[0][1], axes[1][2] - axes[1][1]])
    return np.asarray((points - lows) / spans * 100.0)


def make_doc(
    points: dict[str, tuple[float, float]],
    axes: tuple[tuple[str, float, float, str], ...] = TURN_SPEED,
    durations: dict[str, float] | None = None,
    layers: list[dict[str, Any]] | None = None,
    triangles: list[list[int]] | None = None,
) -> BlendSpaceDocument:
    """A document placed by hand, triangulated by scipy's Delaunay on normalised coordinates
    unless ``triangles`` are given (a degenerate space has none)."""
    names = list(points)
    positions = np.array([points[n] for n in names], dtype=float)
    if triangles is None:
        triangles = Delaunay(_normalised(positions, axes)).simplices.tolist()
    return BlendSpaceDocument.model_validate(
        {
            "schema_version": 1,
            "name": "test",
            "axes": [
                {"name": n, "feature": f, "min": lo, "max": hi, "divisions": 10, "unit": u}
                for n, (f, lo, hi, u) in zip("xy", axes, strict=True)
            ],
            "samples": [
                _sample(n, p, (durations or {}).get(n)) for n, p in zip(names, positions, strict=True)
            ],
            "triangles": triangles,
            "layers": layers or [],
        }
    )


def _sample(name: str, position: Any, duration: float | None) -> dict[str, Any]:
    features = {"duration": duration} if duration is not None else {}
    return {
        "name": name,
        "source": f"clips/{name}.bvh",
        "features": features,
        "position": list(map(float, position)),
    }


def weights_of(result: Evaluation) -> dict[str, float]:
    merged: dict[str, float] = {}
    for entry in result.weights:
        merged[entry.clip] = merged.get(entry.clip, 0.0) + entry.weight
    return merged


LOCOMOTION = {
    "idle": (0.0, 0.0),
    "walk": (0.0, 1.4),
    "run": (0.0, 4.5),
    "sprint": (0.0, 6.0),
    "back": (0.0, -1.5),
    "back_run": (0.0, -3.0),
    "turn_l": (90.0, 0.0),
    "turn_r": (-90.0, 0.0),
    "walk_l": (45.0, 1.4),
    "walk_r": (-45.0, 1.4),
    "run_l": (120.0, 4.5),
    "run_r": (-120.0, 4.5),
    "spin_l": (180.0, 0.0),
    "back_l": (60.0, -2.0),
}


def test_weights_match_an_independent_barycentric_computation_inside_the_hull() -> None:
    doc = make_doc(LOCOMOTION)
    names = list(LOCOMOTION)
    positions = np.array([LOCOMOTION[n] for n in names])
    delaunay = Delaunay(_normalised(positions, TURN_SPEED))
    rng = np.random.default_rng(7)
    candidates = rng.uniform([-180.0, -3.0], [180.0, 6.0], size=(3000, 2))
    inside = candidates[delaunay.find_simplex(_normalised(candidates, TURN_SPEED)) >= 0][:600]
    assert len(inside) >= 500
    for query in inside:
        expected = _scipy_weights(delaunay, _normalised(query[None, :], TURN_SPEED)[0], names)
        result = evaluate(doc, *query, cull=0.0)
        got = weights_of(result)
        assert not result.outside_hull
        for name in set(expected) | set(got):
            assert got.get(name, 0.0) == pytest.approx(expected.get(name, 0.0), abs=1e-6)


def _scipy_weights(delaunay: Delaunay, point: np.ndarray, names: list[str]) -> dict[str, float]:
    """Barycentric weights from scipy's affine transform of the containing simplex."""
    simplex = int(delaunay.find_simplex(point))
    transform = delaunay.transform[simplex]
    partial = transform[:2] @ (point - transform[2])
    weights = [*partial, 1.0 - partial.sum()]
    return {
        names[int(v)]: float(w)
        for v, w in zip(delaunay.simplices[simplex], weights, strict=True)
        if w > 1e-12
    }


def test_weights_sum_to_one_inside_on_edges_on_vertices_and_outside() -> None:
    doc = make_doc(LOCOMOTION)
    positions = {name: np.array(p) for name, p in LOCOMOTION.items()}
    names = list(LOCOMOTION)
    queries = [np.array(p) for p in positions.values()]
    for triangle in doc.triangles:
        a, b, c = (positions[names[i]] for i in triangle)
        queries += [(a + b) / 2, (b + c) / 2, (c + a) / 2, (a + b + c) / 3]
    queries += [
        np.array(q) for q in [(-180.0, 6.0), (180.0, -3.0), (170.0, 5.5), (-170.0, -2.9), (500.0, 50.0)]
    ]
    for query in queries:
        result = evaluate(doc, *query)
        assert sum(e.weight for e in result.weights) == pytest.approx(1.0, abs=1e-12)
        assert all(e.weight >= 0.01 for e in result.weights)
    for name, position in positions.items():
        assert weights_of(evaluate(doc, *position)) == pytest.approx({name: 1.0})


def test_points_outside_the_hull_go_to_the_nearest_hull_point() -> None:
    doc = make_doc(LOCOMOTION)
    names = list(LOCOMOTION)
    positions = np.array([LOCOMOTION[n] for n in names])
    normalised = _normalised(positions, TURN_SPEED)
    hull = ConvexHull(normalised)
    rng = np.random.default_rng(11)
    outside = [q for q in rng.uniform([-180.0, -3.0], [180.0, 6.0], size=(400, 2)) if not _in_hull(hull, q)]
    assert len(outside) > 50
    spans, lows = np.array([360.0, 9.0]), np.array([-180.0, -3.0])
    for query in outside:
        point, (a, b) = _nearest_on_hull(hull, normalised, _normalised(query[None, :], TURN_SPEED)[0])
        result = evaluate(doc, *query, cull=0.0)
        assert result.outside_hull
        assert result.hull_point is not None
        assert np.array(result.hull_point) == pytest.approx(point / 100.0 * spans + lows, abs=1e-6)
        # The weights blend the end points of the hull segment holding that point (qhull leaves
        # collinear boundary samples out of its edges, the triangulation keeps them: test both).
        got = weights_of(result)
        assert 1 <= len(got) <= 2
        blended = sum(normalised[names.index(n)] * w for n, w in got.items())
        assert blended == pytest.approx(point, abs=1e-6)
        for name in got:
            assert _on_segment(normalised[names.index(name)], normalised[a], normalised[b])


def _on_segment(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> bool:
    ab, ap = b - a, p - a
    cross = ab[0] * ap[1] - ab[1] * ap[0]
    t = float(ap @ ab / (ab @ ab))
    return abs(cross) < 1e-6 * float(ab @ ab) and -1e-9 <= t <= 1 + 1e-9


def _in_hull(hull: ConvexHull, query: np.ndarray) -> bool:
    point = _normalised(query[None, :], TURN_SPEED)[0]
    return bool(np.all(hull.equations[:, :2] @ point + hull.equations[:, 2] <= 1e-9))


def _nearest_on_hull(
    hull: ConvexHull, vertices: np.ndarray, point: np.ndarray
) -> tuple[np.ndarray, tuple[int, int]]:
    best: tuple[float, np.ndarray, tuple[int, int]] | None = None
    for a, b in hull.simplices:
        ab = vertices[b] - vertices[a]
        t = float(np.clip((point - vertices[a]) @ ab / (ab @ ab), 0.0, 1.0))
        closest = vertices[a] + t * ab
        distance = float(np.linalg.norm(point - closest))
        if best is None or distance < best[0]:
            best = (distance, closest, (int(a), int(b)))
    assert best is not None
    return best[1], best[2]


TRIANGLE = {"a": (0.0, 0.0), "b": (1.0, 0.0), "c": (0.0, 1.0)}


def test_beta_layer_blends_the_second_space_and_merges_shared_clips() -> None:
    beta = {
        "name": "lateral",
        "kind": "beta",
        "source": "lateral.yaml",
        # "a" is the same clip as the main space's "a": it must come out once.
        "samples": [
            _sample("a", (0.0, 0.0), None),
            _sample("e", (1.0, 0.0), None),
            _sample("f", (0.0, 1.0), None),
        ],
        "triangles": [[0, 1, 2]],
    }
    doc = make_doc(TRIANGLE, axes=UNIT_BOX, layers=[beta])
    # Main at (0.25, 0.5): a .25, b .25, c .5; beta space: a .25, e .25, f .5; beta = 0.4.
    result = evaluate(doc, 0.25, 0.5, layers={"lateral": 0.4}, cull=0.0)
    assert weights_of(result) == pytest.approx({"a": 0.25, "b": 0.15, "c": 0.3, "e": 0.1, "f": 0.2})
    assert [e.clip for e in result.weights].count("a") == 1
    layers = {e.clip: e.layer for e in result.weights}
    assert layers == {"a": None, "b": None, "c": None, "e": "lateral", "f": "lateral"}
    assert result.layers[0].share == pytest.approx(0.4)
    assert weights_of(evaluate(doc, 0.25, 0.5, layers={"lateral": 1.0})) == pytest.approx(
        {"a": 0.25, "e": 0.25, "f": 0.5}
    )


def _style(
    feature: str = "speed", mask: dict[str, Any] | None = None, back: float = -1.0, fwd: float = 2.0
) -> dict[str, Any]:
    return {
        "name": "drunk",
        "kind": "style",
        "axis": {"feature": feature, "min": -1.0, "max": 2.0},
        "samples": [
            {"name": "drunk_fwd", "source": "s/fwd.bvh", "position": [fwd], "features": {"duration": 1.2}},
            {"name": "drunk_back", "source": "s/back.bvh", "position": [back], "features": {"duration": 0.9}},
        ],
        "mask": mask,
    }


def test_style_layer_is_evaluated_at_the_query_speed_and_mixed_by_intensity() -> None:
    doc = make_doc(TRIANGLE, axes=UNIT_BOX, layers=[_style()])
    # Speed 0.5 sits halfway between the style clips at -1 and 2; intensity 0.3.
    result = evaluate(doc, 0.25, 0.5, layers={"drunk": 0.3}, cull=0.0)
    expected = {"a": 0.175, "b": 0.175, "c": 0.35, "drunk_back": 0.15, "drunk_fwd": 0.15}
    assert weights_of(result) == pytest.approx(expected)
    assert not result.layers[0].outside_hull
    at_one = evaluate(doc, 0.0, 1.0, layers={"drunk": 0.6}, cull=0.0)  # speed 1: 2/3 of the way to 2
    assert weights_of(at_one) == pytest.approx({"c": 0.4, "drunk_fwd": 0.4, "drunk_back": 0.2})


def test_style_layer_clamps_at_the_ends_of_its_axis() -> None:
    doc = make_doc(TRIANGLE, axes=UNIT_BOX, layers=[_style(back=-0.5, fwd=0.5)])
    above = evaluate(doc, 0.0, 1.0, layers={"drunk": 0.5})
    assert weights_of(above) == pytest.approx({"c": 0.5, "drunk_fwd": 0.5})
    assert above.layers[0].outside_hull and not above.outside_hull
    below = evaluate(doc, 0.0, -1.0, layers={"drunk": 0.5})
    assert weights_of(below) == pytest.approx({"a": 0.5, "drunk_back": 0.5})
    assert below.outside_hull  # the main space has nothing below speed 0


def test_style_axis_is_found_by_feature_not_by_position() -> None:
    swapped = (UNIT_BOX[1], UNIT_BOX[0])  # x = speed, y = turn_rate
    doc = make_doc({"a": (0.0, 0.0), "b": (0.0, 1.0), "c": (1.0, 0.0)}, axes=swapped, layers=[_style()])
    result = evaluate(doc, 0.5, 0.25, layers={"drunk": 0.3}, cull=0.0)
    assert weights_of(result)["drunk_back"] == pytest.approx(0.15)
    assert weights_of(result)["drunk_fwd"] == pytest.approx(0.15)
    other = make_doc(TRIANGLE, axes=UNIT_BOX, layers=[_style(feature="forward_speed")])
    with pytest.raises(InputError, match="forward_speed"):
        evaluate(other, 0.0, 0.0, layers={"drunk": 0.5})


def test_joint_masks_scale_the_style_and_are_reported() -> None:
    mask = {"joints": {"Hips": 1.0, "Spine": 0.5}, "default": 0.0}
    doc = make_doc(TRIANGLE, axes=UNIT_BOX, layers=[_style(mask=mask)])
    whole = evaluate(doc, 0.0, 0.5, layers={"drunk": 0.4}, cull=0.0)
    assert whole.layers[0].mask is not None
    assert whole.layers[0].mask.joints == {"Hips": 1.0, "Spine": 0.5}
    assert whole.to_json()["layers"][0]["mask"] == mask
    spine = evaluate(doc, 0.0, 0.5, layers={"drunk": 0.4}, joint="Spine", cull=0.0)
    assert sum(w for c, w in weights_of(spine).items() if c.startswith("drunk")) == pytest.approx(0.2)
    # A joint the mask does not list takes its default (0 here): the hint's way to evaluate it.
    head = evaluate(doc, 0.0, 0.5, layers={"drunk": 0.4 * 0.0}, cull=0.0)
    assert weights_of(head) == pytest.approx({"a": 0.5, "c": 0.5})


def test_a_masked_style_clip_is_not_merged_with_the_same_clip_of_the_main_space() -> None:
    style = _style(mask={"joints": {"Hips": 1.0}, "default": 0.0})
    style["samples"][1] = {"name": "a", "source": "clips/a.bvh", "position": [-1.0], "features": {}}
    doc = make_doc(TRIANGLE, axes=UNIT_BOX, layers=[style])
    result = evaluate(doc, 0.0, 0.5, layers={"drunk": 0.5}, cull=0.0)
    layers_of_a = sorted((e.layer or "") for e in result.weights if e.clip == "a")
    assert layers_of_a == ["", "drunk"]


def test_small_weights_are_culled_and_the_rest_renormalised() -> None:
    doc = make_doc(TRIANGLE, axes=UNIT_BOX)
    # (0.005, 0.5): a .495, b .005, c .5 — b falls under the 1 % threshold.
    kept = weights_of(evaluate(doc, 0.005, 0.5, cull=0.0))
    assert kept == pytest.approx({"a": 0.495, "b": 0.005, "c": 0.5})
    culled = weights_of(evaluate(doc, 0.005, 0.5))
    assert culled == pytest.approx({"a": 0.495 / 0.995, "c": 0.5 / 0.995})
    assert sum(culled.values()) == pytest.approx(1.0)


def test_playback_rates_make_every_cycle_last_the_weighted_cycle() -> None:
    doc = make_doc(TRIANGLE, axes=UNIT_BOX, durations={"a": 1.0, "b": 2.0, "c": 1.5})
    result = evaluate(doc, 0.25, 0.5)  # weights a .25, b .25, c .5 → blended cycle 1.5 s
    assert result.cycle_length == pytest.approx(1.5)
    rates = {e.clip: e.playback_rate for e in result.weights}
    assert rates == pytest.approx({"a": 1.0 / 1.5, "b": 2.0 / 1.5, "c": 1.0})
    for entry in result.weights:
        assert entry.cycle_length is not None and entry.playback_rate is not None
        assert entry.cycle_length / entry.playback_rate == pytest.approx(1.5)


def test_cycle_length_falls_back_to_the_clip_duration_and_unknown_lengths_have_no_rate() -> None:
    raw = make_doc(TRIANGLE, axes=UNIT_BOX, durations={"a": 1.0}).model_dump()
    raw["samples"][1]["clip"] = {
        "duration": 3.0, "fps": 30.0, "frames": 90, "meters_per_unit": 1.0,
        "units_source": "file", "up_axis": "y", "root": "hips", "facing": "hips",
    }  # fmt: skip
    doc = BlendSpaceDocument.model_validate(raw)
    result = evaluate(doc, 0.25, 0.5)  # a .25 (1 s), b .25 (3 s), c .5 (unknown)
    rates = {e.clip: e.playback_rate for e in result.weights}
    assert result.cycle_length == pytest.approx(2.0)
    assert rates == {"a": pytest.approx(0.5), "b": pytest.approx(1.5), "c": None}


def _clip_info(duration: float, **extra: Any) -> dict[str, Any]:
    return {
        "duration": duration, "fps": 30.0, "frames": round(duration * 30) + 1, "meters_per_unit": 1.0,
        "units_source": "file", "up_axis": "y", "root": "hips", "facing": "hips", **extra,
    }  # fmt: skip


def test_rates_sync_stride_periods_and_clips_without_a_gait_play_at_rate_one() -> None:
    raw = make_doc(TRIANGLE, axes=UNIT_BOX, durations={"a": 2.0, "b": 1.5, "c": 1.0}).model_dump()
    # a is idle (no stride); b holds two strides of 0.75 s; c one stride of 1 s.
    for sample, period in zip(raw["samples"], (None, 0.75, 1.0), strict=True):
        sample["clip"] = _clip_info(sample["features"]["duration"], gait_period=period)
    result = evaluate(BlendSpaceDocument.model_validate(raw), 0.25, 0.5)  # a .25, b .25, c .5
    # Only the walking clips set the cadence: (0.25 x 0.75 + 0.5 x 1) / 0.75.
    blended = (0.25 * 0.75 + 0.5 * 1.0) / 0.75
    assert result.cycle_length == pytest.approx(blended)
    rates = {e.clip: e.playback_rate for e in result.weights}
    assert rates == pytest.approx({"a": 1.0, "b": 0.75 / blended, "c": 1.0 / blended})
    assert {e.clip: e.cycle_length for e in result.weights}["a"] is None


def _write_bvh_project(folder: Path, specs: list[GaitSpec]) -> Path:
    (folder / "clips").mkdir(parents=True)
    for spec in specs:
        write_bvh_clip(generate(spec), folder / "clips" / f"{spec.name}.bvh")
    manifest = folder / "manifest.yaml"
    manifest.write_text("schema_version: 1\nname: gait\nclips:\n  - path: clips/*.bvh\n", encoding="utf-8")
    return manifest


def test_built_documents_carry_the_stride_period_and_eval_syncs_by_it(tmp_path: Path) -> None:
    """Procedural clips of known stride: walk_fwd one stride in 1 s, walk_right two strides of
    0.75 s in 1.5 s (its duration is not its cycle), idle none."""
    specs = [
        GaitSpec("idle", duration=2.0),
        GaitSpec("walk_fwd", speed=1.3, duration=1.0),
        GaitSpec("walk_right", speed=1.4, turn_rate=-60.0, duration=1.5),
    ]
    doc = to_document(analyse(_write_bvh_project(tmp_path, specs), with_layers=False), tmp_path)
    periods = {s.name: s.clip.gait_period if s.clip else "missing" for s in doc.samples}
    assert periods == {"idle": None, "walk_fwd": pytest.approx(1.0, rel=0.01),
                       "walk_right": pytest.approx(0.75, rel=0.01)}  # fmt: skip
    # The written JSON says so too (null for idle), and survives the round trip.
    raw = json.loads(doc.model_dump_json())
    assert {s["name"]: s["clip"]["gait_period"] for s in raw["samples"]}["idle"] is None
    doc = BlendSpaceDocument.model_validate(raw)
    result = evaluate(doc, -30.0, 1.0, cull=0.0)
    weights = weights_of(result)
    assert set(weights) == {"idle", "walk_fwd", "walk_right"}
    blended = (weights["walk_fwd"] * 1.0 + weights["walk_right"] * 0.75) / (
        weights["walk_fwd"] + weights["walk_right"]
    )
    assert result.cycle_length == pytest.approx(blended, rel=0.01)
    rates = {e.clip: e.playback_rate for e in result.weights}
    assert rates["idle"] == 1.0
    # Synced by duration instead, walk_right would play at 1.5 / ~1.2, faster than walk_fwd.
    assert rates["walk_right"] == pytest.approx(0.75 / blended, rel=0.01)
    slow_down, speed_up = rates["walk_right"], rates["walk_fwd"]
    assert slow_down is not None and speed_up is not None
    assert slow_down < 1.0 < speed_up  # the quicker stride slows down, the slower one speeds up
    for entry in result.weights:
        if entry.clip != "idle":
            assert entry.cycle_length is not None and entry.playback_rate is not None
            assert entry.cycle_length / entry.playback_rate == pytest.approx(blended, rel=0.01)


# --- degenerate spaces ------------------------------------------------------------------------

COLLINEAR = {"idle": (0.0, 0.0), "walk": (0.0, 1.4), "run": (0.0, 4.0)}


@pytest.mark.parametrize(
    ("query", "expected", "outside", "evaluated"),
    [
        # On the chain: linear between the neighbouring samples, (4 - 2) / (4 - 1.4) for walk.
        ((0.0, 2.0), {"walk": 2.0 / 2.6, "run": 0.6 / 2.6}, False, None),
        ((0.0, 0.7), {"idle": 0.5, "walk": 0.5}, False, None),
        ((0.0, 1.4), {"walk": 1.0}, False, None),
        # Off the line: projected onto the nearest point of the chain (x = 0, same speed).
        ((90.0, 1.0), {"idle": 0.4 / 1.4, "walk": 1.0 / 1.4}, True, (0.0, 1.0)),
        # Beyond its ends: the end sample.
        ((0.0, 5.0), {"run": 1.0}, True, (0.0, 4.0)),
        ((-45.0, -2.0), {"idle": 1.0}, True, (0.0, 0.0)),
    ],
)
def test_collinear_samples_interpolate_along_their_chain(
    query: tuple[float, float],
    expected: dict[str, float],
    outside: bool,
    evaluated: tuple[float, float] | None,
) -> None:
    doc = make_doc(COLLINEAR, triangles=[])
    result = evaluate(doc, *query, cull=0.0)
    assert weights_of(result) == pytest.approx(expected)
    assert result.outside_hull is outside
    assert result.dimension == 1
    if evaluated is None:
        assert result.hull_point is None
    else:
        assert result.hull_point == pytest.approx(evaluated)


def test_a_diagonal_chain_interpolates_in_normalised_space() -> None:
    # On one line in axis units is on one line in normalised units (the map is affine).
    doc = make_doc({"a": (-90.0, -1.5), "b": (0.0, 0.0), "c": (90.0, 1.5)}, triangles=[])
    result = evaluate(doc, 45.0, 0.75, cull=0.0)
    assert weights_of(result) == pytest.approx({"b": 0.5, "c": 0.5})
    assert not result.outside_hull and result.dimension == 1


def test_a_single_sample_takes_everything_and_is_outside_elsewhere() -> None:
    doc = make_doc({"idle": (0.0, 0.0)}, triangles=[])
    at = evaluate(doc, 0.0, 0.0)
    assert weights_of(at) == {"idle": 1.0} and not at.outside_hull and at.dimension == 0
    away = evaluate(doc, 30.0, 2.0)
    assert weights_of(away) == {"idle": 1.0} and away.outside_hull and away.hull_point == (0.0, 0.0)
    assert evaluate(make_doc(LOCOMOTION), 0.0, 1.0).dimension == 2


def test_eval_command_says_when_the_space_is_degenerate(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = _write(make_doc(COLLINEAR, triangles=[]), tmp_path)
    assert main(["eval", str(path), "--at", "x=0,y=2"]) == 0
    text = capsys.readouterr().out
    assert "degenerate space (1D)" in text and "outside" not in text
    assert main(["eval", str(path), "--at", "x=90,y=1"]) == 0
    assert "outside the hull: the main space evaluates at the nearest point of the sample line (0, 1)" in (
        capsys.readouterr().out
    )
    assert main(["eval", str(path), "--at", "x=0,y=2", "--format", "json"]) == 0
    assert json.loads(capsys.readouterr().out)["dimension"] == 1
    single = _write(make_doc({"idle": (0.0, 0.0)}, triangles=[]), tmp_path)
    assert main(["eval", str(single), "--at", "x=0,y=0"]) == 0
    assert "degenerate space (0D)" in capsys.readouterr().out
    assert main(["eval", str(_write(make_doc(TRIANGLE, axes=UNIT_BOX), tmp_path)), "--at", "x=0,y=0"]) == 0
    assert "degenerate" not in capsys.readouterr().out


def test_unknown_layer_and_out_of_range_values_are_input_errors() -> None:
    doc = make_doc(TRIANGLE, axes=UNIT_BOX, layers=[_style()])
    with pytest.raises(InputError) as unknown:
        evaluate(doc, 0.0, 0.0, layers={"drunnk": 0.5})
    assert unknown.value.hint is not None and "did you mean 'drunk'" in unknown.value.hint
    with pytest.raises(InputError, match=r"outside \[0, 1\]"):
        evaluate(doc, 0.0, 0.0, layers={"drunk": 1.5})
    with pytest.raises(InputError, match="cull"):
        evaluate(doc, 0.0, 0.0, cull=1.0)


def test_layer_models_parse_both_kinds_and_reject_unknown_keys() -> None:
    doc = make_doc(TRIANGLE, axes=UNIT_BOX, layers=[_style(mask={"joints": {"Hips": 1.0}, "default": 0.0})])
    (layer,) = parse_layers(doc)
    assert isinstance(layer, StyleLayerDoc) and layer.mask is not None and layer.mask.weight("Head") == 0.0
    with pytest.raises(ValueError, match="extra"):
        parse_layer_list([{**_style(), "intensity": 0.5}])


# --- the command --------------------------------------------------------------------------


def _write(doc: BlendSpaceDocument, tmp_path: Path) -> Path:
    path = tmp_path / "test.blendspace.json"
    path.write_text(doc.model_dump_json(indent=1), encoding="utf-8")
    return path


def test_eval_command_prints_text_and_json(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    doc = make_doc(TRIANGLE, axes=UNIT_BOX, durations={"a": 1.0, "b": 2.0, "c": 1.5}, layers=[_style()])
    path = _write(doc, tmp_path)
    assert main(["eval", str(path), "--at", "x=0.25,y=0.5"]) == 0
    text = capsys.readouterr().out
    rows = [line.split() for line in text.splitlines()]
    assert ["a", "0.2500", "0.667", "(main)"] in rows
    assert ["c", "0.5000", "1.000", "(main)"] in rows
    assert "blended cycle: 1.500 s" in text
    assert "layer drunk (style) = 0" in text
    argv = ["eval", str(path), "--at", "turn_rate=0.25,speed=0.5", "--layer", "drunk=0.3", "--format", "json"]
    assert main(argv) == 0
    data = json.loads(capsys.readouterr().out)
    assert set(data) >= {"weights", "outside_hull"}
    assert set(data["weights"][0]) == {"clip", "weight", "layer", "playback_rate"}
    assert {w["clip"]: w["weight"] for w in data["weights"]} == pytest.approx(
        {"a": 0.175, "b": 0.175, "c": 0.35, "drunk_back": 0.15, "drunk_fwd": 0.15}
    )
    assert data["outside_hull"] is False
    assert {w["clip"]: w["layer"] for w in data["weights"]}["drunk_fwd"] == "drunk"


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--at", "x=0.1"], "must give both axes"),
        (["--at", "x=a,y=1"], "is not a number"),
        (["--at", "z=1,y=1"], "unknown axis 'z'"),
        (["--at", "x=0,x=1,y=1"], "gives axis x twice"),  # the last x won
        (["--at", "x=0,turn_rate=1,y=1"], "gives axis x twice"),
        (["--at", "x=0,y=0", "--layer", "drunkk=0.5"], "did you mean 'drunk'"),
        (["--at", "x=0,y=0", "--layer", "drunk"], "not NAME=VALUE"),
        (["--at", "x=0,y=0", "--layer", "drunk=0.5", "--layer", "drunk=0.7"], "--layer drunk is given twice"),
        (["--at", "x=0,y=0", "--joint", "Hips"], "no layer of this blend space has a per-joint mask"),
    ],
)
def test_eval_command_rejects_bad_arguments(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str], message: str
) -> None:
    path = _write(make_doc(TRIANGLE, axes=UNIT_BOX, layers=[_style()]), tmp_path)
    assert main(["eval", str(path), *argv]) == 2
    err = capsys.readouterr().err
    assert message in err and str(path) in err and "hint:" in err


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ('{"schema_version": 1, "name": ', "not valid JSON"),
        ('{"schema_version": 1, "name": "x"}', "not a blend-space document: axes"),
        (None, "cannot read"),
        # These were internal errors (exit 3): a binary file, deep nesting, a huge integer.
        (b"\x89PNG\r\n\x1a\n\x00\x00", "the file is not UTF-8 text"),
        ("[" * 100_000 + "]" * 100_000, "nested too deeply"),
        ('{"schema_version": ' + "9" * 5000 + "}", "a number too long to read"),
    ],
)
@pytest.mark.parametrize("command", ["eval", "export"])
def test_eval_and_export_reject_bad_documents(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    content: str | bytes | None,
    message: str,
    command: str,
) -> None:
    path = tmp_path / "bad.blendspace.json"
    if isinstance(content, bytes):
        path.write_bytes(content)
    elif content is not None:
        path.write_text(content, encoding="utf-8")
    argv = (
        ["--at", "x=0,y=0"] if command == "eval" else ["--engine", "godot", "--out", str(tmp_path / "x.tres")]
    )
    assert main([command, str(path), *argv]) == 2
    err = capsys.readouterr().err
    assert message in err and "hint:" in err and "Traceback" not in err


@pytest.mark.skipif(not Path("/dev/zero").exists(), reason="no /dev/zero here")
def test_eval_refuses_a_device_instead_of_reading_it_until_memory_runs_out(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert main(["eval", "/dev/zero", "--at", "x=0,y=0"]) == 2
    assert "not a regular file" in capsys.readouterr().err


def test_eval_command_rejects_triangles_naming_missing_samples(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    raw = make_doc(TRIANGLE, axes=UNIT_BOX).model_dump()
    raw["triangles"] = [[0, 1, 7]]
    path = tmp_path / "bad.blendspace.json"
    path.write_text(json.dumps(raw), encoding="utf-8")
    assert main(["eval", str(path), "--at", "x=0,y=0"]) == 2
    assert "triangle 0 [0, 1, 7]" in capsys.readouterr().err


def test_eval_command_rejects_a_joint_no_mask_names(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    mask = {"joints": {"Hips": 1.0, "Spine": 0.5}, "default": 0.25}
    path = _write(make_doc(TRIANGLE, axes=UNIT_BOX, layers=[_style(mask=mask)]), tmp_path)
    assert main(["eval", str(path), "--at", "x=0,y=0", "--layer", "drunk=0.4", "--joint", "Nope"]) == 2
    err = capsys.readouterr().err
    assert "--joint Nope: no mask names this joint (masked joints: Hips, Spine)" in err
    assert "drunk 0.25" in err and "Traceback" not in err
    assert main(["eval", str(path), "--at", "x=0,y=0", "--joint", "spine"]) == 2
    assert "did you mean 'Spine'" in capsys.readouterr().err
    assert main(["eval", str(path), "--at", "x=0,y=0", "--layer", "drunk=0.4", "--joint", "Spine"]) == 0
