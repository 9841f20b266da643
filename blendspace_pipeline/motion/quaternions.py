"""Vectorised quaternion maths on numpy arrays.

Convention: quaternions are stored scalar-last, ``(x, y, z, w)``, the order glTF and scipy use,
so readers convert once at the edge. All functions broadcast over leading axes.
"""

from __future__ import annotations

import functools
import math
import warnings

import numpy as np
from numpy.typing import NDArray

from blendspace_pipeline import native

FloatArray = NDArray[np.float64]

IDENTITY = np.array([0.0, 0.0, 0.0, 1.0])


def multiply(a: FloatArray, b: FloatArray) -> FloatArray:
    """Hamilton product ``a * b`` (apply ``b`` first, then ``a``)."""
    ax, ay, az, aw = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    bx, by, bz, bw = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
    # Written into one array (np.stack would copy four temporaries; same sums, same order).
    product: FloatArray = np.empty(np.broadcast_shapes(np.shape(a), np.shape(b)), dtype=np.result_type(a, b))
    product[..., 0] = aw * bx + ax * bw + ay * bz - az * by
    product[..., 1] = aw * by - ax * bz + ay * bw + az * bx
    product[..., 2] = aw * bz + ax * by - ay * bx + az * bw
    product[..., 3] = aw * bw - ax * bx - ay * by - az * bz
    return product


def conjugate(q: FloatArray) -> FloatArray:
    conjugated: FloatArray = np.asarray(q, dtype=np.float64) * np.array([-1.0, -1.0, -1.0, 1.0])
    return conjugated


def normalize(q: FloatArray) -> FloatArray:
    norm = np.linalg.norm(q, axis=-1, keepdims=True)
    return np.asarray(q / np.where(norm == 0.0, 1.0, norm), dtype=np.float64)


def rotate(q: FloatArray, v: FloatArray) -> FloatArray:
    """Rotate vectors ``v`` (..., 3) by unit quaternions ``q`` (..., 4)."""
    # v + w t + u x t with t = 2 u x v, written out per component: numpy's loops over an inner
    # axis of 3 (and the (..., 1) scalar part broadcast over it) cost more than the arithmetic.
    # The same products and sums in the same order, so the same values.
    ux, uy, uz, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    vx, vy, vz = v[..., 0], v[..., 1], v[..., 2]
    tx = 2.0 * (uy * vz - uz * vy)
    ty = 2.0 * (uz * vx - ux * vz)
    tz = 2.0 * (ux * vy - uy * vx)
    rotated: FloatArray = np.empty((*np.broadcast_shapes(np.shape(q)[:-1], np.shape(v)[:-1]), 3))
    rotated[..., 0] = vx + w * tx + (uy * tz - uz * ty)
    rotated[..., 1] = vy + w * ty + (uz * tx - ux * tz)
    rotated[..., 2] = vz + w * tz + (ux * ty - uy * tx)
    return rotated


def cross(a: FloatArray, b: FloatArray) -> FloatArray:
    """``np.cross(a, b)`` of 3-vectors (broadcasting), the same products in the same order."""
    return _cross(a, b)


def _cross(a: FloatArray, b: FloatArray) -> FloatArray:
    # Written out: np.cross spends most of its time moving axes around on the small arrays
    # forward kinematics passes per joint.
    ax, ay, az = a[..., 0], a[..., 1], a[..., 2]
    bx, by, bz = b[..., 0], b[..., 1], b[..., 2]
    product: FloatArray = np.empty(np.broadcast_shapes(np.shape(a), np.shape(b)), dtype=np.result_type(a, b))
    product[..., 0] = ay * bz - az * by
    product[..., 1] = az * bx - ax * bz
    product[..., 2] = ax * by - ay * bx
    return product


def vector_norm(v: FloatArray) -> FloatArray:
    """``np.linalg.norm(v, axis=-1)`` for 2- and 3-vectors, written out: numpy's reduction over so
    short an axis costs several times the arithmetic. The squares are summed in numpy's own order
    (first plus second, plus third), so the result is the same to the last bit."""
    squares = v[..., 0] * v[..., 0] + v[..., 1] * v[..., 1]
    if v.shape[-1] == 3:
        squares = squares + v[..., 2] * v[..., 2]
    elif v.shape[-1] != 2:
        raise ValueError(f"vector_norm: 2- or 3-vectors expected, not {v.shape[-1]}")
    norm: FloatArray = np.sqrt(squares)
    return norm


def from_axis_angle(axis: FloatArray, angle: FloatArray | float) -> FloatArray:
    """Quaternions rotating by ``angle`` radians about unit ``axis`` (broadcasts)."""
    axis = np.asarray(axis, dtype=np.float64)
    half = 0.5 * np.asarray(angle, dtype=np.float64)[..., None]
    return np.concatenate([axis * np.sin(half), np.cos(half)], axis=-1)


_AXIS = {"X": np.array([1.0, 0.0, 0.0]), "Y": np.array([0.0, 1.0, 0.0]), "Z": np.array([0.0, 0.0, 1.0])}


def from_euler(angles_deg: FloatArray, order: str) -> FloatArray:
    """Intrinsic Euler rotation as BVH defines it: ``order`` lists the axes left to right
    (e.g. ``"ZXY"``) and the rotation is ``R = R[order[0]] * R[order[1]] * R[order[2]]``.

    ``angles_deg`` has shape (..., len(order)), one column per letter of ``order``.
    """
    half = np.deg2rad(np.asarray(angles_deg, dtype=np.float64)) * 0.5
    cosines, sines = np.cos(half), np.sin(half)
    result: FloatArray | None = None
    for column, letter in enumerate(order):
        # An axis rotation has one vector component: build it directly (hot path of BVH reading).
        factor = np.zeros((*half.shape[:-1], 4))
        factor[..., "XYZ".index(letter.upper())] = sines[..., column]
        factor[..., 3] = cosines[..., column]
        result = factor if result is None else multiply(result, factor)
    if result is None:
        return np.broadcast_to(IDENTITY, (*half.shape[:-1], 4)).copy()
    return result


def to_euler(q: FloatArray, order: str) -> FloatArray:
    """Inverse of `from_euler` (degrees, one column per letter of ``order``).

    Uses scipy's intrinsic-rotation decomposition (upper-case sequence), which matches the
    BVH convention of `from_euler`.
    """
    from scipy.spatial.transform import Rotation

    flat = q.reshape(-1, 4)
    with warnings.catch_warnings():
        # At gimbal lock scipy sets the third angle to 0 and folds it into the first: the
        # rotation is still exact, which is all a writer needs.
        warnings.filterwarnings("ignore", message="Gimbal lock detected")
        angles = Rotation.from_quat(flat).as_euler(order.upper(), degrees=True)
    return np.asarray(angles.reshape((*q.shape[:-1], len(order))), dtype=np.float64)


def slerp(a: FloatArray, b: FloatArray, t: FloatArray | float) -> FloatArray:
    """Spherical interpolation from ``a`` to ``b`` (shortest arc), ``t`` broadcasting."""
    t_arr = np.asarray(t, dtype=np.float64)
    fast = _slerp_kernel(a, b, t_arr)
    if fast is not None:
        return fast
    dot = np.sum(a * b, axis=-1, keepdims=True)
    b = np.where(dot < 0.0, -b, b)
    dot = np.abs(dot)
    theta = np.arccos(np.clip(dot, -1.0, 1.0))
    sin_theta = np.sin(theta)
    small = sin_theta < 1e-6
    safe = np.where(small, 1.0, sin_theta)
    t_b = t_arr[..., None] if t_arr.ndim == a.ndim - 1 and t_arr.ndim > 0 else t_arr
    wa = np.where(small, 1.0 - t_b, np.sin((1.0 - t_b) * theta) / safe)
    wb = np.where(small, t_b, np.sin(t_b * theta) / safe)
    return normalize(wa * a + wb * b)


def _slerp_kernel(a: FloatArray, b: FloatArray, t: FloatArray) -> FloatArray | None:
    """`slerp` by the compiled kernel (the same operations one row at a time: 5-10x faster on a
    played blend's poses), or None to compute it with numpy: no kernels, shapes that broadcast
    otherwise than pairwise, or a numpy whose acos or sin round differently from the C
    library's (`_libm_agrees`)."""
    kernels = native.kernels
    if (
        kernels is None
        or not isinstance(a, np.ndarray)
        or not isinstance(b, np.ndarray)
        or a.dtype != np.float64
        or b.dtype != np.float64  # float32 would be computed in float32 by numpy
        or a.shape != b.shape
        or a.ndim < 1
        or a.shape[-1] != 4
    ):
        return None
    lead = a.shape[:-1]
    # `slerp`'s broadcasting: t of the leading shape is one per quaternion; else it broadcasts
    # against (..., 4) and must then be the same along the last axis (a trailing 1, or a scalar).
    if t.ndim in (0, len(lead)):
        per = t
    elif t.shape[-1] == 1:
        per = t[..., 0]
    else:
        return None
    try:
        per = np.broadcast_to(per, lead)
    except ValueError:
        return None
    if not _libm_agrees():
        return None
    first, second = np.ascontiguousarray(a), np.ascontiguousarray(b)
    weights = np.ascontiguousarray(per, dtype=np.float64)
    out: FloatArray = np.empty(first.shape, dtype=np.float64)
    if not kernels.slerp(first, second, weights, out, first.size // 4):
        return None
    return out


@functools.cache
def _libm_agrees() -> bool:
    """Whether numpy's float64 acos and sin give the C library's values (Python's `math` calls the
    C library, as the kernel does) on a spread of arguments, the ones slerp passes included. On
    x86-64 with AVX2 they do; a numpy that dispatches to its own SIMD versions (AVX-512) may
    round some differently, and then slerp stays in numpy so its values never change."""
    probe = np.concatenate(
        [np.linspace(-1.0, 1.0, 2049), np.linspace(0.0, np.pi, 2049), np.geomspace(1e-12, 1.0, 512)]
    )
    acos = np.arccos(np.clip(probe, -1.0, 1.0))
    sin = np.sin(probe)
    return all(
        float(x) == math.acos(min(1.0, max(-1.0, float(p)))) for p, x in zip(probe, acos, strict=True)
    ) and all(float(y) == math.sin(float(p)) for p, y in zip(probe, sin, strict=True))
