"""Quality of generated (blended) clips on real mocap: foot sliding, loop seam, bone lengths.

    python benchmarks/bench_blend_quality.py

Blends pairs of steady walking ranges of the CMU takes in ../shared/data/cmu (the fix loop's
`blend_clips`, as `fixes` uses it) and prints, per blend:
- foot sliding: (without re-planting, "no IK", then with it) mean ground speed of the planted feet (m/s, `contacts.foot_sliding` on the
  clip's own contacts), of the blend and the weighted mean of its sources, and their ratio
  (goal: <= 1.1);
- loop seam: largest distance (cm) of any joint, in the character's own frame, between the
  blend's last frame and its first (it is built as a closed loop; goal: <= 1 cm);
- bone lengths: largest change of any bone's length over the clip (file units; goal: 0).
Nothing here asserts; the figures go in the issue notes.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

from blendspace_pipeline.motion import quaternions as quat
from blendspace_pipeline.motion.clip import Clip, forward_kinematics
from blendspace_pipeline.motion.clip_ops.blend import blend_clips, measured_part
from blendspace_pipeline.motion.clip_ops.feet import clip_contacts, contact_joints
from blendspace_pipeline.motion.clip_ops.root_motion import decompose
from blendspace_pipeline.motion.contacts import foot_sliding
from blendspace_pipeline.motion.detect import RigSettings, resolve_root, resolve_units, resolve_up
from blendspace_pipeline.motion.measure import trim
from blendspace_pipeline.readers import read_clips

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "cmu"
SETTINGS = RigSettings()
RANGES = {
    "01_4-6": ("131_01.bvh", (4.0, 6.0)),
    "01_5-7": ("131_01.bvh", (5.0, 7.0)),
    "02_2.5-5.8": ("131_02.bvh", (2.5, 5.8)),
    "02_4-6": ("131_02.bvh", (4.0, 6.0)),
}
BLENDS = [
    ("01_4-6", "02_2.5-5.8", 0.5),
    ("01_5-7", "02_4-6", 0.5),
    ("02_2.5-5.8", "02_4-6", 0.5),
    ("01_4-6", "02_2.5-5.8", 0.3),
]


def units(clip: Clip) -> tuple[float, str]:
    _, positions = forward_kinematics(clip)
    up, _ = resolve_up(clip, positions, SETTINGS)
    mpu, _, _ = resolve_units(clip, positions, SETTINGS, up, resolve_root(clip, SETTINGS, positions))
    return mpu, up


def sliding(clip: Clip, mpu: float, up: str) -> float:
    positions = forward_kinematics(clip)[1]
    contacts = clip_contacts(clip, SETTINGS, positions, meters_per_unit=mpu, up_axis=up)
    joints = contact_joints(clip, SETTINGS)
    assert contacts is not None and joints is not None
    value = foot_sliding(positions, joints, contacts, fps=clip.fps, meters_per_unit=mpu, up_axis=up)
    return value if value is not None else float("nan")


def loop_seam(clip: Clip, mpu: float) -> float:
    """cm between the last and first frame of every joint, in the character's moving frame."""
    motion = decompose(clip, SETTINGS)
    positions = forward_kinematics(clip)[1]
    inverse = quat.conjugate(quat.from_axis_angle(motion.up, motion.heading))
    local = quat.rotate(
        np.broadcast_to(inverse[:, None], (*positions.shape[:2], 4)),
        positions - motion.trajectory_points()[:, None],
    )
    return float(np.linalg.norm(local[-1] - local[0], axis=1).max()) * mpu * 100.0


def bone_error(clip: Clip) -> float:
    positions = forward_kinematics(clip)[1]
    worst = 0.0
    for joint, parent in enumerate(clip.skeleton.parents):
        if parent >= 0:
            length = np.linalg.norm(positions[:, joint] - positions[:, parent], axis=1)
            worst = max(
                worst, float(np.abs(length - np.linalg.norm(clip.skeleton.rest_translations[joint])).max())
            )
    return worst


def main() -> int:
    if not DATA.is_dir():
        print(f"{DATA} is missing: the benchmark needs the shared CMU takes")
        return 1
    takes = {name: read_clips(DATA / name)[0] for name in {f for f, _ in RANGES.values()}}
    sources = {key: measured_part(trim(takes[f], r), SETTINGS) for key, (f, r) in RANGES.items()}
    mpu, up = units(takes["131_01.bvh"])
    print(f"unit {mpu:.4g} m per unit, up {up}")
    print(
        f"{'blend':32} {'src slide':>9} {'no IK':>7} {'slide':>7} {'ratio':>6} {'seam cm':>8} {'bone err':>9} {'s':>5}"
    )
    for a, b, w in BLENDS:
        start = time.perf_counter()
        blended = blend_clips([sources[a], sources[b]], [w, 1.0 - w], name="blend", settings=SETTINGS)
        seconds = time.perf_counter() - start
        loose = blend_clips(
            [sources[a], sources[b]], [w, 1.0 - w], name="loose", settings=SETTINGS, plant=False
        )
        source = w * sliding(sources[a], mpu, up) + (1.0 - w) * sliding(sources[b], mpu, up)
        result = sliding(blended, mpu, up)
        print(
            f"{f'{w:.1f} {a} + {1 - w:.1f} {b}':32} {source:9.3f} {sliding(loose, mpu, up):7.3f} {result:7.3f} {result / source:6.2f} "
            f"{loop_seam(blended, mpu):8.2f} {bone_error(blended):9.2e} {seconds:5.2f}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
