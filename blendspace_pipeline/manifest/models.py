"""The manifest (``schema_version: 1``) as pydantic models.

The keys and defaults are the contract in spec.md. Every model forbids unknown keys so a typo is an
error with a line number instead of a silently ignored setting, and every field carries a
description because these models generate the committed JSON Schema (`blendspace schema`).
Rules that need a hint to be useful raise `PydanticCustomError` with a ``hint`` in its context;
the loader turns it into the error's ``hint:`` line.
"""

from __future__ import annotations

import os
import re
from typing import Annotated, Any, Literal

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    NonNegativeFloat,
    PositiveFloat,
    PositiveInt,
    Strict,
    field_validator,
    model_validator,
)
from pydantic_core import PydanticCustomError

FeatureName = Literal[
    "speed",
    "displacement_speed",
    "forward_speed",
    "lateral_speed",
    "direction",
    "turn_rate",
    "turn",
    "duration",
]
FEATURES: tuple[FeatureName, ...] = (
    "speed",
    "displacement_speed",
    "forward_speed",
    "lateral_speed",
    "direction",
    "turn_rate",
    "turn",
    "duration",
)
Unit = Literal["auto", "m", "cm", "mm", "in"]
# YAML gives numbers and booleans their own types: `divisions: true` is not 1, `min: "-3"` is not
# a number and `mirror: "off"` not false (the committed JSON Schema says so; the models agree).
Number = Annotated[float, Strict()]
Flag = Annotated[bool, Strict()]
Weight = Annotated[float, Strict(), Field(ge=0.0, le=1.0)]
_SAFE_STEM = re.compile(r"[A-Za-z0-9_.\-]+")


def rule_error(message: str, hint: str) -> PydanticCustomError:
    """A validation failure the loader reports with its own hint (braces escaped for pydantic's template)."""
    template = message.replace("{", "{{").replace("}", "}}")
    return PydanticCustomError("manifest_rule", template, {"hint": hint})


class _Model(BaseModel):
    # allow_inf_nan=False: `.inf`/`.nan` are valid YAML floats but meaningless in an axis or threshold.
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


class IgnoreEntry(_Model):
    """Silence one rule for one clip; the reason is required so the suppression explains itself."""

    rule: str = Field(description="Rule slug (e.g. too-close) or code (e.g. BS004) to silence for this clip.")
    reason: str = Field(description="Why the finding is accepted; shown in the report. Must not be empty.")

    @field_validator("reason")
    @classmethod
    def _reason_not_blank(cls, value: str) -> str:
        if not value.strip():
            raise rule_error(
                "the reason is empty", 'say why the finding is accepted, e.g. reason: "kept for the style"'
            )
        return value


# Control characters (C0, DEL, C1) and the bidirectional overrides and isolates (a name that
# reads one way and sorts another).
_UNPRINTABLE = re.compile("[\x00-\x1f\x7f-\x9f\u202a-\u202e\u2066-\u2069]")


class MirrorTokens(_Model):
    """Name tokens swapped to mirror a clip (e.g. Left <-> Right)."""

    left: str = Field(description="Token that marks left-side joints, e.g. 'Left' or '_l'.")
    right: str = Field(description="Token that marks right-side joints, e.g. 'Right' or '_r'.")

    @model_validator(mode="after")
    def _two_tokens(self) -> MirrorTokens:
        # Empty or equal tokens pair every joint with itself: a "mirror" that swaps nothing was
        # written, with no word.
        if not self.left.strip() or not self.right.strip():
            raise rule_error(
                "a mirror token is empty", "write the two side tokens, e.g. {left: Left, right: Right}"
            )
        if self.left == self.right:
            raise rule_error(
                f"left and right are the same token {self.left!r}",
                "write the two side tokens, e.g. {left: Left, right: Right}",
            )
        return self


class SkeletonSettings(_Model):
    """How to read the rig; everything is auto-detected unless set here."""

    units: Unit | Annotated[PositiveFloat, Strict()] = Field(
        default="auto",
        description="Length unit of the clip files: auto, m, cm, mm, in, or a number of metres per file unit "
        "(for unusual mocap units).",
    )
    up: Literal["auto", "y", "z"] = Field(default="auto", description="Up axis of the clip files.")
    root: str = Field(
        default="auto",
        description="Joint whose ground projection is the root motion; auto = the midpoint of the hips.",
    )
    left_hip: str = Field(
        default="auto", description="Left hip joint name; auto = found from the joint names."
    )
    right_hip: str = Field(
        default="auto", description="Right hip joint name; auto = found from the joint names."
    )
    mirror: Literal["auto"] | MirrorTokens = Field(
        default="auto", description="Left/right name tokens swapped when mirroring clips; auto = detected."
    )
    forward: Literal["auto", "+x", "-x", "+y", "-y", "+z", "-z"] = Field(
        default="auto",
        description="The root joint's forward axis, used when facing cannot come from the hip line.",
    )
    tpose: Literal["auto", "keep", "drop"] = Field(
        default="auto", description="Whether to drop a T-pose/rest first frame; auto = drop it when detected."
    )


class ClipEntry(_Model):
    """One clip file, or a glob of clip files, with optional per-clip settings."""

    path: str = Field(
        description="Clip file or glob (*, ?, [...], **), relative to the manifest's folder; absolute paths "
        "and '..' are allowed, backslashes are read as folder separators."
    )
    name: str | None = Field(
        default=None,
        description="Clip name; default the file stem ('<stem>/<animation>' for multi-animation files). "
        "A named glob must match exactly one file.",
    )
    range: tuple[Number, Number] | Literal["auto"] | None = Field(
        default=None,
        description="Optional trim [start, end] in seconds (0 <= start < end), or auto: the steady "
        "locomotion part as whole gait cycles (T-pose, start from standing and stop left out).",
    )
    expect: dict[FeatureName, Number] | None = Field(
        default=None,
        description="Intended feature values, checked by the misalignment rule (e.g. {turn_rate: 0}).",
    )
    position: tuple[Number, Number] | None = Field(
        default=None,
        description="Hand placement [x, y] in axis units, compared with the measured one in the report.",
    )
    ignore: list[IgnoreEntry] = Field(
        default_factory=list, description="Rules silenced for this clip, each with a reason."
    )
    skeleton: SkeletonSettings | None = Field(
        default=None,
        description="Per-entry override of the top-level skeleton: keys (for mixed libraries); keys not "
        "set here come from the top level.",
    )

    @field_validator("name")
    @classmethod
    def _printable_name(cls, value: str | None) -> str | None:
        # A name goes into every output and engine asset (a Godot .tres took a NUL byte raw).
        if value is not None and (odd := _UNPRINTABLE.search(value)):
            raise rule_error(
                f"the name holds the control character U+{ord(odd.group()):04X}",
                "use letters, digits, spaces and punctuation in clip names",
            )
        return value

    @field_validator("range", mode="before")
    @classmethod
    def _range_shape(cls, value: object) -> object:
        # Checked before the union so a wrong shape reads as one message, not one per member.
        if isinstance(value, list | tuple) and len(value) != 2:
            raise rule_error(
                f"expected 2 values, got {len(value)}", "write range: [start, end] or range: auto"
            )
        if isinstance(value, str) and value != "auto":
            raise rule_error(
                f"expected [start, end] or auto, got {value!r}", "write range: [start, end] or range: auto"
            )
        return value

    @field_validator("range")
    @classmethod
    def _range_order(
        cls, value: tuple[float, float] | Literal["auto"] | None
    ) -> tuple[float, float] | Literal["auto"] | None:
        if value is None or value == "auto":
            return value
        start, end = value
        if start < 0:
            raise rule_error(
                f"starts before 0 s ({start:g})", "clip time starts at 0; use range: [0, end] or later"
            )
        if start >= end:
            raise rule_error(f"start {start:g} s is not before end {end:g} s", "write range: [start, end]")
        return value


class Axis(_Model):
    """One blend-space axis: the feature that drives it and its grid."""

    feature: FeatureName = Field(description="Measured feature that drives this axis.")
    min: Number = Field(description="Lower end of the axis, in the feature's unit.")
    max: Number = Field(description="Upper end of the axis, in the feature's unit; greater than min.")
    divisions: Annotated[PositiveInt, Strict()] = Field(
        description="Grid intervals; positions snap to min + k*(max-min)/divisions."
    )

    @model_validator(mode="after")
    def _min_below_max(self) -> Axis:
        if self.min >= self.max:
            raise rule_error(
                f"min {self.min:g} is not below max {self.max:g}",
                "swap them or widen the range, e.g. min: -3, max: 6",
            )
        return self


def _default_x() -> Axis:
    return Axis(feature="turn_rate", min=-180.0, max=180.0, divisions=100)


def _default_y() -> Axis:
    return Axis(feature="speed", min=-3.0, max=6.0, divisions=90)


class Axes(_Model):
    """The two axes of the blend space."""

    x: Axis = Field(
        default_factory=_default_x, description="First blend parameter (default turn_rate, -180..180)."
    )
    y: Axis = Field(default_factory=_default_y, description="Second blend parameter (default speed, -3..6).")

    @model_validator(mode="after")
    def _distinct_features(self) -> Axes:
        # Both axes on one feature put every sample on a line: nothing can be triangulated.
        if self.x.feature == self.y.feature:
            raise rule_error(
                f"both axes use the feature {self.x.feature!r}",
                "give x and y different features, e.g. x: turn_rate and y: speed",
            )
        return self


class Thresholds(_Model):
    """Rule thresholds: distances in normalised axis space (each axis 0..100), angles in degrees."""

    crossing_axis: Annotated[NonNegativeFloat, Strict()] = Field(
        default=5.0,
        description="τχ: how far beyond a main axis an edge's end points may lie before it counts "
        "(the paper's value, Delicado & Pelechano 2019).",
    )
    too_close: Annotated[NonNegativeFloat, Strict()] = Field(
        default=8.0,
        description="τd: samples closer than this are too close (the paper's value, Delicado & Pelechano 2019).",
    )
    acute_angle: Annotated[NonNegativeFloat, Strict()] = Field(
        default=15.0,
        description="Triangles with an angle below this (deg) are acute. Our default, not the paper's "
        "(it gives no number): a 15° sliver has a long edge about 4x its height.",
    )
    misalignment: Annotated[NonNegativeFloat, Strict()] = Field(
        default=3.0,
        description="A clip whose measured position is off a main axis by at most this much is misaligned. "
        "Our default, not the paper's (it gives no number): below τχ, so a misaligned clip still "
        "counts as on the axis for crossing-axis.",
    )


class RuleSettings(_Model):
    """Which rules run and how severe their findings are."""

    select: list[str] = Field(
        default_factory=lambda: ["all"], description="Rule slugs or codes to run; 'all' = every rule."
    )
    ignore: list[str] = Field(default_factory=list, description="Rule slugs or codes not to run.")
    severity: dict[str, Literal["error", "warning", "info", "off"]] = Field(
        default_factory=dict, description="Severity overrides by rule slug or code; 'off' disables the rule."
    )
    options: dict[str, dict[str, Any]] = Field(
        default_factory=dict,
        description="Typed options by rule slug or code (see `blendspace rules`), checked against the rule.",
    )


class FixSettings(_Model):
    """Which automatic fixes a build applies (check never applies them)."""

    mirror: Flag = Field(
        default=True, description="Generate mirrored clips to fill the other side of the space."
    )
    axis_clips: Flag = Field(
        default=True, description="Generate clips on the main axes for crossing-axis edges."
    )
    too_close: Literal["report", "keep-representative", "merge"] = Field(
        default="report", description="What to do with samples that are too close."
    )
    straighten: Flag = Field(default=False, description="Straighten clips that are slightly off their axis.")


class Mask(_Model):
    """Per-joint weights of a style layer."""

    joints: dict[str, Weight] = Field(description="Weight per joint name, 0..1.")
    default: Weight = Field(default=1.0, description="Weight of joints not listed, 0..1.")


def _layer_name(value: str) -> str:
    """A layer name `eval --layer NAME=VALUE` can reach: not empty, no `=`, no control character,
    no space at either end (`--layer` strips them)."""
    if not value.strip():
        raise rule_error("the layer name is empty", "name the layer, e.g. name: lateral")
    if "=" in value or _UNPRINTABLE.search(value) or value != value.strip():
        raise rule_error(
            f"the layer name {value!r} cannot be given to `eval --layer NAME=VALUE`",
            "use letters, digits, spaces, '_' or '-', e.g. name: lateral",
        )
    return value


class BetaLayer(_Model):
    """A second blend space with the same axes (BS2), blended with the main one by beta in [0, 1]."""

    name: str = Field(description="Layer name, used by `blendspace eval --layer NAME=VALUE`.")
    kind: Literal["beta"] = Field(description="Layer kind: beta.")
    manifest: str = Field(description="Manifest of the second blend space, relative to this manifest.")

    @field_validator("name")
    @classmethod
    def _addressable(cls, value: str) -> str:
        return _layer_name(value)


class StyleLayer(_Model):
    """A 1D style space over the speed axis, blended in by an intensity."""

    name: str = Field(description="Layer name, used by `blendspace eval --layer NAME=VALUE`.")
    kind: Literal["style"] = Field(description="Layer kind: style.")
    clips: list[str | ClipEntry] = Field(
        min_length=1, description="Style clips: paths, globs or clip entries."
    )
    mask: Mask | None = Field(default=None, description="Optional per-joint weights of the style.")

    @field_validator("name")
    @classmethod
    def _addressable(cls, value: str) -> str:
        return _layer_name(value)

    def entries(self) -> list[ClipEntry]:
        """The style clips as clip entries (a bare path is an entry of that path)."""
        return [ClipEntry(path=item) if isinstance(item, str) else item for item in self.clips]

    @field_validator("clips")
    @classmethod
    def _style_entry_keys(cls, value: list[str | ClipEntry]) -> list[str | ClipEntry]:
        # A style clip sits at its measured speed on the style axis, checked by the main space's
        # rules: these keys did nothing here, and said nothing (even `ignore: [{rule: not-a-rule}]`).
        for entry in value:
            if isinstance(entry, ClipEntry):
                unused = [key for key in ("position", "expect", "ignore") if key in entry.model_fields_set]
                if unused:
                    raise rule_error(
                        f"a style clip takes no `{unused[0]}:` (its place is its measured speed)",
                        f"drop `{unused[0]}:` from the style layer's clip entry",
                    )
        return value


Layer = Annotated[BetaLayer | StyleLayer, Field(discriminator="kind")]
LAYER_KINDS: tuple[str, ...] = ("beta", "style")


OutputFormat = Literal["json", "usd", "html", "png"]


def _all_formats() -> list[OutputFormat]:
    return ["json", "usd", "html", "png"]


ClipFormat = Literal["usd", "glb", "bvh"]


def _all_clip_formats() -> list[ClipFormat]:
    return ["usd", "glb", "bvh"]


class OutputSettings(_Model):
    """Where and what a build writes."""

    dir: str = Field(
        default="build", description="Output folder, relative to the manifest (`~` is the home folder)."
    )
    formats: list[OutputFormat] = Field(
        default_factory=_all_formats, min_length=1, description="Outputs to write (at least one)."
    )
    clip_formats: list[ClipFormat] = Field(
        default_factory=_all_clip_formats,
        min_length=1,
        description="Files written for each generated clip under clips/: usd (UsdSkel .usda), glb (for "
        "Godot, Unreal and Unity's glTFast) and bvh (only when every source is BVH).",
    )

    @field_validator("dir")
    @classmethod
    def _a_folder_here(cls, value: str) -> str:
        # `C:\\build` on Linux or macOS made a folder named `C:` beside the manifest.
        if os.name != "nt" and re.match(r"^[A-Za-z]:[\\/]", value):
            raise rule_error(
                f"{value!r} is a Windows drive path, and this system has no drives",
                "write a folder relative to the manifest (e.g. build), or an absolute path of this system",
            )
        if not value.strip():
            raise rule_error("the output folder is empty", "write a folder, e.g. dir: build")
        return value


class BlendSettings(_Model):
    """How the engine plays the blend, for the build's blend-quality maps."""

    sync: Literal["none", "normalized", "markers"] = Field(
        default="normalized",
        description="How blended clips keep in step: `normalized` (lengths stretched to the weighted "
        "mean, what Unity blend trees, Unreal blend spaces and Godot do and what our exports set up), "
        "`markers` (the heaviest clip plays at 1, the others match its stride, as Unreal's sync "
        "markers do) or `none` (every clip at rate 1). The `blend_quality` maps play the blend so.",
    )


class Manifest(_Model):
    """A blendspace-pipeline manifest: the clips of one blend space and how to build it."""

    schema_version: Literal[1] = Field(description="Version of the manifest layout; must be 1.")
    name: str = Field(
        description="Blend-space name, the file stem of the outputs: letters, digits, '_', '-', '.'."
    )
    clips: list[ClipEntry] = Field(min_length=1, description="Clip files or globs, relative to the manifest.")
    skeleton: SkeletonSettings = Field(default_factory=SkeletonSettings, description="How to read the rig.")
    axes: Axes = Field(default_factory=Axes, description="The x and y axes.")
    thresholds: Thresholds = Field(default_factory=Thresholds, description="Rule thresholds.")
    rules: RuleSettings = Field(default_factory=RuleSettings, description="Rule selection and severities.")
    fixes: FixSettings = Field(default_factory=FixSettings, description="Automatic fixes a build applies.")
    plugins: list[str] = Field(
        default_factory=list, description="Studio rule modules: importable names or paths."
    )
    layers: list[Layer] = Field(default_factory=list, description="Beta and style layers (more dimensions).")
    output: OutputSettings = Field(default_factory=OutputSettings, description="Output folder and formats.")
    blend: BlendSettings = Field(
        default_factory=BlendSettings, description="How the engine plays the blend (sync mode)."
    )

    @field_validator("name")
    @classmethod
    def _safe_stem(cls, value: str) -> str:
        if not _SAFE_STEM.fullmatch(value) or value in (".", ".."):
            raise rule_error(
                f"{value!r} cannot be used as a file name",
                "use letters, digits, '_', '-' and '.' only, e.g. name: locomotion",
            )
        return value
