"""Test helpers: ``vplace.View`` objects from dicts of arrays, with defaults for what a test
does not care about."""

from __future__ import annotations

from typing import Any

import numpy as np
import vplace

#: An invertible world-to-clip matrix for views whose camera the test does not use.
ANY_CAMERA = np.array(
    [[1.0, 0, 0, 0], [0, 1.0, 0, 0], [0, 0, -1.02, -0.2], [0, 0, -1.0, 0]], dtype=np.float64
)


def view(d: dict[str, Any], name: str = "view", **override: Any) -> vplace.View:
    """A View from the arrays of ``d`` (and ``override``); missing passes are zeros, a missing
    depth is 1 and a missing camera is :data:`ANY_CAMERA` at (0, 0, 10)."""
    d = {**d, **override}
    h, w = d["position"].shape[:2]
    zeros = np.zeros((h, w, 3), np.float32)
    f32 = lambda a: None if a is None else np.ascontiguousarray(a, dtype=np.float32)  # noqa: E731
    return vplace.View(
        position=f32(d["position"]),
        normal=f32(d["normal"]),
        albedo=f32(d["albedo"]),
        covered=np.ascontiguousarray(d["covered"], dtype=bool),
        depth=f32(d.get("depth", np.ones((h, w)))),
        direct=f32(d.get("direct", zeros)),
        diffuse_direct=f32(d.get("diffuse_direct", zeros)),
        diffuse_indirect=f32(d.get("diffuse_indirect")),
        indirect=f32(d.get("indirect")),
        specular=f32(d.get("specular")),
        diffuse_color=f32(d.get("diffuse_color")),
        camera_position=list(np.asarray(d.get("camera_position", [0.0, 0.0, 10.0]), float)),
        world_to_clip=np.asarray(d.get("world_to_clip", ANY_CAMERA), dtype=np.float64).tolist(),
        name=name,
    )
