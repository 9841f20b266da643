"""Notes a measurement leaves on a clip that later stages recognise (kept light: the exporters
import it without the measurement code)."""

from __future__ import annotations

# The first frame was a rest pose and is left out of the measurement (`measure.detect_tpose_frame`):
# the exports say the engine still plays it.
REST_FRAME_NOTE = "first frame is a rest/T-pose and was left out of the measurement"

# Frames at either end that repeat one pose were left out (`detect.held_ends`): the exports say the
# engine still plays them. `HELD_MARK` begins every such note.
HELD_MARK = "held keys left out of the measurement"
STILL_NOTE = "every frame holds the same pose (a still idle, or a pose exported as an animation)"


def held_note(leading: int, trailing: int, fps: float) -> str:
    parts = [
        f"the {where} {frames} frame{'s' if frames != 1 else ''} ({frames / fps:.2f} s)"
        for where, frames in (("first", leading), ("last", trailing))
        if frames
    ]
    return (
        f"{HELD_MARK} (each repeats the pose next to it, as a scene range longer than the action "
        f"leaves them): {', '.join(parts)}"
    )
