"""Recognising joints by name: sides (left/right) and the hip joints.

Rigs name the same joint many ways (`LeftUpLeg`, `thigh.L`, `L_Thigh`, `LHipJoint`,
`b_LeftLeg01`, DAZ's `lThigh`, CMU ASF's `lfemur`, MikuMikuDance's `左足`); these helpers read the side token and the base name so measurement can find
the hips and mirroring can pair left with right.
"""

from __future__ import annotations

import re
import unicodedata
from functools import lru_cache

from blendspace_pipeline.motion.clip import Skeleton

Side = str  # "L", "R" or ""

_SEPARATED = re.compile(r"(?:^|(?<=[._\-\s:|]))(l|r|left|right)(?=$|[._\-\s:|\d])", re.IGNORECASE)
# A side letter before a capital (`LThigh`, `RFOOT`, `b_LHand`); and before a capitalised word
# only (so `C_ROOT`, `DEF_RIBS` stay centre joints): DAZ's `lThigh`, an asset prefix's
# `Skeleton1_LThigh`.
_CAMEL_PREFIX = re.compile(r"^(?:[a-z]+_)?(L|R)(?=[A-Z])")
_CAMEL_WORD = re.compile(r"^(?:[A-Za-z0-9]+_)?([LRlr])(?=[A-Z][a-z])")
_WORD = re.compile(r"(left|right)", re.IGNORECASE)
# MikuMikuDance's Japanese names: the side is a kanji (左 left, 右 right) and the base is read
# through `_JAPANESE` (longest first: 足首 is the ankle, 足 the leg at the hip socket).
_KANJI_SIDE = {"左": "L", "右": "R"}
_JAPANESE = (
    ("つま先", "toe"),
    ("足首", "ankle"),
    ("手首", "wrist"),
    ("下半身", "pelvis"),
    ("上半身", "spine"),
    ("ひざ", "knee"),
    ("ひじ", "elbow"),
    ("足", "leg"),
    ("腕", "arm"),
    ("肩", "shoulder"),
    ("首", "neck"),
    ("頭", "head"),
)

# Base names of the joint at the hip socket, most specific first (`femur`: CMU's ASF names).
_HIP_BASES = ("upleg", "upperleg", "legupper", "thigh", "femur", "hip", "leg")
_NOT_HIP = ("hipjoint", "hips", "pelvis")


# Measuring one clip asks for its hips and feet a dozen times and a library repeats a few rigs
# thousands of times: both answers depend on the names alone, so they are remembered.
@lru_cache(maxsize=8192)
def split_side(name: str) -> tuple[Side, str]:
    """(side, base) where base is the name without its side token, lower-case, alphanumeric."""
    side = ""
    stripped = name
    word = _WORD.search(name)
    kanji = next((k for k in _KANJI_SIDE if k in name), None)
    if kanji is not None:
        side = _KANJI_SIDE[kanji]
        stripped = name.replace(kanji, "", 1)
    elif word:
        side = "L" if word.group(1).lower() == "left" else "R"
        stripped = name[: word.start()] + name[word.end() :]
    else:
        separated = _SEPARATED.search(name)
        camel = _CAMEL_PREFIX.search(name) or _CAMEL_WORD.search(name)
        if separated:
            side = separated.group(1)[0].upper()
            stripped = name[: separated.start(1)] + name[separated.end(1) :]
        elif camel:
            side = camel.group(1).upper()
            stripped = name[: camel.start(1)] + name[camel.end(1) :]
    lowered = stripped.lower()
    if not lowered.isascii():
        lowered = unicodedata.normalize("NFKC", lowered).lower()  # full-width ＩＫ is IK
        for japanese, english in _JAPANESE:
            lowered = lowered.replace(japanese, english)
    base = re.sub(r"[^a-z]", "", lowered)
    return side, base


def letter_partner(name: str, names: set[str] | frozenset[str]) -> str | None:
    """The partner of an all-lower-case name whose first letter is its side, when ``names`` has
    it: CMU's ASF names (`lfemur` and `rfemur`, `lhipjoint`, `ltibia`). A name alone does not
    say it (`lowerback` is no left `owerback`), so only a pair in one skeleton counts."""
    if len(name) < 3 or name[0] not in "lr" or not name[1:].isalpha() or not name.islower():
        return None
    partner = ("r" if name[0] == "l" else "l") + name[1:]
    return partner if partner in names else None


def find_hips(skeleton: Skeleton) -> tuple[int, int] | None:
    """Indices of the (left, right) hip-socket joints, or None when no pair is recognised."""
    return _hips_of(tuple(skeleton.names))


@lru_cache(maxsize=1024)
def _hips_of(names: tuple[str, ...]) -> tuple[int, int] | None:
    by_base: dict[str, dict[Side, int]] = {}
    known = frozenset(names)
    for index, name in enumerate(names):
        side, base = split_side(name)
        if not side and letter_partner(name, known) is not None:
            side, base = name[0].upper(), re.sub(r"[^a-z]", "", name[1:])
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
