"""Cheaper steps of reading a clip give what the plain steps give: the still joints' quaternions
remembered per angles, the still-channel test by extremes, and `validate_clip`'s one-pass check."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from blendspace_pipeline.errors import ClipReadError
from blendspace_pipeline.motion.clip import validate_clip
from blendspace_pipeline.motion.procedural import GaitSpec, generate
from blendspace_pipeline.readers import bvh
from blendspace_pipeline.writers.bvh import write_bvh_clip


def test_still_joints_remembered_give_the_converted_quaternions(tmp_path: Path) -> None:
    path = tmp_path / "walk.bvh"
    write_bvh_clip(generate(GaitSpec("walk", speed=1.4, turn_rate=15.0, duration=1.0, fps=60.0)), path)
    bvh._STILL.clear()
    first = bvh.read(path)[0]
    assert bvh._STILL  # the walk has still joints
    again = bvh.read(path)[0]  # from the memo
    assert again.rotations.tobytes() == first.rotations.tobytes()
    assert again.rotations.flags.writeable
    for key, remembered in bvh._STILL.items():
        order, shape, raw = key
        angles = np.frombuffer(raw).reshape(shape)
        assert (
            remembered.tobytes()
            == np.ascontiguousarray(bvh.euler_quaternions(angles, order)[..., 0].T).tobytes()
        )
    again.rotations[:] = 0.0  # a clip's arrays are its own: the memo is not touched
    assert bvh.read(path)[0].rotations.tobytes() == first.rotations.tobytes()


@settings(max_examples=100, deadline=None)
@given(
    rows=st.lists(
        st.lists(st.sampled_from([0.0, -0.0, 1.5, -1.5, 1e-300, 7.0]), min_size=1, max_size=6),
        min_size=1,
        max_size=5,
    ).filter(lambda rows: len({len(r) for r in rows}) == 1)
)
def test_still_by_extremes_is_still_by_equality(rows: list[list[float]]) -> None:
    values = np.array(rows)
    assert ((values.max(axis=1) == values.min(axis=1)) == (values == values[:, :1]).all(axis=1)).all()


def _message(clip: object) -> str:
    with pytest.raises(ClipReadError) as caught:
        validate_clip(clip)  # type: ignore[arg-type]
    return caught.value.message


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
@pytest.mark.parametrize("where", ["rotations", "translations"])
def test_validate_names_the_first_non_finite_value(bad: float, where: str) -> None:
    clip = generate(GaitSpec("walk", speed=1.4, duration=0.5))
    values = getattr(clip, where).copy()
    values[7, 3, 1] = bad
    values[9, 2, 0] = bad
    message = _message(replace(clip, **{where: values}))
    label = "rotation" if where == "rotations" else "translation"
    assert f"non-finite {label} value (NaN or inf) at frame 7, joint {clip.skeleton.names[3]!r}" in message


def test_validate_accepts_finite_values_whose_sum_overflows() -> None:
    clip = generate(GaitSpec("walk", speed=1.4, duration=0.5))
    translations = clip.translations.copy()
    translations[:, 0, 0] = 1e308  # finite, but their sum is inf
    assert validate_clip(replace(clip, translations=translations)) is not None
