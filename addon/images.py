"""Display images: scene-linear float arrays to sRGB PNG files (what 'Standard' shows)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image


def linear_to_srgb(x: np.ndarray) -> np.ndarray:
    """The sRGB transfer function on values clamped to [0, 1]."""
    x = np.clip(x, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)


def save_png(path: Path, linear: np.ndarray, exposure: float = 0.0) -> Path:
    """Saves an H x W x 3 scene-linear image as an 8-bit sRGB PNG (row 0 at the top)."""
    display = linear_to_srgb(np.asarray(linear, dtype=np.float64)[..., :3] * 2.0**exposure)
    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray((display * 255.0 + 0.5).astype(np.uint8), "RGB").save(path)
    return path


def load_png_linear(path: Path) -> np.ndarray:
    """Reads an 8-bit sRGB PNG back to scene-linear float32 (H x W x 3)."""
    c = np.asarray(Image.open(path).convert("RGB"), dtype=np.float64) / 255.0
    lin = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    return lin.astype(np.float32)
