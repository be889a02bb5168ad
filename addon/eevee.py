"""EEVEE as a measured output: float renders scored like the evaluator's image.

:func:`render` renders the scene with EEVEE from a camera into a 32-bit float EXR (Standard view
transform, so the pixels are scene-linear as in Cycles' passes) and returns it as numpy, row 0 at
the top. Every setting it changes is restored afterwards, also when the render fails. An 8-bit
PNG is a picture, not a measurement: the report and the demo score these float images against
the same Cycles ground truth as the evaluator's.
"""

from __future__ import annotations

import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import bpy
import numpy as np
import OpenEXR

from .capture import IMAGE_SETTINGS
from .errors import AddonError
from .settings import SettingsGuard, override, standard_view


@dataclass
class EeveeImage:
    """An EEVEE render: scene-linear RGB (H, W, 3) float32, row 0 at the top, and its time."""

    image: np.ndarray
    seconds: float


def read_exr_rgb(path: Path) -> np.ndarray:
    """The RGB channels of a single-layer EXR as (H, W, 3) float32, row 0 at the top."""
    with OpenEXR.File(str(path)) as f:
        channels = f.parts[0].channels
        if "RGB" in channels or "RGBA" in channels:
            px = np.asarray(channels.get("RGB", channels.get("RGBA")).pixels, dtype=np.float32)
            return np.ascontiguousarray(px[..., :3])
        return np.stack(
            [np.asarray(channels[c].pixels, dtype=np.float32) for c in ("R", "G", "B")], axis=-1
        )


def _configure_output(g: SettingsGuard, scene: bpy.types.Scene, path: Path) -> None:
    r = scene.render
    g.set(r, "filepath", str(path))
    g.set(r, "use_compositing", False)
    g.set(r, "use_sequencer", False)
    g.set(r, "use_border", False)
    standard_view(g, scene)
    ims = r.image_settings
    g.remember(ims, IMAGE_SETTINGS)
    g.set(ims, "media_type", "IMAGE")
    g.set(ims, "file_format", "OPEN_EXR")
    g.set(ims, "color_mode", "RGB")
    g.set(ims, "color_depth", "32")
    g.set(ims, "exr_codec", "NONE")


def render(
    scene: bpy.types.Scene,
    *,
    resolution: tuple[int, int],
    camera: bpy.types.Object | None = None,
    samples: int | None = None,
    engine: str = "BLENDER_EEVEE",
    configure: Callable[[SettingsGuard], Any] | None = None,
) -> EeveeImage:
    """Renders ``scene`` from ``camera`` (default: the scene camera) with ``engine`` to a float
    image. ``samples``: EEVEE's render samples (default: the scene's); ``configure`` may change
    further settings through the guard (they are restored with the others)."""
    camera = camera if camera is not None else scene.camera
    if camera is None or camera.type != "CAMERA":
        raise AddonError("the render needs a camera object")
    with tempfile.TemporaryDirectory(prefix="vplace-eevee-") as tmp:
        path = Path(tmp) / "render.exr"
        with override() as g:
            r = scene.render
            g.set(scene, "camera", camera)
            g.set(r, "engine", engine)
            g.set(r, "resolution_x", resolution[0])
            g.set(r, "resolution_y", resolution[1])
            g.set(r, "resolution_percentage", 100)
            if samples is not None and engine == "BLENDER_EEVEE":
                g.set(scene.eevee, "taa_render_samples", samples)
            _configure_output(g, scene, path)
            if configure is not None:
                configure(g)
            start = time.perf_counter()
            result = bpy.ops.render.render(write_still=True, scene=scene.name)
            seconds = time.perf_counter() - start
        if "FINISHED" not in result or not path.exists():
            raise AddonError(f"the {engine} render did not finish ({result})")
        return EeveeImage(read_exr_rgb(path), seconds)
