"""FBX in through ufbx (`pufbx`, the optional `fbx` extra): what happens without the extra, on a
broken file, and how GlobalSettings (units, up axis, handedness, frame rate) are read. Files
written by a real DCC are read in tests/test_blender.py (Blender writes them)."""

from __future__ import annotations

import struct
import sys
from pathlib import Path

import pytest

from blendspace_pipeline.cli import main
from blendspace_pipeline.errors import ClipReadError
from blendspace_pipeline.readers import read_clips
from blendspace_pipeline.readers.fbx import read_settings


def _binary_fbx(settings: dict[str, tuple[str, float]], version: int = 7400) -> bytes:
    """A minimal binary FBX: header, GlobalSettings > Properties70 > P records, null record."""
    wide = version >= 7500
    null = b"\0" * (25 if wide else 13)

    def record(name: str, properties: bytes, count: int, children: bytes, start: int) -> bytes:
        header_size = (24 if wide else 12) + 1 + len(name)
        nested = children + null if children else b""
        end = start + header_size + len(properties) + len(nested)
        fmt = "<QQQ" if wide else "<III"
        return (
            struct.pack(fmt, end, count, len(properties))
            + bytes([len(name)])
            + name.encode()
            + properties
            + nested
        )

    def string(text: str) -> bytes:
        return b"S" + struct.pack("<I", len(text)) + text.encode()

    def p_record(name: str, kind: str, value: float, start: int) -> bytes:
        number = b"I" + struct.pack("<i", int(value)) if kind == "int" else b"D" + struct.pack("<d", value)
        properties = string(name) + string(kind) + string("") + string("") + number
        return record("P", properties, 5, b"", start)

    header = b"Kaydara FBX Binary  \x00\x1a\x00" + struct.pack("<I", version)
    # Offsets are absolute: build inside out with the positions each record will have.
    base = len(header)
    top_header = (24 if wide else 12) + 1 + len("GlobalSettings")
    p70_start = base + top_header
    p70_header = (24 if wide else 12) + 1 + len("Properties70")
    cursor = p70_start + p70_header
    entries = b""
    for name, (kind, value) in settings.items():
        entry = p_record(name, kind, value, cursor)
        entries += entry
        cursor += len(entry)
    p70 = record("Properties70", b"", 0, entries, p70_start)
    top = record("GlobalSettings", b"", 0, p70, base)
    return header + top + null


MAYA_CM = {"UpAxis": ("int", 1), "UpAxisSign": ("int", 1), "FrontAxis": ("int", 2), "FrontAxisSign": ("int", 1),
           "CoordAxis": ("int", 0), "CoordAxisSign": ("int", 1), "UnitScaleFactor": ("double", 1.0),
           "TimeMode": ("int", 6)}  # fmt: skip


@pytest.mark.parametrize("version", [7400, 7500])
def test_global_settings_give_units_up_axis_and_frame_rate(tmp_path: Path, version: int) -> None:
    path = tmp_path / "a.fbx"
    path.write_bytes(_binary_fbx(MAYA_CM, version))
    settings = read_settings(path)
    assert (settings.meters_per_unit, settings.up_axis, settings.fps) == (0.01, "y", 30.0)
    # 3ds Max: Z up, front -Y, inches (2.54 cm per unit), custom 25 fps.
    max_inches = {**MAYA_CM, "UpAxis": ("int", 2), "FrontAxis": ("int", 1), "FrontAxisSign": ("int", -1),
                  "UnitScaleFactor": ("double", 2.54), "TimeMode": ("int", 14), "CustomFrameRate": ("double", 25.0)}  # fmt: skip
    path.write_bytes(_binary_fbx(max_inches, version))
    settings = read_settings(path)
    assert (settings.meters_per_unit, settings.up_axis, settings.fps) == (pytest.approx(0.0254), "z", 25.0)


def test_left_handed_and_unsupported_up_axes_are_refused(tmp_path: Path) -> None:
    path = tmp_path / "a.fbx"
    path.write_bytes(_binary_fbx({**MAYA_CM, "FrontAxisSign": ("int", -1)}))
    with pytest.raises(ClipReadError, match="left-handed"):
        read_settings(path)
    path.write_bytes(_binary_fbx({**MAYA_CM, "UpAxis": ("int", 0)}))
    with pytest.raises(ClipReadError, match=r"up axis \+X is not supported"):
        read_settings(path)


def test_ascii_fbx_settings(tmp_path: Path) -> None:
    path = tmp_path / "a.fbx"
    path.write_text(
        "; FBX 7.4.0 project file\nGlobalSettings:  {\n\tVersion: 1000\n\tProperties70:  {\n"
        '\t\tP: "UpAxis", "int", "Integer", "",2\n\t\tP: "FrontAxis", "int", "Integer", "",1\n'
        '\t\tP: "FrontAxisSign", "int", "Integer", "",-1\n\t\tP: "UnitScaleFactor", "double", "Number", "",100\n'
        '\t\tP: "TimeMode", "enum", "", "",3\n\t}\n}\n',
        encoding="utf-8",
    )
    settings = read_settings(path)
    assert (settings.meters_per_unit, settings.up_axis, settings.fps) == (1.0, "z", 60.0)


def test_without_the_extra_the_error_says_how_to_install_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "walk.fbx"
    path.write_bytes(_binary_fbx(MAYA_CM))
    monkeypatch.setitem(sys.modules, "pufbx", None)  # as if not installed: import raises ImportError
    with pytest.raises(ClipReadError) as caught:
        read_clips(path)
    assert caught.value.message == "reading FBX needs the optional pufbx package"
    assert caught.value.hint is not None and "pip install 'blendspace-pipeline[fbx]'" in caught.value.hint
    manifest = tmp_path / "m.yaml"
    manifest.write_text("schema_version: 1\nname: t\nclips:\n  - path: walk.fbx\n", encoding="utf-8")
    assert main(["check", str(manifest)]) == 2
    err = capsys.readouterr().err
    assert "pufbx" in err and "[fbx]" in err and "Traceback" not in err


def test_a_broken_fbx_is_an_input_error(tmp_path: Path) -> None:
    pytest.importorskip("pufbx")
    path = tmp_path / "broken.fbx"
    path.write_bytes(_binary_fbx(MAYA_CM)[:40])
    with pytest.raises(ClipReadError):
        read_clips(path)
    path.write_bytes(_binary_fbx(MAYA_CM))  # settings but no objects: no skeleton
    with pytest.raises(ClipReadError):
        read_clips(path)
