"""A Z-up clip turned Y up, as an engine's importer turns a Z-up file.

Only the root joints change (rest and animated transforms rotated -90 degrees about X: +Z -> +Y,
+Y -> -Z); every other joint's local transforms are the same in both conventions. Units are left
as they are. Two takes of one rig exported Z-up and Y-up play as one blend only once they share
an up axis (a root rotation slerped between the two conventions is no pose at all).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from blendspace_pipeline.motion import quaternions as quat
from blendspace_pipeline.motion.clip import Clip, Skeleton
from blendspace_pipeline.motion.quaternions import FloatArray

Z_TO_Y_UP = quat.from_axis_angle(np.array([1.0, 0.0, 0.0]), -0.5 * np.pi)


def turn_roots_y_up(
    skeleton: Skeleton,
    rest_translations: FloatArray,
    rest_rotations: FloatArray,
    translations: FloatArray,
    rotations: FloatArray,
) -> None:
    """Turn the root joints' rest (J, ...) and animated (F, J, ...) transforms from Z up to Y up,
    in place (a flat skeleton, animation tracks without a hierarchy: every joint is a root)."""
    roots = [j for j, p in enumerate(skeleton.parents) if p < 0 or not skeleton.has_hierarchy]
    rest_translations[roots] = quat.rotate(Z_TO_Y_UP, rest_translations[roots])
    rest_rotations[roots] = quat.multiply(Z_TO_Y_UP, rest_rotations[roots])
    translations[:, roots] = quat.rotate(Z_TO_Y_UP, translations[:, roots])
    rotations[:, roots] = quat.multiply(Z_TO_Y_UP, rotations[:, roots])


def y_up(clip: Clip) -> Clip:
    """``clip``, a Z-up take, as a new Y-up clip (the source is not changed)."""
    skeleton = clip.skeleton
    rest_t, rest_r = skeleton.rest_translations.copy(), skeleton.rest_rotations.copy()
    translations, rotations = clip.translations.copy(), clip.rotations.copy()
    turn_roots_y_up(skeleton, rest_t, rest_r, translations, rotations)
    turned = replace(skeleton, rest_translations=rest_t, rest_rotations=rest_r)
    return replace(
        clip,
        skeleton=turned,
        translations=translations,
        rotations=rotations,
        up_axis="y",
        notes=list(clip.notes),
    )
