"""The measured features of spec.md and their units: one table for the measurement, the manifest,
the document, the report and the rules (`api.FEATURE_UNITS`)."""

from __future__ import annotations

FEATURE_UNITS: dict[str, str] = {
    "speed": "m/s",
    "displacement_speed": "m/s",
    "forward_speed": "m/s",
    "lateral_speed": "m/s",
    "direction": "deg",
    "turn_rate": "deg/s",
    "turn": "deg",
    "duration": "s",
}
