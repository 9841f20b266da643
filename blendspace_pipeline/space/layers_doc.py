"""The entries of `BlendSpaceDocument.layers`: beta and style layers as written by the build.

spec.md's *Layers* section describes them in the manifest; these are their resolved form in the
JSON, what `eval`, the exports and the report read. A beta layer is a second 2D space on the
main axes (paper §4, BS2); a style layer is a 1D space over one feature of the main space
(normally speed) with an optional per-joint mask (MechWarrior's feathering).
`read_document` is how `eval` and `export` load a JSON file: schema and cross-references checked,
every problem an `InputError` with a hint.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, TypeAdapter, ValidationError

from blendspace_pipeline.errors import InputError
from blendspace_pipeline.space.document import BlendSpaceDocument, ClipInfoDoc, DiagnosticDoc, SampleDoc


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid")


class MaskDoc(_Strict):
    """Per-joint multipliers of a layer's weight (feather blending)."""

    joints: dict[str, float] = Field(description="Weight per joint name, 0..1.")
    default: float = Field(default=1.0, description="Weight of the joints not listed, 0..1.")

    def weight(self, joint: str) -> float:
        return self.joints.get(joint, self.default)


class BetaLayerDoc(_Strict):
    name: str = Field(description="Layer name, used by `blendspace eval --layer NAME=VALUE`.")
    kind: Literal["beta"] = Field(
        description="Layer kind: beta (a second 2D space blended by beta in [0, 1])."
    )
    source: str = Field(description="Path of the second space's manifest or JSON, relative to this JSON.")
    samples: list[SampleDoc] = Field(description="Placed clips of the second space, on the main axes.")
    triangles: list[list[int]] = Field(
        description="Triangles of the second space as indices into its samples."
    )
    diagnostics: list[DiagnosticDoc] = Field(default_factory=list, description="Findings of the rules on it.")


class StyleAxisDoc(_Strict):
    feature: str = Field(description="Feature of the main space the style is laid out on (normally speed).")
    min: float = Field(description="Lower end of the axis, in the feature's unit.")
    max: float = Field(description="Upper end of the axis, in the feature's unit.")
    unit: str | None = Field(default=None, description="Unit of the feature.")


class StyleSampleDoc(_Strict):
    name: str = Field(description="Clip name, unique in the layer.")
    source: str = Field(description="Path of the clip file, relative to the JSON file when possible.")
    position: list[float] = Field(
        min_length=1, max_length=1, description="Position on the style axis, [value]."
    )
    features: dict[str, float] = Field(description="Unsnapped measured features (see spec.md).")
    clip: ClipInfoDoc | None = Field(default=None, description="Facts about the measured clip.")


class StyleLayerDoc(_Strict):
    name: str = Field(description="Layer name, used by `blendspace eval --layer NAME=VALUE`.")
    kind: Literal["style"] = Field(description="Layer kind: style (a 1D space mixed in by an intensity).")
    axis: StyleAxisDoc = Field(description="The 1D axis the style clips are placed on.")
    samples: list[StyleSampleDoc] = Field(min_length=1, description="Style clips on that axis.")
    mask: MaskDoc | None = Field(
        default=None, description="Per-joint weights of the style, or none (all joints)."
    )
    diagnostics: list[DiagnosticDoc] = Field(default_factory=list, description="Findings of the rules on it.")


LayerDoc = Annotated[BetaLayerDoc | StyleLayerDoc, Field(discriminator="kind")]
_LAYERS: TypeAdapter[list[BetaLayerDoc | StyleLayerDoc]] = TypeAdapter(list[LayerDoc])


def parse_layer_list(raw: list[dict[str, Any]]) -> list[BetaLayerDoc | StyleLayerDoc]:
    """Validate raw layer dictionaries (raises pydantic's ValidationError)."""
    return _LAYERS.validate_python(raw)


def parse_layers(doc: BlendSpaceDocument) -> list[BetaLayerDoc | StyleLayerDoc]:
    """The document's layers as models, in document order."""
    return parse_layer_list(doc.layers)


def read_document(path: Path) -> BlendSpaceDocument:
    """Load and check a blend-space JSON file for `eval` and `export`.

    Everything a user can get wrong (a missing file, broken JSON, a document from another tool
    or a hand edit that breaks the layout) becomes an `InputError` naming the file and the key.
    """
    hint = "pass the N.blendspace.json that `blendspace build` wrote (in the manifest's output dir)"
    # A regular file of bounded size, opened without blocking: /dev/zero or a FIFO would be read
    # until memory runs out, or wait forever.
    from blendspace_pipeline.readers.limits import read_regular_file

    try:
        text = read_regular_file(path, what="blend-space JSON", limit=MAX_DOCUMENT_BYTES).decode("utf-8")
    except InputError as error:
        raise InputError(error.message, path=path, hint=hint) from None
    except UnicodeDecodeError:
        raise InputError("not a blend-space JSON: the file is not UTF-8 text", path=path, hint=hint) from None
    try:
        raw = json.loads(text)
    except json.JSONDecodeError as error:
        raise InputError(
            f"not valid JSON: {error.msg}", path=path, line=error.lineno, column=error.colno, hint=_REBUILD
        ) from None
    except RecursionError:
        raise InputError("not a blend-space JSON: nested too deeply", path=path, hint=_REBUILD) from None
    except ValueError:  # an integer of thousands of digits (Python's conversion limit)
        raise InputError(
            "not a blend-space JSON: a number too long to read", path=path, hint=_REBUILD
        ) from None
    doc = _validated(raw, path)
    _check_consistency(doc, path)
    return doc


# A build of 10,000 samples writes ~12 MB; ten times the samples with room to spare.
MAX_DOCUMENT_BYTES = 1024 * 1024**2
_REBUILD = "regenerate the file with `blendspace build MANIFEST` rather than editing it by hand"


def _validated(raw: Any, path: Path) -> BlendSpaceDocument:
    try:
        doc = BlendSpaceDocument.model_validate(raw)
    except ValidationError as error:
        raise _schema_error(error, "", path) from None
    try:
        parse_layers(doc)
    except ValidationError as error:
        raise _schema_error(error, "layers.", path) from None
    return doc


def _schema_error(error: ValidationError, prefix: str, path: Path) -> InputError:
    first = error.errors()[0]
    where = prefix + ".".join(str(part) for part in first["loc"])
    return InputError(
        f"not a blend-space document: {where}: {first['msg']} ({error.error_count()} problem(s) in all)",
        path=path,
        hint=_REBUILD,
    )


def _check_consistency(doc: BlendSpaceDocument, path: Path) -> None:
    if [axis.name for axis in doc.axes] != ["x", "y"]:
        raise InputError("the document must have exactly two axes, x then y", path=path, hint=_REBUILD)
    for axis in doc.axes:
        if not (math.isfinite(axis.min) and math.isfinite(axis.max)):
            raise InputError(f"axis {axis.name} has a range that is not finite", path=path, hint=_REBUILD)
        if not axis.max > axis.min:
            raise InputError(
                f"axis {axis.name} has min {axis.min} >= max {axis.max}", path=path, hint=_REBUILD
            )
    _check_space("", doc.samples, doc.triangles, path)
    for layer in parse_layers(doc):
        if isinstance(layer, BetaLayerDoc):
            _check_space(f"layer {layer.name!r}: ", layer.samples, layer.triangles, path)


def _check_space(prefix: str, samples: list[SampleDoc], triangles: list[list[int]], path: Path) -> None:
    for sample in samples:
        if len(sample.position) != 2:
            raise InputError(
                f"{prefix}sample {sample.name!r} has {len(sample.position)} coordinates, not 2",
                path=path,
                hint=_REBUILD,
            )
        if not all(math.isfinite(v) for v in sample.position):
            # eval blended with it and export wrote `Vector2(nan, 1)`: no engine plays that.
            raise InputError(
                f"{prefix}sample {sample.name!r} is at {sample.position}, not a finite position",
                path=path,
                hint=_REBUILD,
            )
    for index, triangle in enumerate(triangles):
        if len(triangle) != 3 or any(not 0 <= i < len(samples) for i in triangle):
            raise InputError(
                f"{prefix}triangle {index} {triangle} does not name three of the {len(samples)} samples",
                path=path,
                hint=_REBUILD,
            )
