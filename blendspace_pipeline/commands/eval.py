"""`blendspace eval BLENDSPACE.json --at x=..,y=.. [--layer NAME=VALUE ...]`: weights at one query.

`--points FILE` evaluates every row of a CSV file (x,y per line, axis units; an optional header
row) in one batch (`evaluate_many`): one line per query, or a JSON array with `--format json`.

Prints what the blend graph (main space, beta and style layers) blends at the query: clips,
weights summing to 1, the layer each clip comes from and the playback rate that keeps the gait
cycles aligned, then what those rates deliver (forward, lateral, turn) next to what was asked;
`--sync none|markers` gives the delivered motion under that sync mode instead of the listed
(normalized) rates. `--format json` gives `Evaluation.to_json()` plus `delivered` (null for blends
involving layers).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np

from blendspace_pipeline.commands._arguments import given_path
from blendspace_pipeline.errors import EXIT_OK, InputError, UsageError
from blendspace_pipeline.motion.blend_model import DEFAULT_SYNC, SYNC_MODES, SyncMode, playback_rates
from blendspace_pipeline.readers.limits import read_regular_file
from blendspace_pipeline.space.document import BlendSpaceDocument
from blendspace_pipeline.space.evaluate import (
    DEFAULT_CULL,
    Evaluation,
    LayerReport,
    evaluate,
    evaluate_many,
)
from blendspace_pipeline.space.layers_doc import read_document
from blendspace_pipeline.space.runtime_blend import delivered_at_rates, sample_period

HELP = "blend weights (and playback rates) the blend graph gives at one query point"

_AT_HINT = (
    "write --at x=VALUE,y=VALUE (axis units), or name the axes by feature, e.g. --at turn_rate=0,speed=1.4"
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "blendspace", type=given_path, metavar="BLENDSPACE.json", help="a built N.blendspace.json"
    )
    where = parser.add_mutually_exclusive_group(required=True)
    where.add_argument("--at", metavar="x=..,y=..", help="the query point, in axis units")
    where.add_argument(
        "--points",
        type=given_path,
        metavar="FILE.csv",
        help="evaluate every 'x,y' row of this CSV file (axis units; '-' reads stdin) in one batch",
    )
    parser.add_argument(
        "--layer",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="beta value or style intensity of a layer, 0..1 (repeatable; layers not given are off)",
    )
    parser.add_argument(
        "--cull", type=float, default=DEFAULT_CULL, help=f"drop weights below this (default {DEFAULT_CULL})"
    )
    parser.add_argument("--joint", metavar="NAME", help="apply the layers' per-joint masks for this joint")
    parser.add_argument(
        "--sync",
        choices=SYNC_MODES,
        default=DEFAULT_SYNC,
        help="how the engine keeps the clips in step, for the delivered motion of an --at query: "
        "normalized (the rates "
        "listed, what the exports set up), markers (the heaviest clip at 1, the others match its "
        f"stride) or none (every clip at 1) (default: {DEFAULT_SYNC})",
    )
    parser.add_argument(
        "--format", choices=("text", "json"), default="text", help="output format (default: text)"
    )


def run(args: argparse.Namespace) -> int:
    doc = read_document(args.blendspace)
    if args.points is not None:
        return _run_batch(args, doc)
    try:
        x, y = parse_at(args.at, doc)
        layers = parse_layer_values(args.layer)
        result = evaluate(doc, x, y, layers=layers, cull=args.cull, joint=args.joint)
    except InputError as error:
        if error.path is None:
            error.path = args.blendspace
        raise
    sync: SyncMode = args.sync
    if args.format == "json":
        # `Evaluation.to_json` stays what scripting gets; the command adds the delivered motion.
        data = {**result.to_json(), "delivered": delivered_motion(doc, result, sync)}
        sys.stdout.write(json.dumps(data, indent=2) + "\n")
    else:
        sys.stdout.write(render(doc, result, sync))
    return EXIT_OK


def _run_batch(args: argparse.Namespace, doc: BlendSpaceDocument) -> int:
    points = read_points(args.points, doc)
    try:
        result = evaluate_many(
            doc, points, layers=parse_layer_values(args.layer), cull=args.cull, joint=args.joint
        )
    except InputError as error:
        if error.path is None:
            error.path = args.blendspace
        raise
    if args.format == "json":
        sys.stdout.write(json.dumps(result.to_json()) + "\n")
        return EXIT_OK
    lines = []
    for row in range(len(result)):
        x, y = result.queries[row]
        parts = [
            f"{result.clips[index].name}={weight:.4f}"
            for index, weight in zip(result.clip_index[row], result.weights[row], strict=True)
            if index >= 0
        ]
        lines.append(f"{x:g},{y:g}: " + " ".join(parts) + (" (outside)" if result.outside_hull[row] else ""))
    sys.stdout.write("\n".join(lines) + "\n")
    return EXIT_OK


def read_points(path: Path, doc: BlendSpaceDocument) -> np.ndarray:
    """(Q, 2) queries from a CSV file of ``x,y`` rows. A first row that is not numbers is a header
    naming the columns, by axis (``x``, ``y``) or feature (``turn_rate``, ``speed``), in either
    order: a header ``speed,turn_rate`` had been skipped unread, and every row evaluated at the
    swapped point. A header that names no axis is an error, not skipped."""
    try:
        if str(path) == "-":
            text = sys.stdin.read()
        else:  # a regular file, opened without blocking (`--points /dev/zero` read until memory ran out)
            text = read_regular_file(path, what="points file").decode("utf-8")
    except InputError as error:
        raise InputError(error.message, path=path, hint="give a CSV file of x,y rows") from None
    except (OSError, UnicodeDecodeError) as error:
        raise InputError(
            f"cannot read points: {error}", path=path, hint="give a CSV file of x,y rows"
        ) from None
    text = text.removeprefix("\ufeff")  # Excel's UTF-8 byte-order mark, before a number or a header
    rows: list[tuple[float, float]] = []
    order = (0, 1)  # the column of x, of y
    for number, line in enumerate(text.splitlines(), start=1):
        cells = [cell.strip() for cell in line.split(",")]
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        try:
            if len(cells) != 2:
                raise ValueError
            values = float(cells[0]), float(cells[1])
        except ValueError:
            if not rows and number == 1:
                order = _header_order(cells, doc, path)
                continue
            raise InputError(
                f"row {number} is not two numbers: {line.strip()!r}",
                path=path,
                line=number,
                hint="each row is x,y in axis units, e.g. 0,1.4",
            ) from None
        x, y = values[order[0]], values[order[1]]
        if not (math.isfinite(x) and math.isfinite(y)):
            raise InputError(f"row {number} is not finite", path=path, line=number, hint="use finite numbers")
        rows.append((x, y))
    if not rows:
        raise InputError("no points in the file", path=path, hint="each row is x,y in axis units, e.g. 0,1.4")
    return np.array(rows, dtype=np.float64)


def _header_order(cells: list[str], doc: BlendSpaceDocument, path: Path) -> tuple[int, int]:
    """The columns of x and y that a header row names (axis names or features, any order)."""
    aliases: dict[str, int] = {axis.name: index for index, axis in enumerate(doc.axes)}
    aliases.update({axis.feature: index for index, axis in enumerate(doc.axes)})
    axes = [aliases.get(cell.strip("\"' \ufeff")) for cell in cells]
    if len(cells) != 2 or sorted(a for a in axes if a is not None) != [0, 1]:
        raise InputError(
            f"the header row {','.join(cells)!r} does not name both axes",
            path=path,
            line=1,
            hint=f"name the columns by axis or feature ({_axis_listing(doc)}), e.g. "
            f"{doc.axes[0].feature},{doc.axes[1].feature}, or leave the header out for x,y",
        )
    return (axes.index(0), axes.index(1))


def parse_at(text: str, doc: BlendSpaceDocument) -> tuple[float, float]:
    """``x=1,y=2`` or ``turn_rate=1,speed=2`` (the axes' features) → (x, y)."""
    aliases: dict[str, int] = {axis.name: index for index, axis in enumerate(doc.axes)}
    aliases.update({axis.feature: index for index, axis in enumerate(doc.axes)})
    values: dict[int, float] = {}
    for part in text.split(","):
        key, value = _key_value(part, "--at", _AT_HINT)
        if key not in aliases:
            raise UsageError(f"--at: unknown axis {key!r} (axes: {_axis_listing(doc)})", hint=_AT_HINT)
        if aliases[key] in values:  # x=0,x=1 (or x=0,turn_rate=1): not "the last one wins"
            raise UsageError(f"--at {text!r} gives axis {doc.axes[aliases[key]].name} twice", hint=_AT_HINT)
        values[aliases[key]] = _number(value, f"--at {key}", _AT_HINT)
    if set(values) != {0, 1}:
        raise UsageError(f"--at {text!r} must give both axes ({_axis_listing(doc)})", hint=_AT_HINT)
    return values[0], values[1]


def parse_layer_values(texts: list[str]) -> dict[str, float]:
    """Every ``--layer NAME=VALUE``; a layer given twice is an error, not "the last one wins"."""
    values: dict[str, float] = {}
    for text in texts:
        name, value = parse_layer_value(text)
        if name in values:
            raise UsageError(
                f"--layer {name} is given twice ({values[name]:g} and {value:g})",
                hint=f"give each layer once, e.g. --layer {name}={value:g}",
            )
        values[name] = value
    return values


def parse_layer_value(text: str) -> tuple[str, float]:
    hint = "write --layer NAME=VALUE with VALUE in 0..1, e.g. --layer lateral=0.5"
    name, value = _key_value(text, "--layer", hint)
    return name, _number(value, f"--layer {name}", hint)


def _key_value(part: str, option: str, hint: str) -> tuple[str, str]:
    key, sep, value = part.partition("=")
    if not sep or not key.strip() or not value.strip():
        raise UsageError(f"{option}: {part!r} is not NAME=VALUE", hint=hint)
    return key.strip(), value.strip()


def _number(text: str, what: str, hint: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise UsageError(f"{what}: {text!r} is not a number", hint=hint) from None
    if not math.isfinite(value):
        raise UsageError(f"{what}: {text!r} is not a finite number", hint=hint)
    return value


def _axis_listing(doc: BlendSpaceDocument) -> str:
    return ", ".join(f"{axis.name} = {axis.feature}" for axis in doc.axes)


def render(doc: BlendSpaceDocument, result: Evaluation, sync: SyncMode = DEFAULT_SYNC) -> str:
    """The text form: one line per clip, then where the query went and how each layer took part."""
    x_axis, y_axis = doc.axes
    lines = [
        f"{doc.name} at {x_axis.feature}={result.query[0]:g} {x_axis.unit}, "
        f"{y_axis.feature}={result.query[1]:g} {y_axis.unit}"
        + (f" (joint {result.joint})" if result.joint else ""),
    ]
    if result.dimension < 2:
        lines.append(_DEGENERATE[result.dimension])
    width = max([len("clip"), *(len(entry.clip) for entry in result.weights)])
    lines.append(f"  {'clip':<{width}}  weight  rate   layer")
    for entry in result.weights:
        rate = f"{entry.playback_rate:.3f}" if entry.playback_rate is not None else "  -  "
        layer = entry.layer if entry.layer is not None else "(main)"
        lines.append(f"  {entry.clip:<{width}}  {entry.weight:.4f}  {rate}  {layer}")
    if result.cycle_length is not None:
        lines.append(f"blended cycle: {result.cycle_length:.3f} s")
    if result.hull_point is not None:
        where = _NEAREST.get(result.dimension, "the nearest hull point")
        x, y = result.hull_point
        lines.append(f"outside the hull: the main space evaluates at {where} ({x:g}, {y:g})")
    elif result.outside_hull:
        lines.append("outside the hull of a beta layer: it evaluates at its nearest hull point")
    lines += [_layer_line(report) for report in result.layers]
    delivered = delivered_motion(doc, result, sync)
    if delivered is not None:
        lines.append(_delivered_line(delivered))
    return "\n".join(lines) + "\n"


def delivered_motion(
    doc: BlendSpaceDocument, result: Evaluation, sync: SyncMode = DEFAULT_SYNC
) -> dict[str, object] | None:
    """What the character really does when the clips play at the rates of ``sync`` (a clip played
    slower moves and turns slower), next to what was asked; main-space blends only, else None.

    ``normalized`` uses the rates `evaluate` lists (stride-normalised, what the exports set up);
    ``markers`` and ``none`` the rates `motion.blend_model.playback_rates` gives for that mode.
    """
    by_name = {s.name: s for s in doc.samples}
    entries = result.weights
    if not entries or any(
        e.layer is not None or e.playback_rate is None or e.clip not in by_name for e in entries
    ):
        return None
    samples = [by_name[e.clip] for e in entries]
    weights = [e.weight for e in entries]
    if sync == "normalized":
        rates = [float(e.playback_rate or 1.0) for e in entries]
    else:
        durations = [s.features.get("duration", 1.0) for s in samples]
        rates = playback_rates(weights, durations, [sample_period(s) for s in samples], sync)
    motion = delivered_at_rates(samples, weights, rates)
    if motion is None:
        return None
    asked = []
    for axis, value in zip(doc.axes, result.hull_point or result.query, strict=True):
        got = motion.feature(axis.feature)
        if got is not None:
            asked.append({"feature": axis.feature, "unit": axis.unit, "delivered": got, "asked": value})
    return {
        "sync": sync,
        "playback_rates": {e.clip: rate for e, rate in zip(entries, rates, strict=True)},
        "forward_speed": motion.forward,
        "lateral_speed": motion.lateral,
        "turn_rate": motion.turn_rate,
        "axes": asked,
    }


def _delivered_line(delivered: dict[str, Any]) -> str:
    asked = [
        f"{a['feature']} {a['delivered']:.3g} {a['unit']} for {a['asked']:g} asked" for a in delivered["axes"]
    ]
    sync = "" if delivered["sync"] == DEFAULT_SYNC else f" (sync {delivered['sync']})"
    return (
        f"delivered at these rates{sync}: forward {delivered['forward_speed']:.3g} m/s, "
        f"lateral {delivered['lateral_speed']:.3g} m/s, turn {delivered['turn_rate']:.3g} deg/s"
        + (f" ({'; '.join(asked)})" if asked else "")
    )


_NEAREST = {0: "the only sample position", 1: "the nearest point of the sample line"}
# Said when the main space has no triangles, so nobody mistakes it for a 2D blend.
_DEGENERATE = {
    0: "degenerate space (0D): every sample sits at one position, so it takes the whole weight; "
    "add clips elsewhere to blend",
    1: "degenerate space (1D): the samples lie on one line, so weights interpolate along it "
    "between neighbouring samples; add a clip off the line for a 2D blend",
}


def _layer_line(report: LayerReport) -> str:
    text = f"layer {report.name} ({report.kind}) = {report.value:g}, share {report.share:.4f}"
    if report.outside_hull:
        text += ", clamped to its range" if report.kind == "style" else ", outside its hull"
    if report.mask is not None:
        joints = ", ".join(f"{name} {weight:g}" for name, weight in sorted(report.mask.joints.items()))
        text += f"; mask: {joints}; other joints {report.mask.default:g}"
    return text
