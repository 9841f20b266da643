"""The blend-space USD writer emits `.usda` text itself (linear, small constant at 10,000
samples); these tests hold it to what usd-core writes for the same specs: the Sdf authoring the
writer used before is kept here as the oracle and the two texts must be equal byte for byte, on
hand-made documents with every kind of value, a random one, and a real build with layers. Then
usd-core reads the written file back and finds the document's values."""

from __future__ import annotations

import json
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pytest
from pxr import Sdf, Tf, Usd, UsdGeom, Vt

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_report import TRICKY, make_document, sample_document

from blendspace_pipeline.space.document import BlendSpaceDocument, MarkerDoc, SampleDoc
from blendspace_pipeline.space.layers_doc import BetaLayerDoc, parse_layers
from blendspace_pipeline.writers.usd_blendspace import _double, usda_text, write_usd_blendspace

# ---- the oracle: the writer's former Sdf authoring ----------------------------------------------

ORACLE_NAMESPACE = "blendspace"


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
        prim, f"{ORACLE_NAMESPACE}:{name}", type_name, Sdf.VariabilityVarying, declaresCustom=True
    )
    spec.default = value


def _scope(parent: Sdf.PrimSpec | Sdf.Layer, name: str) -> Sdf.PrimSpec:
    """``def Scope "name"`` under ``parent`` (a prim, or the layer for a root prim)."""
    return Sdf.PrimSpec(parent, name, Sdf.SpecifierDef, "Scope")


def sdf_text(doc: BlendSpaceDocument) -> str:
    """The oracle: the same layer authored as Sdf specs and exported by usd-core."""
    layer = Sdf.Layer.CreateAnonymous(".usda")
    with Sdf.ChangeBlock():
        _write_layer(layer, doc)
    return str(layer.ExportToString())


def _write_layer(layer: Sdf.Layer, doc: BlendSpaceDocument) -> None:
    layer.pseudoRoot.SetInfo(UsdGeom.Tokens.upAxis, UsdGeom.Tokens.y)
    layer.pseudoRoot.SetInfo(UsdGeom.Tokens.metersPerUnit, 1.0)
    root = _scope(layer, _identifier(doc.name, set()))
    layer.defaultPrim = root.name
    layer.customLayerData = {f"{ORACLE_NAMESPACE}:schemaVersion": doc.schema_version}
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


# ---- tests --------------------------------------------------------------------------------------


def _every_kind_of_value() -> BlendSpaceDocument:
    doc = sample_document()
    first, second = doc.samples[0], doc.samples[1]
    first.contacts = {"left": [[0.0, 0.4], [0.5, 1e-7]], "right": []}
    first.markers = [MarkerDoc(name="LeftFootDown", time=0.5), MarkerDoc(name="RightFootDown", time=0.75)]
    first.features |= {"tiny": 1e-7, "small": 0.00001234, "huge": 1e21, "big": 123456789012345678.0,
                       "neg_zero": -0.0, "sum": 0.1 + 0.2, "third": 1 / 3, "neg_tiny": -2.5e-12, "mid": 1234567890123456.0, "e15": 1e15, "micro": 1e-6}  # fmt: skip
    second.fix = "axis-clip"
    second.name = "two words/and\\slash"
    second.source = "clips/odd @ name.bvh"
    doc.samples[3].name = "quote's"
    doc.samples[4].name = "tab\there"
    doc.name = "loco motion"
    return doc


def test_text_equals_usd_cores_export_on_every_kind_of_value() -> None:
    doc = _every_kind_of_value()
    assert usda_text(doc) == sdf_text(doc)


def test_text_equals_usd_cores_export_on_a_random_space() -> None:
    rng = np.random.default_rng(11)
    points = [(f"c{i:03d}", float(rng.uniform(-180, 180)), float(rng.uniform(-3, 6))) for i in range(200)]
    doc = make_document(points, generated=frozenset({"c007", "c100"}))
    for sample in doc.samples:
        sample.features["lateral_speed"] = float(rng.normal(0, 1e-3))
    assert usda_text(doc) == sdf_text(doc)


@pytest.mark.parametrize(
    "value",
    [
        0.0,
        -0.0,
        1.0,
        0.5,
        1e-7,
        1.5e-7,
        9.99e-7,
        1e-6,
        1e-5,
        1e-4,
        1e15,
        1e16,
        1e20,
        1e21,
        1.5e300,
        -3.25e-200,
    ],
)
def test_doubles_read_back_exactly(value: float) -> None:
    assert float(_double(value)) == value


def test_a_built_space_with_layers_matches_and_reads_back(tmp_path: Path) -> None:
    from test_layers import _project

    from blendspace_pipeline.cli import main

    manifest = _project(tmp_path)
    out = tmp_path / "out"
    assert main(["build", str(manifest), "--out", str(out)]) in (0, 1)
    doc = BlendSpaceDocument.model_validate_json((out / "loco.blendspace.json").read_text())
    assert parse_layers(doc), "the project is meant to have layers"
    assert (out / "loco.blendspace.usda").read_text(encoding="utf-8") == sdf_text(doc)
    stage = Usd.Stage.Open(str(out / "loco.blendspace.usda"))
    root = stage.GetDefaultPrim()
    order = list(root.GetChild("Samples").GetAttribute("blendspace:order").Get())
    assert len(order) == len(doc.samples)
    for name, sample in zip(order, doc.samples, strict=True):
        prim = root.GetChild("Samples").GetChild(name)
        assert prim.GetAttribute("blendspace:name").Get() == sample.name
        assert tuple(prim.GetAttribute("blendspace:position").Get()) == tuple(sample.position)
        for feature, value in sample.features.items():
            assert prim.GetAttribute(f"blendspace:features:{feature}").Get() == value


def test_written_file_opens_and_holds_the_tricky_names(tmp_path: Path) -> None:
    doc = _every_kind_of_value()
    path = tmp_path / "loco.blendspace.usda"
    write_usd_blendspace(doc, path)
    stage = Usd.Stage.Open(str(path))
    names = {
        p.GetAttribute("blendspace:name").Get()
        for p in stage.GetDefaultPrim().GetChild("Samples").GetChildren()
    }
    assert names == {s.name for s in doc.samples} and TRICKY in names
    sources = {
        p.GetAttribute("blendspace:source").Get().path
        for p in stage.GetDefaultPrim().GetChild("Samples").GetChildren()
    }
    assert "clips/odd @ name.bvh" in sources
    assert json.loads(json.dumps(UsdGeom.GetStageUpAxis(stage))) == "Y"
