"""Provenance of a generated clip: what made it, stored in the clip file itself.

A clip the fix loop bakes says in its own file which rule made it, from which source clips, with
which weights, and with which tool version. The fix loop recognises a clip of an earlier build
(fed back as a source) by this record alone, never by where it sits in the space: an authored
walk at a cluster's centre is not a merge. Each format keeps it where its tools leave it alone:

- USD: the default prim's ``customData``, a dictionary under `USD_KEY`;
- glTF/GLB: the animation's ``extras``, an object under `GLTF_KEY`;
- BVH (which has no metadata): one comment line after the last frame, `BVH_PREFIX` + JSON.
  Readers that stop after ``Frames:`` lines (the format's rule) never see it; ours drops it.
"""

from __future__ import annotations

import json
import struct
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

USD_KEY = "blendspace_pipeline:provenance"
GLTF_KEY = "blendspace_pipeline"
BVH_PREFIX = "# blendspace-pipeline provenance: "


@dataclass(frozen=True)
class Provenance:
    """Who made a clip: the fix rule, its source clips and weights, the tool and its version."""

    rule: str
    sources: tuple[str, ...]
    weights: tuple[float, ...]
    tool: str
    version: str
    note: str = ""

    def as_dict(self) -> dict[str, Any]:
        return {
            "rule": self.rule,
            "sources": list(self.sources),
            "weights": [float(w) for w in self.weights],
            "tool": self.tool,
            "version": self.version,
            "note": self.note,
        }

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any]) -> Provenance | None:
        """The record in ``data``, or None when it is not one (a hand-edited or foreign field)."""
        try:
            rule, tool, version = str(data["rule"]), str(data["tool"]), str(data["version"])
            sources = tuple(str(s) for s in data["sources"])
            weights = tuple(float(w) for w in data.get("weights", ()))
        except (KeyError, TypeError, ValueError):
            return None
        if not rule or not sources:
            return None
        return cls(rule, sources, weights, tool, version, str(data.get("note", "")))


def bvh_line(provenance: Provenance) -> str:
    return BVH_PREFIX + json.dumps(provenance.as_dict(), sort_keys=True, separators=(",", ":")) + "\n"


def strip_bvh_provenance(text: str) -> str:
    """``text`` without its trailing provenance line (the BVH reader parses frames only)."""
    at = text.rfind(BVH_PREFIX)
    if at < 0 or (at > 0 and text[at - 1] != "\n") or text[at:].strip().count("\n"):
        return text
    return text[:at]


def read_provenance(path: Path) -> Provenance | None:
    """The provenance record in the clip file ``path``, or None (authored clips have none).

    Never raises for a file it cannot read: the clip's reader reports that with a line number.
    """
    suffix = path.suffix.lower()
    try:
        if suffix == ".bvh":
            return _bvh(path)
        if suffix in (".gltf", ".glb"):
            return _gltf(path)
        if suffix in (".usd", ".usda", ".usdc", ".usdz"):
            return _usd(path)
    except (OSError, ValueError, RuntimeError, struct.error):
        return None
    return None


def _bvh(path: Path) -> Provenance | None:
    with path.open("rb") as handle:
        handle.seek(0, 2)
        size = handle.tell()
        handle.seek(max(0, size - 65536))  # the record is one line at the very end
        tail = handle.read().decode("utf-8", errors="replace")
    at = tail.rfind(BVH_PREFIX)
    if at < 0:
        return None
    data = json.loads(tail[at + len(BVH_PREFIX) :].strip())
    return Provenance.from_mapping(data) if isinstance(data, dict) else None


def _gltf(path: Path) -> Provenance | None:
    raw = path.read_bytes()
    if raw[:4] == b"glTF":
        length, kind = struct.unpack_from("<II", raw, 12)
        if kind != 0x4E4F534A:
            return None
        document = json.loads(raw[20 : 20 + length])
    else:
        document = json.loads(raw)
    for animation in document.get("animations", []) if isinstance(document, dict) else []:
        extras = animation.get("extras") if isinstance(animation, dict) else None
        if isinstance(extras, dict) and isinstance(extras.get(GLTF_KEY), dict):
            return Provenance.from_mapping(extras[GLTF_KEY])
    return None


def _usd(path: Path) -> Provenance | None:
    from pxr import Usd  # heavy: only when a USD clip is asked about

    stage = Usd.Stage.Open(str(path), Usd.Stage.LoadNone)
    if stage is None:
        return None
    prim = stage.GetDefaultPrim()
    if not prim:
        return None
    data = prim.GetCustomDataByKey(USD_KEY)
    return Provenance.from_mapping(dict(data)) if isinstance(data, dict) else None
