"""The BVH reader's remembered parts give what parsing afresh gives: the hierarchy remembered per
header text, the pyarrow option objects per layout, and the one-copy (tensor) extraction of the
MOTION columns."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from blendspace_pipeline.errors import ClipReadError
from blendspace_pipeline.motion.procedural import GaitSpec, generate
from blendspace_pipeline.readers import bvh
from blendspace_pipeline.writers.bvh import write_bvh_clip


@pytest.fixture(autouse=True)
def _fresh(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(bvh, "_HIERARCHIES", {})
    monkeypatch.setattr(bvh, "ARROW_AFTER_BYTES", -1)  # pyarrow on every file, as in a library


def _plain(path: Path) -> tuple[bvh.BvhHeader, np.ndarray]:
    """`bvh.parse` with nothing remembered."""
    saved = dict(bvh._HIERARCHIES)
    bvh._HIERARCHIES.clear()
    try:
        return bvh.parse(path)
    finally:
        bvh._HIERARCHIES.clear()
        bvh._HIERARCHIES.update(saved)


def _take(folder: Path, name: str, seconds: float, fps: float = 120.0) -> Path:
    path = folder / f"{name}.bvh"
    write_bvh_clip(generate(GaitSpec(name, speed=1.3, turn_rate=20.0, duration=seconds, fps=fps)), path)
    return path


def test_takes_of_one_rig_read_as_if_nothing_was_remembered(tmp_path: Path) -> None:
    paths = [_take(tmp_path, "a", 1.0), _take(tmp_path, "b", 0.5, fps=60.0), _take(tmp_path, "c", 2.0)]
    for path in paths:
        header, values = bvh.parse(path)
        plain_header, plain_values = _plain(path)
        assert header == plain_header
        assert values.tobytes() == plain_values.tobytes()
    assert len(bvh._HIERARCHIES) == 1  # one rig: parsed once
    first = bvh.read(paths[0])[0]
    assert first.rotations.tobytes() == bvh._clip(paths[0], *_plain(paths[0])).rotations.tobytes()


def test_a_returned_header_is_a_copy(tmp_path: Path) -> None:
    path = _take(tmp_path, "a", 0.5)
    header, _ = bvh.parse(path)
    header.joints[0].name = "changed"
    header.joints.append(header.joints[0])
    again, _ = bvh.parse(path)
    assert again == _plain(path)[0]


def _error(path: Path) -> tuple[int | None, str]:
    with pytest.raises(ClipReadError) as caught:
        bvh.parse(path)
    return caught.value.line, caught.value.message


@pytest.mark.parametrize(
    ("old", "new"),
    [
        ("Frames: 61", "Frames: 6x"),
        ("Frame Time: 0.01666667", "Frame Time: -1"),
        ("Frame Time: 0.01666667", "Frame Time: 0.0000001"),
        ("Frames: 61", "Frames: 0"),
        ("Frame Time: 0.01666667", "Speed: 3"),
    ],
)
def test_a_remembered_rig_with_a_broken_motion_header_names_the_same_line(
    tmp_path: Path, old: str, new: str
) -> None:
    good = _take(tmp_path, "good", 1.0, fps=60.0)
    bvh.parse(good)  # remembers the rig
    assert len(bvh._HIERARCHIES) == 1
    broken = tmp_path / "broken.bvh"
    text = good.read_text()
    assert old in text
    broken.write_text(text.replace(old, new))
    remembered = _error(broken)
    bvh._HIERARCHIES.clear()
    assert remembered == _error(broken)


def test_a_stray_motion_word_above_the_motion_line_is_not_remembered(tmp_path: Path) -> None:
    good = _take(tmp_path, "good", 0.5)
    text = good.read_text()
    # "MOTION 2" stops the hierarchy walk (its first word is MOTION) but is not the MOTION line the
    # bytes search finds; such a file must fail as it always did, remembered rig or not.
    odd = tmp_path / "odd.bvh"
    odd.write_text(text.replace("HIERARCHY\n", "HIERARCHY\nMOTION 2\n", 1))
    bvh.parse(good)
    first = _error(odd)
    assert len(bvh._HIERARCHIES) == 1
    bvh._HIERARCHIES.clear()
    assert first == _error(odd)
    assert not bvh._HIERARCHIES


@settings(max_examples=40, deadline=None)
@given(
    frames=st.integers(min_value=1, max_value=40),
    channels=st.integers(min_value=1, max_value=12),
    chunks=st.integers(min_value=1, max_value=4),
    seed=st.integers(min_value=0, max_value=2**32 - 1),
)
def test_channel_major_tensor_equals_column_copies(
    frames: int, channels: int, chunks: int, seed: int
) -> None:
    """The tensor copy and the column-by-column copy give the same array, one chunk or several."""
    import pyarrow as pa

    values = np.random.default_rng(seed).normal(scale=1e3, size=(frames, channels))
    columns = {f"c{i}": values[:, i] for i in range(channels)}
    table = pa.table(columns)
    if chunks > 1:
        cut = np.linspace(0, frames, chunks + 1).astype(int)
        table = pa.concat_tables([table.slice(a, b - a) for a, b in itertools.pairwise(cut.tolist())])
    got = bvh._channel_major(table, channels, frames)
    assert got.shape == (channels, frames) and got.flags.c_contiguous and got.dtype == np.float64
    assert got.tobytes() == np.ascontiguousarray(values.T).tobytes()
