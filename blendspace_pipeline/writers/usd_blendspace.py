"""`N.blendspace.usda`: the blend space as a USD asset, written with usd-core.

The blend-space prim is a `Scope` carrying typed attributes under the `blendspace:` namespace
(see docs/decisions/0001-usd-blendspace-layout.md for why not a codeless schema): axes,
triangles, and one child prim per sample with its source clip as an `asset` path, its measured
features and its snapped position. Clips written by the build as USD are also referenced as
payload-free `references` on the sample prim so a DCC can open the animation directly.

The file is authored on the layer itself (Sdf prim and attribute specs in one change block),
not through a `Usd.Stage`: a stage recomposes after every prim and attribute it defines, which
made 10,000 samples cost seconds per thousand; the text written is the same.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from pxr import Sdf, Tf, UsdGeom, Vt

from blendspace_pipeline.space.document import BlendSpaceDocument, SampleDoc
from blendspace_pipeline.space.layers_doc import BetaLayerDoc, parse_layers

NAMESPACE = "blendspace"


def _identifier(name: str, taken: set[str]) -> str:
    """A valid, unique USD prim name for a clip name (clip names may contain '/' or spaces)."""
    candidate = str(Tf.MakeValidIdentifier(name))
    unique, counter = candidate, 1
    while unique in taken:
        counter += 1
        unique = f"{candidate}_{counter}"
    taken.add(unique)
    return unique


def _attr(prim: Sdf.PrimSpec, name: str, type_name: Sdf.ValueTypeName, value: object) -> None:
    spec = Sdf.AttributeSpec(
        prim, f"{NAMESPACE}:{name}", type_name, Sdf.VariabilityVarying, declaresCustom=True
    )
    spec.default = value


def _scope(parent: Sdf.PrimSpec | Sdf.Layer, name: str) -> Sdf.PrimSpec:
    """``def Scope "name"`` under ``parent`` (a prim, or the layer for a root prim)."""
    return Sdf.PrimSpec(parent, name, Sdf.SpecifierDef, "Scope")


def write_usd_blendspace(doc: BlendSpaceDocument, path: Path) -> None:
    """Write ``doc`` to ``path`` (a new file; the caller stages it for an atomic build)."""
    layer = Sdf.Layer.CreateAnonymous(".usda")
    with Sdf.ChangeBlock():
        _write_layer(layer, doc)
    text = layer.ExportToString()
    path.write_text(text, encoding="utf-8")


def _write_layer(layer: Sdf.Layer, doc: BlendSpaceDocument) -> None:
    layer.pseudoRoot.SetInfo(UsdGeom.Tokens.upAxis, UsdGeom.Tokens.y)
    layer.pseudoRoot.SetInfo(UsdGeom.Tokens.metersPerUnit, 1.0)
    root = _scope(layer, _identifier(doc.name, set()))
    layer.defaultPrim = root.name
    layer.customLayerData = {f"{NAMESPACE}:schemaVersion": doc.schema_version}
    _attr(root, "name", Sdf.ValueTypeNames.String, doc.name)
    for axis in doc.axes:
        prefix = f"axes:{axis.name}"
        _attr(root, f"{prefix}:feature", Sdf.ValueTypeNames.Token, axis.feature)
        _attr(root, f"{prefix}:min", Sdf.ValueTypeNames.Double, axis.min)
        _attr(root, f"{prefix}:max", Sdf.ValueTypeNames.Double, axis.max)
        _attr(root, f"{prefix}:divisions", Sdf.ValueTypeNames.Int, axis.divisions)
        _attr(root, f"{prefix}:unit", Sdf.ValueTypeNames.String, axis.unit)
    _attr(root, "triangles", Sdf.ValueTypeNames.Int3Array, Vt.Vec3iArray([tuple(t) for t in doc.triangles]))
    _write_samples(root, doc.samples)
    _write_placeholders(root, doc)
    _write_layers(root, doc)


def _write_samples(parent: Sdf.PrimSpec, sample_docs: Sequence[SampleDoc]) -> None:
    samples = _scope(parent, "Samples")
    taken: set[str] = set()
    order = []
    for sample in sample_docs:
        prim = _scope(samples, _identifier(sample.name, taken))
        order.append(prim.name)
        _attr(prim, "name", Sdf.ValueTypeNames.String, sample.name)
        _attr(prim, "source", Sdf.ValueTypeNames.Asset, Sdf.AssetPath(sample.source))
        _attr(prim, "position", Sdf.ValueTypeNames.Double2, tuple(sample.position))
        _attr(prim, "generated", Sdf.ValueTypeNames.Bool, sample.generated)
        if sample.fix:
            _attr(prim, "fix", Sdf.ValueTypeNames.Token, sample.fix)
        if sample.contacts is not None:
            # Per foot, [start, end] seconds of the used range, as pairs (spec.md's `contacts`).
            for foot, spans in sorted(sample.contacts.items()):
                _attr(prim, f"contacts:{foot}", Sdf.ValueTypeNames.Double2Array, [tuple(s) for s in spans])
        if sample.markers is not None:
            # Sync markers as two parallel arrays (name, seconds of the used range), sorted by time.
            _attr(prim, "markers:names", Sdf.ValueTypeNames.TokenArray, [m.name for m in sample.markers])
            _attr(prim, "markers:times", Sdf.ValueTypeNames.DoubleArray, [m.time for m in sample.markers])
        for feature, value in sorted(sample.features.items()):
            _attr(prim, f"features:{feature}", Sdf.ValueTypeNames.Double, value)
    # Triangle indices refer to samples in this order, whatever order a tool lists children in.
    _attr(samples, "order", Sdf.ValueTypeNames.TokenArray, order)


def _write_placeholders(root: Sdf.PrimSpec, doc: BlendSpaceDocument) -> None:
    if not doc.placeholders:
        return
    scope = _scope(root, "Placeholders")
    for index, mark in enumerate(doc.placeholders):
        prim = _scope(scope, f"placeholder_{index}")
        _attr(prim, "position", Sdf.ValueTypeNames.Double2, tuple(mark.position))
        _attr(prim, "priority", Sdf.ValueTypeNames.Token, mark.priority)
        _attr(prim, "rule", Sdf.ValueTypeNames.Token, mark.rule)
        _attr(prim, "reason", Sdf.ValueTypeNames.String, mark.reason)


def _write_layers(root: Sdf.PrimSpec, doc: BlendSpaceDocument) -> None:
    """Beta layers as nested blend spaces (samples + triangles); style layers as a 1D axis."""
    layers = parse_layers(doc)
    if not layers:
        return
    scope = _scope(root, "Layers")
    taken: set[str] = set()
    for entry in layers:
        prim = _scope(scope, _identifier(entry.name, taken))
        _attr(prim, "name", Sdf.ValueTypeNames.String, entry.name)
        _attr(prim, "kind", Sdf.ValueTypeNames.Token, entry.kind)
        if isinstance(entry, BetaLayerDoc):
            _attr(prim, "source", Sdf.ValueTypeNames.Asset, Sdf.AssetPath(entry.source))
            triangles = Vt.Vec3iArray([tuple(t) for t in entry.triangles])
            _attr(prim, "triangles", Sdf.ValueTypeNames.Int3Array, triangles)
            _write_samples(prim, entry.samples)
            continue
        _attr(prim, "axis:feature", Sdf.ValueTypeNames.Token, entry.axis.feature)
        _attr(prim, "axis:min", Sdf.ValueTypeNames.Double, entry.axis.min)
        _attr(prim, "axis:max", Sdf.ValueTypeNames.Double, entry.axis.max)
        if entry.mask is not None:
            names = sorted(entry.mask.joints)
            _attr(prim, "mask:joints", Sdf.ValueTypeNames.StringArray, names)
            weights = [entry.mask.joints[n] for n in names]
            _attr(prim, "mask:weights", Sdf.ValueTypeNames.DoubleArray, weights)
            _attr(prim, "mask:default", Sdf.ValueTypeNames.Double, entry.mask.default)
        samples = _scope(prim, "Samples")
        names_taken: set[str] = set()
        for sample in entry.samples:
            child = _scope(samples, _identifier(sample.name, names_taken))
            _attr(child, "name", Sdf.ValueTypeNames.String, sample.name)
            _attr(child, "source", Sdf.ValueTypeNames.Asset, Sdf.AssetPath(sample.source))
            _attr(child, "position", Sdf.ValueTypeNames.Double, sample.position[0])
