"""Our Unity `.controller` compared field by field with two the Unity editor saved.

The reference is not in the repository: `unity_controller_reference.py` holds only its structure
(field names in order, value kinds, serializedVersions), made by `controller_structure` below from
the two files named there. To remake it, download them and run
``python tests/test_export_unity_reference.py Locomotion.controller ThirdPersonAnimatorController.controller``.

Both files are parsed with ruamel.yaml through the Unity-aware parser of tests/test_export.py.
"""

from __future__ import annotations

import pprint
import re
import sys
from pathlib import Path
from typing import Any

import pytest
from ruamel.yaml import YAML
from test_export import LAYOUT, UNITY_TAG, _unity_project, _UnityParser, _Yaml12Resolver, make_doc
from unity_controller_reference import HEADER, STRUCTURE

from blendspace_pipeline.exporters import ExportContext, export

# List fields whose items are objects of their own, named as in UnityEditor.Animations.
NESTED = {
    "m_AnimatorParameters": "AnimatorControllerParameter",
    "m_AnimatorLayers": "AnimatorControllerLayer",
    "m_ChildStates": "ChildAnimatorState",
    "m_Childs": "ChildMotion",
}
# The objects our export writes; the reference also has transitions (1101), which we do not need.
OURS = ("AnimatorController", "AnimatorStateMachine", "AnimatorState", "BlendTree")

Structure = dict[str, dict[str, Any]]


def _kind(value: Any) -> str:
    """What Unity's serializer wrote: int, float, str, ref, vector, list, map."""
    if isinstance(value, bool):  # not expected with the YAML 1.2 resolver; keep it visible
        return "bool"
    if isinstance(value, int):
        return "int"
    if isinstance(value, float):
        return "float"
    if value is None or isinstance(value, str):  # Unity writes an empty string as `key: `
        return "str"
    if isinstance(value, dict):
        keys = list(value)
        if keys and keys[0] == "fileID":
            # {fileID} inside the file, {fileID, guid, type} in another asset: same kind.
            assert keys in (["fileID"], ["fileID", "guid", "type"]), keys
            return "ref"
        if keys in (["x", "y"], ["x", "y", "z"]):
            return "vector" + str(len(keys))
        return "map"
    if isinstance(value, list):
        return "list"
    raise TypeError(type(value))


def _objects(owner: str, fields: dict[str, Any]) -> list[tuple[str, dict[str, Any]]]:
    """The object and, depth first, the objects in its NESTED lists."""
    found = [(owner, fields)]
    for key, value in fields.items():
        if key in NESTED and isinstance(value, list):
            for item in value:
                found += _objects(NESTED[key], dict(item))
    return found


def _shape(fields: dict[str, Any]) -> dict[str, Any]:
    kinds = {key: _kind(value) for key, value in fields.items()}
    kinds.update({key: f"list[{NESTED[key]}]" for key in fields if key in NESTED})
    shape: dict[str, Any] = {"fields": list(fields), "kinds": kinds}
    if "serializedVersion" in fields:
        shape["serializedVersion"] = fields["serializedVersion"]
    return shape


def _record(owner: str, fields: dict[str, Any], into: Structure) -> None:
    shape = _shape(fields)
    entry = into.setdefault(owner, shape)
    # Every object of one class in a Unity file lists the same fields in the same order.
    assert entry["fields"] == shape["fields"], (owner, entry["fields"], shape["fields"])
    assert entry.get("serializedVersion") == shape.get("serializedVersion"), owner
    for key, kind in shape["kinds"].items():
        # A float field holding a whole number is written like an int (`m_Threshold: 0`).
        if {entry["kinds"][key], kind} == {"int", "float"}:
            entry["kinds"][key] = "float"


def parse_controller(text: str) -> list[tuple[int, str, dict[str, Any]]]:
    """(class ID, class name, fields) for each document, parsed by ruamel.yaml."""
    yaml = YAML(typ="rt")
    yaml.Parser = _UnityParser
    yaml.Resolver = _Yaml12Resolver
    documents = []
    for document in yaml.load_all(text):
        tag = document.tag.value
        assert tag.startswith(UNITY_TAG)
        ((name, fields),) = document.items()
        documents.append((int(tag[len(UNITY_TAG) :]), name, fields))
    return documents


def controller_structure(*texts: str) -> dict[str, Any]:
    """The structure of `.controller` files: header lines, class IDs and, per class, fields and kinds.

    Several files merge into one (they must agree on every field order); a field that holds a
    fraction in any of them is a float field.
    """
    headers = {tuple(text.split("\n--- ", 1)[0].split("\n")) for text in texts}
    (header,) = headers
    structure: Structure = {}
    class_ids: dict[str, int] = {}
    for text in texts:
        for class_id, name, fields in parse_controller(text):
            class_ids[name] = class_id
            for owner, each in _objects(name, dict(fields)):
                _record(owner, each, structure)
    # Nested objects carry no tags; leave them without a class ID.
    return {
        "header": list(header),
        "sorted_by_file_id": all(_file_ids(t) == sorted(_file_ids(t)) for t in texts),
        "class_ids": class_ids,
        "structure": structure,
    }


def _file_ids(text: str) -> list[int]:
    return [int(i) for i in re.findall(r"^--- !u!\d+ &(-?\d+)", text, re.MULTILINE)]


def _compatible(ours: str, unity: str) -> bool:
    # A float field that happens to hold whole numbers in our export prints like an int, as Unity's do.
    return ours == unity or (unity == "float" and ours == "int")


def differences(text: str) -> list[str]:
    """Where our controller departs from the reference, one line each (empty when it matches)."""
    documents = parse_controller(text)
    header = text.split("\n--- ", 1)[0].split("\n")
    problems = [] if header == HEADER else [f"header {header} != {HEADER}"]
    tags = re.findall(r"^--- .*$", text, re.MULTILINE)
    problems += [f"document line {t!r}" for t in tags if not re.fullmatch(r"--- !u!\d+ &-?\d+", t)]
    # Unity saves objects in ascending local file ID; another order is rewritten on its first save.
    if STRUCTURE["sorted_by_file_id"] and _file_ids(text) != sorted(_file_ids(text)):
        problems.append(f"documents not in ascending file ID order: {_file_ids(text)}")
    reference: Structure = STRUCTURE["structure"]
    seen = set()
    for class_id, name, fields in documents:
        if STRUCTURE["class_ids"].get(name) != class_id:
            problems.append(f"{name} is !u!{class_id}, Unity writes !u!{STRUCTURE['class_ids'].get(name)}")
        # Each object on its own, nested ones too: one child without a field is one child too many.
        for owner, each in _objects(name, dict(fields)):
            seen.add(owner)
            if owner not in reference:
                problems.append(f"{owner}: no such object in the reference")
                continue
            shape, unity = _shape(each), reference[owner]
            if shape["fields"] != unity["fields"]:
                problems.append(f"{owner} fields {shape['fields']} != Unity's {unity['fields']}")
            for key, kind in shape["kinds"].items():
                if key in unity["kinds"] and not _compatible(kind, unity["kinds"][key]):
                    problems.append(f"{owner}.{key} is {kind}, Unity writes {unity['kinds'][key]}")
            if shape.get("serializedVersion") != unity.get("serializedVersion"):
                problems.append(
                    f"{owner} serializedVersion {shape.get('serializedVersion')} != "
                    f"{unity.get('serializedVersion')}"
                )
    problems += [f"{o} not written" for o in (*OURS, *NESTED.values()) if o not in seen]
    return problems


def _export_with_guids(tmp_path: Path) -> str:
    # With a project, children reference clips by {fileID, guid, type} as in the reference.
    context = ExportContext(unity_project=_unity_project(tmp_path / "Game"))
    return export(make_doc(LAYOUT), "unity", context=context).text


def test_the_fixture_records_unitys_2d_tree_with_asset_references() -> None:
    # What the reference shows and the comparison relies on: thresholds are floats, motions references.
    assert HEADER == ["%YAML 1.1", "%TAG !u! tag:unity3d.com,2011:"]
    assert STRUCTURE["class_ids"]["BlendTree"] == 206
    child = STRUCTURE["structure"]["ChildMotion"]
    assert child["kinds"]["m_Motion"] == "ref" and child["kinds"]["m_Threshold"] == "float"
    assert child["kinds"]["m_TimeScale"] == "float"  # 0.1 in the Standard Assets jump tree
    assert STRUCTURE["structure"]["BlendTree"]["kinds"]["m_BlendType"] == "int"


def test_our_controller_matches_what_unity_writes_field_by_field(tmp_path: Path) -> None:
    text = _export_with_guids(tmp_path)
    assert differences(text) == []
    motions = [c["m_Motion"] for _, _, f in parse_controller(text) if "m_Childs" in f for c in f["m_Childs"]]
    assert any(list(m) == ["fileID", "guid", "type"] for m in motions)


def test_an_unassigned_export_matches_too() -> None:
    assert differences(export(make_doc(LAYOUT), "unity").text) == []


@pytest.mark.parametrize(
    ("old", "new", "expected"),
    [
        ("    m_Mirror: 0\n", "", "ChildMotion fields"),  # a field Unity writes, left out
        ("  m_MinThreshold: 0\n  m_MaxThreshold: 1\n", "  m_MaxThreshold: 1\n  m_MinThreshold: 0\n",
         "BlendTree fields"),  # order
        ("  m_BlendType: 3\n", "  m_BlendType: 3.0\n", "BlendTree.m_BlendType is float"),  # type
        ("    m_TimeScale: 1\n", "    m_TimeScale: fast\n", "ChildMotion.m_TimeScale is str"),
        ("  serializedVersion: 6\n  m_ObjectHideFlags: 1\n", "  serializedVersion: 7\n  m_ObjectHideFlags: 1\n",
         "serializedVersion 7"),
        ("--- !u!206 ", "--- !u!207 ", "BlendTree is !u!207"),
        ("%YAML 1.1\n", "%YAML 1.2\n", "header"),
        ("--- !u!91 &9100000\n", "--- !u!91 &2061000000000000000\n", "ascending file ID"),
    ],
)  # fmt: skip
def test_the_comparison_catches_what_unity_would_not_write(
    tmp_path: Path, old: str, new: str, expected: str
) -> None:
    text = _export_with_guids(tmp_path)
    assert old in text
    problems = differences(text.replace(old, new, 1))
    assert any(expected in p for p in problems), problems


if __name__ == "__main__":  # remake the fixture from the downloaded reference files
    texts = [Path(name).read_text(encoding="utf-8") for name in sys.argv[1:]]
    print(pprint.pformat(controller_structure(*texts), width=110))
