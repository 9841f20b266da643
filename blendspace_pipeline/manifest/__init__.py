"""The manifest: YAML in, validated models out, with the line of every key kept for messages.

`load_manifest` reads and validates a file; `paths.resolve_clip_files` turns its `clips:` entries
into clip files. The models in `models` are the contract of spec.md and generate the JSON Schema.
"""

from __future__ import annotations

from blendspace_pipeline.features import FEATURE_UNITS
from blendspace_pipeline.manifest.loader import (
    KeyPath,
    LoadedManifest,
    ManifestProblemsError,
    Problem,
    load_manifest,
)
from blendspace_pipeline.manifest.models import FEATURES, ClipEntry, FeatureName, Manifest

__all__ = [
    "FEATURES",
    "FEATURE_UNITS",
    "ClipEntry",
    "FeatureName",
    "KeyPath",
    "LoadedManifest",
    "Manifest",
    "ManifestProblemsError",
    "Problem",
    "load_manifest",
]
