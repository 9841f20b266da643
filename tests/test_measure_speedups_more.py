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
