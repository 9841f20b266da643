"""Engine exports of a blend-space document: one adapter module per engine.

Each module in this package (`godot`, `unity`, `unreal`) exposes ``CONVENTION`` (the engine's
units and sign of turning), ``SUFFIX`` (the default file ending), ``LAYER_ADVICE`` (how to build
the layers it cannot hold) and ``render(space) -> (text, notes)``. This module turns the
document into an `EngineSpace` in the engine's conventions — the same for every engine, so the
adapters only format — and collects what no target can express. docs/decisions/0003 explains
the conventions.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass, field
from pathlib import Path
from types import ModuleType

from blendspace_pipeline.errors import InputError
from blendspace_pipeline.motion.notes import HELD_MARK, REST_FRAME_NOTE
from blendspace_pipeline.report.atomic import atomic_path
from blendspace_pipeline.space.document import AxisDoc, BlendSpaceDocument, SampleDoc
from blendspace_pipeline.space.layers_doc import parse_layers

ENGINES = ("godot", "unity", "unreal")

# Features whose sign depends on handedness: positive means left / counter-clockwise from above
# in our JSON (spec.md), and must flip for engines where positive yaw turns right.
HANDED_FEATURES = frozenset({"turn_rate", "turn", "direction", "lateral_speed"})
_LENGTH_UNITS = {"m/s": "/s", "m": ""}
_ANGLE_UNITS = {"deg/s": "/s", "deg": ""}
_DIGITS = 9  # far below any measurement's precision; hides float noise from unit conversion


@dataclass(frozen=True)
class Convention:
    """How an engine measures what our axes carry."""

    engine: str
    length_unit: str  # e.g. "m", "cm"
    metres_to_length: float
    angle_unit: str  # "deg" or "rad"
    degrees_to_angle: float
    left_positive: bool  # positive yaw / lateral = left (counter-clockwise seen from above)
    handedness: str  # for the notes: e.g. "right-handed, Y up"


@dataclass(frozen=True)
class EngineAxis:
    feature: str
    unit: str
    minimum: float
    maximum: float
    divisions: int
    flipped: bool  # the sign was flipped for the engine's handedness

    @property
    def label(self) -> str:
        return f"{self.feature} ({self.unit})" if self.unit else self.feature

    @property
    def step(self) -> float:
        return rounded((self.maximum - self.minimum) / self.divisions)


@dataclass(frozen=True)
class EngineSample:
    name: str
    source: str
    position: tuple[float, float]
    generated: bool
    # Foot-down sync markers (name, seconds from the start of the clip's file: the measured range's
    # own times shifted by its `range:` start), for engines that sync by markers (Unreal).
    markers: tuple[tuple[str, float], ...] = ()
    # The seconds of the source file the sample was measured on, when a `range:` trimmed it or its
    # first frame, a rest pose, was left out (``rest_frame``).
    trim: tuple[float, float] | None = None
    rest_frame: bool = False
    held_keys: bool = False  # frames repeating the pose at either end were left out


@dataclass(frozen=True)
class EngineSpace:
    name: str
    axes: tuple[EngineAxis, EngineAxis]
    samples: list[EngineSample]
    triangles: list[tuple[int, int, int]]
    layer_names: list[str]
    source: str  # the JSON file the export came from, for headers
    notes: list[str] = field(default_factory=list)


@dataclass(frozen=True)
class Export:
    engine: str
    text: str
    suffix: str
    notes: list[str]
    # Extra files the engine needs beside the main one (Unity `.meta` files of generated clips):
    # path -> text, written with the export and never over a file the user already has.
    extra_files: dict[Path, str] = field(default_factory=dict)


@dataclass(frozen=True)
class ExportContext:
    """What an export may know beyond the document: the files around it.

    ``previous`` is the text of the file the export replaces, so identifiers an engine added to it
    (Godot's ``uid``, Unity's hand-assigned motions) survive a re-export. ``clip_files`` maps each
    sample to the clip files the build wrote or read (absolute paths), ``target`` is where the
    export goes and ``unity_project`` the Unity project whose `.meta` GUIDs to use.
    """

    previous: str | None = None
    target: Path | None = None
    clip_files: dict[str, list[Path]] = field(default_factory=dict)
    unity_project: Path | None = None


def rounded(value: float) -> float:
    return round(float(value), _DIGITS) + 0.0  # + 0.0 turns -0.0 into 0.0


def format_number(value: float) -> str:
    """Shortest text for a number: ``1`` for 1.0, ``-0.25``, ``0.017453293``."""
    value = rounded(value)
    return str(int(value)) if value.is_integer() and abs(value) < 1e15 else repr(value)


def adapter(engine: str) -> ModuleType:
    if engine not in ENGINES:
        raise InputError(f"unknown engine {engine!r}", hint="choose one of: " + ", ".join(ENGINES))
    return importlib.import_module(f"blendspace_pipeline.exporters.{engine}")


def export(
    doc: BlendSpaceDocument, engine: str, source: str = "", context: ExportContext | None = None
) -> Export:
    """The engine file for ``doc`` and the notes on what the engine cannot express."""
    module = adapter(engine)
    space = to_engine(doc, module.CONVENTION, source)
    text, notes, extra = module.render(space, context or ExportContext())
    common = common_notes(space, module.CONVENTION, module.LAYER_ADVICE)
    return Export(engine=engine, text=text, suffix=module.SUFFIX, notes=[*common, *notes], extra_files=extra)


def write_export(result: Export, path: Path) -> None:
    """Write atomically: a failed export never leaves half a file for an engine to import.

    Extra files (Unity `.meta`) are written first: a controller never points at a GUID whose
    `.meta` is missing.
    """
    for extra, text in result.extra_files.items():
        with atomic_path(extra) as temporary:
            temporary.write_text(text, encoding="utf-8", newline="\n")
    with atomic_path(path) as temporary:
        temporary.write_text(result.text, encoding="utf-8", newline="\n")


# --- conversion -------------------------------------------------------------------------------


def _scale(axis: AxisDoc, convention: Convention) -> tuple[float, str]:
    """Factor from our unit to the engine's, and the engine's unit name."""
    if axis.unit in _LENGTH_UNITS:
        return convention.metres_to_length, convention.length_unit + _LENGTH_UNITS[axis.unit]
    if axis.unit in _ANGLE_UNITS:
        return convention.degrees_to_angle, convention.angle_unit + _ANGLE_UNITS[axis.unit]
    return 1.0, axis.unit


def _factor(axis: AxisDoc, convention: Convention) -> tuple[float, str, bool]:
    scale, unit = _scale(axis, convention)
    flipped = not convention.left_positive and axis.feature in HANDED_FEATURES
    return (-scale if flipped else scale), unit, flipped


def to_engine(doc: BlendSpaceDocument, convention: Convention, source: str = "") -> EngineSpace:
    factors = [_factor(axis, convention) for axis in doc.axes]
    axes = tuple(_engine_axis(axis, *factor) for axis, factor in zip(doc.axes, factors, strict=True))
    samples = [
        EngineSample(
            name=s.name,
            source=s.source,
            position=(rounded(s.position[0] * factors[0][0]), rounded(s.position[1] * factors[1][0])),
            generated=s.generated,
            markers=_markers(s),
            trim=_trim(s),
            rest_frame=s.clip is not None and REST_FRAME_NOTE in s.clip.notes,
            held_keys=s.clip is not None and any(HELD_MARK in note for note in s.clip.notes),
        )
        for s in doc.samples
    ]
    return EngineSpace(
        name=doc.name,
        axes=(axes[0], axes[1]),
        samples=samples,
        triangles=[(t[0], t[1], t[2]) for t in doc.triangles],
        layer_names=[layer.name for layer in parse_layers(doc)],
        source=source,
    )


def _engine_axis(axis: AxisDoc, factor: float, unit: str, flipped: bool) -> EngineAxis:
    ends = sorted((rounded(axis.min * factor), rounded(axis.max * factor)))
    return EngineAxis(axis.feature, unit, ends[0], ends[1], axis.divisions, flipped)


# --- what the engines cannot express ----------------------------------------------------------


def _trim(sample: SampleDoc) -> tuple[float, float] | None:
    """The span of its file a take was measured on, when not all of it: a `range:` (or `range:
    auto`), or its first frame, a rest pose, left out."""
    clip = sample.clip
    if clip is None or not clip.range or sample.generated:
        return None
    return clip.range[0], clip.range[1]


def common_notes(space: EngineSpace, convention: Convention, layer_advice: str) -> list[str]:
    notes = [_convention_note(space, convention)]
    if space.layer_names:
        notes.append(
            f"layers {', '.join(space.layer_names)} are not exported: one {convention.engine} blend space "
            f"holds the main space only; {layer_advice}"
        )
    outside = [s.name for s in space.samples if not _inside(s.position, space.axes)]
    if outside:
        notes.append(f"samples outside the axis ranges: {', '.join(outside)}")
    for sample in space.samples:
        if sample.trim is not None:
            # The exports name clips, and engines play a clip file whole: a take measured over a
            # `range:` (start, walk, stop) would blend its start and stop too, and a rest pose
            # left in the file pops at the start of every loop.
            left_out = [
                what
                for what, yes in (
                    ("its first frame, a rest pose, left out", sample.rest_frame),
                    ("held keys at its ends left out", sample.held_keys),
                )
                if yes
            ]
            why = f" ({'; '.join(left_out)})" if left_out else ""
            notes.append(
                f"{sample.name} was measured on {sample.trim[0]:.2f}-{sample.trim[1]:.2f} s of "
                f"{Path(sample.source).name}{why}: {convention.engine} plays the whole file unless that span "
                "is imported as its own clip (or the file is cut to it)"
            )
    generated = [s.name for s in space.samples if s.generated]
    if generated:
        notes.append(
            f"generated clips must be imported too (see the build's clips/ folder): {', '.join(generated)}"
        )
    return notes


def _convention_note(space: EngineSpace, convention: Convention) -> str:
    flips = [axis.feature for axis in space.axes if axis.flipped]
    text = f"{convention.engine} conventions ({convention.handedness}): axes in " + ", ".join(
        axis.label for axis in space.axes
    )
    if flips:
        text += f"; sign of {', '.join(flips)} flipped (positive turns right in {convention.engine})"
    return text


def _inside(position: tuple[float, float], axes: tuple[EngineAxis, EngineAxis]) -> bool:
    return all(axis.minimum <= value <= axis.maximum for value, axis in zip(position, axes, strict=True))


def duplicate_positions(space: EngineSpace) -> list[tuple[str, str]]:
    seen: dict[tuple[float, float], str] = {}
    pairs: list[tuple[str, str]] = []
    for sample in space.samples:
        if sample.position in seen:
            pairs.append((seen[sample.position], sample.name))
        else:
            seen[sample.position] = sample.name
    return pairs


def _markers(sample: SampleDoc) -> tuple[tuple[str, float], ...]:
    if not sample.markers:
        return ()
    start = sample.clip.range[0] if sample.clip is not None and sample.clip.range else 0.0
    return tuple((m.name, round(m.time + start, 6)) for m in sample.markers)
