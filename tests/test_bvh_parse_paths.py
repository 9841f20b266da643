"""The BVH reader's three MOTION parsers agree: pyarrow's CSV reader (the fast path), numpy's
``fromstring`` and the line-by-line walk give the same values to the bit and the same
``path:line`` errors, on real CMU takes and on the whitespace and number spellings real exporters
write (tabs, CRLF, trailing spaces, runs of spaces, exponents, wrapped frames) or break."""

from __future__ import annotations

import os
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from conftest import shared_data
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from blendspace_pipeline import native
from blendspace_pipeline.errors import ClipReadError
from blendspace_pipeline.motion import quaternions as quat
from blendspace_pipeline.motion.clip import Clip, forward_kinematics
from blendspace_pipeline.motion.procedural import GaitSpec, generate
from blendspace_pipeline.readers import bvh
from blendspace_pipeline.readers.limits import read_regular_file
from blendspace_pipeline.readers.provenance import BVH_PREFIX, strip_bvh_provenance
from blendspace_pipeline.writers.bvh import write_bvh_clip

HEADER = """HIERARCHY
ROOT Hips
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT Spine
  {
    OFFSET 0 1 0
    CHANNELS 3 Zrotation Yrotation Xrotation
    End Site
    {
      OFFSET 0 1 0
    }
  }
}
MOTION
Frames: {frames}
Frame Time: 0.0333333
"""
CHANNELS = 9
HEADER_LINES = HEADER.count("\n")  # frame lines start on line HEADER_LINES + 1


class Paths:
    """Which parser produced the values of each read (the fast paths must really be taken)."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch) -> None:
        self.monkeypatch = monkeypatch
        self.arrow_results: list[bool] = []
        self.native_results: list[bool] = []
        real, real_native = bvh._motion_arrow, bvh._motion_native

        def spy(*args: object, **kwargs: object) -> object:
            result = real(*args, **kwargs)  # type: ignore[arg-type]
            self.arrow_results.append(result is not None)
            return result

        def spy_native(*args: object, **kwargs: object) -> object:
            result = real_native(*args, **kwargs)  # type: ignore[arg-type]
            if native.kernels is not None:  # only the reads that try the kernel
                self.native_results.append(result is not None)
            return result

        monkeypatch.setattr(bvh, "_motion_arrow", spy)
        monkeypatch.setattr(bvh, "_motion_native", spy_native)

    def read(self, path: Path, parser: str) -> Clip:
        """``parser``: "native" (the compiled kernel first, then pyarrow: as a build reads),
        "arrow" (no kernel, pyarrow first), "numpy" (neither)."""
        if parser == "native":
            assert native.kernels is not None, "the compiled kernels were not built (setup.py)"
        with self.monkeypatch.context() as patch:
            if parser != "native":
                patch.setattr(native, "kernels", None)
            if parser in ("native", "arrow"):  # also on the small files here (a build uses numpy below 32 KB)
                patch.setattr(bvh, "ARROW_AFTER_BYTES", -1)
                patch.setattr(bvh, "ARROW_MIN_BLOCK", 0)
            else:
                patch.setitem(sys.modules, "pyarrow.csv", None)  # `import pyarrow.csv` fails
            return bvh.read(path)[0]


@pytest.fixture
def paths(monkeypatch: pytest.MonkeyPatch) -> Paths:
    return Paths(monkeypatch)


def _slow_values(path: Path) -> np.ndarray:
    """The line-by-line walk alone: (frames, channels)."""
    text = bvh._without_provenance(bvh.bvh_text(path))
    header, head_end = bvh._split_header(text, path)
    start = text.count("\n", 0, head_end) + 1
    return bvh._motion_slow(text[head_end:].split("\n"), start, header, path)


def _same_bits(a: Clip, b: Clip) -> None:
    assert a.rotations.tobytes() == b.rotations.tobytes()
    assert a.translations.tobytes() == b.translations.tobytes()
    assert (a.fps, a.skeleton.names, a.skeleton.parents) == (b.fps, b.skeleton.names, b.skeleton.parents)


def _error(read: object) -> tuple[int | None, str]:
    with pytest.raises(ClipReadError) as caught:
        read()  # type: ignore[operator]
    return caught.value.line, caught.value.message


def _values(frames: int, seed: int = 3) -> np.ndarray:
    rng = np.random.default_rng(seed)
    values = rng.uniform(-180.0, 180.0, (frames, CHANNELS))
    values[:, 1] = rng.uniform(80.0, 100.0, frames)  # a hip height
    values[:, 7] = 12.5  # a channel that never moves
    return values


def _file(tmp_path: Path, rows: list[str], name: str = "t.bvh", newline: str = "\n", frames: int = 0) -> Path:
    text = HEADER.replace("{frames}", str(frames or len(rows))) + "".join(row + "\n" for row in rows)
    path = tmp_path / name
    path.write_bytes(text.replace("\n", newline).encode())
    return path


def _spell(value: float, spell: str) -> str:
    return repr(float(value)) if spell == "repr" else format(float(value), spell)


def _format(values: np.ndarray, spell: str, sep: str = " ", trailing: str = "") -> list[str]:
    return [sep.join(_spell(v, spell) for v in row) + trailing for row in values]


def _written(values: np.ndarray, spell: str) -> np.ndarray:
    """What `float` reads back from the text written with ``spell``."""
    return np.array([[float(_spell(v, spell)) for v in row] for row in values])


# Spellings exporters write; each must give the values `float` gives, on every parser.
VARIANTS = {
    "single spaces": dict(spell=".6f"),
    "full precision": dict(spell="repr"),
    "exponents": dict(spell=".9e"),
    "upper-case exponents": dict(spell=".17E"),
    "general": dict(spell=".8g"),
    "trailing space (CMU)": dict(spell=".4f", trailing=" "),
    "tabs": dict(spell=".6f", sep="\t"),
    "tabs and a trailing tab": dict(spell=".6f", sep="\t", trailing="\t"),
    "CRLF": dict(spell=".6f", newline="\r\n"),
    "CRLF and a trailing space": dict(spell=".6f", trailing=" ", newline="\r\n"),
    "runs of spaces": dict(spell=".6f", sep="   "),
    "leading spaces": dict(spell=".6f", lead="  "),
    "blank lines between frames": dict(spell=".6f", blank=True),  # pyarrow skips them too
    "trailing blank lines": dict(spell=".6f", tail="\n\n  \n"),
    "wrapped frames": dict(spell=".6f", wrap=True),
}


def _variant(tmp_path: Path, values: np.ndarray, variant: dict[str, object], name: str = "t.bvh") -> Path:
    spell = str(variant["spell"])
    rows = _format(values, spell, str(variant.get("sep", " ")), str(variant.get("trailing", "")))
    rows = [str(variant.get("lead", "")) + row for row in rows]
    if variant.get("wrap"):  # some exporters break long frames over two lines
        rows = [part for row in rows for part in (row.split(" ", 4)[:4], row.split(" ", 4)[4:])]
        rows = [" ".join(part) for part in rows]
    if variant.get("blank"):
        rows = [line for row in rows for line in (row, "")]
    path = _file(tmp_path, rows, name, str(variant.get("newline", "\n")), frames=len(values))
    tail = str(variant.get("tail", ""))
    if tail:
        path.write_bytes(path.read_bytes() + tail.encode())
    return path


@pytest.mark.parametrize("variant", list(VARIANTS), ids=list(VARIANTS))
def test_spellings_give_the_same_values_on_every_parser(tmp_path: Path, paths: Paths, variant: str) -> None:
    values = _values(40)
    spec = VARIANTS[variant]
    path = _variant(tmp_path, values, spec)
    arrow, numpy = paths.read(path, "arrow"), paths.read(path, "numpy")
    _same_bits(arrow, numpy)
    _same_bits(paths.read(path, "native"), numpy)
    written = _written(values, str(spec["spell"]))
    assert arrow.translations[:, 0].tobytes() == np.ascontiguousarray(written[:, :3]).tobytes()
    if not spec.get("wrap"):  # the walk reads one frame per line: wrapped frames are numpy's alone
        assert _slow_values(path).tobytes() == written.tobytes()
    # The fast path takes every file whose lines are alike; the others fall back, same answer.
    regular = not any(spec.get(key) for key in ("lead", "wrap")) and spec.get("sep", " ") in (
        " ",
        "\t",
    )
    # The kernel takes any whitespace; it declines 17-digit significands (to pyarrow, same values).
    assert paths.arrow_results == [regular] + (
        [] if spec["spell"] in (".6f", ".4f", ".9e", ".8g") else [regular]
    )
    assert paths.native_results == [spec["spell"] in (".6f", ".4f", ".9e", ".8g")]


@pytest.mark.parametrize(
    ("variant", "breakage", "line", "words"),
    [
        ("single spaces", "short", 3, "frame 3 has 8 values"),
        ("single spaces", "long", 3, "frame 3 has 10 values"),
        ("trailing space (CMU)", "short", 3, "frame 3 has 8 values"),
        ("trailing space (CMU)", "long", 3, "frame 3 has 10 values"),
        ("tabs", "long", 3, "frame 3 has 10 values"),
        ("CRLF", "short", 3, "frame 3 has 8 values"),
        ("single spaces", "nan", 3, "'nan' is not a finite number"),
        ("single spaces", "NaN", 3, "'NaN' is not a finite number"),
        ("single spaces", "inf", 3, "'inf' is not a finite number"),
        ("single spaces", "1e999", 3, "'1e999' is not a finite number"),
        ("single spaces", "word", 3, "'x1' is not a number"),
        ("single spaces", "NA", 3, "'NA' is not a number"),
        ("single spaces", "empty field", 3, "frame 3 has 8 values"),
        ("single spaces", "missing frame", 5, "says 6 but the file has 5"),
        ("single spaces", "extra frame", 5, "says 4 but the file has 5 frame lines"),
        ("single spaces", "huge angle", 3, "rotation 1e+07 is out of range"),
    ],
)
def test_broken_rows_give_the_same_path_line_error(
    tmp_path: Path, paths: Paths, variant: str, breakage: str, line: int, words: str
) -> None:
    values = _values(5)
    spec = VARIANTS[variant]
    rows = _format(values, str(spec["spell"]), str(spec.get("sep", " ")), str(spec.get("trailing", "")))
    sep = str(spec.get("sep", " "))
    fields = rows[2].rstrip().split(sep)
    frames = 5
    if breakage == "short":
        rows[2] = sep.join(fields[:-1]) + str(spec.get("trailing", ""))
    elif breakage == "long":
        rows[2] = sep.join([*fields, "1.5"]) + str(spec.get("trailing", ""))
    elif breakage == "empty field":  # a value missing between two spaces
        rows[2] = sep.join(fields[:4]) + sep + sep + sep.join(fields[5:])
    elif breakage == "missing frame":
        frames = 6
    elif breakage == "extra frame":
        frames = 4
    elif breakage == "huge angle":
        rows[2] = sep.join([*fields[:4], "1e7", *fields[5:]])
    else:
        token = {"word": "x1"}.get(breakage, breakage)
        rows[2] = sep.join([*fields[:4], token, *fields[5:]])
    path = _file(tmp_path, rows, newline=str(spec.get("newline", "\n")), frames=frames)
    with_arrow = _error(lambda: paths.read(path, "arrow"))
    assert with_arrow == _error(lambda: paths.read(path, "numpy"))
    assert with_arrow == _error(lambda: paths.read(path, "native"))
    assert with_arrow[0] == HEADER_LINES + line, with_arrow
    assert words in with_arrow[1]


def test_real_cmu_takes_identical_on_every_parser(paths: Paths) -> None:
    for name in ("131_01.bvh", "131_02.bvh"):
        path = shared_data("cmu", name)
        _same_bits(paths.read(path, "arrow"), paths.read(path, "numpy"))
        _same_bits(paths.read(path, "native"), paths.read(path, "numpy"))
    assert paths.arrow_results == [True, True]  # the fast paths read real mocap takes
    assert paths.native_results == [True, True]


def test_generated_clip_with_provenance_identical_on_every_parser(tmp_path: Path, paths: Paths) -> None:
    clip = generate(GaitSpec("walk", speed=1.4, duration=1.0, fps=60.0))
    path = tmp_path / "walk.bvh"
    write_bvh_clip(clip, path)
    with path.open("a") as stream:
        stream.write(BVH_PREFIX + '{"rule":"r","sources":["a"],"tool":"t","version":"1"}\n')
    arrow = paths.read(path, "arrow")
    assert paths.arrow_results == [True]
    _same_bits(arrow, paths.read(path, "numpy"))
    assert arrow.frame_count == clip.frame_count


def _euler_before(angles_deg: np.ndarray, order: str) -> np.ndarray:
    """`euler_quaternions` as it was before the still-channel and closed-form shortcuts."""
    half = np.radians(angles_deg) * 0.5
    sines, cosines = np.sin(half), np.cos(half)
    q = np.zeros((4, *half.shape[1:]))
    q["XYZ".index(order[0])], q[3] = sines[0], cosines[0]
    for row in range(1, len(order)):
        k = "XYZ".index(order[row])
        i, j = (k + 1) % 3, (k + 2) % 3
        s, c = sines[row], cosines[row]
        step = np.empty_like(q)
        step[k] = c * q[k] + s * q[3]
        step[i] = c * q[i] + s * q[j]
        step[j] = c * q[j] - s * q[i]
        step[3] = c * q[3] - s * q[k]
        q = step
    return q


@pytest.mark.parametrize("order", ["ZXY", "ZYX", "XYZ", "YXZ", "XZY", "YZX", "ZX", "Y", "ZZX"])
def test_euler_conversion_matches_the_plain_formula(order: str) -> None:
    rng = np.random.default_rng(len(order))
    angles = rng.uniform(-720.0, 720.0, (len(order), 5, 50))
    angles[:, 1] = 30.0  # a joint that never moves
    angles[0, 2] = -200.0  # one still letter of a moving joint
    angles[:, 3, 7] = 0.0
    fast = bvh.euler_quaternions(angles, order)
    assert np.array_equal(fast, _euler_before(angles, order))
    # The general product (another operation order) agrees to rounding.
    general = quat.from_euler(np.moveaxis(angles, 0, -1), order)
    assert np.max(np.abs(np.moveaxis(fast, 0, -1) - general)) < 1e-12


FLOATS = st.floats(min_value=-1e4, max_value=1e4, allow_nan=False, allow_infinity=False)
SPELLINGS = st.sampled_from(["repr", ".6f", ".3f", ".10e", ".15g", ".4E", ".0f"])


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    values=st.lists(st.lists(FLOATS, min_size=CHANNELS, max_size=CHANNELS), min_size=1, max_size=6),
    spell=SPELLINGS,
    sep=st.sampled_from([" ", "\t", "  "]),
    trailing=st.sampled_from(["", " ", "\t"]),
    newline=st.sampled_from(["\n", "\r\n"]),
    corrupt=st.sampled_from([None, "drop", "add", "nan", "wrap"]),
    where=st.integers(min_value=0, max_value=5),
)
def test_property_fast_path_equals_numpy_path(
    tmp_path_factory: pytest.TempPathFactory,
    values: list[list[float]],
    spell: str,
    sep: str,
    trailing: str,
    newline: str,
    corrupt: str | None,
    where: int,
) -> None:
    """Any spelling, separator and line end, intact or with one row broken: the fast path gives
    what the numpy path (the reader before it) gives, values to the bit or the same error."""
    rows = _format(np.array(values), spell, sep, trailing)
    row = where % len(rows)
    fields = rows[row].rstrip(" \t").split(sep)
    if corrupt == "drop":
        rows[row] = sep.join(fields[:-1]) + trailing
    elif corrupt == "add":
        rows[row] = sep.join([*fields, "7"]) + trailing
    elif corrupt == "nan":
        rows[row] = sep.join(["nan", *fields[1:]]) + trailing
    elif corrupt == "wrap":  # one frame broken over two lines
        rows[row : row + 1] = [sep.join(fields[:3]), sep.join(fields[3:]) + trailing]
    path = _file(tmp_path_factory.mktemp("prop"), rows, newline=newline, frames=len(values))
    with pytest.MonkeyPatch.context() as monkeypatch:
        paths = Paths(monkeypatch)
        try:
            numpy = paths.read(path, "numpy")
        except ClipReadError as error:
            assert _error(lambda: paths.read(path, "arrow")) == (error.line, error.message)
            assert _error(lambda: paths.read(path, "native")) == (error.line, error.message)
            return
        arrow = paths.read(path, "arrow")
        _same_bits(paths.read(path, "native"), numpy)
    _same_bits(arrow, numpy)
    written = _written(np.array(values), spell)
    assert arrow.translations[:, 0].tobytes() == np.ascontiguousarray(written[:, :3]).tobytes()


@settings(max_examples=300, deadline=None)
@given(
    st.lists(
        st.sampled_from(["\n", "\r\n", " ", "\t", "\x1c", "\x0b", "x", "1 2", BVH_PREFIX, "{}", "#"]),
        max_size=12,
    )
)
def test_provenance_is_stripped_from_the_last_line_exactly_as_before(parts: list[str]) -> None:
    text = "".join(parts)
    assert bvh._without_provenance(text) == strip_bvh_provenance(text)
    assert bvh._content_end(text.encode()) == len(strip_bvh_provenance(text))


@settings(max_examples=300, deadline=None)
@given(
    st.lists(
        st.sampled_from(
            [
                "MOTION",
                "motion",
                "Frames: 2",
                "frames :x",
                "Frame Time: 0.1",
                "FRAME  TIME:",
                "\n",
                "\r",
                " ",
                "\t",
                "1",
            ]
        ),
        max_size=14,
    )
)
def test_header_end_in_bytes_is_where_it_is_in_the_text(parts: list[str]) -> None:
    text = "".join(parts)
    for end in (len(text), len(text) // 2):
        in_text = bvh._head_end(text[:end], end, bvh._MOTION, bvh._FRAME_TIME, bvh._FRAMES)
        in_bytes = bvh._head_end(
            text.encode(), end, bvh._MOTION_BYTES, bvh._FRAME_TIME_BYTES, bvh._FRAMES_BYTES
        )
        assert in_text == in_bytes


def test_non_ascii_names_take_the_text_path_with_the_same_values(tmp_path: Path, paths: Paths) -> None:
    values = _values(12)
    plain = _file(tmp_path, _format(values, ".6f"), "plain.bvh")
    named = tmp_path / "named.bvh"
    named.write_bytes(plain.read_bytes().replace(b"JOINT Spine", "JOINT Rücken".encode()))
    a, b = paths.read(plain, "arrow"), paths.read(named, "arrow")
    assert b.skeleton.names == ("Hips", "Rücken")
    assert paths.arrow_results == [True, True]
    assert a.rotations.tobytes() == b.rotations.tobytes()


def test_pyarrow_is_imported_only_once_a_process_reads_a_library(tmp_path: Path) -> None:
    """Without the compiled kernel, `import blendspace_pipeline.api` and reading one small clip
    stay without pyarrow's import (~70 ms); once more than `ARROW_AFTER_BYTES` went through numpy,
    pyarrow takes over. With it, pyarrow is not imported at all."""
    small = _file(tmp_path, _format(_values(10), ".6f"), "small.bvh")
    large = _file(tmp_path, _format(_values(bvh.ARROW_AFTER_BYTES // 90 + 10, seed=5), ".6f"), "large.bvh")
    assert large.stat().st_size > bvh.ARROW_AFTER_BYTES
    code = (
        "import sys, blendspace_pipeline.api\n"
        "from pathlib import Path\n"
        "assert 'pyarrow' not in sys.modules, 'api'\n"
        "from blendspace_pipeline.readers.bvh import read\n"
        f"assert read(Path({str(small)!r}))[0].frame_count == 10\n"
        "assert 'pyarrow' not in sys.modules, 'one small clip'\n"
        f"read(Path({str(large)!r}))\n"
        f"assert read(Path({str(small)!r}))[0].frame_count == 10\n"
        "assert 'pyarrow.csv' in sys.modules, 'a library'\n"
    )
    without_kernels = {**os.environ, native.NO_KERNELS_VARIABLE: "1"}
    subprocess.run([sys.executable, "-c", code], check=True, timeout=120, env=without_kernels)
    # With the compiled kernel, plain takes never need pyarrow.
    kernel_code = code.replace("'pyarrow.csv' in sys.modules", "'pyarrow' not in sys.modules")
    subprocess.run([sys.executable, "-c", kernel_code], check=True, timeout=120)


def test_read_regular_file_reads_all_and_keeps_its_limit(tmp_path: Path) -> None:
    path = tmp_path / "data.bin"
    path.write_bytes(bytes(range(256)) * 1000)
    assert read_regular_file(path) == path.read_bytes()
    empty = tmp_path / "empty.bin"
    empty.write_bytes(b"")
    assert read_regular_file(empty) == b""
    with pytest.raises(ClipReadError, match="more than the limit"):
        read_regular_file(path, limit=1000)


def _fk_before(clip: Clip) -> tuple[np.ndarray, np.ndarray]:
    """Forward kinematics as it was: `quaternions.multiply` and `rotate` joint by joint."""
    skeleton = clip.skeleton
    world_rot, world_pos = np.empty_like(clip.rotations), np.empty_like(clip.translations)
    for joint, parent in enumerate(skeleton.parents):
        if parent < 0 or not skeleton.has_hierarchy:
            world_rot[:, joint], world_pos[:, joint] = clip.rotations[:, joint], clip.translations[:, joint]
            continue
        world_rot[:, joint] = quat.multiply(world_rot[:, parent], clip.rotations[:, joint])
        world_pos[:, joint] = world_pos[:, parent] + quat.rotate(
            world_rot[:, parent], clip.translations[:, joint]
        )
    return world_rot, world_pos


def test_forward_kinematics_is_the_joint_by_joint_composition_to_the_bit(tmp_path: Path) -> None:
    clips = [bvh.read(shared_data("cmu", "131_01.bvh"))[0]]
    clips.append(generate(GaitSpec("turn", speed=1.1, turn_rate=40.0, duration=0.5, fps=30.0)))
    two_roots = _file(tmp_path, _format(_values(6), ".6f"))
    two_roots.write_bytes(
        two_roots.read_bytes()
        .replace(b"JOINT Spine", b"}\nROOT Spine", 1)
        .replace(b"}\n}\nMOTION", b"}\nMOTION")
    )
    clips.append(bvh.read(two_roots)[0])
    assert clips[-1].skeleton.parents == (-1, -1)
    flat = clips[0]
    clips.append(
        Clip(
            flat.name,
            flat.source,
            replace(flat.skeleton, has_hierarchy=False),
            flat.rotations,
            flat.translations,
            flat.fps,
        )
    )
    for clip in clips:
        fast, before = forward_kinematics(clip), _fk_before(clip)
        assert fast[0].tobytes() == before[0].tobytes()
        assert fast[1].tobytes() == before[1].tobytes()
