"""Regenerate the sample project's clips from the procedural generator.

The sample clips are made by the project's own code so their ground truth is known: each clip
does exactly what its `GaitSpec` says (speeds in m/s, turn rates in deg/s). The set is a
realistic first draft of a locomotion set, flaws included, so a build shows the rules and fixes
at work: there is no right turn in place and no right running turn (mirroring makes them), the
"forward" walk drifts a few degrees per second to the left (misalignment), and a relaxed walk sits
almost on top of the normal one (too close).

    python sample_project/make_clips.py        # rewrites sample_project/clips and styles

`tests/test_sample_project.py` regenerates the clips into a temporary folder and compares them
byte for byte with the committed ones, so the files here never drift from this script.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from blendspace_pipeline.motion.procedural import GaitSpec, generate
from blendspace_pipeline.writers.usd_clip import write_usd_clip

HERE = Path(__file__).resolve().parent

# The main (turn_rate, speed) space: forward-facing locomotion.
MAIN = (
    GaitSpec("idle", duration=2.0),
    GaitSpec("walk_fwd", speed=1.4, turn_rate=3.0, duration=1.0),  # drifts left: misalignment
    GaitSpec("walk_relaxed", speed=1.5, duration=1.0, stride_length=1.4),  # too close to walk_fwd
    GaitSpec("run_fwd", speed=4.0, duration=0.8, stride_length=2.6),
    GaitSpec("walk_bwd", speed=1.1, direction=180.0, duration=1.0, stride_length=1.1),
    GaitSpec("run_bwd", speed=2.6, direction=180.0, duration=0.8, stride_length=2.0),
    GaitSpec("walk_turn_left", speed=1.4, turn_rate=60.0, duration=1.5),
    GaitSpec("walk_turn_right", speed=1.4, turn_rate=-60.0, duration=1.5),
    GaitSpec("run_turn_left", speed=4.0, turn_rate=90.0, duration=1.0, stride_length=2.6),
    GaitSpec("turn_in_place_left", turn_rate=90.0, duration=2.0),
)
# The beta layer's space (lateral.yaml): the same axes, stepping sideways to the left.
LATERAL = (
    GaitSpec("strafe_left_walk", speed=1.2, direction=90.0, duration=1.0, stride_length=1.0),
    GaitSpec("strafe_left_run", speed=3.0, direction=90.0, duration=0.8, stride_length=1.8),
    GaitSpec("strafe_left_back", speed=1.0, direction=135.0, duration=1.0, stride_length=1.0),
)
# The style layer: a limp, forward and backward, on the speed axis.
STYLE = (
    GaitSpec("limp_fwd", speed=0.9, duration=1.2, stride_length=0.9, sway=0.08, bob=0.06, pelvis_yaw=12.0),
    GaitSpec("limp_bwd", speed=0.6, direction=180.0, duration=1.2, stride_length=0.7, sway=0.08, bob=0.06),
)


def write_clips(root: Path) -> list[Path]:
    """Write every sample clip under ``root`` (clips/ and styles/) and return the paths."""
    written = []
    for folder, specs in (("clips", MAIN + LATERAL), ("styles", STYLE)):
        for spec in specs:
            path = root / folder / f"{spec.name}.usda"
            path.parent.mkdir(parents=True, exist_ok=True)
            clip = generate(spec, source=path)
            write_usd_clip(clip, path, meters_per_unit=1.0, up_axis="y")
            written.append(path)
    return written


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--out", type=Path, default=HERE, help="project folder to write into")
    args = parser.parse_args()
    for path in write_clips(args.out):
        print(path)


if __name__ == "__main__":
    main()
