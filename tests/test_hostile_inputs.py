"""A corpus of hostile and broken inputs, as a new user or an attacker would try them.

Every case runs through the real command line (`cli.main`, in process; cases that could hang run
in a subprocess with a timeout) for `check` and for `build`, and asserts the exit code, that the
message names the file (and line) with a hint, that no traceback escapes, that nothing is written
(no output folder, no new or changed file anywhere in the project) and that sources are intact.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

from blendspace_pipeline.cli import main
from blendspace_pipeline.motion.procedural import GaitSpec, generate
from blendspace_pipeline.writers.bvh import write_bvh_clip
from blendspace_pipeline.writers.gltf import write_gltf_clip
from blendspace_pipeline.writers.usd_clip import write_usd_clip

HEADER = "schema_version: 1\nname: t\n"
GOOD = HEADER + "clips:\n  - path: clips/*.usda\n"


@pytest.fixture(autouse=True)
def _no_cache(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    # A cached measurement of an earlier run must not hide what the reader says about a file.
    monkeypatch.setenv("BLENDSPACE_CACHE_DIR", "off")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "user-cache"))
    monkeypatch.delenv("BLENDSPACE_RULE_PATH", raising=False)
    monkeypatch.delenv("BLENDSPACE_NO_PLUGINS", raising=False)


def _project(tmp: Path) -> Path:
    """A valid project (three USD clips) that each case then breaks in one way."""
    root = tmp / "project"
    clips = root / "clips"
    clips.mkdir(parents=True)
    specs = {
        "idle": GaitSpec("idle"),
        "walk": GaitSpec("walk", speed=1.4),
        "turn": GaitSpec("turn", turn_rate=90.0),
    }
    for name, spec in specs.items():
        write_usd_clip(generate(spec), clips / f"{name}.usda", meters_per_unit=1.0, up_axis="y")
    (root / "manifest.yaml").write_text(GOOD, encoding="utf-8")
    return root


def _bvh_text(tmp: Path) -> str:
    path = tmp / "template.bvh"
    write_bvh_clip(generate(GaitSpec("walk", speed=1.4)), path)
    text = path.read_text(encoding="utf-8")
    path.unlink()
    return text


def _gltf(root: Path) -> dict[str, object]:
    path = root / "clips" / "g.gltf"
    write_gltf_clip(generate(GaitSpec("walk", speed=1.4)), path)
    return json.loads(path.read_text(encoding="utf-8"))  # type: ignore[no-any-return]


def _snapshot(root: Path) -> dict[str, bytes]:
    state: dict[str, bytes] = {}
    for path in sorted(root.rglob("*")):
        if path.is_symlink() or not path.exists():
            state[path.relative_to(root).as_posix()] = b"link"
        elif path.is_file():
            state[path.relative_to(root).as_posix()] = path.read_bytes()
        elif path.is_dir():
            state[path.relative_to(root).as_posix() + "/"] = b""
    return state


# -- the manifest ---------------------------------------------------------------------------------

AXIS = HEADER + "clips:\n  - path: clips/*.usda\naxes:\n  x: {{feature: turn_rate, {axis}}}\n"
MANIFEST_BODIES: dict[str, tuple[str, str]] = {
    # name: (manifest text, expected location in the first line)
    "divisions_10_pow_1000": (AXIS.format(axis="min: -180, max: 180, divisions: 1" + "0" * 1000), ":6:"),
    "divisions_too_many": (AXIS.format(axis="min: -180, max: 180, divisions: 100001"), ":6:"),
    "divisions_zero": (AXIS.format(axis="min: -180, max: 180, divisions: 0"), ":6:"),
    "divisions_negative": (AXIS.format(axis="min: -180, max: 180, divisions: -5"), ":6:"),
    "divisions_float": (AXIS.format(axis="min: -180, max: 180, divisions: 2.5"), ":6:"),
    "divisions_text": (AXIS.format(axis="min: -180, max: 180, divisions: many"), ":6:"),
    "axis_minus_1e308_to_1e308": (AXIS.format(axis="min: -1e308, max: 1e308, divisions: 100"), ":6:"),
    "axis_infinite": (AXIS.format(axis="min: -.inf, max: 180, divisions: 100"), ":6:"),
    "axis_nan": (AXIS.format(axis="min: .nan, max: 180, divisions: 100"), ":6:"),
    "axis_too_wide": (AXIS.format(axis="min: -1e7, max: 1e7, divisions: 100"), ":6:"),
    "axis_min_above_max": (AXIS.format(axis="min: 180, max: -180, divisions: 100"), ":6:"),
    "axis_empty_range": (AXIS.format(axis="min: 5, max: 5, divisions: 100"), ":6:"),
    "axis_tiny_range": (AXIS.format(axis="min: 0, max: 1e-9, divisions: 100"), ":6:"),
    "axis_unknown_feature": (
        "schema_version: 1\nname: t\nclips:\n  - path: clips/*.usda\naxes:\n"
        "  x: {feature: wobble, min: -1, max: 1, divisions: 10}\n",
        ":6:",
    ),
    "units_2_pow_63": (GOOD + "skeleton: {units: 9223372036854775808}\n", ":5:"),
    "units_huge_float": (GOOD + "skeleton: {units: 1e300}\n", ":5:"),
    "units_tiny": (GOOD + "skeleton: {units: 1e-300}\n", ":5:"),
    "units_zero": (GOOD + "skeleton: {units: 0}\n", ":5:"),
    "units_negative": (GOOD + "skeleton: {units: -0.01}\n", ":5:"),
    "units_word": (GOOD + "skeleton: {units: furlong}\n", ":5:"),
    "up_axis_x": (GOOD + "skeleton: {up: x}\n", ":5:"),
    "schema_version_2": ("schema_version: 2\nname: t\nclips:\n  - path: clips/*.usda\n", ":1:"),
    "schema_version_text": ("schema_version: one\nname: t\nclips:\n  - path: clips/*.usda\n", ":1:"),
    "schema_version_missing": ("name: t\nclips:\n  - path: clips/*.usda\n", "manifest.yaml"),
    "unknown_top_key": (GOOD + "thresholds_typo: {too_close: 8}\n", ":5:"),
    "unknown_entry_key": (HEADER + "clips:\n  - path: clips/walk.usda\n    nmae: w\n", ":5:"),
    "clips_empty_list": (HEADER + "clips: []\n", ":3:"),
    "clips_a_mapping": (HEADER + "clips: {path: clips/walk.usda}\n", ":3:"),
    "clips_missing": (HEADER, "manifest.yaml"),
    "clip_path_empty": (HEADER + "clips:\n  - path: ''\n", ":4:"),
    "clip_path_number": (HEADER + "clips:\n  - path: 12\n", ":4:"),
    "clip_path_300_chars": (HEADER + "clips:\n  - path: clips/" + "a" * 300 + ".usda\n", ":4:"),
    "clip_path_5000_chars": (HEADER + "clips:\n  - path: " + "d/" * 2500 + "x.usda\n", ":4:"),
    "clip_path_nul": (HEADER + 'clips:\n  - path: "clips/walk\\0.usda"\n', ":4:"),
    "clip_path_folder": (HEADER + "clips:\n  - path: clips\n", ":4:"),
    "clip_path_missing": (HEADER + "clips:\n  - path: clips/nothere.usda\n", ":4:"),
    "clip_path_absolute_missing": (HEADER + "clips:\n  - path: /nonexistent/x.bvh\n", ":4:"),
    "clip_glob_nothing": (HEADER + "clips:\n  - path: clips/*.bvh\n", ":4:"),
    "clip_glob_only_unreadable": (HEADER + "clips:\n  - path: clips/*\n    name: x\n", ":4:"),
    "clip_fbx": (HEADER + "clips:\n  - path: clips/walk.fbx\n", ":4:"),
    "clip_dev_null": (HEADER + "clips:\n  - path: /dev/null\n", ":4:"),
    "clip_range_reversed": (HEADER + "clips:\n  - path: clips/walk.usda\n    range: [2, 1]\n", ":5:"),
    "clip_range_text": (HEADER + "clips:\n  - path: clips/walk.usda\n    range: [a, b]\n", ":5:"),
    "clip_range_huge": (HEADER + "clips:\n  - path: clips/walk.usda\n    range: [0, 1e308]\n", ":5:"),
    "duplicate_names": (
        HEADER + "clips:\n  - path: clips/walk.usda\n  - path: clips/turn.usda\n    name: walk\n",
        ":5:",
    ),
    "rules_unknown": (GOOD + "rules: {select: [no-such-rule]}\n", ":5:"),
    "threshold_negative": (GOOD + "thresholds: {too_close: -1}\n", ":5:"),
    "fixes_wrong_type": (GOOD + "fixes: {mirror: sometimes}\n", ":5:"),
    "layer_missing_manifest": (GOOD + "layers:\n  - {name: l, kind: beta, manifest: nothere.yaml}\n", ":6:"),
    "layer_kind_unknown": (GOOD + "layers:\n  - {name: l, kind: gamma}\n", ":6:"),
    "layer_duplicate_names": (
        GOOD + "layers:\n  - {name: l, kind: style, clips: [clips/walk.usda]}\n"
        "  - {name: l, kind: style, clips: [clips/turn.usda]}\n",
        ":7:",
    ),
    "yaml_tab_indent": (HEADER + "clips:\n\t- path: clips/*.usda\n", ":4:"),
    "yaml_unclosed_bracket": (HEADER + "clips: [\n", "manifest.yaml:"),
    "yaml_duplicate_key": (GOOD + "name: u\n", ":5:"),
    "yaml_nested_10000": ("a: " + "[" * 10000 + "]" * 10000 + "\n", "manifest.yaml"),
    "yaml_flow_nested_100": (GOOD + "x: " + "{a: " * 100 + "1" + "}" * 100 + "\n", "manifest.yaml"),
    "yaml_control_character": (GOOD + "note: \x07\n", "manifest.yaml"),
    "yaml_a_list": ("- 1\n- 2\n", ":1:"),
    "yaml_a_string": ("just text\n", ":1:"),
    "yaml_empty": ("", "manifest.yaml"),
    # Found by the fuzzer: a lone surrogate escape was a UnicodeEncodeError (exit 3) in the build.
    "yaml_lone_surrogate": (HEADER + 'clips:\n  - path: "clips/\\ud800.usda"\n', ":4:"),
    "yaml_python_tag": (GOOD + "x: !!python/object:os.system ls\n", "manifest.yaml"),
}


def _alias_bomb() -> str:
    lines = ["a: &a [x, x, x, x, x, x, x, x, x, x]"]
    for i in range(1, 12):
        lines.append(f"{chr(97 + i)}: &{chr(97 + i)} [" + ", ".join([f"*{chr(96 + i)}"] * 10) + "]")
    return "\n".join(lines) + "\n"


MANIFEST_BODIES["yaml_alias_bomb"] = (_alias_bomb(), "manifest.yaml")


def _manifest_case(body: str, where: str) -> Callable[[Path], tuple[Path, str]]:
    def case(root: Path) -> tuple[Path, str]:
        manifest = root / "manifest.yaml"
        manifest.write_text(body, encoding="utf-8")
        (root / "clips" / "notes.txt").write_text("not a clip\n", encoding="utf-8")
        return manifest, where

    return case


def _raw_manifest(data: bytes, where: str) -> Callable[[Path], tuple[Path, str]]:
    def case(root: Path) -> tuple[Path, str]:
        manifest = root / "manifest.yaml"
        manifest.write_bytes(data)
        return manifest, where

    return case


# -- BVH ------------------------------------------------------------------------------------------


def _bvh_case(edit: Callable[[str], str | bytes], where: str) -> Callable[[Path], tuple[Path, str]]:
    def case(root: Path) -> tuple[Path, str]:
        edited = edit(_bvh_text(root))
        path = root / "clips" / "b.bvh"
        if isinstance(edited, bytes):
            path.write_bytes(edited)
        else:
            path.write_text(edited, encoding="utf-8")
        manifest = root / "manifest.yaml"
        manifest.write_text(GOOD + "  - path: clips/b.bvh\n", encoding="utf-8")
        return manifest, where

    return case


def _frame_time(value: str) -> Callable[[str], str]:
    return lambda text: re.sub(r"Frame Time:.*", f"Frame Time: {value}", text)


def _value(frame: int, column: int, value: str) -> Callable[[str], str]:
    def edit(text: str) -> str:
        lines = text.split("\n")
        first = next(i for i, line in enumerate(lines) if line.startswith("Frame Time")) + 1
        numbers = lines[first + frame].split()
        numbers[column] = value
        lines[first + frame] = " ".join(numbers)
        return "\n".join(lines)

    return edit


def _frames(count: int) -> Callable[[str], str]:
    def edit(text: str) -> str:
        head, _, body = text.partition("Frames:")
        rows = body.split("\n")[2:]
        rows = [r for r in rows if r.strip()]
        frame_time = body.split("\n")[1]
        data = "\n".join(rows[i % len(rows)] for i in range(count))
        return f"{head}Frames: {count}\n{frame_time}\n{data}\n"

    return edit


def _deep_hierarchy(depth: int) -> str:
    lines = [
        "HIERARCHY",
        "ROOT Hips",
        "{",
        "OFFSET 0 0 0",
        "CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation",
    ]
    for index in range(depth):
        lines += [f"JOINT J{index}", "{", "OFFSET 0 1 0", "CHANNELS 3 Zrotation Xrotation Yrotation"]
    lines += ["End Site", "{", "OFFSET 0 1 0", "}"] + ["}"] * (depth + 1)
    channels = 6 + 3 * depth
    lines += ["MOTION", "Frames: 2", "Frame Time: 0.033333"] + [" ".join(["0"] * channels)] * 2
    return "\n".join(lines) + "\n"


BVH_EDITS: dict[str, tuple[Callable[[str], str | bytes], str]] = {
    "frame_time_1e-300": (_frame_time("1e-300"), "b.bvh:119"),
    "frame_time_1e300": (_frame_time("1e300"), "b.bvh:119"),
    "frame_time_zero": (_frame_time("0"), "b.bvh:119"),
    "frame_time_negative": (_frame_time("-0.033"), "b.bvh:119"),
    "frame_time_nan": (_frame_time("nan"), "b.bvh:119"),
    "frame_time_inf": (_frame_time("inf"), "b.bvh:119"),
    "frame_time_text": (_frame_time("fast"), "b.bvh:119"),
    "rotation_1e308": (_value(2, 5, "1e308"), "b.bvh:122"),
    "rotation_minus_1e308": (_value(0, 8, "-1e308"), "b.bvh:120"),
    "rotation_1e7": (_value(1, 4, "1e7"), "b.bvh:121"),
    "position_1e308": (_value(3, 1, "1e308"), "b.bvh:123"),
    "position_1e20": (_value(3, 0, "1e20"), "b.bvh:123"),
    "value_nan": (_value(4, 3, "nan"), "b.bvh:124"),
    "value_inf": (_value(4, 3, "inf"), "b.bvh:124"),
    "value_word": (_value(4, 3, "abc"), "b.bvh:124"),
    "frames_200000": (_frames(200_000), "b.bvh:118"),
    "frames_declared_huge": (lambda t: re.sub(r"Frames:.*", "Frames: 99999999999", t), "b.bvh:118"),
    "frames_declared_negative": (lambda t: re.sub(r"Frames:.*", "Frames: -3", t), "b.bvh:118"),
    "frames_text": (lambda t: re.sub(r"Frames:.*", "Frames: lots", t), "b.bvh:118"),
    "frames_more_than_data": (lambda t: re.sub(r"Frames:.*", "Frames: 40", t), "b.bvh:"),
    "frames_fewer_than_data": (lambda t: re.sub(r"Frames:.*", "Frames: 5", t), "b.bvh:"),
    "no_motion": (lambda t: t.split("MOTION")[0], "b.bvh"),
    "no_hierarchy": (lambda t: t.replace("HIERARCHY", "HIERARCHI", 1), "b.bvh:1"),
    "unbalanced_braces": (lambda t: t.replace("}", "", 1), "b.bvh:"),
    "channels_seven": (
        lambda t: t.replace("CHANNELS 3 Zrotation Xrotation Yrotation", "CHANNELS 7 Zrotation", 1),
        "b.bvh:",
    ),
    "channel_unknown": (lambda t: t.replace("Xrotation", "Wrotation", 1), "b.bvh:5"),
    "channel_count_negative": (lambda t: t.replace("CHANNELS 3", "CHANNELS -3", 1), "b.bvh:"),
    "offset_text": (lambda t: t.replace("OFFSET 0.090000", "OFFSET abc", 1), "b.bvh:8"),
    "offset_1e308": (lambda t: t.replace("OFFSET 0.090000", "OFFSET 1e308", 1), "b.bvh"),
    "binary_garbage": (lambda t: b"\x89PNG\r\n\x1a\n\x00\x00garbage", "b.bvh"),
    "empty_file": (lambda t: "", "b.bvh"),
    "only_a_bom": (lambda t: b"\xef\xbb\xbf", "b.bvh"),
    "latin1_joint_name": (lambda t: t.encode().replace(b"LeftUpLeg", b"Left\xe9UpLeg", 1) + b"\xff", "b.bvh"),
    "joints_3000": (lambda t: _deep_hierarchy(3000), "b.bvh"),
    "utf16": (lambda t: t.encode("utf-16"), "b.bvh"),
    # Found by the fuzzer: a brace after an End Site keyword opened a block owned by no joint.
    "stray_brace_after_end_site": (
        lambda t: (
            "HIERARCHY\nROOT Hips\n{\nEnd Site\n}\n{\nOFFSET 0 1 0\n}\nMOTION\nFrames: 1\n"
            "Frame Time: 0.03\n0\n"
        ),
        "b.bvh:7",
    ),
}


# -- glTF -----------------------------------------------------------------------------------------


def _gltf_case(
    edit: Callable[[dict[str, object], Path], object], where: str
) -> Callable[[Path], tuple[Path, str]]:
    def case(root: Path) -> tuple[Path, str]:
        document = _gltf(root)
        result = edit(document, root)
        path = root / "clips" / "g.gltf"
        if isinstance(result, bytes):
            path.write_bytes(result)
        else:
            path.write_text(json.dumps(document), encoding="utf-8")
        manifest = root / "manifest.yaml"
        manifest.write_text(GOOD + "  - path: clips/g.gltf\n", encoding="utf-8")
        return manifest, where

    return case


def _uri(value: Callable[[Path], str]) -> Callable[[dict[str, object], Path], None]:
    def edit(document: dict[str, object], root: Path) -> None:
        document["buffers"][0]["uri"] = value(root)  # type: ignore[index]

    return edit


def _fifo(root: Path) -> str:
    os.mkfifo(root / "clips" / "pipe.bin")
    return "pipe.bin"


def _outside(root: Path) -> str:
    (root.parent / "outside.bin").write_bytes(b"\0" * 100_000)
    return "../../outside.bin"


def _symlink_out(root: Path) -> str:
    os.symlink("/etc/passwd", root / "clips" / "inside.bin")
    return "inside.bin"


def _set(key: str, value: object) -> Callable[[dict[str, object], Path], None]:
    def edit(document: dict[str, object], root: Path) -> None:
        target: object = document
        *parents, last = key.split(".")
        for part in parents:
            target = target[int(part)] if isinstance(target, list) else target[part]  # type: ignore[index]
        if isinstance(target, list):
            target[int(last)] = value
        else:
            target[last] = value  # type: ignore[index]

    return edit


GLTF_EDITS: dict[str, tuple[Callable[[dict[str, object], Path], object], str]] = {
    "uri_etc_passwd": (_uri(lambda r: "../../../../../../../../etc/passwd"), "g.gltf"),
    "uri_absolute_etc_passwd": (_uri(lambda r: "/etc/passwd"), "g.gltf"),
    "uri_dev_zero": (_uri(lambda r: "/dev/zero"), "g.gltf"),
    "uri_fifo": (_uri(_fifo), "g.gltf"),
    "uri_outside_project": (_uri(_outside), "g.gltf"),
    "uri_symlink_leaving_project": (_uri(_symlink_out), "g.gltf"),
    "uri_remote": (_uri(lambda r: "https://example.com/x.bin"), "g.gltf"),
    "uri_missing": (_uri(lambda r: "nothere.bin"), "g.gltf"),
    "uri_folder": (_uri(lambda r: "."), "g.gltf"),
    "uri_bad_data": (_uri(lambda r: "data:application/octet-stream;base64,@@@@"), "g.gltf"),
    "uri_number": (_uri(lambda r: 12), "g.gltf"),  # type: ignore[arg-type,return-value]
    "byte_length_huge": (_set("buffers.0.byteLength", 10**12), "g.gltf"),
    "byte_length_negative": (_set("buffers.0.byteLength", -1), "g.gltf"),
    "accessor_count_huge": (_set("accessors.0.count", 10**12), "g.gltf"),
    "accessor_index_missing": (_set("animations.0.samplers.0.input", 9999), "g.gltf"),
    "version_1": (_set("asset.version", "1.0"), "g.gltf"),
    "component_type_list": (_set("accessors.0.componentType", [5126]), "g.gltf"),  # found by the fuzzer
    "nested_200000": (lambda d, r: b"[" * 200_000 + b"]" * 200_000, "g.gltf"),
    "nested_objects_200000": (lambda d, r: b'{"a":' * 200_000 + b"1" + b"}" * 200_000, "g.gltf"),
    "not_json": (lambda d, r: b"{not json", "g.gltf:1"),
    "json_array": (lambda d, r: b"[1, 2]", "g.gltf"),
    "not_utf8": (lambda d, r: b'{"asset": "\xff"}', "g.gltf"),
    "no_animations": (_set("animations", []), "g.gltf"),
}


def _glb_case(data: bytes, where: str) -> Callable[[Path], tuple[Path, str]]:
    def case(root: Path) -> tuple[Path, str]:
        (root / "clips" / "g.glb").write_bytes(data)
        manifest = root / "manifest.yaml"
        manifest.write_text(GOOD + "  - path: clips/g.glb\n", encoding="utf-8")
        return manifest, where

    return case


GLB_DATA: dict[str, bytes] = {
    "glb_bad_magic": b"glTX" + b"\0" * 40,
    "glb_truncated_header": b"glTF\x02\0\0",
    "glb_chunk_length_overflow": b"glTF\x02\0\0\0\x20\0\0\0\xff\xff\xff\x7fJSON{}",
    "glb_empty": b"",
}


# -- USD ------------------------------------------------------------------------------------------


def _usd_case(edit: Callable[[Path], None], where: str) -> Callable[[Path], tuple[Path, str]]:
    def case(root: Path) -> tuple[Path, str]:
        edit(root / "clips" / "walk.usda")
        return root / "manifest.yaml", where

    return case


def _replace_bytes(old: bytes, new: bytes) -> Callable[[Path], None]:
    def edit(path: Path) -> None:
        data = path.read_bytes()
        assert old in data, old
        path.write_bytes(data.replace(old, new, 1))

    return edit


def _sublayer(target: Callable[[Path], str]) -> Callable[[Path], None]:
    def edit(path: Path) -> None:
        text = path.read_text(encoding="utf-8")
        header, rest = text.split("\n", 1)
        path.write_text(f"{header}\n(\n    subLayers = [@{target(path)}@]\n)\n{rest}", encoding="utf-8")

    return edit


def _usd_fifo(path: Path) -> str:
    os.mkfifo(path.parent / "pipe.usda")
    return "./pipe.usda"


def _usd_outside(path: Path) -> str:
    outside = path.parents[2] / "outside.usda"
    outside.write_text("#usda 1.0\n", encoding="utf-8")
    return "../../outside.usda"


USD_EDITS: dict[str, tuple[Callable[[Path], None], str]] = {
    "usd_non_utf8_bytes": (
        _replace_bytes(
            b"def ",
            b"def \xff\xfe",
        ),
        "walk.usda:",
    ),
    "usd_joints_wrong_type": (
        lambda p: p.write_text(
            re.sub(
                r"uniform token\[\] joints = \[[^\]]*\]",
                "uniform int[] joints = [1, 2]",
                p.read_text(encoding="utf-8"),
                count=1,
            ),
            encoding="utf-8",
        ),
        "walk.usda",
    ),
    "usd_sublayer_outside": (_sublayer(_usd_outside), "walk.usda"),
    "usd_sublayer_etc": (_sublayer(lambda p: "/etc/hosts.usda"), "walk.usda"),
    "usd_sublayer_fifo": (_sublayer(_usd_fifo), "walk.usda"),
    "usd_garbage": (lambda p: p.write_bytes(b"#usda 1.0\n(((( garbage"), "walk.usda"),
    "usd_empty": (lambda p: p.write_bytes(b""), "walk.usda"),
    "usd_binary_garbage": (lambda p: p.write_bytes(b"PXR-USDC" + b"\xff" * 64), "walk.usda"),
    "usd_nan_time_codes": (_replace_bytes(b"timeCodesPerSecond = ", b"timeCodesPerSecond = 1e300 #"), "walk"),
}


# -- files that are not files ---------------------------------------------------------------------


def _clip_fifo(root: Path) -> tuple[Path, str]:
    os.mkfifo(root / "clips" / "pipe.bvh")
    manifest = root / "manifest.yaml"
    manifest.write_text(GOOD + "  - path: clips/pipe.bvh\n", encoding="utf-8")
    return manifest, ":5:"


def _clip_dev_zero_link(root: Path) -> tuple[Path, str]:
    os.symlink("/dev/zero", root / "clips" / "zero.bvh")
    manifest = root / "manifest.yaml"
    manifest.write_text(GOOD + "  - path: clips/zero.bvh\n", encoding="utf-8")
    return manifest, ":5:"


def _manifest_fifo(root: Path) -> tuple[Path, str]:
    manifest = root / "fifo.yaml"
    os.mkfifo(manifest)
    return manifest, "fifo.yaml"


def _manifest_folder(root: Path) -> tuple[Path, str]:
    (root / "folder.yaml").mkdir()
    return root / "folder.yaml", "folder.yaml"


def _glob_symlink_loop(root: Path) -> tuple[Path, str]:
    os.symlink(".", root / "clips" / "a")
    os.symlink(".", root / "clips" / "b")
    os.symlink("..", root / "clips" / "up")
    (root / "clips" / "broken.usda").write_text("#usda 1.0\n(((\n", encoding="utf-8")
    manifest = root / "manifest.yaml"
    manifest.write_text(HEADER + "clips:\n  - path: clips/**/*.usda\n", encoding="utf-8")
    return manifest, "broken.usda"


def _glob_bvh_fifo_links(root: Path) -> tuple[Path, str]:
    os.symlink(".", root / "clips" / "a")
    os.symlink(".", root / "clips" / "b")
    os.mkfifo(root / "clips" / "pipe.bvh")
    manifest = root / "manifest.yaml"
    manifest.write_text(HEADER + "clips:\n  - path: clips/**/*.bvh\n", encoding="utf-8")
    return manifest, ":4:"


Case = Callable[[Path], tuple[Path, str]]
CASES: dict[str, Case] = {}
CASES.update({f"manifest-{k}": _manifest_case(*v) for k, v in MANIFEST_BODIES.items()})
CASES["manifest-not_utf8"] = _raw_manifest(GOOD.encode() + b"note: \xff\xfe\n", ":5:")
CASES["manifest-binary"] = _raw_manifest(b"\x00\x01\x02\xff" * 100, "manifest.yaml")
CASES["manifest-bom_then_garbage"] = _raw_manifest(b"\xef\xbb\xbf\xef\xbb\xbf[", "manifest.yaml")
CASES.update({f"bvh-{k}": _bvh_case(*v) for k, v in BVH_EDITS.items()})
CASES.update({f"gltf-{k}": _gltf_case(*v) for k, v in GLTF_EDITS.items()})
CASES.update({f"glb-{k}": _glb_case(v, "g.glb") for k, v in GLB_DATA.items()})
CASES.update({f"usd-{k}": _usd_case(*v) for k, v in USD_EDITS.items()})
CASES["file-manifest_folder"] = _manifest_folder
CASES["file-clip_dev_zero_symlink"] = _clip_dev_zero_link
# Cases that hung before: they run in a subprocess with a timeout, so a regression fails the test
# instead of hanging the suite.
SUBPROCESS_CASES: dict[str, Case] = {
    "file-clip_fifo": _clip_fifo,
    "file-manifest_fifo": _manifest_fifo,
    "gltf-uri_fifo_subprocess": _gltf_case(_uri(_fifo), "g.gltf"),
    "glob-symlink_loops": _glob_symlink_loop,
    "glob-bvh_fifo_and_loops": _glob_bvh_fifo_links,
}
ALL = {**CASES, **SUBPROCESS_CASES}


def _run(command: str, manifest: Path, name: str, capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    if name in SUBPROCESS_CASES:
        try:
            done = subprocess.run(
                [sys.executable, "-m", "blendspace_pipeline", command, str(manifest)],
                capture_output=True,
                text=True,
                timeout=120,
                check=False,
                env={**os.environ},
            )
        except subprocess.TimeoutExpired:
            pytest.fail(f"{name}: `blendspace {command}` hung")
        return done.returncode, done.stdout, done.stderr
    code = main([command, str(manifest)])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


@pytest.mark.parametrize("command", ["check", "build"])
@pytest.mark.parametrize("name", sorted(ALL))
def test_hostile_input_exits_2_with_location_hint_and_writes_nothing(
    name: str, command: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    root = _project(tmp_path)
    manifest, where = ALL[name](root)
    before = _snapshot(tmp_path)
    code, out, err = _run(command, manifest, name, capsys)
    assert code == 2, f"exit {code}\n{out}\n{err}"
    assert "Traceback" not in out + err
    first = err.splitlines()[0] if err else ""
    assert where in first, first
    assert "hint:" in err, err
    after = _snapshot(tmp_path)
    new = sorted(set(after) - set(before))
    assert not new, f"written: {new}"
    assert after == before  # the sources, byte for byte
    assert len(err.splitlines()) < 40  # a message, not a dump of library errors


WORKER_CASES = sorted(name for name in CASES if name.split("-")[0] in ("bvh", "gltf", "glb", "usd"))


@pytest.mark.parametrize("name", WORKER_CASES)
def test_a_hostile_clip_read_by_a_worker_exits_2_with_its_location(
    name: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The same clip files measured by `--jobs 2` workers (the default on a multi-core Linux
    machine): the error crosses a process boundary and must arrive as it does in one process."""
    root = _project(tmp_path)
    manifest, where = ALL[name](root)
    before = _snapshot(tmp_path)
    code = main(["check", str(manifest), "--jobs", "2"])
    out, err = capsys.readouterr()
    assert code == 2, f"exit {code}\n{out}\n{err}"
    assert "Traceback" not in out + err and "internal error" not in err
    assert where in (err.splitlines()[0] if err else ""), err
    assert "hint:" in err, err
    assert _snapshot(tmp_path) == before


def test_the_corpus_is_large() -> None:
    # Kept honest: the 132 hand-made inputs, each tried with check and build.
    assert len(ALL) >= 130, len(ALL)


def test_a_gltf_buffer_elsewhere_in_the_project_is_read(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """References are confined to the project, not to the clip's own folder: a studio layout with
    buffers in a sibling folder (`../buffers/walk.bin`) reads; one that leaves the project does not."""
    root = tmp_path / "project"
    (root / "clips").mkdir(parents=True)
    (root / "buffers").mkdir()
    document = _gltf(root)
    buffer = document["buffers"][0]  # type: ignore[index]
    if str(buffer.get("uri", "")).startswith("data:"):
        import base64

        data = base64.b64decode(buffer["uri"].split(",", 1)[1])
    else:
        data = (root / "clips" / buffer["uri"]).read_bytes()
    (root / "buffers" / "walk.bin").write_bytes(data)
    buffer["uri"] = "../buffers/walk.bin"
    (root / "clips" / "g.gltf").write_text(json.dumps(document), encoding="utf-8")
    manifest = root / "manifest.yaml"
    manifest.write_text(HEADER + "clips:\n  - path: clips/g.gltf\n", encoding="utf-8")
    assert main(["check", str(manifest)]) in (0, 1)
    assert "outside the project" not in capsys.readouterr().err
    # The same layout with the manifest inside clips/: the buffer now lies outside its project.
    inner = root / "clips" / "manifest.yaml"
    inner.write_text(HEADER + "clips:\n  - path: g.gltf\n", encoding="utf-8")
    assert main(["check", str(inner)]) == 2
    assert "outside the project" in capsys.readouterr().err
