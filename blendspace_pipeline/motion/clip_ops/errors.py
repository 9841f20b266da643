"""Why a clip operation cannot run: the fix loop turns this into a placeholder, not a crash."""

from __future__ import annotations


class IncompatibleClips(Exception):
    """The clips cannot be combined (different skeletons or units, unpaired mirror joints)."""
