"""The blend-space JSON document (`N.blendspace.json`, ``schema_version: 1``).

This is the engine-neutral result of a build and the input of `eval`, `export` and the report.
The keys named in spec.md are the contract; the extra keys (``snapping_error``, ``clip`` with its
``gait_period``, ``hint``, ``location``, ``build``) carry what the report and CI integrations need.
`blendspace schema blendspace` prints the JSON Schema of this model.
"""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

Severity = Literal["error", "warning", "info"]


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid")


class AxisDoc(_Strict):
    name: Literal["x", "y"] = Field(description="Axis name: x is the first blend parameter, y the second.")
    feature: str = Field(description="Measured feature that drives this axis (e.g. turn_rate, speed).")
    min: float = Field(description="Lower end of the axis range, in the feature's unit.")
    max: float = Field(description="Upper end of the axis range, in the feature's unit.")
    divisions: int = Field(
        description="Number of grid intervals; positions snap to min + k*(max-min)/divisions."
    )
    unit: str = Field(description="Unit of the feature (m/s, deg/s, deg, s).")


class ClipInfoDoc(_Strict):
    duration: float = Field(description="Length of the measured range, seconds.")
    fps: float = Field(description="Frames per second of the source.")
    frames: int = Field(description="Frames in the measured range.")
    meters_per_unit: float = Field(description="Length unit used for the measurement, metres per file unit.")
    units_source: str = Field(description="Where the unit came from: file, manifest or auto-detected.")
    up_axis: str = Field(description="Up axis used for the measurement (y or z).")
    root: str = Field(description="What the root motion was measured from (hip midpoint or a joint name).")
    facing: str = Field(description="What the facing was measured from (hip line or a joint axis).")
    range: list[float] | None = Field(
        default=None,
        description="The trimmed range measured, seconds: the frames `range:` (or range: auto) selected, "
        "first to last; also set when the file's first frame, a rest pose, was left out (`notes` says so). "
        "Contacts and markers count from its start.",
    )
    range_auto: bool = Field(default=False, description="Whether range: auto chose the range.")
    guesses: list[str] = Field(
        default_factory=list,
        description="Detection guesses (up axis, unit, root, facing) with the override that replaces each.",
    )
    notes: list[str] = Field(default_factory=list, description="What the reader or measurement noticed.")
    gait_period: float | None = Field(
        default=None,
        description="Seconds per stride (two steps) of the clip's gait, null when it has none (idle, "
        "turn on the spot); `eval` syncs playback rates by it. Absent in documents written before it "
        "existed, where `eval` falls back to the clip's duration.",
    )
    plant_phases: dict[str, float] | None = Field(
        default=None,
        description="Stride phase (0..1, 0 where the left foot passes the right one going forward) at "
        "which each foot plants (`left`, `right`); null without a gait or without foot contacts.",
    )


class MarkerDoc(_Strict):
    name: Literal["LeftFootDown", "RightFootDown"] = Field(description="Which foot comes down.")
    time: float = Field(description="When, in seconds of the used range.")


class SampleDoc(_Strict):
    name: str = Field(description="Clip name, unique in the blend space.")
    source: str = Field(description="Path of the clip file, relative to the JSON file when possible.")
    features: dict[str, float] = Field(
        description="Unsnapped measured features (see spec.md for units and signs)."
    )
    position: list[float] = Field(description="Snapped position in axis order (x, y).")
    generated: bool = Field(default=False, description="True when a fix generated this clip.")
    fix: str | None = Field(default=None, description="For generated samples, the fix that made it.")
    snapping_error: list[float] = Field(
        default_factory=lambda: [0.0, 0.0],
        description="Snapped minus measured value, per axis, in axis units.",
    )
    manual_position: list[float] | None = Field(
        default=None, description="Position an author gave by hand in the manifest (`position:`), if any."
    )
    clip: ClipInfoDoc | None = Field(default=None, description="Facts about the measured clip.")
    contacts: dict[str, list[list[float]]] | None = Field(
        default=None,
        description="Foot contacts per foot (`left`, `right`): [start, end] seconds of the used range "
        "during which the foot stands on the ground; absent for rigs without recognisable feet.",
    )
    markers: list[MarkerDoc] | None = Field(
        default=None,
        description="Sync markers (Unreal's sync markers): every foot-down event of `contacts`, sorted by "
        "time; a contact already under way at the first frame is not one. Absent without contacts.",
    )


class LocationDoc(_Strict):
    path: str = Field(description="File the diagnostic points at (usually the manifest).")
    line: int | None = Field(default=None, description="1-based line.")
    column: int | None = Field(default=None, description="1-based column.")


class DiagnosticDoc(_Strict):
    rule: str = Field(description="Rule slug, e.g. crossing-axis.")
    code: str = Field(description="Stable rule code, e.g. BS001.")
    severity: Severity = Field(description="error, warning or info.")
    message: str = Field(description="What is wrong, in one sentence.")
    clips: list[str] = Field(default_factory=list, description="Names of the clips involved.")
    position: list[float] | None = Field(default=None, description="Where in the space, in axis units.")
    fix: str | None = Field(default=None, description="Name of the automatic fix that applies, if any.")
    hint: str | None = Field(default=None, description="How to fix it.")
    location: LocationDoc | None = Field(default=None, description="Where in the manifest.")


class PlaceholderDoc(_Strict):
    position: list[float] = Field(description="Where a clip should be added, in axis units.")
    priority: Literal["necessary", "suggested"] = Field(
        description="necessary (orange) or suggested (green)."
    )
    rule: str = Field(description="Rule that asks for it.")
    reason: str = Field(description="Why a clip is wanted there.")
    features: dict[str, float] = Field(
        default_factory=dict, description="Feature values a new clip must have."
    )


class BuildInfoDoc(_Strict):
    tool_version: str = Field(description="blendspace-pipeline version that wrote the file.")
    manifest: str = Field(description="Manifest path.")
    thresholds: dict[str, float] = Field(default_factory=dict, description="Thresholds in force.")
    settings: dict[str, Any] = Field(default_factory=dict, description="Other settings in force.")


Grid = list[list[float | None]]


class BlendQualityDoc(_Strict):
    """The blend as the engine plays it (`space.runtime_blend`, `pipeline.blend_quality`)."""

    sync: Literal["none", "normalized", "markers"] = Field(
        description="How the samples were synced: none (every clip at rate 1), normalized (clip lengths "
        "stretched to their weighted mean: Unity, Unreal blend spaces, Godot) or markers (foot-down "
        "markers aligned to the heaviest clip)."
    )
    horizon: float = Field(description="Seconds of play the drift is measured over.")
    xs: list[float] = Field(description="Grid x values, axis units (columns).")
    ys: list[float] = Field(description="Grid y values, axis units (rows).")
    trajectory_error: Grid = Field(
        description="Per grid point (rows along y), the distance between the requested and the delivered "
        "axis values, % of an axis range; null outside the hull."
    )
    drift: Grid = Field(description="Metres between the requested and the delivered paths after `horizon` s.")
    drift_turn: Grid = Field(description="Degrees between their headings after `horizon` s.")
    foot_skate: Grid | None = Field(
        default=None,
        description="Mean ground speed (m/s) of the planted feet of the blended pose; null where unknown "
        "(outside the hull, clips without feet or unreadable).",
    )
    summary: dict[str, float] = Field(
        default_factory=dict,
        description="max/mean of each grid inside the hull (trajectory_error_max, drift_max, foot_skate_max, ...).",
    )


class BlendSpaceDocument(_Strict):
    schema_version: Literal[1] = Field(description="Version of this JSON layout.")
    name: str = Field(description="Blend-space name (file stem of the outputs).")
    axes: list[AxisDoc] = Field(description="The two axes, x then y.")
    samples: list[SampleDoc] = Field(description="Placed clips.")
    triangles: list[list[int]] = Field(description="Delaunay triangles as sample indices, counter-clockwise.")
    diagnostics: list[DiagnosticDoc] = Field(default_factory=list, description="Findings of the rules.")
    placeholders: list[PlaceholderDoc] = Field(default_factory=list, description="Clips the set should gain.")
    layers: list[dict[str, Any]] = Field(default_factory=list, description="Beta and style layers.")
    blend_quality: BlendQualityDoc | None = Field(
        default=None, description="The blend as the engine plays it: trajectory error, drift and foot skate."
    )
    build: BuildInfoDoc | None = Field(default=None, description="Build metadata (omitted from goldens).")
