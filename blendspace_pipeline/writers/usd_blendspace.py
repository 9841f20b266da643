"""`N.blendspace.usda`: the blend space as a USD asset (a `.usda` layer usd-core reads).

The blend-space prim is a `Scope` carrying typed attributes under the `blendspace:` namespace
(see docs/decisions/0001-usd-blendspace-layout.md for why not a codeless schema): axes,
triangles, and one child prim per sample with its source clip as an `asset` path, its measured
features and its snapped position; placeholders and layers as child scopes.

The text is written directly, in the form usd-core's `Sdf.Layer.ExportToString` gives for the
same specs (properties sorted by name, children in order, the same number formatting): authoring
10,000 samples as Sdf specs cost seconds (160,000 attribute specs, then the export), while the
text costs a tenth of that, linearly. tests/test_usd_text.py holds the Sdf authoring as the
oracle and checks the two agree byte for byte, and that usd-core reads the values back. usd-core
is still the authority for what the emitter cannot spell alone: prim names
(`Tf.MakeValidIdentifier`) and quoting of unusual strings and asset paths (`_sdf_literal`).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from decimal import Decimal
from functools import cache
from pathlib import Path

from pxr import Sdf, Tf

from blendspace_pipeline.space.document import BlendSpaceDocument, SampleDoc
from blendspace_pipeline.space.layers_doc import BetaLayerDoc, parse_layers

NAMESPACE = "blendspace"
Property = tuple[str, str, str]  # (name without namespace, USD type, value literal)


class _Prim:
    """A `def Scope` with its properties and children, rendered as `.usda` text."""

    def __init__(self, name: str) -> None:
        self.name = name
        self.properties: list[Property] = []
        self.children: list[_Prim] = []

    def child(self, name: str) -> _Prim:
        prim = _Prim(name)
        self.children.append(prim)
        return prim

    def add(self, name: str, kind: str, literal: str) -> None:
        self.properties.append((name, kind, literal))

    def render(self, out: list[str], depth: int) -> None:
        pad = "    " * depth
        out.append(f'{pad}def Scope "{self.name}"\n{pad}{{\n')
        for name, kind, literal in sorted(self.properties):  # Sdf writes properties by name
            out.append(f"{pad}    custom {kind} {NAMESPACE}:{name} = {literal}\n")
        for index, child in enumerate(self.children):
            if index or self.properties:
                out.append("\n")
            child.render(out, depth + 1)
        out.append(f"{pad}}}\n")


def _identifier(name: str, taken: set[str]) -> str:
    """A valid, unique USD prim name for a clip name (clip names may contain '/' or spaces)."""
    candidate = str(Tf.MakeValidIdentifier(name))
    unique, counter = candidate, 1
    while unique in taken:
        counter += 1
        unique = f"{candidate}_{counter}"
    taken.add(unique)
    return unique


def _double(value: float) -> str:
    """A double as Sdf writes it: the shortest round-trip digits (as Python's repr), fixed
    notation from 1e-6 up to below 1e15 without a trailing '.0', else an exponent ('1e-7',
    '1.5e17': no '+')."""
    text = repr(float(value))
    if "e" not in text and "n" not in text and abs(value) < 1e15:  # fixed in both spellings
        return text[:-2] if text.endswith(".0") else text
    if not math.isfinite(value):
        return "nan" if math.isnan(value) else ("inf" if value > 0 else "-inf")
    sign, digits, exponent = Decimal(text).as_tuple()
    figures = "".join(map(str, digits)).rstrip("0") or "0"
    point = int(exponent) + len(digits)  # the decimal point sits after this many figures
    head = "-" if sign else ""
    if len(figures) <= point <= 15:
        return head + figures + "0" * (point - len(figures))
    if 0 < point <= 15:
        return head + figures[:point] + "." + figures[point:]
    if -6 < point <= 0:
        return head + "0." + "0" * -point + figures
    mantissa = figures[0] + ("." + figures[1:] if len(figures) > 1 else "")
    return f"{head}{mantissa}e{point - 1}"


def _tuple(values: Iterable[float]) -> str:
    return "(" + ", ".join(_double(v) for v in values) + ")"


def _array(values: Iterable[float]) -> str:
    return "[" + ", ".join(_double(v) for v in values) + "]"


def _string(text: str) -> str:
    """A string or token literal: plain text in double quotes, anything else as Sdf spells it."""
    if '"' not in text and "\\" not in text and text.isprintable():
        return f'"{text}"'
    return _sdf_literal("string", text)


def _asset(path: str) -> str:
    if "@" not in path and "\\" not in path and path.isprintable():
        return f"@{path}@"
    return _sdf_literal("asset", path)


@cache
def _sdf_literal(kind: str, text: str) -> str:
    """How usd-core writes a string or asset value (quotes, escapes, triple quotes): asked of a
    one-attribute layer, for the rare names and paths the plain spelling would not hold."""
    layer = Sdf.Layer.CreateAnonymous(".usda")
    prim = Sdf.PrimSpec(layer, "p", Sdf.SpecifierDef, "Scope")
    value_type = Sdf.ValueTypeNames.Asset if kind == "asset" else Sdf.ValueTypeNames.String
    spec = Sdf.AttributeSpec(prim, "v", value_type, Sdf.VariabilityVarying, declaresCustom=True)
    spec.default = Sdf.AssetPath(text) if kind == "asset" else text
    line = next(line for line in layer.ExportToString().splitlines() if " v = " in line)
    return str(line.split(" v = ", 1)[1])


def _strings(values: Sequence[str]) -> str:
    return "[" + ", ".join(_string(v) for v in values) + "]"


def write_usd_blendspace(doc: BlendSpaceDocument, path: Path) -> None:
    """Write ``doc`` to ``path`` (a new file; the caller stages it for an atomic build)."""
    path.write_text(usda_text(doc), encoding="utf-8")


def usda_text(doc: BlendSpaceDocument) -> str:
    root = _Prim(_identifier(doc.name, set()))
    root.add("name", "string", _string(doc.name))
    for axis in doc.axes:
        prefix = f"axes:{axis.name}"
        root.add(f"{prefix}:feature", "token", _string(axis.feature))
        root.add(f"{prefix}:min", "double", _double(axis.min))
        root.add(f"{prefix}:max", "double", _double(axis.max))
        root.add(f"{prefix}:divisions", "int", str(int(axis.divisions)))
        root.add(f"{prefix}:unit", "string", _string(axis.unit))
    root.add("triangles", "int3[]", _triangles(doc.triangles))
    _samples(root, doc.samples)
    _placeholders(root, doc)
    _layers(root, doc)
    out = [
        "#usda 1.0\n(\n    customLayerData = {\n"
        f'        int "{NAMESPACE}:schemaVersion" = {int(doc.schema_version)}\n    }}\n'
        f'    defaultPrim = "{root.name}"\n    metersPerUnit = 1\n    upAxis = "Y"\n)\n\n'
    ]
    root.render(out, 0)
    out.append("\n")  # usd-core ends the layer with an empty line
    return "".join(out)


def _triangles(triangles: Sequence[Sequence[int]]) -> str:
    return "[" + ", ".join(f"({int(a)}, {int(b)}, {int(c)})" for a, b, c in triangles) + "]"


def _samples(parent: _Prim, sample_docs: Sequence[SampleDoc]) -> None:
    samples = parent.child("Samples")
    taken: set[str] = set()
    order = []
    for sample in sample_docs:
        prim = samples.child(_identifier(sample.name, taken))
        order.append(prim.name)
        prim.add("name", "string", _string(sample.name))
        prim.add("source", "asset", _asset(sample.source))
        prim.add("position", "double2", _tuple(sample.position))
        prim.add("generated", "bool", "1" if sample.generated else "0")
        if sample.fix:
            prim.add("fix", "token", _string(sample.fix))
        if sample.contacts is not None:
            # Per foot, [start, end] seconds of the used range, as pairs (spec.md's `contacts`).
            for foot, spans in sorted(sample.contacts.items()):
                prim.add(f"contacts:{foot}", "double2[]", "[" + ", ".join(_tuple(s) for s in spans) + "]")
        if sample.markers is not None:
            # Sync markers as two parallel arrays (name, seconds of the used range), sorted by time.
            prim.add("markers:names", "token[]", _strings([m.name for m in sample.markers]))
            prim.add("markers:times", "double[]", _array(m.time for m in sample.markers))
        for feature, value in sample.features.items():
            prim.add(f"features:{feature}", "double", _double(value))
    # Triangle indices refer to samples in this order, whatever order a tool lists children in.
    samples.add("order", "token[]", _strings(order))


def _placeholders(root: _Prim, doc: BlendSpaceDocument) -> None:
    if not doc.placeholders:
        return
    scope = root.child("Placeholders")
    for index, mark in enumerate(doc.placeholders):
        prim = scope.child(f"placeholder_{index}")
        prim.add("position", "double2", _tuple(mark.position))
        prim.add("priority", "token", _string(mark.priority))
        prim.add("rule", "token", _string(mark.rule))
        prim.add("reason", "string", _string(mark.reason))


def _layers(root: _Prim, doc: BlendSpaceDocument) -> None:
    """Beta layers as nested blend spaces (samples + triangles); style layers as a 1D axis."""
    layers = parse_layers(doc)
    if not layers:
        return
    scope = root.child("Layers")
    taken: set[str] = set()
    for entry in layers:
        prim = scope.child(_identifier(entry.name, taken))
        prim.add("name", "string", _string(entry.name))
        prim.add("kind", "token", _string(entry.kind))
        if isinstance(entry, BetaLayerDoc):
            prim.add("source", "asset", _asset(entry.source))
            prim.add("triangles", "int3[]", _triangles(entry.triangles))
            _samples(prim, entry.samples)
            continue
        prim.add("axis:feature", "token", _string(entry.axis.feature))
        prim.add("axis:min", "double", _double(entry.axis.min))
        prim.add("axis:max", "double", _double(entry.axis.max))
        if entry.mask is not None:
            names = sorted(entry.mask.joints)
            prim.add("mask:joints", "string[]", _strings(names))
            prim.add("mask:weights", "double[]", _array(entry.mask.joints[n] for n in names))
            prim.add("mask:default", "double", _double(entry.mask.default))
        samples = prim.child("Samples")
        names_taken: set[str] = set()
        for sample in entry.samples:
            child = samples.child(_identifier(sample.name, names_taken))
            child.add("name", "string", _string(sample.name))
            child.add("source", "asset", _asset(sample.source))
            child.add("position", "double", _double(sample.position[0]))
