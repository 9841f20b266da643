"""Recognising joints by name: sides (left/right) and the hip joints.

Rigs name the same joint many ways (`LeftUpLeg`, `thigh.L`, `L_Thigh`, `LHipJoint`,
`b_LeftLeg01`); these helpers read the side token and the base name so measurement can find
the hips and mirroring can pair left with right.
"""

from __future__ import annotations

import re
from functools import lru_cache

from blendspace_pipeline.motion.clip import Skeleton

Side = str  # "L", "R" or ""

_SEPARATED = re.compile(r"(?:^|(?<=[._\-\s:|]))(l|r|left|right)(?=$|[._\-\s:|\d])", re.IGNORECASE)
_CAMEL_PREFIX = re.compile(r"^(?:[a-z]+_)?(L|R)(?=[A-Z])")
_WORD = re.compile(r"(left|right)", re.IGNORECASE)

# Base names of the joint at the hip socket, most specific first.
_HIP_BASES = ("upleg", "upperleg", "legupper", "thigh", "hip", "leg")
_NOT_HIP = ("hipjoint", "hips", "pelvis")


# Measuring one clip asks for its hips and feet a dozen times and a library repeats a few rigs
# thousands of times: both answers depend on the names alone, so they are remembered.
@lru_cache(maxsize=8192)
def split_side(name: str) -> tuple[Side, str]:
    """(side, base) where base is the name without its side token, lower-case, alphanumeric."""
    side = ""
    stripped = name
    word = _WORD.search(name)
    if word:
        side = "L" if word.group(1).lower() == "left" else "R"
        stripped = name[: word.start()] + name[word.end() :]
    else:
        separated = _SEPARATED.search(name)
        camel = _CAMEL_PREFIX.search(name)
        if separated:
            side = separated.group(1)[0].upper()
            stripped = name[: separated.start(1)] + name[separated.end(1) :]
        elif camel:
            side = camel.group(1)
            stripped = name[: camel.start(1)] + name[camel.end(1) :]
    base = re.sub(r"[^a-z]", "", stripped.lower())
    return side, base


def find_hips(skeleton: Skeleton) -> tuple[int, int] | None:
    """Indices of the (left, right) hip-socket joints, or None when no pair is recognised."""
    return _hips_of(tuple(skeleton.names))


@lru_cache(maxsize=1024)
def _hips_of(names: tuple[str, ...]) -> tuple[int, int] | None:
    by_base: dict[str, dict[Side, int]] = {}
    for index, name in enumerate(names):
        side, base = split_side(name)
        if side and base not in _NOT_HIP:
            by_base.setdefault(base, {}).setdefault(side, index)
    for wanted in _HIP_BASES:
        for base, sides in sorted(by_base.items()):
            core = base.rstrip("0123456789")
            if (core == wanted or core.endswith(wanted) or core.startswith(wanted)) and {"L", "R"} <= set(
                sides
            ):
                return sides["L"], sides["R"]
    return None
