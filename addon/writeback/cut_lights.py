"""The surfaces whose plane cuts a light, which EEVEE darkens (``docs/EEVEE_NOTES.md``, Q11).

EEVEE traces a soft shadow with rays to points all over the light's shape. Where a surface's own
plane passes through the light (a box beside a ceiling lamp, a wall beside a lamp that pokes
past it), the rays to the part behind the plane start into the surface and count as shadowed,
on top of the part its shading already leaves out: the Cornell box's tall block gets 0.80x
Cycles' direct light in EEVEE, 1.025x with the lamp's shadow off, and every other surface 1.00x
(Blender 5.0, four shadow rays). Jitter, the shadow filter and the shadow map's resolution do
not change it. It is EEVEE's rendering of the light, not vplace's: this module finds those
surfaces, for the report's attribution (:func:`cut_pixels`), and the lamps whose light such
surfaces the cameras see hold a share of (:func:`lamps_cut_in`), for "Match EEVEE's direct
light" left to decide and for the lamp notes. The share counts: a curved surface's planes pass
through every lamp along its terminator, lit at grazing angles, where EEVEE darkens next to
nothing.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import bpy
import numpy as np
from mathutils import Matrix, Vector

from ..native import vplace
from ..scene.export import VPL_MARKER

#: A plane "cuts" a light where more than this share of the light's radius lies on each side of
#: it (a wall flush with a lamp's edge, or a lamp flush with the ceiling, does not cut it).
TOLERANCE = 0.02
#: Points on an outline: an area light's edges, a sphere light's surface.
OUTLINE_POINTS = 32


def _sphere_points(n: int) -> np.ndarray:
    """``n`` points spread over the unit sphere (a Fibonacci lattice), (n, 3)."""
    i = np.arange(n) + 0.5
    z = 1.0 - 2.0 * i / n
    r = np.sqrt(1.0 - z * z)
    phi = math.pi * (3.0 - math.sqrt(5.0)) * i
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=-1)


def light_shape(obj: bpy.types.Object) -> vplace.job.LightShape | None:
    """The emitting shape of the light ``obj`` in world space: an AREA light's outline facing
    its local -Z, a POINT or SPOT light of non-zero radius as a sphere; None for a sun or a
    point light of radius 0 (nothing to cut)."""
    light = obj.data
    m = obj.matrix_world
    centre = np.asarray(m.translation, dtype=np.float64)
    if light.type == "AREA":
        sx = light.size / 2.0
        sy = (light.size_y if light.shape in ("RECTANGLE", "ELLIPSE") else light.size) / 2.0
        t = np.linspace(0.0, 2.0 * math.pi, OUTLINE_POINTS, endpoint=False)
        if light.shape in ("DISK", "ELLIPSE"):
            local = np.stack([sx * np.cos(t), sy * np.sin(t), np.zeros_like(t)], axis=-1)
        else:  # the square's edges, walked at even steps of the angle
            c, s = np.cos(t), np.sin(t)
            k = 1.0 / np.maximum(np.abs(c), np.abs(s))
            local = np.stack([sx * c * k, sy * s * k, np.zeros_like(t)], axis=-1)
        facing = np.asarray(m.to_3x3() @ Vector((0.0, 0.0, -1.0)), dtype=np.float64)
        norm = np.linalg.norm(facing)
        if norm <= 0.0 or max(sx, sy) <= 0.0:
            return None
        return vplace.job.LightShape(_world(m, local), centre, facing / norm)
    if light.type in ("POINT", "SPOT") and light.shadow_soft_size > 0.0:
        local = light.shadow_soft_size * _sphere_points(OUTLINE_POINTS)
        return vplace.job.LightShape(centre + local @ _scale(m).T, centre, None)
    return None


def _scale(m: Matrix) -> np.ndarray:
    """``m``'s uniform scale as a 3x3 matrix (a sphere light's radius ignores rotation)."""
    return np.eye(3) * float(np.cbrt(abs(np.linalg.det(np.asarray(m.to_3x3())))))


def _world(m: Matrix, local: np.ndarray) -> np.ndarray:
    a = np.asarray(m, dtype=np.float64)
    return local @ a[:3, :3].T + a[:3, 3]


def scene_lights(scene: bpy.types.Scene, *, users_only: bool) -> list[bpy.types.Object]:
    """The render-visible lights of ``scene`` that cast shadows in EEVEE (none where the scene's
    shadows are off): the user's, and with ``users_only`` False also vplace's stand-ins (the
    VPLs themselves are left out: their light is attribution part (b))."""
    if not scene.eevee.use_shadows:
        return []
    out = []
    for obj in scene.objects:
        if obj.type != "LIGHT" or obj.hide_render or not obj.data.use_shadow:
            continue
        if obj.get("vplace_index") is not None:
            continue
        if users_only and obj.get(VPL_MARKER, False):
            continue
        out.append(obj)
    return out


def cut_pixels(
    scene: bpy.types.Scene, view: vplace.View, seen: np.ndarray | None = None
) -> np.ndarray:
    """(H, W) bool: the pixels of ``view`` (its G-buffer) whose surface's plane cuts one of the
    shadowed lights of ``scene`` other than the VPLs (:func:`scene_lights`), less those of
    ``seen`` ((H, W) bool, ``vplace.job.seen_directly``: the pixels that see an emitter, whose
    error is its edges, not light on a surface)."""
    shapes = [s for o in scene_lights(scene, users_only=False) if (s := light_shape(o))]
    cut = vplace.job.cut_by_lights(
        np.asarray(view.position), np.asarray(view.normal), shapes, TOLERANCE
    )
    return cut if seen is None else cut & ~np.asarray(seen, dtype=bool)


def lamps_cut_in(
    scene: bpy.types.Scene,
    gbuffers: Iterable[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]],
) -> list[str]:
    """The user's shadowed lamps (not vplace's, :func:`scene_lights`) whose shape the planes of
    pixels of ``gbuffers`` cut where those pixels hold at least ``vplace.job.CUT_SHARE`` of one
    gbuffer's light (each: positions and normals (H, W, 3), the (H, W) mask of the pixels to
    test, a capture's surfaces, and the (H, W) luminance of their direct light): where "Match
    EEVEE's direct light" is worth its EEVEE renders when left to decide (``Job.match_eevee``
    "auto"). The direct light is every lamp's: the share is of the view's light that lies on
    surfaces cutting the lamp, what EEVEE's darkening of them can touch. Sorted by name."""
    lamps = {o.name: s for o in scene_lights(scene, users_only=True) if (s := light_shape(o))}
    found: set[str] = set()
    for position, normal, mask, light in gbuffers:
        m = np.asarray(mask, dtype=bool)
        if not m.any():
            continue
        x, n, w = np.asarray(position)[m], np.asarray(normal)[m], np.asarray(light)[m]
        for name, shape in lamps.items():
            if name not in found and (
                vplace.job.cut_share(x, n, w, shape, TOLERANCE) >= vplace.job.CUT_SHARE
            ):
                found.add(name)
    return sorted(found)
