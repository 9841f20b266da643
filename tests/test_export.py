"""Engine exports, each parsed back: Godot `.tres` with a tokenizer for Godot's text resource
format, Unity's `.controller` with ruamel.yaml, the Unreal script with `ast` (and run against a
recording stand-in for the editor's `unreal` module, which cannot run outside the editor)."""

from __future__ import annotations

import ast
import math
import re
import sys
import types
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import shared_data
from ruamel.yaml import YAML
from ruamel.yaml.parser import RoundTripParser
from ruamel.yaml.resolver import VersionedResolver
from scipy.spatial import Delaunay

from blendspace_pipeline.cli import main
from blendspace_pipeline.errors import InputError
from blendspace_pipeline.exporters import ExportContext, export
from blendspace_pipeline.space.document import BlendSpaceDocument

# --- documents ------------------------------------------------------------------------------

Axis = tuple[str, float, float, int, str]
TURN_SPEED: tuple[Axis, Axis] = (("turn_rate", -90.0, 180.0, 54, "deg/s"), ("speed", -3.0, 6.0, 90, "m/s"))
LAYOUT = {
    "idle": (0.0, 0.0),
    "walk": (0.0, 1.4),
    "run": (0.0, 4.5),
    "back": (0.0, -1.5),
    "turn_l": (90.0, 0.0),
    "turn_r": (-90.0, 0.0),
    "walk_l": (45.0, 1.4),
    "run_l": (180.0, 4.5),
}


def make_doc(
    points: dict[str, tuple[float, float]],
    axes: tuple[Axis, Axis] = TURN_SPEED,
    layers: list[dict[str, Any]] | None = None,
) -> BlendSpaceDocument:
    names = list(points)
    positions = np.array([points[n] for n in names], dtype=float)
    lows = np.array([axes[0][1], axes[1][1]])
    spans = np.array([axes[0][2] - axes[0][1], axes[1][2] - axes[1][1]])
    return BlendSpaceDocument.model_validate(
        {
            "schema_version": 1,
            "name": "loco",
            "axes": [
                {"name": n, "feature": f, "min": lo, "max": hi, "divisions": d, "unit": u}
                for n, (f, lo, hi, d, u) in zip("xy", axes, strict=True)
            ],
            "samples": [
                {"name": n, "source": f"clips/{n}.bvh", "features": {}, "position": list(p)}
                for n, p in zip(names, positions, strict=True)
            ],
            "triangles": Delaunay((positions - lows) / spans * 100.0).simplices.tolist(),
            "layers": layers or [],
        }
    )


STYLE = {
    "name": "drunk",
    "kind": "style",
    "axis": {"feature": "speed", "min": -3.0, "max": 6.0},
    "samples": [{"name": "drunk_fwd", "source": "s/f.bvh", "position": [1.2], "features": {}}],
}

# --- a Godot text-resource reader -------------------------------------------------------------

_TOKEN = re.compile(
    r"""(?P<space>\s+)
      |(?P<comment>;[^\n]*)
      |(?P<stringname>&"(?:[^"\\]|\\.)*")
      |(?P<string>"(?:[^"\\]|\\.)*")
      |(?P<number>[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)
      |(?P<ident>[A-Za-z_][A-Za-z0-9_/:.]*)
      |(?P<punct>[\[\](){},=:])""",
    re.VERBOSE,
)


@dataclass(frozen=True)
class Constructor:
    """A typed value such as Vector2(1, 0) or SubResource("id")."""

    name: str
    args: list[Any]


@dataclass
class Section:
    tag: str
    attributes: dict[str, Any]
    properties: list[tuple[str, Any]] = field(default_factory=list)

    def get(self, key: str) -> Any:
        return dict(self.properties)[key]


def tokenize(text: str) -> list[tuple[str, str]]:
    tokens, position = [], 0
    while position < len(text):
        match = _TOKEN.match(text, position)
        if match is None:
            raise ValueError(f"unexpected character {text[position]!r} at {position}")
        kind = match.lastgroup
        assert kind is not None
        if kind not in ("space", "comment"):
            tokens.append((kind, match.group()))
        position = match.end()
    return tokens


class GodotResourceParser:
    """`[tag key=value ...]` headers, each followed by `key = value` lines."""

    def __init__(self, text: str) -> None:
        self.tokens = tokenize(text)
        self.index = 0

    def peek(self) -> tuple[str, str] | None:
        return self.tokens[self.index] if self.index < len(self.tokens) else None

    def take(self, value: str | None = None) -> tuple[str, str]:
        token = self.tokens[self.index]
        if value is not None and token[1] != value:
            raise ValueError(f"expected {value!r}, found {token[1]!r}")
        self.index += 1
        return token

    def sections(self) -> list[Section]:
        result = []
        while self.peek() is not None:
            self.take("[")
            tag = self.take()[1]
            attributes = {}
            while self.peek() != ("punct", "]"):
                key = self.take()[1]
                self.take("=")
                attributes[key] = self.value()
            self.take("]")
            section = Section(tag, attributes)
            while (token := self.peek()) is not None and token[0] == "ident":
                key = self.take()[1]
                self.take("=")
                section.properties.append((key, self.value()))
            result.append(section)
        return result

    def value(self) -> Any:
        kind, text = self.take()
        if kind == "number":
            return float(text) if any(c in text for c in ".eE") else int(text)
        if kind in ("string", "stringname"):
            return ast.literal_eval(text.lstrip("&"))  # Godot's escapes are a subset of Python's
        if kind == "ident":
            if text in ("true", "false", "null"):
                return {"true": True, "false": False, "null": None}[text]
            return Constructor(text, self.sequence("(", ")"))
        if text == "[":
            self.index -= 1
            return self.sequence("[", "]")
        raise ValueError(f"unexpected {text!r}")

    def sequence(self, opening: str, closing: str) -> list[Any]:
        self.take(opening)
        items = []
        while self.peek() != ("punct", closing):
            items.append(self.value())
            if self.peek() == ("punct", ","):
                self.take(",")
        self.take(closing)
        return items


@dataclass
class GodotBlendSpace:
    header: Section
    nodes: dict[str, str]  # sub-resource id -> animation name
    resource: Section

    @property
    def points(self) -> dict[str, tuple[float, float]]:
        """Animation name -> position, following blend_point_N/node to its sub-resource."""
        points, index = {}, 0
        while f"blend_point_{index}/node" in dict(self.resource.properties):
            node = self.resource.get(f"blend_point_{index}/node")
            position = self.resource.get(f"blend_point_{index}/pos")
            assert node.name == "SubResource" and position.name == "Vector2"
            points[self.nodes[node.args[0]]] = (float(position.args[0]), float(position.args[1]))
            index += 1
        return points


def read_godot(text: str) -> GodotBlendSpace:
    header, *rest = GodotResourceParser(text).sections()
    subs = [s for s in rest if s.tag == "sub_resource"]
    assert all(s.attributes["type"] == "AnimationNodeAnimation" for s in subs)
    (resource,) = [s for s in rest if s.tag == "resource"]
    return GodotBlendSpace(header, {s.attributes["id"]: s.get("animation") for s in subs}, resource)


# --- Godot --------------------------------------------------------------------------------------


def test_godot_export_places_every_point_with_our_triangles() -> None:
    doc = make_doc(LAYOUT)
    result = export(doc, "godot")
    space = read_godot(result.text)
    assert space.header.tag == "gd_resource"
    assert space.header.attributes["type"] == "AnimationNodeBlendSpace2D"
    assert space.header.attributes["load_steps"] == len(LAYOUT) + 1
    radians = math.pi / 180.0  # Godot angles are radians; metres stay metres; no sign flip
    expected = {name: (x * radians, y) for name, (x, y) in LAYOUT.items()}
    assert space.points.keys() == expected.keys()
    for name, position in space.points.items():
        assert position == pytest.approx(expected[name], abs=1e-8)
    props = space.resource
    assert props.get("min_space").args == pytest.approx([-90 * radians, -3.0])
    assert props.get("max_space").args == pytest.approx([180 * radians, 6.0])
    assert props.get("snap").args == pytest.approx([5 * radians, 0.1])
    assert props.get("x_label") == "turn_rate (rad/s)"
    assert props.get("auto_triangles") is False
    flat = props.get("triangles")
    assert flat.name == "PackedInt32Array"
    assert [flat.args[i : i + 3] for i in range(0, len(flat.args), 3)] == doc.triangles


def test_godot_writes_auto_triangles_off_and_triangles_after_every_point() -> None:
    keys = [key for key, _ in read_godot(export(make_doc(LAYOUT), "godot").text).resource.properties]
    last_point = max(i for i, key in enumerate(keys) if key.startswith("blend_point_"))
    assert keys.index("auto_triangles") < keys.index("triangles")
    assert keys.index("triangles") > last_point
    nodes = [i for i, key in enumerate(keys) if key.endswith("/node")]
    assert all(keys[i + 1].endswith("/pos") for i in nodes)  # node creates the point, then pos


def test_godot_round_trips_the_tps_demo_layout() -> None:
    sources = shared_data("godot-tps-demo", "SOURCES.md").read_text(encoding="utf-8")
    found = re.findall(r"(\w+) at \((-?\d+),\s*(-?\d+)\)", sources)
    layout = {name: (float(x), float(y)) for name, x, y in found}
    assert layout == {
        "strafe_left": (1.0, 0.0),
        "strafe_right": (-1.0, 0.0),
        "strafe_back": (0.0, -1.0),
        "strafe_front": (0.0, 1.0),
        "Idlecombat": (0.0, 0.0),
    }
    axes: tuple[Axis, Axis] = (
        ("lateral_speed", -1.0, 1.0, 20, "m/s"),
        ("forward_speed", -1.0, 1.0, 20, "m/s"),
    )
    doc = make_doc(layout, axes=axes)
    space = read_godot(export(doc, "godot").text)
    assert space.points == layout
    assert space.resource.get("min_space").args == [-1, -1]
    assert space.resource.get("max_space").args == [1, 1]
    assert space.resource.get("snap").args == pytest.approx([0.1, 0.1])
    assert len(space.resource.get("triangles").args) == 4 * 3  # the diamond around Idlecombat


def test_godot_refuses_more_points_than_it_can_hold() -> None:
    grid = {f"c{i}_{j}": (float(i * 20 - 90), float(j - 3)) for i in range(11) for j in range(6)}
    with pytest.raises(InputError, match="at most 64"):
        export(make_doc(grid), "godot")


def _without_triangles(names: list[str]) -> BlendSpaceDocument:
    """A degenerate space: only the samples ``names`` (on one line, or one), no triangles."""
    raw = make_doc(LAYOUT).model_dump()
    raw["samples"] = [sample for sample in raw["samples"] if sample["name"] in names]
    raw["triangles"] = []
    return BlendSpaceDocument.model_validate(raw)


@pytest.mark.parametrize("names", [["idle", "walk", "run", "back"], ["idle"]])
def test_godot_refuses_a_space_without_triangles(names: list[str]) -> None:
    # Godot blends only inside triangles, and its auto_triangles finds none on one line either.
    with pytest.raises(InputError, match="blends only inside triangles and this space has none") as error:
        export(_without_triangles(names), "godot")
    assert error.value.hint is not None and "AnimationNodeBlendSpace1D" in error.value.hint


def test_godot_string_escapes_survive_the_parser() -> None:
    doc = make_doc({'a "quoted" \\ name': (0.0, 0.0), "b": (90.0, 0.0), "c": (0.0, 4.5)})
    assert 'a "quoted" \\ name' in read_godot(export(doc, "godot").text).points


def test_godot_strings_escape_every_control_character() -> None:
    """A name read from a clip file may hold a control character: a NUL byte went into the
    .tres raw. Every one is a `\\uXXXX` escape now, read back as the same name."""
    odd = "walk\x00\x07\r\t\x1b\x85 end"
    doc = make_doc({odd: (0.0, 0.0), "b": (90.0, 0.0), "c": (0.0, 4.5)})
    text = export(doc, "godot").text
    assert not any((ord(c) < 0x20 and c != "\n") or 0x7F <= ord(c) <= 0x9F for c in text)
    assert odd in read_godot(text).points


def _replay_godot_bounds(properties: list[tuple[str, Any]]) -> tuple[list[float], list[float]]:
    """Godot 4's loader calls each setter in file order on a new AnimationNodeBlendSpace2D.

    animation_blend_space_2d.cpp: the constructor sets min_space (-1, -1) and max_space (1, 1);
    set_min_space lowers a component >= max_space to max - 1, set_max_space raises a component
    <= min_space to min + 1. Vector2 is float32.
    """
    low, high = [np.float32(-1.0)] * 2, [np.float32(1.0)] * 2
    for key, value in properties:
        if key == "min_space":
            low = [np.float32(v) for v in value.args]
            low = [lo if lo < hi else hi - np.float32(1) for lo, hi in zip(low, high, strict=True)]
        elif key == "max_space":
            high = [np.float32(v) for v in value.args]
            high = [hi if hi > lo else lo + np.float32(1) for lo, hi in zip(low, high, strict=True)]
    return [float(v) for v in low], [float(v) for v in high]


RANGES = [(1.0, 6.0), (-6.0, -1.0), (-1.0, 1.0), (0.0, 6.0), (-3.0, 6.0), (-6.0, 0.0), (0.25, 0.75),
          (-0.75, -0.25), (2.0, 2.5), (-1.0, 3.0), (-3.0, -0.5), (0.999, 1.5), (-1.5, -1.0)]  # fmt: skip


@pytest.mark.parametrize("x_range", RANGES)
@pytest.mark.parametrize("y_range", RANGES)
def test_godot_loads_the_bounds_exactly_for_any_range(
    x_range: tuple[float, float], y_range: tuple[float, float]
) -> None:
    axes: tuple[Axis, Axis] = (
        ("lateral_speed", *x_range, 10, "m/s"),
        ("forward_speed", *y_range, 10, "m/s"),
    )
    (x0, x1), (y0, y1) = x_range, y_range
    doc = make_doc({"a": (x0, y0), "b": (x1, y0), "c": (x0, y1)}, axes=axes)
    properties = read_godot(export(doc, "godot").text).resource.properties
    low, high = _replay_godot_bounds(properties)
    assert low == pytest.approx([x0, y0], abs=1e-6) and high == pytest.approx([x1, y1], abs=1e-6)


def test_the_bounds_replay_catches_the_old_min_first_order() -> None:
    # The test above can fail: a run-only axis written min first loads as 0..6 (the bug it guards).
    old = [("min_space", Constructor("Vector2", [1, -1])), ("max_space", Constructor("Vector2", [6, 1]))]
    assert _replay_godot_bounds(old) == ([0.0, -1.0], [6.0, 1.0])
    old_max_first = [
        ("max_space", Constructor("Vector2", [1, -1])),
        ("min_space", Constructor("Vector2", [-1, -6])),
    ]
    assert _replay_godot_bounds(old_max_first) == ([-1.0, -6.0], [1.0, 0.0])


def test_godot_header_has_a_stable_uid_and_a_reexport_keeps_godots() -> None:
    doc = make_doc(LAYOUT)
    first = read_godot(export(doc, "godot").text).header.attributes["uid"]
    assert re.fullmatch(r"uid://[a-y0-8]{1,13}", first)
    assert read_godot(export(doc, "godot").text).header.attributes["uid"] == first
    # Godot rewrote the file with its own uid: the next export keeps it.
    previous = export(doc, "godot").text.replace(first, "uid://cs1k22tdf04k4")
    again = export(doc, "godot", context=ExportContext(previous=previous)).text
    assert read_godot(again).header.attributes["uid"] == "uid://cs1k22tdf04k4"


def test_godot_writes_fields_as_godot_4_does_in_the_tps_demo() -> None:
    # godotengine/tps-demo player/player.tscn at 117eca0 (Godot 4, format=3) holds the strafe space:
    #   [sub_resource type="AnimationNodeAnimation" id="19"] / animation = &"strafe_left" ...
    #   blend_point_0/node = SubResource("19") / blend_point_0/pos = Vector2(1, 0) ...
    # The same layout exported by us uses the same types, keys, order and literal syntax.
    layout = {"strafe_left": (1.0, 0.0), "strafe_right": (-1.0, 0.0), "strafe_back": (0.0, -1.0),
              "strafe_front": (0.0, 1.0), "Idlecombat": (0.0, 0.0)}  # fmt: skip
    axes: tuple[Axis, Axis] = (
        ("lateral_speed", -1.0, 1.0, 20, "m/s"),
        ("forward_speed", -1.0, 1.0, 20, "m/s"),
    )
    text = export(make_doc(layout, axes=axes), "godot").text
    assert text.startswith('[gd_resource type="AnimationNodeBlendSpace2D" load_steps=6 format=3 uid="uid://')
    assert (
        '[sub_resource type="AnimationNodeAnimation" id="AnimationNodeAnimation_0"]\nanimation = &"strafe_left"\n'
        in text
    )
    expected = [
        f'blend_point_{i}/node = SubResource("AnimationNodeAnimation_{i}")\nblend_point_{i}/pos = Vector2({x:g}, {y:g})'
        for i, (x, y) in enumerate(layout.values())
    ]
    assert "\n".join(expected) in text
    assert "min_space = Vector2(-1, -1)\nmax_space = Vector2(1, 1)\n" in text


# --- Unity --------------------------------------------------------------------------------------

UNITY_TAG = "tag:unity3d.com,2011:"


class _UnityParser(RoundTripParser):
    """Unity declares `%TAG !u!` once for every document; YAML scopes it to the first one."""

    def process_directives(self) -> Any:
        value = super().process_directives()
        self.tag_handles.setdefault("!u!", UNITY_TAG)
        return value


class _Yaml12Resolver(VersionedResolver):
    """Unity writes `%YAML 1.1` but means no 1.1 booleans: `{x: 0, y: 0}` has a key `y`."""

    @property
    def processing_version(self) -> Any:
        return (1, 2)


def read_unity(text: str) -> dict[int, tuple[int, dict[str, Any]]]:
    """fileID -> (class ID, the object's fields)."""
    yaml = YAML(typ="rt")
    yaml.Parser = _UnityParser
    yaml.Resolver = _Yaml12Resolver
    objects = {}
    for document in yaml.load_all(text):
        tag = document.tag.value
        assert tag.startswith(UNITY_TAG)
        ((_, fields),) = document.items()
        objects[int(document.anchor.value)] = (int(tag[len(UNITY_TAG) :]), fields)
    return objects


def _of_class(objects: dict[int, tuple[int, dict[str, Any]]], class_id: int) -> tuple[int, dict[str, Any]]:
    (found,) = [(file_id, fields) for file_id, (cid, fields) in objects.items() if cid == class_id]
    return found


def test_unity_export_is_a_controller_with_a_freeform_cartesian_tree() -> None:
    result = export(make_doc(LAYOUT), "unity")
    assert result.text.startswith("%YAML 1.1\n%TAG !u! tag:unity3d.com,2011:\n--- !u!91 &9100000\n")
    objects = read_unity(result.text)
    controller_id, controller = _of_class(objects, 91)
    machine_id, machine = _of_class(objects, 1107)
    state_id, state = _of_class(objects, 1102)
    tree_id, tree = _of_class(objects, 206)
    assert controller_id == 9100000
    assert [p["m_Name"] for p in controller["m_AnimatorParameters"]] == ["turn_rate", "speed"]
    assert all(p["m_Type"] == 1 for p in controller["m_AnimatorParameters"])  # float parameters
    assert controller["m_AnimatorLayers"][0]["m_StateMachine"]["fileID"] == machine_id
    assert machine["m_DefaultState"]["fileID"] == state_id
    assert machine["m_ChildStates"][0]["m_State"]["fileID"] == state_id
    assert state["m_Motion"]["fileID"] == tree_id
    assert tree["m_BlendType"] == 3
    assert (tree["m_BlendParameter"], tree["m_BlendParameterY"]) == ("turn_rate", "speed")
    # Unity's positive yaw turns right: turn rates change sign, speeds stay in m/s.
    positions = [(c["m_Position"]["x"], c["m_Position"]["y"]) for c in tree["m_Childs"]]
    # Compare pair by pair: pytest.approx does not take nested sequences (pytest >= 9.2).
    assert positions == [pytest.approx((-x, y)) for x, y in LAYOUT.values()]
    assert any("gradient bands" in note for note in result.notes)
    assert any("turn_rate flipped" in note for note in result.notes)


# A Unity project as Unity lays it out: an FBX whose ModelImporter .meta names its takes in
# internalIDToNameTable (Unity 2019.3+), an older FBX meta with fileIDToRecycleName, and a native .anim.
_FBX_META = """fileFormatVersion: 2
guid: {guid}
ModelImporter:
  serializedVersion: 21300
  internalIDToNameTable:
  - first:
      74: -203655887218126122
    second: walk
  - first:
      74: 1827226128182048838
    second: run
  externalObjects: {{}}
  materials:
    materialImportMode: 2
  animations:
    legacyGenerateAnimations: 4
    clipAnimations: []
"""
_OLD_FBX_META = """fileFormatVersion: 2
guid: {guid}
timeCreated: 1520000000
ModelImporter:
  serializedVersion: 22
  fileIDToRecycleName:
    100000: Hips
    400000: Hips
    7400000: Take 001
  materials:
    importMaterials: 1
"""
_ANIM_META = """fileFormatVersion: 2
guid: {guid}
NativeFormatImporter:
  externalObjects: {{}}
  mainObjectFileID: 7400000
  userData:
"""
GUIDS = {"loco": "1f6f6d1b7a0e4f3c9d2b5a8c7e6f5d4c", "back": "0a1b2c3d4e5f60718293a4b5c6d7e8f9",
         "idle": "abcdefabcdefabcdefabcdefabcdef01"}  # fmt: skip


def _unity_project(root: Path) -> Path:
    clips = root / "Assets" / "Animations"
    clips.mkdir(parents=True)
    (clips / "loco.fbx.meta").write_text(_FBX_META.format(guid=GUIDS["loco"]), encoding="utf-8")
    (clips / "back.fbx.meta").write_text(_OLD_FBX_META.format(guid=GUIDS["back"]), encoding="utf-8")
    (clips / "idle.anim.meta").write_text(_ANIM_META.format(guid=GUIDS["idle"]), encoding="utf-8")
    return root


def _motions(text: str) -> list[dict[str, Any]]:
    tree = _of_class(read_unity(text), 206)[1]
    return [dict(child["m_Motion"]) for child in tree["m_Childs"]]


def test_unity_children_reference_the_clips_guids_from_the_project(tmp_path: Path) -> None:
    context = ExportContext(unity_project=_unity_project(tmp_path / "Game"))
    result = export(make_doc(LAYOUT), "unity", context=context)
    motions = dict(zip(LAYOUT, _motions(result.text), strict=True))
    assert motions["walk"] == {"fileID": -203655887218126122, "guid": GUIDS["loco"], "type": 3}
    assert motions["run"] == {"fileID": 1827226128182048838, "guid": GUIDS["loco"], "type": 3}
    assert motions["back"] == {"fileID": 7400000, "guid": GUIDS["back"], "type": 3}  # single take, by file
    assert motions["idle"] == {"fileID": 7400000, "guid": GUIDS["idle"], "type": 2}  # a native .anim
    assert motions["turn_l"] == {"fileID": 0}
    (note,) = [n for n in result.notes if n.startswith("Motions not assigned")]
    assert "4: turn_l" in note and ": walk," not in note


def test_unity_reexport_keeps_hand_assignments(tmp_path: Path) -> None:
    first = export(make_doc(LAYOUT), "unity").text
    # The user assigned turn_l (child 4, at x = -90 in Unity's turning sign) by hand in Unity.
    hand = "{fileID: 7400000, guid: 0123456789abcdef0123456789abcdef, type: 3}"
    children = first.split("  - serializedVersion: 2\n")
    children[5] = children[5].replace("m_Motion: {fileID: 0}", f"m_Motion: {hand}", 1)
    edited = "  - serializedVersion: 2\n".join(children)
    again = export(make_doc(LAYOUT), "unity", context=ExportContext(previous=edited)).text
    motions = dict(zip(LAYOUT, _motions(again), strict=True))
    assert motions["turn_l"]["guid"] == "0123456789abcdef0123456789abcdef"
    assert sum(1 for m in motions.values() if m != {"fileID": 0}) == 1


def test_unity_warns_where_its_inspector_would() -> None:
    # Mixed units: the turn axis spans 270 deg/s, so 1 % of 1.35 x 270 = 3.6: walk (0, 1.4) and
    # idle (0, 0) are "too close" for Unity although 1.4 m/s apart.
    result = export(make_doc(LAYOUT), "unity")
    (note,) = [n for n in result.notes if "too close to each other" in n]
    assert "idle / walk" in note and "back" in note
    narrow = {"a": (0.0, 0.0), "b": (90.0, 0.0), "c": (0.0, 4.5)}
    assert not [n for n in export(make_doc(narrow), "unity").notes if "too close" in n]


# --- Unreal -------------------------------------------------------------------------------------


def _literals(script: str) -> dict[str, Any]:
    values = {}
    for node in ast.parse(script).body:
        if isinstance(node, ast.Assign) and isinstance(node.targets[0], ast.Name):
            values[node.targets[0].id] = ast.literal_eval(node.value)
    return values


def _calls(script: str) -> list[str]:
    """Every call in the script as source text, e.g. `unreal.BlendSample()`."""
    return [ast.unparse(node) for node in ast.walk(ast.parse(script)) if isinstance(node, ast.Call)]


def test_unreal_script_sets_axes_and_samples_in_unreal_units() -> None:
    result = export(make_doc(LAYOUT), "unreal")
    values = _literals(result.text)
    # x: turn_rate flips sign (positive yaw turns right) so -90..180 becomes -180..90 deg/s;
    # y: speed becomes cm/s.
    assert values["AXES"] == [("turn_rate (deg/s)", -180.0, 90.0, 54), ("speed (cm/s)", -300.0, 600.0, 90)]
    assert values["SAMPLES"] == [
        (n, pytest.approx(-x), pytest.approx(y * 100.0)) for n, (x, y) in LAYOUT.items()
    ]
    assert set(values["ANIMATIONS"]) == set(LAYOUT)
    calls = _calls(result.text)
    assert "unreal.BlendSpaceFactoryNew()" in calls
    assert "tools.create_asset(ASSET_NAME, PACKAGE_PATH, unreal.BlendSpace, factory)" in calls
    assert "blend_space.set_editor_property('blend_parameters', parameters)" in calls
    assert "blend_space.set_editor_property('sample_data', samples)" in calls
    assert "parameter.set_editor_property('grid_num', divisions)" in calls
    assert "unreal.Vector(x, y, 0.0)" in calls
    assert "unreal.EditorAssetLibrary.save_loaded_asset(blend_space, False)" in calls
    assert "task.set_editor_property('automated', True)" in calls  # imports raise no dialog


class _Struct:
    def __init__(self, *args: Any) -> None:
        self.args = args
        self.props: dict[str, Any] = {}

    def set_editor_property(self, name: str, value: Any) -> None:
        self.props[name] = value

    def get_editor_property(self, name: str) -> Any:
        return self.props[name]

    def modify(self) -> None:
        self.props["modified"] = True


SKELETON = "/Game/Characters/Mannequins/Meshes/SK_Mannequin"


def _stand_in_unreal(
    missing: set[str], command_line: str = "UnrealEditor.exe", other_skeleton: set[str] | None = None
) -> tuple[types.ModuleType, dict[str, Any]]:
    """The `unreal` names the script uses, recording what it does to the asset and the files it imports."""
    record: dict[str, Any] = {"imported": [], "errors": []}
    unreal = types.ModuleType("unreal")
    assets: dict[str, Any] = {}

    class BlendSpace(_Struct):
        pass

    class AnimSequence(_Struct):
        pass

    class Vector(tuple[float, ...]):
        x = property(lambda self: self[0])
        y = property(lambda self: self[1])

    def load_asset(path: str) -> Any:
        if path in missing:
            return None
        if path not in assets:
            if path == SKELETON:
                assets[path] = _Struct(path)
            else:
                sequence = AnimSequence(path)
                owner = "/Game/Other" if path in (other_skeleton or set()) else SKELETON
                sequence.set_editor_property("skeleton", load_asset(owner) if owner == SKELETON else owner)
                assets[path] = sequence
        return assets[path]

    def create_asset(name: str, path: str, cls: type[_Struct], factory: _Struct) -> _Struct:
        asset = cls()
        asset.set_editor_property("blend_parameters", [_Struct(), _Struct(), _Struct()])
        record.update(created=(name, path, factory.props), asset=asset)
        return asset

    def import_asset_tasks(tasks: list[_Struct]) -> None:
        for task in tasks:
            record["imported"].append(dict(task.props))
            destination = f"{task.props['destination_path']}/{task.props['destination_name']}"
            task.set_editor_property("imported_object_paths", [destination])

    def fail(text: str) -> None:
        record["errors"].append(text)

    unreal.BlendSpace = BlendSpace  # type: ignore[attr-defined]
    unreal.AnimSequence = AnimSequence  # type: ignore[attr-defined]
    unreal.BlendParameter = unreal.BlendSample = unreal.BlendSpaceFactoryNew = _Struct  # type: ignore[attr-defined]
    unreal.AssetImportTask = _Struct  # type: ignore[attr-defined]
    unreal.Vector = lambda *xyz: Vector(xyz)  # type: ignore[attr-defined]
    unreal.load_asset = load_asset  # type: ignore[attr-defined]
    unreal.log = lambda text: record.setdefault("log", text)  # type: ignore[attr-defined]
    unreal.log_error = fail  # type: ignore[attr-defined]
    tools = types.SimpleNamespace(create_asset=create_asset, import_asset_tasks=import_asset_tasks)
    unreal.AssetToolsHelpers = types.SimpleNamespace(get_asset_tools=lambda: tools)  # type: ignore[attr-defined]
    unreal.SystemLibrary = types.SimpleNamespace(get_command_line=lambda: command_line)  # type: ignore[attr-defined]
    unreal.EditorAssetLibrary = types.SimpleNamespace(  # type: ignore[attr-defined]
        does_asset_exist=lambda path: False,
        save_loaded_asset=lambda asset, only_if_dirty: record.setdefault("saved", asset) is asset,
    )
    editor = types.SimpleNamespace(open_editor_for_assets=lambda assets: record.setdefault("opened", assets))
    unreal.AssetEditorSubsystem = object  # type: ignore[attr-defined]
    unreal.get_editor_subsystem = lambda cls: editor  # type: ignore[attr-defined]
    return unreal, record


def _run_script(
    script: str, missing: set[str], monkeypatch: pytest.MonkeyPatch, **options: Any
) -> dict[str, Any]:
    unreal, record = _stand_in_unreal(missing, **options)
    monkeypatch.setitem(sys.modules, "unreal", unreal)
    exec(compile(script, "loco_unreal.py", "exec"), {"__name__": "__main__"})
    return record


def test_unreal_script_runs_and_builds_the_asset(monkeypatch: pytest.MonkeyPatch) -> None:
    script = export(make_doc(LAYOUT), "unreal").text
    record = _run_script(script, set(), monkeypatch)
    asset = record["asset"]
    assert record["created"][:2] == ("BS_loco", "/Game/BlendSpaces")
    x_axis, y_axis, _ = asset.get_editor_property("blend_parameters")
    assert (x_axis.props["min"], x_axis.props["max"], x_axis.props["grid_num"]) == (-180.0, 90.0, 54)
    assert (y_axis.props["min"], y_axis.props["max"], y_axis.props["grid_num"]) == (-300.0, 600.0, 90)
    assert x_axis.props["snap_to_grid"] and y_axis.props["display_name"] == "speed (cm/s)"
    samples = asset.get_editor_property("sample_data")
    assert [s.props["animation"].args[0] for s in samples] == [f"/Game/Animations/{n}" for n in LAYOUT]
    values = [s.props["sample_value"] for s in samples]
    assert values == [pytest.approx((-x, y * 100.0, 0.0)) for x, y in LAYOUT.values()]
    assert asset.props["modified"] and record["saved"] is asset and record["opened"] == [asset]


def test_unreal_script_imports_generated_clips_and_runs_headless(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    doc = make_doc(LAYOUT)
    raw = doc.model_dump()
    raw["samples"][1]["generated"] = True
    glb = tmp_path / "clips" / "walk.glb"
    context = ExportContext(clip_files={"walk": [glb]})
    script = export(BlendSpaceDocument.model_validate(raw), "unreal", context=context).text
    assert "'walk'" not in script.split("ANIMATIONS = {")[1].split("}")[0]  # imported, not listed
    record = _run_script(script, set(), monkeypatch, command_line="UnrealEditor-Cmd -run=pythonscript")
    (task,) = record["imported"]
    assert task["filename"] == str(glb) and task["automated"] and task["destination_name"] == "walk"
    samples = record["asset"].get_editor_property("sample_data")
    assert samples[1].props["animation"].args[0] == "/Game/Animations/Generated/walk"
    assert record["saved"] is record["asset"] and "opened" not in record  # no editor window headless


def test_unreal_script_stops_before_touching_anything_when_animations_are_missing(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    script = export(make_doc(LAYOUT), "unreal").text
    with pytest.raises(RuntimeError, match="walk: /Game/Animations/walk not found"):
        _run_script(script, {"/Game/Animations/walk"}, monkeypatch)


def test_unreal_script_fails_loudly_on_a_missing_skeleton_or_a_foreign_clip(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    script = export(make_doc(LAYOUT), "unreal").text
    with pytest.raises(RuntimeError, match="skeleton not found"):
        _run_script(script, {SKELETON}, monkeypatch)
    with pytest.raises(RuntimeError, match="run: /Game/Animations/run is not an animation of"):
        _run_script(script, set(), monkeypatch, other_skeleton={"/Game/Animations/run"})
    # Headless, a failure is a non-zero exit, and nothing was created or saved.
    unreal, record = _stand_in_unreal({SKELETON}, command_line="UnrealEditor-Cmd -run=pythonscript")
    monkeypatch.setitem(sys.modules, "unreal", unreal)
    with pytest.raises(SystemExit) as stopped:
        exec(compile(script, "loco_unreal.py", "exec"), {"__name__": "__main__"})
    assert stopped.value.code == 1 and "created" not in record and "saved" not in record


def test_unreal_notes_duplicate_positions() -> None:
    doc = make_doc({"a": (0.0, 0.0), "b": (90.0, 0.0), "c": (0.0, 4.5)})
    raw = doc.model_dump()
    raw["samples"].append({"name": "d", "source": "clips/d.bvh", "features": {}, "position": [90.0, 0.0]})
    result = export(BlendSpaceDocument.model_validate(raw), "unreal")
    assert any("b = d" in note for note in result.notes)


# --- the command ------------------------------------------------------------------------------


def _write(doc: BlendSpaceDocument, folder: Path) -> Path:
    path = folder / "loco.blendspace.json"
    path.write_text(doc.model_dump_json(), encoding="utf-8")
    return path


@pytest.mark.parametrize(("engine", "file_name"), [("godot", "loco.tres"), ("unity", "loco.controller"),
                                                    ("unreal", "loco_unreal.py")])  # fmt: skip
def test_export_command_writes_beside_the_json_and_notes_what_is_lost(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], engine: str, file_name: str
) -> None:
    path = _write(make_doc(LAYOUT, layers=[STYLE]), tmp_path)
    assert main(["export", str(path), "--engine", engine]) == 0
    captured = capsys.readouterr()
    assert (tmp_path / file_name).is_file()
    assert f"wrote {tmp_path / file_name}" in captured.out
    assert "layers drunk are not exported" in captured.err
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["loco.blendspace.json", file_name])


def test_export_command_out_takes_a_file_or_a_folder(tmp_path: Path) -> None:
    path = _write(make_doc(LAYOUT), tmp_path)
    (tmp_path / "godot").mkdir()
    assert main(["export", str(path), "--engine", "godot", "--out", str(tmp_path / "godot")]) == 0
    assert (
        read_godot((tmp_path / "godot" / "loco.tres").read_text(encoding="utf-8")).points.keys()
        == LAYOUT.keys()
    )
    assert main(["export", str(path), "--engine", "godot", "--out", str(tmp_path / "walk.tres")]) == 0
    assert (tmp_path / "walk.tres").is_file()


def test_export_command_rejects_bad_input(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _write(make_doc(LAYOUT), tmp_path)
    assert main(["export", str(path), "--engine", "godot", "--out", str(tmp_path / "no" / "x.tres")]) == 2
    assert "does not exist" in capsys.readouterr().err
    assert main(["export", str(path), "--engine", "cryengine"]) == 2
    assert main(["export", str(tmp_path / "missing.json"), "--engine", "unity"]) == 2
    assert "cannot read" in capsys.readouterr().err


def test_export_command_refuses_a_godot_space_without_triangles(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = _write(_without_triangles(["idle", "walk", "run"]), tmp_path)
    assert main(["export", str(path), "--engine", "godot"]) == 2
    err = capsys.readouterr().err
    assert f"{path}: Godot's AnimationNodeBlendSpace2D blends only inside triangles" in err
    assert "Traceback" not in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["loco.blendspace.json"]  # nothing written


def test_export_command_out_with_a_trailing_separator_is_a_folder(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = _write(make_doc(LAYOUT), tmp_path)
    out = tmp_path / "ex" / "godot"
    assert main(["export", str(path), "--engine", "godot", "--out", f"{out}/"]) == 0
    assert out.is_dir() and (out / "loco.tres").is_file()
    assert f"wrote {out / 'loco.tres'} (godot)" in capsys.readouterr().out
    # Again: the same file, and the output says it replaced it.
    assert main(["export", str(path), "--engine", "godot", "--out", f"{out}/"]) == 0
    assert f"wrote {out / 'loco.tres'} (godot; replaced the previous file)" in capsys.readouterr().out
    assert [p.name for p in out.iterdir()] == ["loco.tres"]


@pytest.mark.parametrize(
    "engine, name", [("godot", "loco.tres"), ("unity", "loco.controller"), ("unreal", "loco_unreal.py")]
)
def test_export_command_out_to_a_new_path_without_an_extension_is_a_folder(
    engine: str, name: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`--out Assets/Animators` for a folder not made yet (no trailing /) wrote a file called
    `Animators` that no engine imports; it is the folder, as with the /."""
    path = _write(make_doc(LAYOUT), tmp_path)
    out = tmp_path / "Assets" / "Animators"
    assert main(["export", str(path), "--engine", engine, "--out", str(out)]) == 0
    assert out.is_dir() and [p.name for p in out.iterdir()] == [name]
    assert f"wrote {out / name} ({engine})" in capsys.readouterr().out
    file_name = tmp_path / "Assets" / f"named{Path(name).suffix}"
    assert main(["export", str(path), "--engine", engine, "--out", str(file_name)]) == 0
    assert file_name.is_file()  # a path with an extension is the file, as before


@pytest.mark.parametrize(
    ("engine", "name", "content"),
    [
        ("unreal", "manifest.yaml", "schema_version: 1\nname: loco\n"),  # the reviewer's case
        ("godot", "loco.blendspace.json", None),  # the export's own input
        ("godot", "loco.controller", None),  # another engine's extension, new file
        ("godot", "material.tres", '[gd_resource type="StandardMaterial3D" format=3]\n'),
        ("unity", "Player.controller", "%YAML 1.1\n--- !u!1 &1\nGameObject:\n"),
        ("unreal", "tools_unreal.py", "print('a studio script')\n"),
    ],
)
def test_export_command_never_replaces_a_file_that_is_not_an_export(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], engine: str, name: str, content: str | None
) -> None:
    """`export --out manifest.yaml` replaced the manifest with an Unreal script (exit 0). An
    existing --out must be this engine's blend-space file, and a new one must have its
    extension; otherwise exit 2 and nothing is written."""
    path = _write(make_doc(LAYOUT), tmp_path)
    target = tmp_path / name
    if content is not None:
        target.write_text(content, encoding="utf-8")
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    assert main(["export", str(path), "--engine", engine, "--out", str(target)]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and ("is an existing file that is not" in err or "export is a" in err), err
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before


@pytest.mark.parametrize("engine", ["godot", "unity", "unreal"])
def test_export_command_replaces_its_own_file_and_an_engine_saved_one(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], engine: str
) -> None:
    path = _write(make_doc(LAYOUT), tmp_path)
    assert main(["export", str(path), "--engine", engine]) == 0
    assert main(["export", str(path), "--engine", engine]) == 0
    assert "replaced the previous file" in capsys.readouterr().out
    if engine == "godot":  # a blend space Godot's editor saved, uid and all
        saved = tmp_path / "saved.tres"
        saved.write_text('[gd_resource type="AnimationNodeBlendSpace2D" format=3 uid="uid://b1"]\n', "utf-8")
        assert main(["export", str(path), "--engine", engine, "--out", str(saved)]) == 0


def test_export_command_turns_write_failures_into_input_errors(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = _write(make_doc(LAYOUT), tmp_path)
    (tmp_path / "afile").write_text("in the way", encoding="utf-8")
    target = tmp_path / "afile" / "x.tres"
    assert main(["export", str(path), "--engine", "godot", "--out", str(target)]) == 2
    err = capsys.readouterr().err
    assert f"cannot write {target}: " in err and "Traceback" not in err
    assert main(["export", str(path), "--engine", "godot", "--out", f"{tmp_path / 'afile'}/"]) == 2
    assert "is a file, not a folder" in capsys.readouterr().err
    assert (tmp_path / "afile").read_text(encoding="utf-8") == "in the way"


def test_export_command_reads_a_unity_project_and_checks_the_option(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = _write(make_doc(LAYOUT), tmp_path)
    project = _unity_project(tmp_path / "Game")
    assert main(["export", str(path), "--engine", "unity", "--unity-project", str(project)]) == 0
    motions = _motions((tmp_path / "loco.controller").read_text(encoding="utf-8"))
    assert motions[1] == {"fileID": -203655887218126122, "guid": GUIDS["loco"], "type": 3}
    capsys.readouterr()
    assert main(["export", str(path), "--engine", "godot", "--unity-project", str(project)]) == 2
    assert "--unity-project is for --engine unity" in capsys.readouterr().err
    assert main(["export", str(path), "--engine", "unity", "--unity-project", str(tmp_path / "nope")]) == 2
    assert "is not a folder" in capsys.readouterr().err


def test_unreal_script_writes_the_foot_down_sync_markers(monkeypatch: pytest.MonkeyPatch) -> None:
    """Issue 13 item 6: the contacts' foot-down events become sync markers on their own track,
    at times in the clip file (the used range's start added back), replacing ours on a re-run."""
    raw = make_doc(LAYOUT).model_dump()
    walk, run = raw["samples"][1], raw["samples"][2]
    walk["markers"] = [{"name": "LeftFootDown", "time": 0.1}, {"name": "RightFootDown", "time": 0.6}]
    run["markers"] = [{"name": "RightFootDown", "time": 0.25}]
    info = {
        "duration": 2.0,
        "fps": 30.0,
        "frames": 61,
        "meters_per_unit": 1.0,
        "units_source": "file",
        "up_axis": "y",
        "root": "hip midpoint",
        "facing": "hip line",
    }
    run["clip"] = {**info, "range": [1.5, 3.5]}
    doc = BlendSpaceDocument.model_validate(raw)
    script = export(doc, "unreal").text
    assert _literals(script)["SYNC_MARKERS"] == {
        walk["name"]: [("LeftFootDown", 0.1), ("RightFootDown", 0.6)],
        run["name"]: [("RightFootDown", 1.75)],
    }
    for existing_track in (False, True):
        record, calls, saved = _run_with_animation_library(script, existing_track, monkeypatch)
        assert not record["errors"]
        first = "clear" if existing_track else "track"
        assert (first, f"/Game/Animations/{walk['name']}", "blendspace_sync") in calls
        assert (
            "marker",
            f"/Game/Animations/{run['name']}",
            "RightFootDown",
            1.75,
            "blendspace_sync",
        ) in calls
        assert sum(c[0] == "marker" for c in calls) == 3
        assert saved[-1] is record["asset"]  # the blend space is saved after the clips' markers


def _run_with_animation_library(
    script: str, existing_track: bool, monkeypatch: pytest.MonkeyPatch
) -> tuple[dict[str, Any], list[tuple[Any, ...]], list[Any]]:
    """Run the script with a stand-in `unreal.AnimationLibrary` recording what it does to clips."""
    unreal, record = _stand_in_unreal(set())
    calls: list[tuple[Any, ...]] = []
    saved: list[Any] = []
    unreal.AnimationLibrary = types.SimpleNamespace(  # type: ignore[attr-defined]
        is_valid_anim_notify_track_name=lambda seq, track: not existing_track,
        add_animation_notify_track=lambda seq, track: calls.append(("track", seq.args[0], track)),
        remove_animation_sync_markers_by_track=lambda seq, track: calls.append(("clear", seq.args[0], track)),
        add_animation_sync_marker=lambda seq, name, time, track: calls.append(
            ("marker", seq.args[0], name, time, track)
        ),
    )
    unreal.EditorAssetLibrary.save_loaded_asset = lambda asset, dirty: saved.append(asset) or True  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, "unreal", unreal)
    exec(compile(script, "loco_unreal.py", "exec"), {"__name__": "__main__"})
    return record, calls, saved


@pytest.mark.parametrize("engine", ["godot", "unity", "unreal"])
def test_export_notes_each_take_measured_on_a_range_of_its_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], engine: str
) -> None:
    """Two `range:`s of one CMU take were exported as the whole take under two names, without a
    word: the engine blends its start and stop too. Each trimmed take is noted with its span; a
    whole take (its T-pose first frame left out or not) is not."""
    take = shared_data("cmu", "131_01.bvh")
    manifest = tmp_path / "manifest.yaml"
    manifest.write_text(
        "schema_version: 1\nname: cmu\nclips:\n"
        f"  - {{path: '{take.as_posix()}', name: walk_a, range: [2.5, 6.0]}}\n"
        f"  - {{path: '{take.as_posix()}', name: walk_a_early, range: [1.5, 3.0]}}\n"
        f"  - {{path: '{shared_data('cmu', '131_02.bvh').as_posix()}', name: whole}}\n",
        encoding="utf-8",
    )
    out = tmp_path / "build"
    assert main(["build", str(manifest), "--out", str(out), "--no-fix"]) in (0, 1)
    capsys.readouterr()
    assert main(["export", str(out / "cmu.blendspace.json"), "--engine", engine]) == 0
    notes = [line for line in capsys.readouterr().err.splitlines() if "was measured on" in line]
    label = {"godot": "Godot", "unity": "Unity", "unreal": "Unreal"}[engine]
    assert notes == [
        f"note: walk_a was measured on 2.50-6.00 s of 131_01.bvh: {label} plays the whole file unless "
        "that span is imported as its own clip (or the file is cut to it)",
        f"note: walk_a_early was measured on 1.50-3.00 s of 131_01.bvh: {label} plays the whole file "
        "unless that span is imported as its own clip (or the file is cut to it)",
    ]
