"""Display images: scene-linear float arrays to sRGB PNG files (what 'Standard' shows).

PNG files are written with ``zlib`` alone, so the add-on needs no imaging package.
"""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import numpy as np


def linear_to_srgb(x: np.ndarray) -> np.ndarray:
    """The sRGB transfer function on values clamped to [0, 1]."""
    x = np.clip(x, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)


def srgb_to_linear(c: np.ndarray) -> np.ndarray:
    """The inverse of :func:`linear_to_srgb` on [0, 1]."""
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def write_png_rgb8(path: Path, rgb: np.ndarray) -> Path:
    """Writes an H x W x 3 uint8 array as a PNG (row 0 at the top)."""
    h, w, c = rgb.shape
    if c != 3 or rgb.dtype != np.uint8:
        raise ValueError(f"expected an (H, W, 3) uint8 array, got {rgb.shape} {rgb.dtype}")
    raw = np.concatenate([np.zeros((h, 1), np.uint8), rgb.reshape(h, w * 3)], axis=1)

    def chunk(kind: bytes, data: bytes) -> bytes:
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))

    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
    png += chunk(b"IDAT", zlib.compress(raw.tobytes(), 6)) + chunk(b"IEND", b"")
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(png)
    return path


def save_png(path: Path, linear: np.ndarray, exposure: float = 0.0) -> Path:
    """Saves an H x W x 3 scene-linear image as an 8-bit sRGB PNG (row 0 at the top)."""
    display = linear_to_srgb(np.asarray(linear, dtype=np.float64)[..., :3] * 2.0**exposure)
    return write_png_rgb8(path, (display * 255.0 + 0.5).astype(np.uint8))
