"""`forward_kinematics` (the compiled kernel, and numpy's all joints of one depth at a time,
component-major) equals the joint-by-joint composition (`forward_kinematics_by_joint`, the code
before it) to the bit."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from conftest import shared_data
from hypothesis import given, settings
from hypothesis import strategies as st

from blendspace_pipeline import native
from blendspace_pipeline.motion import hostile
from blendspace_pipeline.motion.clip import Clip, Skeleton, forward_kinematics, forward_kinematics_by_joint
from blendspace_pipeline.motion.procedural import GaitSpec, generate
from blendspace_pipeline.readers import read_clips


def _same(clip: Clip) -> None:
    """The compiled kernel (when built), the numpy levels and the joint-by-joint path agree."""
    plain = forward_kinematics_by_joint(clip)
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(native, "kernels", None)
        levels = forward_kinematics(clip)
    for fast in (forward_kinematics(clip), levels):
        for a, b in zip(fast, plain, strict=True):
            assert a.shape == b.shape and a.dtype == b.dtype
            assert a.tobytes() == b.tobytes()


def test_real_and_generated_takes() -> None:
    _same(read_clips(shared_data("cmu", "131_01.bvh"))[0])
    _same(read_clips(shared_data("khronos-fox", "Fox.glb"))[0])
    _same(generate(GaitSpec("walk", speed=1.4, turn_rate=30.0, duration=1.0, fps=120.0)))
    _same(generate(GaitSpec("walk", speed=1.4, duration=1.0), with_root_joint=True, up="z"))
    for spec in hostile.studio_set()[:3]:
        _same(hostile.take(spec).clip)


@st.composite
def _clips(draw: st.DrawFn) -> Clip:
    count = draw(st.integers(min_value=1, max_value=12))
    # Any forest: each joint's parent comes before it (or it is a root).
    parents = tuple(draw(st.integers(min_value=-1, max_value=j - 1)) for j in range(count))
    frames = draw(st.integers(min_value=1, max_value=9))
    rng = np.random.default_rng(draw(st.integers(min_value=0, max_value=2**32 - 1)))
    rotations = rng.normal(size=(frames, count, 4))
    rotations /= np.linalg.norm(rotations, axis=-1, keepdims=True)
    translations = rng.normal(scale=draw(st.sampled_from([1e-3, 1.0, 1e4])), size=(frames, count, 3))
    # Exact zeros of both signs and identity rotations, where the order of the sums decides the bits.
    mask = rng.random(rotations.shape) < 0.2
    rotations[mask] = np.where(rng.random(int(mask.sum())) < 0.5, 0.0, -0.0)
    translations[rng.random(translations.shape) < 0.2] = -0.0
    skeleton = Skeleton(
        names=tuple(f"j{i}" for i in range(count)),
        parents=parents,
        rest_translations=translations[0].copy(),
        rest_rotations=np.tile([0.0, 0.0, 0.0, 1.0], (count, 1)),
    )
    return Clip("random", shared_data("cmu"), skeleton, rotations, translations, 30.0)


@settings(max_examples=150, deadline=None)
@given(clip=_clips())
def test_property_any_hierarchy_same_bits(clip: Clip) -> None:
    _same(clip)


def test_without_a_hierarchy_or_in_float32_it_is_the_joint_by_joint_path() -> None:
    clip = generate(GaitSpec("walk", speed=1.4, duration=0.5))
    _same(replace(clip, skeleton=replace(clip.skeleton, has_hierarchy=False)))
    _same(replace(clip, rotations=clip.rotations.astype(np.float32)))
    world_rot, _ = forward_kinematics(replace(clip, skeleton=replace(clip.skeleton, has_hierarchy=False)))
    assert world_rot.tobytes() == clip.rotations.tobytes()


def test_results_do_not_share_the_kept_work_arrays() -> None:
    """The working arrays are kept for the next clip of the same size; results are fresh arrays."""
    a = generate(GaitSpec("a", speed=1.4, duration=0.5))
    b = generate(GaitSpec("b", speed=3.0, turn_rate=90.0, duration=0.5))
    first = forward_kinematics(a)
    kept = [array.copy() for array in first]
    forward_kinematics(b)
    for array, copy in zip(first, kept, strict=True):
        assert array.tobytes() == copy.tobytes()
    _same(a)


def test_threads_each_use_their_own_work_arrays() -> None:
    from concurrent.futures import ThreadPoolExecutor

    clips = [generate(GaitSpec(f"c{i}", speed=0.5 + i, turn_rate=20.0 * i, duration=1.0)) for i in range(6)]
    expected = [forward_kinematics_by_joint(clip) for clip in clips]
    with ThreadPoolExecutor(3) as pool:
        got = list(pool.map(forward_kinematics, clips * 5))
    for index, result in enumerate(got):
        want = expected[index % len(clips)]
        assert result[0].tobytes() == want[0].tobytes() and result[1].tobytes() == want[1].tobytes()
