"""Clip operations the fixes use to bake real animation: blend, mirror, straighten.

Blending puts clips in step by gait phase first (`phase`: the stride found from the feet).

Every operation returns a new `Clip` on the source's skeleton, frame rate and units, with a
note saying how it was made; sources are never changed. Root motion is handled through
`root_motion` (trajectory + pose), so generated clips measure where the fix meant them to.
"""

from blendspace_pipeline.motion.clip_ops.blend import blend_clips
from blendspace_pipeline.motion.clip_ops.errors import IncompatibleClips
from blendspace_pipeline.motion.clip_ops.mirror import mirror_clip, mirror_pairs
from blendspace_pipeline.motion.clip_ops.phase import GaitCycle, detect_cycle
from blendspace_pipeline.motion.clip_ops.straighten import straighten_clip

__all__ = [
    "GaitCycle",
    "IncompatibleClips",
    "blend_clips",
    "detect_cycle",
    "mirror_clip",
    "mirror_pairs",
    "straighten_clip",
]
