"""`N.blendspace.usda`: the blend space as a USD asset, written with usd-core.

The blend-space prim is a `Scope` carrying typed attributes under the `blendspace:` namespace
(see docs/decisions/0001-usd-blendspace-layout.md for why not a codeless schema): axes,
triangles, and one child prim per sample with its source clip as an `asset` path, its measured
features and its snapped position. Clips written by the build as USD are also referenced as
payload-free `references` on the sample prim so a DCC can open the animation directly.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from pxr import Sdf, Tf, Usd, UsdGeom, Vt

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


def _attr(prim: Usd.Prim, name: str, type_name: Sdf.ValueTypeName, value: object) -> None:
    prim.CreateAttribute(f"{NAMESPACE}:{name}", type_name, custom=True).Set(value)


def write_usd_blendspace(doc: BlendSpaceDocument, path: Path) -> None:
    """Write ``doc`` to ``path`` (a new file; the caller stages it for an atomic build)."""
    layer = Sdf.Layer.CreateAnonymous(".usda")
    stage = Usd.Stage.Open(layer)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    root = stage.DefinePrim(f"/{_identifier(doc.name, set())}", "Scope")
    stage.SetDefaultPrim(root)
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
    _write_samples(stage, root, doc.samples)
    _write_placeholders(stage, root, doc)
    _write_layers(stage, root, doc)
    text = layer.ExportToString()
    path.write_text(text, encoding="utf-8")


def _write_samples(stage: Usd.Stage, parent: Usd.Prim, sample_docs: Sequence[SampleDoc]) -> None:
    samples = stage.DefinePrim(parent.GetPath().AppendChild("Samples"), "Scope")
    taken: set[str] = set()
    order = []
    for sample in sample_docs:
        prim = stage.DefinePrim(samples.GetPath().AppendChild(_identifier(sample.name, taken)), "Scope")
        order.append(prim.GetName())
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
        for feature, value in sorted(sample.features.items()):
            _attr(prim, f"features:{feature}", Sdf.ValueTypeNames.Double, value)
    # Triangle indices refer to samples in this order, whatever order a tool lists children in.
    _attr(samples, "order", Sdf.ValueTypeNames.TokenArray, order)


def _write_placeholders(stage: Usd.Stage, root: Usd.Prim, doc: BlendSpaceDocument) -> None:
    if not doc.placeholders:
        return
    scope = stage.DefinePrim(root.GetPath().AppendChild("Placeholders"), "Scope")
    for index, mark in enumerate(doc.placeholders):
        prim = stage.DefinePrim(scope.GetPath().AppendChild(f"placeholder_{index}"), "Scope")
        _attr(prim, "position", Sdf.ValueTypeNames.Double2, tuple(mark.position))
        _attr(prim, "priority", Sdf.ValueTypeNames.Token, mark.priority)
        _attr(prim, "rule", Sdf.ValueTypeNames.Token, mark.rule)
        _attr(prim, "reason", Sdf.ValueTypeNames.String, mark.reason)


def _write_layers(stage: Usd.Stage, root: Usd.Prim, doc: BlendSpaceDocument) -> None:
    """Beta layers as nested blend spaces (samples + triangles); style layers as a 1D axis."""
    layers = parse_layers(doc)
    if not layers:
        return
    scope = stage.DefinePrim(root.GetPath().AppendChild("Layers"), "Scope")
    taken: set[str] = set()
    for entry in layers:
        prim = stage.DefinePrim(scope.GetPath().AppendChild(_identifier(entry.name, taken)), "Scope")
        _attr(prim, "name", Sdf.ValueTypeNames.String, entry.name)
        _attr(prim, "kind", Sdf.ValueTypeNames.Token, entry.kind)
        if isinstance(entry, BetaLayerDoc):
            _attr(prim, "source", Sdf.ValueTypeNames.Asset, Sdf.AssetPath(entry.source))
            triangles = Vt.Vec3iArray([tuple(t) for t in entry.triangles])
            _attr(prim, "triangles", Sdf.ValueTypeNames.Int3Array, triangles)
            _write_samples(stage, prim, entry.samples)
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
        samples = stage.DefinePrim(prim.GetPath().AppendChild("Samples"), "Scope")
        names_taken: set[str] = set()
        for sample in entry.samples:
            child = stage.DefinePrim(
                samples.GetPath().AppendChild(_identifier(sample.name, names_taken)), "Scope"
            )
            _attr(child, "name", Sdf.ValueTypeNames.String, sample.name)
            _attr(child, "source", Sdf.ValueTypeNames.Asset, Sdf.AssetPath(sample.source))
            _attr(child, "position", Sdf.ValueTypeNames.Double, sample.position[0])
