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


def test_contacts_in_metres_read_in_place_equal_the_scaled_and_flipped_reads() -> None:
    """Metres and +up skip the scaling copies; doubling the positions at 0.5 m per unit, or
    flipping the up axis and reading it as -y, takes the scaling paths with the same numbers
    (x * 2 * 0.5 and -(-x) are x exactly), so the contacts must be the same."""
    from blendspace_pipeline.motion.clip import forward_kinematics
    from blendspace_pipeline.motion.clip_ops.feet import contact_joints
    from blendspace_pipeline.motion.detect import RigSettings
    from blendspace_pipeline.motion.procedural import GaitSpec, generate_planted

    clip = generate_planted(GaitSpec("walk", speed=1.4, turn_rate=25.0, duration=3.0, fps=120.0))
    positions = forward_kinematics(clip)[1]
    joints = contact_joints(clip, RigSettings())
    assert joints is not None

    def found(world: np.ndarray, scale: float, up: str) -> contacts.FootContacts:
        return contacts.detect_contacts(world, joints, fps=clip.fps, meters_per_unit=scale, up_axis=up)

    plain = found(positions, 1.0, "y")
    assert plain.left and plain.right
    assert found(positions * 2.0, 0.5, "y") == plain
    flipped = positions.copy()
    flipped[..., 1] = -flipped[..., 1]
    assert found(flipped, 1.0, "-y") == plain
