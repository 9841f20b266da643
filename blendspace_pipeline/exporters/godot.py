"""Godot 4: an `AnimationNodeBlendSpace2D` text resource (`.tres`) with our exact triangles.

Godot triangulates raw (unnormalised) positions when ``auto_triangles`` is on, which would not
match the triangulation the rules checked; so the export turns it off and writes our triangles.
Order matters (engines.md §3): ``_set_triangles`` ignores its input while ``auto_triangles`` is
true and ``add_triangle`` rejects indices of points not yet loaded, so ``auto_triangles = false``
and then ``triangles`` come after every ``blend_point_N`` line. Each point's ``node`` precedes its
``pos`` because setting ``node`` of index N is what creates point N. A space without triangles
(collinear samples, one sample) is refused: Godot would blend nothing in it.

The axis bounds go in an order that Godot's setters cannot clamp (`bounds_lines`); the header
keeps the ``uid`` of the file it replaces (Godot adds one and references the resource by it), or
gets a stable one derived from the space's name. Generated clips are referenced as animations of
the GLB the build wrote, imported into Godot as an Animation Library (see `_generated_clip`).
"""

from __future__ import annotations

import hashlib
import math
import os
import re
from pathlib import Path

from blendspace_pipeline.errors import InputError
from blendspace_pipeline.exporters import Convention, EngineSample, EngineSpace, ExportContext, format_number

# Right-handed, Y up, metres, radians: positive rotation about +Y turns the character left
# (counter-clockwise seen from above), as our turn_rate does; the TPS demo also puts
# strafe_left at +x, matching our lateral_speed > 0 = left. So no sign flips.
CONVENTION = Convention(
    engine="Godot",
    length_unit="m",
    metres_to_length=1.0,
    angle_unit="rad",
    degrees_to_angle=math.pi / 180.0,
    left_positive=True,
    handedness="right-handed, Y up, metres, radians",
)
SUFFIX = ".tres"
REPLACES = "a Godot resource holding a blend space"  # what an existing --out may be (`replaceable`); anything else is refused


def replaceable(text: str) -> bool:
    """Whether an existing --out file is this engine's file of a blend space, one a re-export
    may replace (keeping what the engine added to it); any other file is the user's."""
    return text.lstrip("\ufeff").startswith("[gd_resource") and "AnimationNodeBlendSpace" in text


LAYER_ADVICE = (
    "build them in an AnimationNodeBlendTree: a second BlendSpace2D mixed by an AnimationNodeBlend2 "
    "for beta, a BlendSpace1D over speed mixed by a Blend2 with a bone filter for a style"
)
MAX_BLEND_POINTS = 64  # AnimationNodeBlendSpace2D::MAX_BLEND_POINTS
# AnimationNodeBlendSpace2D's constructor: min_space (-1, -1), max_space (1, 1).
DEFAULT_MIN_SPACE = (-1.0, -1.0)
DEFAULT_MAX_SPACE = (1.0, 1.0)
_UID = re.compile(r'^\[gd_resource\b[^\]\n]*\buid="(uid://[a-y0-8]+)"', re.MULTILINE)
# core/io/resource_uid.cpp: ids are written in base 34 with these digits, most significant first.
_UID_DIGITS = "abcdefghijklmnopqrstuvwxy012345678"


def render(space: EngineSpace, context: ExportContext) -> tuple[str, list[str], dict[Path, str]]:
    if len(space.samples) > MAX_BLEND_POINTS:
        raise InputError(
            f"Godot's AnimationNodeBlendSpace2D holds at most {MAX_BLEND_POINTS} points; "
            f"this space has {len(space.samples)}",
            hint="split the space (e.g. forward and backward halves) or remove near-duplicate clips",
        )
    if not space.triangles:
        # Godot blends only inside triangles (`_process` returns nothing without them), and its own
        # auto_triangles would not help: it needs three points off one line, exactly what our
        # empty triangulation says this space lacks. An asset that plays nothing is worse than none.
        raise InputError(
            f"Godot's AnimationNodeBlendSpace2D blends only inside triangles and this space has none "
            f"(its {len(space.samples)} sample(s) lie on one line or at one point): Godot would play nothing",
            hint="add a clip off the line and rebuild, or blend these clips in an AnimationNodeBlendSpace1D "
            "over the axis they vary along (`blendspace eval` shows the weights along the line)",
        )
    ids = [f"AnimationNodeAnimation_{index}" for index in range(len(space.samples))]
    uid = previous_uid(context.previous) or stable_uid(f"{space.name}/{_file_name(context)}")
    lines = [
        f'[gd_resource type="AnimationNodeBlendSpace2D" load_steps={len(ids) + 1} format=3 uid="{uid}"]',
        "",
    ]
    notes: list[str] = []
    for node_id, sample in zip(ids, space.samples, strict=True):
        name = sample.name
        if sample.generated:
            name, comment, note = _generated_clip(sample, context)
            lines.append(comment)
            notes += [note] if note else []
        lines += [
            f'[sub_resource type="AnimationNodeAnimation" id="{node_id}"]',
            f"animation = &{_string(name)}",
            "",
        ]
    lines.append("[resource]")
    for index, (node_id, sample) in enumerate(zip(ids, space.samples, strict=True)):
        lines.append(f'blend_point_{index}/node = SubResource("{node_id}")')
        lines.append(f"blend_point_{index}/pos = {_vector(sample.position)}")
    x_axis, y_axis = space.axes
    lines += bounds_lines((x_axis.minimum, y_axis.minimum), (x_axis.maximum, y_axis.maximum))
    lines += [
        f"snap = {_vector((x_axis.step, y_axis.step))}",
        f"x_label = {_string(x_axis.label)}",
        f"y_label = {_string(y_axis.label)}",
        "auto_triangles = false",
        "triangles = PackedInt32Array(" + ", ".join(str(i) for t in space.triangles for i in t) + ")",
    ]
    return "\n".join(lines) + "\n", [*notes, *_notes(space)], {}


def bounds_lines(low: tuple[float, float], high: tuple[float, float]) -> list[str]:
    """``min_space``/``max_space`` lines in an order Godot's setters keep exactly.

    Godot loads a `.tres` by calling each property's setter in file order on a new resource, and
    both setters clamp: ``set_min_space`` lowers any component >= the current ``max_space`` (1 by
    default) to max - 1, ``set_max_space`` raises any component <= the current ``min_space`` (-1
    by default) to min + 1. So min first breaks a run-only axis (1..6 loads as 0..6) and max first
    breaks an axis entirely below -1. Min first is safe when every minimum is below the default
    maximum, max first when every maximum is above the default minimum; an x axis of 1..6 with a
    y axis of -6..-1 needs both, so the minimum is first widened below both defaults, then the
    maximum and the real minimum follow (the loader sets a repeated key again, in order).
    """
    if all(value < bound for value, bound in zip(low, DEFAULT_MAX_SPACE, strict=True)):
        return [f"min_space = {_vector(low)}", f"max_space = {_vector(high)}"]
    if all(value > bound for value, bound in zip(high, DEFAULT_MIN_SPACE, strict=True)):
        return [f"max_space = {_vector(high)}", f"min_space = {_vector(low)}"]
    widened = (min(low[0], DEFAULT_MIN_SPACE[0]), min(low[1], DEFAULT_MIN_SPACE[1]))
    return [f"min_space = {_vector(widened)}", f"max_space = {_vector(high)}", f"min_space = {_vector(low)}"]


def previous_uid(text: str | None) -> str | None:
    """The ``uid`` in the header of the file being replaced (Godot adds one when it saves)."""
    match = _UID.search(text or "")
    return match.group(1) if match else None


def stable_uid(key: str) -> str:
    """A Godot resource uid (63-bit id as ``uid://`` text) that is the same on every export of ``key``."""
    number = int.from_bytes(hashlib.sha256(key.encode()).digest()[:8], "big") & (2**63 - 1)
    digits = ""
    while True:
        number, digit = divmod(number, len(_UID_DIGITS))
        digits = _UID_DIGITS[digit] + digits
        if number == 0:
            return "uid://" + digits


def _file_name(context: ExportContext) -> str:
    return context.target.name if context.target is not None else ""


def _generated_clip(sample: EngineSample, context: ExportContext) -> tuple[str, str, str | None]:
    """The animation name of a generated clip, a comment saying where its GLB is, and a note if needed.

    Godot 4 imports a GLB "as Animation Library" (Import dock > Import As), and the AnimationPlayer's
    Manage Animations > Load Library names the library after the file: the animation the build
    wrote as ``<clip>`` in ``<clip>.glb`` is then ``<clip>/<clip>`` for the blend space.
    """
    name = f"{sample.name}/{sample.name}"
    glb = next((p for p in context.clip_files.get(sample.name, []) if p.suffix.lower() == ".glb"), None)
    if glb is None:
        return (
            name,
            f"; {sample.name}: generated clip without a GLB (build with clip_formats incl. glb)",
            (
                f"generated clip {sample.name} has no .glb beside the blend space: Godot 4 cannot import "
                "the USD/BVH; rebuild with `glb` in output.clip_formats"
            ),
        )
    project = _godot_project(context.target)
    if project is not None and _inside(glb, project):
        res = "res://" + glb.resolve().relative_to(project).as_posix()
        return name, f"; {sample.name}: {res} imported as Animation Library {sample.name!r}", None
    return (
        name,
        f"; {sample.name}: copy {glb.name} into the project, import it as Animation Library",
        (
            f"copy {glb} into your Godot project, import it as Animation Library and load it into the "
            f"AnimationPlayer (library {sample.name!r}, animation {name!r})"
        ),
    )


def _godot_project(target: Path | None) -> Path | None:
    """The folder holding ``project.godot`` above ``target``: where ``res://`` points."""
    if target is None:
        return None
    for folder in Path(os.path.abspath(target)).parents:
        if (folder / "project.godot").is_file():
            return folder.resolve()
    return None


def _inside(path: Path, folder: Path) -> bool:
    return path.resolve().is_relative_to(folder)


def _vector(values: tuple[float, float]) -> str:
    return f"Vector2({format_number(values[0])}, {format_number(values[1])})"


def _string(text: str) -> str:
    """A Godot string literal: backslash, quote and every control character escaped (a name read
    from a clip file may hold one; a NUL byte had gone into the .tres raw)."""
    escaped = text.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n")
    escaped = _CONTROL.sub(lambda m: f"\\u{ord(m.group()):04x}", escaped)
    return f'"{escaped}"'


_CONTROL = re.compile("[\x00-\x1f\x7f-\x9f]")


def _notes(space: EngineSpace) -> list[str]:
    names = ", ".join(sample.name for sample in space.samples)
    return [
        "Godot plays each point's animation at its own length; for the cadence rule (`blendspace eval` "
        "playback rates) set sync_mode = Cyclic Mutable on the blend space where your Godot has it "
        "(godot PR #117275); older versions only offer `sync`, which does not align cycle lengths",
        f"AnimationNodeAnimation names must match animations in the AnimationPlayer's library: {names}",
    ]
