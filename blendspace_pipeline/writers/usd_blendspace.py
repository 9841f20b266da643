"""`N.blendspace.usda`: the blend space as a USD asset, written with usd-core.

The blend-space prim is a `Scope` carrying typed attributes under the `blendspace:` namespace
(see docs/decisions/0001-usd-blendspace-layout.md for why not a codeless schema): axes,
triangles, and one child prim per sample with its source clip as an `asset` path, its measured
features and its snapped position. Clips written by the build as USD are also referenced as
payload-free `references` on the sample prim so a DCC can open the animation directly.
"""

from __future__ import annotations

from pathlib import Path

from pxr import Sdf, Tf, Usd, UsdGeom, Vt

from blendspace_pipeline.document import BlendSpaceDocument

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
    samples = stage.DefinePrim(root.GetPath().AppendChild("Samples"), "Scope")
    taken: set[str] = set()
    order = []
    for sample in doc.samples:
        prim = stage.DefinePrim(samples.GetPath().AppendChild(_identifier(sample.name, taken)), "Scope")
        order.append(prim.GetName())
        _attr(prim, "name", Sdf.ValueTypeNames.String, sample.name)
        _attr(prim, "source", Sdf.ValueTypeNames.Asset, Sdf.AssetPath(sample.source))
        _attr(prim, "position", Sdf.ValueTypeNames.Double2, tuple(sample.position))
        _attr(prim, "generated", Sdf.ValueTypeNames.Bool, sample.generated)
        if sample.fix:
            _attr(prim, "fix", Sdf.ValueTypeNames.Token, sample.fix)
        for feature, value in sorted(sample.features.items()):
            _attr(prim, f"features:{feature}", Sdf.ValueTypeNames.Double, value)
    # Triangle indices refer to samples in this order, whatever order a tool lists children in.
    _attr(samples, "order", Sdf.ValueTypeNames.TokenArray, order)
    _write_placeholders(stage, root, doc)
    text = layer.ExportToString()
    path.write_text(text, encoding="utf-8")


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
