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


def held_note(spans: tuple[tuple[int, int], ...], fps: float) -> str:
    """``spans``: the (first, stop) frames left out, each span's seconds said from its first frame
    to its last, as `clip.range` counts them."""
    parts = [
        f"{stop - first} frame{'s' if stop - first != 1 else ''} at {first / fps:.2f}-{(stop - 1) / fps:.2f} s"
        for first, stop in spans
    ]
    return (
        f"{HELD_MARK} (frames that repeat the pose next to them, a hold such as a scene range longer "
        f"than the action leaves): {', '.join(parts)}"
    )
