"""More shortcuts in measurement, each checked against the plain numpy it replaces, to the bit."""

from __future__ import annotations

import numpy as np
import pytest

from blendspace_pipeline.motion import contacts


@pytest.mark.parametrize("joints", [1, 2, 19, 57])
def test_joint_mean_in_metres_skips_the_scaled_copy_with_the_same_bits(joints: int) -> None:
    world_pos = np.random.default_rng(joints).normal(0.0, 30.0, (300, joints, 3))
    world_pos[::7, 0, 1] = -0.0  # signed zeros survive x * 1.0 and must survive the shortcut
    world_pos[3, :, 2] = 0.0
    got = contacts._joint_mean(world_pos, 1.0)
    assert got.tobytes() == (world_pos * 1.0).mean(axis=1).tobytes()


def _ground_speed_before(track: np.ndarray, fps: float, reach: int) -> np.ndarray:
    frames = len(track)
    index = np.arange(frames)
    ahead, behind = np.minimum(index + reach, frames - 1), np.maximum(index - reach, 0)
    span = np.maximum(ahead - behind, 1) / fps
    return contacts.vector_norm(track[ahead] - track[behind]) / span  # type: ignore[no-any-return]


@pytest.mark.parametrize("frames", [1, 2, 3, 5, 6, 7, 12, 841])
@pytest.mark.parametrize("reach", [1, 3])
@pytest.mark.parametrize("fps", [30.0, 120.0, 119.88])
def test_ground_speed_by_slices_is_the_gathered_one(frames: int, reach: int, fps: float) -> None:
    track = np.random.default_rng(frames * reach).normal(0.0, 2.0, (frames, 2))
    track[::3, 0] = -0.0
    got = contacts._ground_speed(track, fps, reach)
    assert got.tobytes() == _ground_speed_before(track, fps, reach).tobytes()
