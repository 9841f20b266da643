"""Flatten the whole blend graph for one query into (clip, weight, layer, playback rate).

This is what an engine would blend at (x, y) with the given layer values, computed the way
method.md §5–6 describes:

- the main space gives barycentric weights in the triangle holding the query (normalised axes,
  `geometry.blend_weights`); outside the hull the query moves to the nearest hull point. A
  degenerate space has no triangles: collinear samples (1D) interpolate linearly along their
  chain, a single sample position (0D) takes everything;
- a beta layer with value β mixes the result so far (1 − β) with its own 2D space at the same
  query (β), paper §4;
- a style layer with intensity s evaluates its 1D space at the query's value of the style's
  feature (normally speed) and mixes it over the result so far: result × (1 − s) + style × s;
  a ``joint`` applies the layer's per-joint mask to s (MechWarrior's feather blending);
- the flat list is then merged (the same clip reached twice counts once), culled (weights below
  ``cull``) and unitized to sum to 1, as MechWarrior 4's blend trees do before interpolating;
- playback rates keep the gait cycles of the blended clips aligned (MechWarrior's cadence
  rule): each walking clip plays at ``own stride period / weighted-average stride period`` so
  that every stride lasts the blended length; a clip without a gait (idle, turn on the spot)
  plays at rate 1 and stays out of the average. The stride period is the build's
  ``clip.gait_period``; documents written before it existed fall back to the clip's duration.

Layers apply in document order; a layer with no value (or 0) does not take part. In the JSON
(`Evaluation.to_json`), an entry's ``layer`` is null for the main space, else the name of the
layer where the graph first reached the clip; ``layers`` reports each layer's value, share of
the total weight, whether it clamped the query, and its per-joint mask.
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from blendspace_pipeline.errors import InputError
from blendspace_pipeline.motion.quaternions import FloatArray
from blendspace_pipeline.space.document import BlendSpaceDocument, SampleDoc
from blendspace_pipeline.space.geometry import AxisRange, blend_weights, normalise, space_dimension
from blendspace_pipeline.space.layers_doc import (
    BetaLayerDoc,
    MaskDoc,
    StyleLayerDoc,
    StyleSampleDoc,
    parse_layers,
)

MAIN = None  # the `layer` of entries that come from the main space
DEFAULT_CULL = 0.01


@dataclass(frozen=True)
class WeightEntry:
    """One clip of the flattened graph."""

    clip: str
    source: str
    weight: float
    layer: str | None  # first place the clip was reached: None = main space, else a layer name
    playback_rate: float | None  # 1 for a clip without a gait; None when its cycle is unknown
    cycle_length: float | None  # stride period (or, for older documents, duration); None: no gait

    def to_json(self) -> dict[str, Any]:
        return {
            "clip": self.clip,
            "weight": self.weight,
            "layer": self.layer,
            "playback_rate": self.playback_rate,
        }


@dataclass(frozen=True)
class LayerReport:
    """How one layer took part in the query."""

    name: str
    kind: str
    value: float
    share: float  # weight of the layer's branch before culling (0 when value is 0)
    outside_hull: bool  # beta: the query left its hull; style: the feature value was clamped
    mask: MaskDoc | None

    def to_json(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "kind": self.kind,
            "value": self.value,
            "share": self.share,
            "outside_hull": self.outside_hull,
            "mask": self.mask.model_dump() if self.mask is not None else None,
        }


@dataclass(frozen=True)
class Evaluation:
    query: tuple[float, float]
    weights: list[WeightEntry]
    outside_hull: bool  # the main space or an active beta space moved the query to its hull
    hull_point: tuple[float, float] | None  # where the main space evaluated, when it moved the query
    cycle_length: float | None  # the blended (weighted-average) cycle length, seconds
    layers: list[LayerReport] = field(default_factory=list)
    joint: str | None = None
    cull: float = DEFAULT_CULL
    dimension: int = 2  # what the main space spans: 2, or 1 (collinear samples) / 0 (one position)

    def to_json(self) -> dict[str, Any]:
        return {
            "weights": [entry.to_json() for entry in self.weights],
            "outside_hull": self.outside_hull,
            "query": list(self.query),
            "hull_point": list(self.hull_point) if self.hull_point is not None else None,
            "cycle_length": self.cycle_length,
            "layers": [layer.to_json() for layer in self.layers],
            "joint": self.joint,
            "cull": self.cull,
            "dimension": self.dimension,
        }


@dataclass
class _Contribution:
    """A clip reached through one branch of the graph, before merging."""

    key: tuple[str, str, str | None]
    sample: SampleDoc | StyleSampleDoc
    weight: float
    layer: str | None


def evaluate(
    doc: BlendSpaceDocument,
    x: float,
    y: float,
    *,
    layers: Mapping[str, float] | None = None,
    cull: float = DEFAULT_CULL,
    joint: str | None = None,
) -> Evaluation:
    """The flattened weights at (x, y) in axis units; see the module docstring for the rules."""
    values = _checked_values(doc, layers or {}, cull)
    _check_joint(doc, joint)
    query = np.array([float(x), float(y)])
    pairs, outside = _space_weights(doc, doc.samples, doc.triangles, query)
    contributions = [_Contribution((s.name, s.source, None), s, w, MAIN) for s, w in pairs]
    hull_point = _evaluated_point(pairs) if outside else None
    any_outside = outside
    reports: list[LayerReport] = []
    for layer in parse_layers(doc):
        value = values.get(layer.name, 0.0)
        intensity = value * _joint_factor(layer, joint)
        branch, layer_outside = _layer_branch(doc, layer, query) if intensity > 0 else ([], False)
        contributions = _mix(contributions, branch, intensity)
        any_outside = any_outside or (layer_outside and isinstance(layer, BetaLayerDoc))
        reports.append(_report(layer, value, layer_outside))
    reports = _with_shares(reports, contributions)
    entries, cycle = _sync(_unitize(_merge(contributions), cull))
    return Evaluation(
        query=(float(x), float(y)),
        weights=entries,
        outside_hull=any_outside,
        hull_point=hull_point,
        cycle_length=cycle,
        layers=reports,
        joint=joint,
        cull=cull,
        dimension=_dimension(doc),
    )


def _joint_factor(layer: BetaLayerDoc | StyleLayerDoc, joint: str | None) -> float:
    """The feather multiplier of ``layer`` at ``joint`` (1 for the whole body or an unmasked layer)."""
    if joint is None or not isinstance(layer, StyleLayerDoc) or layer.mask is None:
        return 1.0
    return layer.mask.weight(joint)


# --- input checks -----------------------------------------------------------------------------


def _checked_values(doc: BlendSpaceDocument, values: Mapping[str, float], cull: float) -> dict[str, float]:
    if not 0.0 <= cull < 1.0:
        raise InputError(f"cull threshold {cull} is outside [0, 1)", hint="use e.g. --cull 0.01 (1 %)")
    names = [layer.name for layer in parse_layers(doc)]
    for name, value in values.items():
        if name not in names:
            raise InputError(f"the blend space has no layer {name!r}", hint=_layer_hint(name, names))
        if not (math.isfinite(value) and 0.0 <= value <= 1.0):
            raise InputError(
                f"layer {name!r} value {value} is outside [0, 1]",
                hint="beta and style intensities run from 0 (layer off) to 1 (layer only)",
            )
    return dict(values)


def _check_joint(doc: BlendSpaceDocument, joint: str | None) -> None:
    """A ``joint`` must be one a layer's mask names: anything else (a typo) would silently get
    the masks' default weight. The document does not record the skeleton's other joints, so
    the hint says how to evaluate those: they all take their mask's default."""
    if joint is None:
        return
    masks = {
        layer.name: layer.mask
        for layer in parse_layers(doc)
        if isinstance(layer, StyleLayerDoc) and layer.mask is not None
    }
    if not masks:
        raise InputError(
            f"--joint {joint}: no layer of this blend space has a per-joint mask",
            hint="leave out --joint: without masks every joint blends the same",
        )
    known = sorted({name for mask in masks.values() for name in mask.joints})
    if joint in known:
        return
    close = difflib.get_close_matches(joint, known, n=1)
    defaults = ", ".join(f"{name} {mask.default:g}" for name, mask in masks.items())
    raise InputError(
        f"--joint {joint}: no mask names this joint (masked joints: {', '.join(known)})",
        hint=(f"did you mean {close[0]!r}? " if close else "")
        + f"joints a mask does not list take its default weight (layers with masks: {defaults}); "
        "for them pass --layer NAME=<value x default> without --joint",
    )


def _layer_hint(name: str, names: Sequence[str]) -> str:
    if not names:
        return "this blend space has no layers; add them under `layers:` in the manifest and rebuild"
    close = difflib.get_close_matches(name, names, n=1)
    listing = "layers: " + ", ".join(names)
    return f"did you mean {close[0]!r}? {listing}" if close else listing


# --- the spaces -------------------------------------------------------------------------------


def _axis_ranges(doc: BlendSpaceDocument) -> tuple[AxisRange, AxisRange]:
    return AxisRange(doc.axes[0].min, doc.axes[0].max), AxisRange(doc.axes[1].min, doc.axes[1].max)


def _space_weights(
    doc: BlendSpaceDocument, samples: Sequence[SampleDoc], triangles: list[list[int]], query: FloatArray
) -> tuple[list[tuple[SampleDoc, float]], bool]:
    """Barycentric weights of a 2D space on the main axes, in normalised coordinates."""
    ranges = _axis_ranges(doc)
    vertices = normalise(np.array([s.position for s in samples], dtype=np.float64).reshape(-1, 2), ranges)
    triangle_array = np.array(triangles, dtype=np.int64).reshape(-1, 3)
    pairs, outside = blend_weights(normalise(query, ranges), vertices, triangle_array)
    return [(samples[index], weight) for index, weight in pairs], outside


def _dimension(doc: BlendSpaceDocument) -> int:
    """What the main space spans (2, 1 or 0), in normalised coordinates like its weights."""
    points = np.array([s.position for s in doc.samples], dtype=np.float64).reshape(-1, 2)
    return space_dimension(normalise(points, _axis_ranges(doc)), np.array(doc.triangles).reshape(-1, 3))


def _evaluated_point(pairs: Sequence[tuple[SampleDoc, float]]) -> tuple[float, float]:
    """The hull point the engine evaluates: weights are linear, so the weighted vertex average."""
    point = sum((np.array(s.position) * w for s, w in pairs), start=np.zeros(2))
    return float(point[0]), float(point[1])


def _layer_branch(
    doc: BlendSpaceDocument, layer: BetaLayerDoc | StyleLayerDoc, query: FloatArray
) -> tuple[list[_Contribution], bool]:
    if isinstance(layer, BetaLayerDoc):
        pairs, outside = _space_weights(doc, layer.samples, layer.triangles, query)
        return [_Contribution((s.name, s.source, None), s, w, layer.name) for s, w in pairs], outside
    value = float(query[_axis_of_feature(doc, layer)])
    style_pairs, clamped = style_weights(layer.samples, value)
    # Masked styles reach only some joints: keep them apart from the same clip at full body.
    tag = layer.name if layer.mask is not None else None
    return [_Contribution((s.name, s.source, tag), s, w, layer.name) for s, w in style_pairs], clamped


def _axis_of_feature(doc: BlendSpaceDocument, layer: StyleLayerDoc) -> int:
    features = [axis.feature for axis in doc.axes]
    if layer.axis.feature not in features:
        raise InputError(
            f"style layer {layer.name!r} is laid out on {layer.axis.feature!r} but the main axes are "
            f"{features[0]!r} and {features[1]!r}",
            hint="a style layer needs its feature on one of the main axes; rebuild with matching axes",
        )
    return features.index(layer.axis.feature)


def style_weights(
    samples: Sequence[StyleSampleDoc], value: float
) -> tuple[list[tuple[StyleSampleDoc, float]], bool]:
    """Linear interpolation between the two style samples around ``value``, clamped at the ends.

    The second value says whether ``value`` was outside the samples' range (clamped).
    """
    ordered = sorted(samples, key=lambda s: s.position[0])
    positions = [s.position[0] for s in ordered]
    if value <= positions[0] or len(ordered) == 1:
        return [(ordered[0], 1.0)], value < positions[0]
    if value >= positions[-1]:
        return [(ordered[-1], 1.0)], value > positions[-1]
    upper = int(np.searchsorted(positions, value, side="right"))
    low, high = positions[upper - 1], positions[upper]
    t = (value - low) / (high - low)  # high > low: `upper` is the first position beyond value
    pairs = [(ordered[upper - 1], 1.0 - t), (ordered[upper], t)]
    return [(s, w) for s, w in pairs if w > 0.0], False


# --- composition ------------------------------------------------------------------------------


def _mix(so_far: list[_Contribution], branch: list[_Contribution], value: float) -> list[_Contribution]:
    """so_far × (1 − value) + branch × value: how both β and style intensities combine."""
    if value <= 0.0 or not branch:
        return so_far
    scaled = [_Contribution(c.key, c.sample, c.weight * (1.0 - value), c.layer) for c in so_far]
    added = [_Contribution(c.key, c.sample, c.weight * value, c.layer) for c in branch]
    return [c for c in scaled + added if c.weight > 0.0]


def _report(layer: BetaLayerDoc | StyleLayerDoc, value: float, outside: bool) -> LayerReport:
    mask = layer.mask if isinstance(layer, StyleLayerDoc) else None
    return LayerReport(layer.name, layer.kind, value, 0.0, outside, mask)


def _with_shares(reports: list[LayerReport], contributions: list[_Contribution]) -> list[LayerReport]:
    share: dict[str | None, float] = {}
    for c in contributions:
        share[c.layer] = share.get(c.layer, 0.0) + c.weight
    return [
        LayerReport(r.name, r.kind, r.value, share.get(r.name, 0.0), r.outside_hull, r.mask) for r in reports
    ]


def _merge(contributions: list[_Contribution]) -> list[_Contribution]:
    """One entry per clip; it keeps the layer where the graph first reached it."""
    merged: dict[tuple[str, str, str | None], _Contribution] = {}
    for c in contributions:
        if c.key in merged:
            merged[c.key].weight += c.weight
        else:
            merged[c.key] = _Contribution(c.key, c.sample, c.weight, c.layer)
    return list(merged.values())


def _unitize(contributions: list[_Contribution], cull: float) -> list[_Contribution]:
    """Drop weights below ``cull`` and rescale the rest to sum to 1 (MechWarrior's unitizing)."""
    total = sum(c.weight for c in contributions)
    if total <= 0.0:
        return []
    kept = [c for c in contributions if c.weight / total >= cull]
    if not kept:  # only when every clip is below the threshold: keep the strongest one
        kept = [max(contributions, key=lambda c: c.weight)]
    kept_total = sum(c.weight for c in kept)
    normalised = [_Contribution(c.key, c.sample, c.weight / kept_total, c.layer) for c in kept]
    return sorted(normalised, key=lambda c: -c.weight)


# --- playback-rate sync -----------------------------------------------------------------------


def cycle_length(sample: SampleDoc | StyleSampleDoc) -> float | None:
    """A clip's gait-cycle length in seconds: its stride period, None when it has no gait.

    Documents written before `clip.gait_period` existed fall back to the measured `duration`
    (else the clip's): right for a clip holding exactly one stride, which is all they knew.
    """
    info = sample.clip
    if info is not None and "gait_period" in info.model_fields_set:
        period = info.gait_period
        return float(period) if period is not None and period > 0.0 else None
    duration = sample.features.get("duration")
    if duration is None and info is not None:
        duration = info.duration
    return float(duration) if duration is not None and duration > 0.0 else None


def _has_no_gait(sample: SampleDoc | StyleSampleDoc) -> bool:
    """The build found no stride in the clip (not: the document does not say)."""
    info = sample.clip
    return info is not None and "gait_period" in info.model_fields_set and info.gait_period is None


def _sync(contributions: list[_Contribution]) -> tuple[list[WeightEntry], float | None]:
    """Rates that make every blended stride last the weighted-average stride (MechWarrior cadence).

    Clips without a gait play at their own speed (rate 1) and stay out of the average; clips
    whose cycle is unknown (an older document without durations) get no rate.
    """
    cycles = [cycle_length(c.sample) for c in contributions]
    known = [
        (c.weight, length) for c, length in zip(contributions, cycles, strict=True) if length is not None
    ]
    known_weight = sum(w for w, _ in known)
    blended = sum(w * length for w, length in known) / known_weight if known_weight > 0.0 else None
    entries = [
        WeightEntry(
            clip=c.sample.name,
            source=c.sample.source,
            weight=c.weight,
            layer=c.layer,
            playback_rate=_rate(c.sample, length, blended),
            cycle_length=length,
        )
        for c, length in zip(contributions, cycles, strict=True)
    ]
    return entries, blended


def _rate(sample: SampleDoc | StyleSampleDoc, length: float | None, blended: float | None) -> float | None:
    if length is not None and blended:
        return length / blended
    return 1.0 if _has_no_gait(sample) else None
