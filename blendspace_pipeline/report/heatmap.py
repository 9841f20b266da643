"""The trajectory-error heat map as a tiny PNG data URI for the HTML report.

A 41×41 grid is a few hundred bytes as PNG, far smaller than 1,681 SVG rectangles, and the
browser scales it smoothly. PNG encoding is a dozen lines of zlib, so the report needs no image
library (OpenImageIO stays in `png.py`).
"""

from __future__ import annotations

import base64
import struct
import zlib

import numpy as np
from numpy.typing import NDArray

from blendspace_pipeline.motion.quaternions import FloatArray

UInt8Array = NDArray[np.uint8]

# Sequential ramp, pale yellow (no drift) → dark red (large drift): reads on white and dark
# backgrounds and in greyscale print, because lightness falls monotonically.
RAMP: list[tuple[float, tuple[int, int, int]]] = [
    (0.0, (255, 255, 204)),
    (0.25, (254, 217, 118)),
    (0.5, (253, 141, 60)),
    (0.75, (227, 26, 28)),
    (1.0, (128, 0, 38)),
]
# Errors below this (normalised units, i.e. percent of an axis) are scaled as if it were the
# maximum, so snapping-sized noise does not light up the whole map.
MIN_SCALE = 5.0


def colour_scale(fractions: FloatArray) -> UInt8Array:
    """RGB (…, 3) for values in 0..1 (clipped) along `RAMP`."""
    values = np.clip(np.nan_to_num(np.asarray(fractions, dtype=np.float64)), 0.0, 1.0)
    stops = np.array([s for s, _ in RAMP])
    colours = np.array([c for _, c in RAMP], dtype=np.float64)
    channels = [np.interp(values, stops, colours[:, k]) for k in range(3)]
    return np.rint(np.stack(channels, axis=-1)).astype(np.uint8)


def css_gradient() -> str:
    """The ramp as a CSS linear-gradient for the colour bar."""
    stops = ", ".join(f"rgb{colour} {stop * 100:g}%" for stop, colour in RAMP)
    return f"linear-gradient(to right, {stops})"


def scale_maximum(*maxima: float) -> float:
    return max([MIN_SCALE, *maxima])


def heat_rgba(distance: FloatArray, maximum: float) -> UInt8Array:
    """RGB image (rows top to bottom) of a (ny, nx) error grid whose row 0 is the axis minimum.

    Grid points outside the hull take the value of the nearest inside point: the report clips
    the image to the hull, and the browser's smooth scaling then never blends in a fake colour
    at the boundary.
    """
    grid = _extend_inside(np.asarray(distance, dtype=np.float64))[::-1]  # image rows start at y max
    return colour_scale(grid / maximum)


def _extend_inside(grid: FloatArray) -> FloatArray:
    outside = np.isnan(grid)
    if not outside.any() or outside.all():
        return np.nan_to_num(grid)
    from scipy.ndimage import distance_transform_edt  # local import: only reports need it

    _, (rows, cols) = distance_transform_edt(outside, return_indices=True)
    return np.asarray(grid[rows, cols])


def png_bytes(rgb: UInt8Array) -> bytes:
    """Minimal PNG (8-bit RGB, no filtering) of an (h, w, 3) array."""
    height, width = rgb.shape[:2]
    raw = b"".join(b"\x00" + rgb[row].tobytes() for row in range(height))

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    header = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)  # bit depth 8, colour type 2: RGB
    return (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", header)
        + chunk(b"IDAT", zlib.compress(raw, 9))
        + chunk(b"IEND", b"")
    )


def png_data_uri(rgb: UInt8Array) -> str:
    return "data:image/png;base64," + base64.b64encode(png_bytes(rgb)).decode("ascii")
