"""Notes a measurement leaves on a clip that later stages recognise (kept light: the exporters
import it without the measurement code)."""

from __future__ import annotations

# The first frame was a rest pose and is left out of the measurement (`measure.detect_tpose_frame`):
# the exports say the engine still plays it.
REST_FRAME_NOTE = "first frame is a rest/T-pose and was left out of the measurement"
