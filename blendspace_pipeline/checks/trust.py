"""The plugin trust switch, kept apart from the rule engine so the command line can name it
without loading rules (`--help` and a no-op replay import nothing heavy)."""

from __future__ import annotations

import os

# Set to 1/true/yes/on for an untrusted run: only built-in and installed entry-point rules load.
NO_PLUGINS_VARIABLE = "BLENDSPACE_NO_PLUGINS"


def plugins_disabled() -> bool:
    """`BLENDSPACE_NO_PLUGINS` set to 1/true/yes/on (`--no-plugins` sets it for its run)."""
    return os.environ.get(NO_PLUGINS_VARIABLE, "").strip().lower() in {"1", "true", "yes", "on"}
