"""Godot 4: an `AnimationNodeBlendSpace2D` text resource (`.tres`) with our exact triangles.

Godot triangulates raw (unnormalised) positions when ``auto_triangles`` is on, which would not
match the triangulation the rules checked; so the export turns it off and writes our triangles.
Order matters (engines.md §3): ``_set_triangles`` ignores its input while ``auto_triangles`` is
true and ``add_triangle`` rejects indices of points not yet loaded, so ``auto_triangles = false``
and then ``triangles`` come after every ``blend_point_N`` line. Each point's ``node`` precedes its
``pos`` because setting ``node`` of index N is what creates point N. A space without triangles
(collinear samples, one sample) is refused: Godot would blend nothing in it.
"""

from __future__ import annotations

import math

from blendspace_pipeline.errors import InputError
from blendspace_pipeline.exporters import Convention, EngineSpace, format_number

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
LAYER_ADVICE = (
    "build them in an AnimationNodeBlendTree: a second BlendSpace2D mixed by an AnimationNodeBlend2 "
    "for beta, a BlendSpace1D over speed mixed by a Blend2 with a bone filter for a style"
)
MAX_BLEND_POINTS = 64  # AnimationNodeBlendSpace2D::MAX_BLEND_POINTS


def render(space: EngineSpace) -> tuple[str, list[str]]:
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
    lines = [f'[gd_resource type="AnimationNodeBlendSpace2D" load_steps={len(ids) + 1} format=3]', ""]
    for node_id, sample in zip(ids, space.samples, strict=True):
        lines += [
            f'[sub_resource type="AnimationNodeAnimation" id="{node_id}"]',
            f"animation = &{_string(sample.name)}",
            "",
        ]
    lines.append("[resource]")
    for index, (node_id, sample) in enumerate(zip(ids, space.samples, strict=True)):
        lines.append(f'blend_point_{index}/node = SubResource("{node_id}")')
        lines.append(f"blend_point_{index}/pos = {_vector(sample.position)}")
    x_axis, y_axis = space.axes
    lines += [
        f"min_space = {_vector((x_axis.minimum, y_axis.minimum))}",
        f"max_space = {_vector((x_axis.maximum, y_axis.maximum))}",
        f"snap = {_vector((x_axis.step, y_axis.step))}",
        f"x_label = {_string(x_axis.label)}",
        f"y_label = {_string(y_axis.label)}",
        "auto_triangles = false",
        "triangles = PackedInt32Array(" + ", ".join(str(i) for t in space.triangles for i in t) + ")",
    ]
    return "\n".join(lines) + "\n", _notes(space)


def _vector(values: tuple[float, float]) -> str:
    return f"Vector2({format_number(values[0])}, {format_number(values[1])})"


def _string(text: str) -> str:
    escaped = text.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n")
    return f'"{escaped}"'


def _notes(space: EngineSpace) -> list[str]:
    names = ", ".join(sample.name for sample in space.samples)
    return [
        "Godot plays each point's animation at its own length; for the cadence rule (`blendspace eval` "
        "playback rates) set sync_mode = Cyclic Mutable on the blend space where your Godot has it "
        "(godot PR #117275); older versions only offer `sync`, which does not align cycle lengths",
        f"AnimationNodeAnimation names must match animations in the AnimationPlayer's library: {names}",
    ]
