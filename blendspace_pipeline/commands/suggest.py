"""`blendspace suggest MANIFEST --library STORE [--format text|json]`: library clips that would
fill the manifest's placeholders.

For every placeholder the rules put in the space, the indexed clips of the same skeleton (the
same joints as the manifest's clips) nearest to it in the normalised space, with their measured
features, and a manifest patch (`clips:` entries) that adds the best one of each placeholder it
fills. A clip fills a placeholder when it lies within `thresholds.too_close` (normalised) of it,
the distance at which the rules count a position as taken; farther candidates are listed as the
nearest the library has, not patched in. Clips already in the manifest are not proposed.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
from pathlib import Path
from typing import Any

from blendspace_pipeline.commands._arguments import given, given_path
from blendspace_pipeline.errors import EXIT_OK

HELP = "propose library clips (from `blendspace index`) that fill a manifest's placeholders"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("manifest", type=given_path, metavar="MANIFEST", help="manifest YAML file")
    parser.add_argument(
        "--library", required=True, type=given, metavar="STORE", help="a store written by `blendspace index`"
    )
    parser.add_argument(
        "--count", type=_count, default=3, metavar="N", help="candidates per placeholder (default 3)"
    )
    parser.add_argument("--format", choices=("text", "json"), default="text", help="output format")


def run(args: argparse.Namespace) -> int:
    from blendspace_pipeline.pipeline.analysis import analyse
    from blendspace_pipeline.pipeline.library import layout_signature, read_index, skeleton_signature

    # The store first: a wrong one is bad input (exit 2), found before the manifest's analysis.
    rows = read_index(args.library)
    space = analyse(args.manifest)
    authored = [s.clip.measurement for s in space.samples if not s.generated]
    skeletons = {skeleton_signature(m.joint_names) for m in authored}
    # A row indexed with its hierarchy must have one of the set's; an older store's rows (no
    # `layout`) are matched by joint names only.
    layouts = {layout_signature(m.joint_names, m.joint_parents) for m in authored}
    in_manifest = {str(Path(s.clip.source).resolve()) for s in space.samples}
    # The same bytes elsewhere (the library holds a copy of the project's takes) are no new clip.
    in_manifest_bytes = {_digest(Path(s.clip.source)) for s in space.samples if not s.generated}
    candidates = [
        r
        for r in rows
        if r["skeleton"] in skeletons
        and r.get("layout") in (None, *layouts)
        and r["path"] not in in_manifest
        and r.get("digest") not in in_manifest_bytes
    ]
    axes = space.axes
    features = [f"feature.{axis.feature}" for axis in axes]
    spans = [axis.maximum - axis.minimum for axis in axes]
    reach = float(space.manifest.model.thresholds.too_close)

    def distance(row: dict[str, Any], position: tuple[float, float]) -> float:
        values = [row.get(feature) for feature in features]
        if any(v is None for v in values):
            return math.inf
        offsets = [100.0 * (float(v or 0.0) - p) / s for v, p, s in zip(values, position, spans, strict=True)]
        return math.hypot(*offsets)

    proposals: list[dict[str, Any]] = []
    for mark in space.placeholders:
        ranked = sorted(candidates, key=lambda row: (distance(row, mark.position), row["path"], row["name"]))
        best = [r for r in ranked[: args.count] if math.isfinite(distance(r, mark.position))]
        proposals.append(
            {
                "position": list(mark.position),
                "priority": mark.priority,
                "rule": mark.rule,
                "reason": mark.reason,
                "candidates": [
                    {
                        "path": row["path"],
                        "name": row["name"],
                        "distance": round(distance(row, mark.position), 6),
                        "fills": distance(row, mark.position) < reach,
                        "features": {
                            k.removeprefix("feature."): v
                            for k, v in row.items()
                            if k.startswith("feature.") and v is not None
                        },
                    }
                    for row in best
                ],
            }
        )
    patch = _patch(args.manifest, proposals, {sample.name for sample in space.samples})
    if args.format == "json":
        sys.stdout.write(
            json.dumps({"manifest": str(args.manifest), "placeholders": proposals, "patch": patch}, indent=2)
            + "\n"
        )
        return EXIT_OK
    lines = [
        f"{args.manifest}: {len(proposals)} placeholder(s), {len(candidates)} library clip(s) of its skeleton"
    ]
    for proposal in proposals:
        x, y = proposal["position"]
        lines.append(f"  {proposal['priority']} ({proposal['rule']}) at ({x:g}, {y:g}): {proposal['reason']}")
        for candidate in proposal["candidates"]:
            shown = ", ".join(
                f"{f}={candidate['features'].get(f.removeprefix('feature.'), float('nan')):.3g}"
                for f in features
            )
            lines.append(
                f"    {candidate['path']} [{candidate['name']}]  distance {candidate['distance']:.3g}  {shown}"
            )
        if not proposal["candidates"]:
            lines.append("    no library clip of this skeleton")
    if patch:
        lines.append("manifest patch (add under clips:):")
        lines += [f"  {line}" for line in patch.splitlines()]
    sys.stdout.write("\n".join(lines) + "\n")
    return EXIT_OK


def _count(text: str) -> int:
    """argparse type for --count: a whole number of at least 1 (argparse turns the error into exit
    2 naming the option). 0 listed no candidate and so said "no library clip" under every
    placeholder of a library that has them; a negative count sliced the ranking from the end."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"{text!r} is not a whole number: give 1 or more, e.g. --count 3"
        ) from None
    if value < 1:
        raise argparse.ArgumentTypeError(
            f"{value} is not a positive number of candidates: give 1 or more, e.g. --count 3"
        )
    return value


def _digest(path: Path) -> str | None:
    from blendspace_pipeline.pipeline.cache import content_digest

    try:
        return content_digest(path)
    except OSError:
        return None


def _patch(manifest: Path, proposals: list[dict[str, Any]], taken: set[str]) -> str:
    """`clips:` entries adding the nearest candidate of each placeholder (each file once), with
    paths relative to the manifest (`../library/...` too: an absolute path ties the manifest to
    one machine), and a `name:` where the clip's own name is one the manifest has already (two
    clips of one name are refused)."""
    chosen: dict[str, str] = {}
    for proposal in proposals:
        if proposal["candidates"] and proposal["candidates"][0]["fills"]:
            best = proposal["candidates"][0]
            chosen.setdefault(best["path"], best["name"])
    base = manifest.resolve().parent
    names = set(taken)
    entries = []
    for path, name in chosen.items():
        try:
            shown = Path(os.path.relpath(path, base)).as_posix()
        except ValueError:  # another drive (Windows)
            shown = Path(path).as_posix()
        entries.append(f"- path: {json.dumps(shown)}")
        if name in names:
            number = 1
            while (unique := f"{name}_library{number if number > 1 else ''}") in names:
                number += 1
            entries.append(f"  name: {json.dumps(unique)}")
            name = unique
        names.add(name)
    return "\n".join(entries) + ("\n" if entries else "")
