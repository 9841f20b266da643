"""The compiled kernels (`blendspace_pipeline/_kernels.c`): built where CI runs, numpy's values to
the bit, and declining (False) every input they cannot vouch for.

The readers and forward kinematics compare kernel and numpy paths on real and generated clips in
`test_bvh_parse_paths.py` and `test_forward_kinematics_levels.py`; here the kernels are driven
directly, with the spellings and sizes a file can hold."""

from __future__ import annotations

import os
import platform
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from blendspace_pipeline import native

kernels = native.kernels
needs_kernels = pytest.mark.skipif(kernels is None, reason="the compiled kernels were not built")


def test_built_where_ci_runs() -> None:
    """CPython on Linux with a compiler (CI, every developer machine here) builds them: a silent
    fallback would lose the speed without a word."""
    if sys.platform.startswith("linux") and platform.python_implementation() == "CPython":
        assert kernels is not None, "pip install -e . did not build blendspace_pipeline._kernels (setup.py)"


def test_the_variable_turns_them_off() -> None:
    code = "from blendspace_pipeline import native; assert native.kernels is None"
    env = {**os.environ, native.NO_KERNELS_VARIABLE: "1"}
    subprocess.run([sys.executable, "-c", code], check=True, env=env, timeout=60)


def _parse(text: str, frames: int, channels: int) -> np.ndarray | None:
    assert kernels is not None
    out = np.full((channels, frames), np.nan)
    return out if kernels.parse_decimals(text.encode(), out, frames, channels) else None


def _expected(tokens: list[str], frames: int, channels: int) -> np.ndarray:
    return np.array([float(t) for t in tokens]).reshape(frames, channels).T.copy()


@needs_kernels
@pytest.mark.parametrize(
    "token",
    [
        "0",
        "-0",
        "-0.000",
        "1.",
        ".5",
        "-.5",
        "007.50",
        "1e5",
        "1E+5",
        "2.5e-3",
        "9007199254740992",
        "0.000000000000000000001",
        "0e999",
        "123456789012345e-22",
        "-1.234567890123456",
    ],
)
def test_plain_spellings_are_taken_exactly(token: str) -> None:
    parsed = _parse(f"{token} 1\n", 1, 2)
    assert parsed is not None, token
    assert parsed[0, 0].tobytes() == np.float64(float(token)).tobytes()  # -0.0 keeps its sign


@needs_kernels
@pytest.mark.parametrize(
    "token",
    [
        "+1",
        "1_0",
        "nan",
        "NaN",
        "inf",
        "-inf",
        "0x10",
        "1,5",
        "1.2.3",
        "--1",
        "1e",
        "1e+",
        ".",
        "-",
        "e5",
        "9007199254740993",
        "12345678901234567890",
        "1e23",
        "1e-23",
        "1.5x",
        "١",
        "1e99999",
    ],
)
def test_anything_else_is_declined(token: str) -> None:
    """Another spelling, a significand past 2^53 or a power of ten past 22: the caller's parsers
    decide (and name the line when it is wrong)."""
    assert _parse(f"1 {token}\n", 1, 2) is None


@needs_kernels
def test_counts_and_buffers_must_match() -> None:
    assert _parse("1 2\n3 4\n", 2, 2) is not None
    assert _parse("1 2\n3 4\n5\n", 2, 2) is None  # one value too many
    assert _parse("1 2\n3\n", 2, 2) is None  # one too few
    assert _parse("", 1, 1) is None
    assert kernels is not None
    assert not kernels.parse_decimals(b"1 2", np.empty(3), 1, 2)  # wrong output size
    for wrong in (np.empty((4, 2))[:, 0], b"\0" * 16):  # not contiguous, read-only
        with pytest.raises((TypeError, BufferError)):
            kernels.parse_decimals(b"1 2", wrong, 1, 2)


SPELL = st.sampled_from([".0f", ".3f", ".6f", ".9f", ".3e", ".8E", ".12g", ".15g", "repr"])
VALUES = st.floats(min_value=-1e9, max_value=1e9, allow_nan=False, allow_infinity=False)
GAP = st.sampled_from([" ", "  ", "\t", " \t", "\r\n", "\n", "\n\n", " \n"])


@needs_kernels
@settings(max_examples=300, deadline=None)
@given(
    rows=st.integers(min_value=1, max_value=6),
    channels=st.integers(min_value=1, max_value=7),
    data=st.data(),
)
def test_property_same_bits_as_float(rows: int, channels: int, data: st.DataObject) -> None:
    """Any values in any spelling and whitespace: the kernel takes exactly the numbers the fast
    path converts exactly (every value exporters write with up to 15 digits), and gives `float`'s
    values to the bit."""
    tokens = []
    for _ in range(rows * channels):
        value, spell = data.draw(VALUES), data.draw(SPELL)
        tokens.append(repr(value) if spell == "repr" else format(value, spell))
    text = data.draw(st.sampled_from(["", " ", "\n"]))
    for token in tokens:
        text += token + data.draw(GAP)
    parsed = _parse(text, rows, channels)
    assert (parsed is not None) == all(_exact_on_the_fast_path(t) for t in tokens), text
    if parsed is not None:
        assert parsed.tobytes() == _expected(tokens, rows, channels).tobytes()


def _exact_on_the_fast_path(token: str) -> bool:
    """Whether Clinger's fast path converts ``token`` exactly: a significand of at most 2^53
    (and 19 digits) times 10^k, |k| <= 22, or a zero."""
    mantissa, _, exponent = token.lower().partition("e")
    whole, _, fraction = mantissa.lstrip("-").partition(".")
    significand = (whole + fraction).lstrip("0")
    scale = int(exponent or 0) - len(fraction)
    if not significand:
        return True
    return len(significand) <= 19 and int(significand) <= 2**53 and -22 <= scale <= 22


@needs_kernels
def test_forward_kinematics_declines_what_it_cannot_compute() -> None:
    assert kernels is not None
    frames, joints = 3, 2
    rot, pos = np.zeros((frames, joints, 4)), np.zeros((frames, joints, 3))
    rot[..., 3] = 1.0
    out_rot, out_pos = np.empty_like(rot), np.empty_like(pos)
    assert kernels.forward_kinematics(rot, pos, np.array([-1, 0]), out_rot, out_pos, frames)
    assert np.array_equal(out_rot, rot)
    child_first = np.array([1, -1])
    assert not kernels.forward_kinematics(rot, pos, child_first, out_rot, out_pos, frames)
    assert not kernels.forward_kinematics(rot, pos, np.array([-1, 0, 0]), out_rot, out_pos, frames)
    assert not kernels.forward_kinematics(rot, pos, np.array([-1, 0]), out_rot, out_pos, 2)
    assert not kernels.forward_kinematics(rot, pos[:2], np.array([-1, 0]), out_rot, out_pos, frames)
    assert not kernels.forward_kinematics(rot, pos, np.array([-1, -2]), out_rot, out_pos, frames)


def _numpy_slerp(a: np.ndarray, b: np.ndarray, t: object, monkeypatch: pytest.MonkeyPatch) -> np.ndarray:
    from blendspace_pipeline.motion import quaternions

    with monkeypatch.context() as patched:
        patched.setattr(native, "kernels", None)
        return quaternions.slerp(a, b, t)  # type: ignore[arg-type]


def _bits(values: np.ndarray) -> bytes:
    return np.ascontiguousarray(values, dtype=np.float64).tobytes()


@needs_kernels
@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), frames=st.integers(1, 40), joints=st.integers(1, 6))
def test_slerp_kernel_is_numpy_to_the_bit(seed: int, frames: int, joints: int) -> None:
    """Every way the blend code calls slerp: per frame (a trailing 1), one weight, one t per
    quaternion; unit and unnormalised quaternions, equal, opposite and zero ones."""
    from blendspace_pipeline.motion import quaternions

    if not quaternions._libm_agrees():
        pytest.skip("numpy's acos/sin are not the C library's here: the kernel is not used")
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(frames, joints, 4))
    a /= np.linalg.norm(a, axis=-1, keepdims=True)
    b = rng.normal(size=(frames, joints, 4)) * rng.uniform(0.5, 2.0)
    b[0] = a[0]  # the small-angle branch
    if frames > 1:
        b[1] = -a[1]  # the shortest arc flips the sign
    if frames > 2:
        a[2, 0] = b[2, 0] = 0.0  # a zero quaternion: no length to divide by
    patch = pytest.MonkeyPatch()
    try:
        for t in (
            rng.uniform(0, 1, frames)[:, None],
            float(rng.uniform()),
            rng.uniform(0, 1, (frames, joints)),
        ):
            fast = quaternions.slerp(a, b, t)
            assert _bits(fast) == _bits(_numpy_slerp(a, b, t, patch))
    finally:
        patch.undo()


@needs_kernels
def test_slerp_stays_in_numpy_where_the_kernel_cannot_vouch(monkeypatch: pytest.MonkeyPatch) -> None:
    from blendspace_pipeline.motion import quaternions

    calls: list[int] = []
    real = kernels.slerp  # type: ignore[union-attr]

    def counting(*args: object) -> bool:
        calls.append(1)
        return real(*args)  # type: ignore[arg-type]

    monkeypatch.setattr(native.kernels, "slerp", counting)
    a = np.tile([0.0, 0.0, 0.0, 1.0], (3, 1))
    b = np.tile([0.0, 0.70710678, 0.0, 0.70710678], (3, 1))
    quaternions.slerp(a, b, 0.5)
    assert calls == [1]
    quaternions.slerp(a[:1], b, 0.5)  # a and b broadcast against each other: numpy's
    quaternions.slerp(a, b, np.linspace(0.1, 0.9, 12).reshape(3, 4))  # a t per component: numpy's
    assert calls == [1]
    monkeypatch.setattr(quaternions, "_libm_agrees", lambda: False)  # another numpy's acos/sin
    expected = _numpy_slerp(a, b, 0.5, monkeypatch)
    assert _bits(quaternions.slerp(a, b, 0.5)) == _bits(expected)
    assert calls == [1]


@needs_kernels
def test_slerp_of_float32_quaternions_stays_in_numpy(monkeypatch: pytest.MonkeyPatch) -> None:
    from blendspace_pipeline.motion import quaternions

    monkeypatch.setattr(native.kernels, "slerp", lambda *args: pytest.fail("float32 went to the kernel"))
    a = np.tile(np.float32([0.0, 0.0, 0.0, 1.0]), (2, 1))
    b = np.tile(np.float32([0.0, 0.6, 0.0, 0.8]), (2, 1))
    assert quaternions.slerp(a, b, 0.5).shape == (2, 4)
