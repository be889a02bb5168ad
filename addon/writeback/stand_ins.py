"""Lights that stand in for emissive meshes in EEVEE (DESIGN: Write-back).

Cycles lights a scene with every emissive surface; EEVEE does not: an emissive mesh shows on
screen, but lights other surfaces only through its ray tracing (what is on screen) and baked
light probes. The evaluator's image takes its direct light from Cycles' capture, so without
help EEVEE with vplace's lights misses a room's panel and screen light altogether (the report's
"EEVEE" rows on ``panelroom``). The write-back therefore adds, beside the VPLs and in their
collection, one AREA light per side of each emissive polygon of the exported scene:

- two triangles that make a rectangle (a quad's two halves, as Blender triangulates it) become
  one RECTANGLE light of the same centre, sides and orientation, exactly the emitter: an AREA
  light of power ``P`` is a Lambertian emitter of radiance ``P / (pi A)``, so ``P = pi A L``
  per channel, as the Cornell box's ceiling light was converted;
- any other triangle becomes a DISK of the same area at its centroid (the far field is the
  same; within about its size of the emitter the light is spread differently);
- both sides, as Cycles' emission shader emits from both; a side whose light cannot leave (a
  panel's back inside its fixture: every one of a few probe rays hits something within the
  emitter's own size) is left out, as it would only cost EEVEE a shadow map;
- at most :data:`MAX_EMITTER_LIGHTS`: when a scene has more emissive polygons, that many are
  drawn by power and each carries ``1 / count`` of the total power in expectation (a large
  emissive mesh becomes a power-sampled set of disks, like the core's emitter sampling).

The lights are shadowed with EEVEE's default shadow resolution (they are direct light, whose
shadows the user sees) and have specular factor 1 (Cycles' emitters give glossy direct light).
An emitter's texture is read as its material's constant emission (the export's rule).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from ..native import vplace
from . import portals

if TYPE_CHECKING:
    from ..scene.export import ExportedScene
    from ..scene.world import WorldInfo

__all__ = ["MAX_EMITTER_LIGHTS", "EmitterLight", "emitter_lights"]

#: The most emitter lights written (sides counted): more are drawn by power.
MAX_EMITTER_LIGHTS = 64
#: Probe rays per side that decide whether its light can leave.
PROBE_RAYS = 8
#: Relative tolerance of the rectangle test (right angle, parallelogram, coplanar).
RECT_TOLERANCE = 1e-4


@dataclass(frozen=True)
class EmitterLight:
    """One side of an emissive polygon as a Blender AREA light."""

    #: Centre, unit emission direction, unit first side direction (world).
    position: tuple[float, float, float]
    normal: tuple[float, float, float]
    tangent: tuple[float, float, float]
    #: "RECTANGLE" (``size`` x ``size_y``) or "DISK" (diameter ``size``).
    shape: str
    size: float
    size_y: float
    #: Power per channel (W): ``pi * area * radiance``.
    power: tuple[float, float, float]
    #: The emissive material's name, or the portal's.
    material: str
    #: A sky portal (``portals``): the world's light through an opening, not an emissive mesh.
    portal: bool = False


class _Shape(NamedTuple):
    """One emissive polygon as the AREA light shape that stands in for it."""

    centre: np.ndarray
    normal: np.ndarray
    tangent: np.ndarray
    shape: str  # "RECTANGLE" or "DISK"
    size: float
    size_y: float
    area: float
    material: int


def _rectangle(pts: np.ndarray, normal: np.ndarray, material: int) -> _Shape | None:
    """The RECTANGLE of the 4 points ``pts`` when they are one, flat across ``normal``."""
    p0 = pts[0]
    far = int(np.argmax(((pts - p0) ** 2).sum(axis=1)))
    rest = [i for i in range(1, 4) if i != far]
    a, b = pts[rest[0]] - p0, pts[rest[1]] - p0
    la, lb = float(np.linalg.norm(a)), float(np.linalg.norm(b))
    if la <= 0.0 or lb <= 0.0:
        return None
    scale = max(la, lb)
    if abs(float(a @ b)) > RECT_TOLERANCE * scale * scale:
        return None
    if float(np.linalg.norm(p0 + a + b - pts[far])) > RECT_TOLERANCE * scale:
        return None
    flat = float(np.abs((pts - p0) @ normal).max())
    if flat > RECT_TOLERANCE * max(float(np.ptp(pts, axis=0).max()), 1e-30):
        return None
    return _Shape(p0 + 0.5 * (a + b), normal, a / la, "RECTANGLE", la, lb, la * lb, material)


def _shapes(exported: ExportedScene, emissive: np.ndarray) -> list[_Shape]:
    """The light shape of each emissive polygon: consecutive triangle pairs that form a
    rectangle are merged, any other triangle is a disk of its area."""
    v, tris, mats = exported.vertices, exported.triangles, exported.material_ids
    out: list[_Shape] = []
    i, n = 0, len(emissive)
    while i < n:
        t = int(emissive[i])
        corners = v[tris[t]].astype(np.float64)
        e1, e2 = corners[1] - corners[0], corners[2] - corners[0]
        cross = np.cross(e1, e2)
        area = 0.5 * float(np.linalg.norm(cross))
        if area <= 0.0:
            i += 1
            continue
        normal = cross / (2.0 * area)
        if i + 1 < n and int(emissive[i + 1]) == t + 1 and mats[t + 1] == mats[t]:
            both = v[np.concatenate([tris[t], tris[t + 1]])].astype(np.float64)
            pts = np.unique(np.round(both, 7), axis=0)
            rect = _rectangle(pts, normal, int(mats[t])) if len(pts) == 4 else None
            if rect is not None:
                out.append(rect)
                i += 2
                continue
        tangent = e1 / max(float(np.linalg.norm(e1)), 1e-30)
        diameter = 2.0 * np.sqrt(area / np.pi)
        out.append(
            _Shape(
                corners.mean(axis=0),
                normal,
                tangent,
                "DISK",
                diameter,
                diameter,
                area,
                int(mats[t]),
            )
        )
        i += 1
    return out


def _cosine_local(u: np.ndarray) -> np.ndarray:
    """(M, 3) cosine-distributed unit directions about +z from (M, 2) uniform numbers."""
    r, phi = np.sqrt(u[:, 0]), 2.0 * np.pi * u[:, 1]
    return np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(1.0 - u[:, 0])], axis=1)


def _tangents(normals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit tangents of each unit normal of ``normals`` (N, 3), a right-handed frame with it."""
    helper = np.where(np.abs(normals[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    tx = np.cross(normals, helper)
    tx /= np.maximum(np.linalg.norm(tx, axis=1, keepdims=True), 1e-12)
    return tx, np.cross(normals, tx)


def _open_sides(
    scene: vplace.Scene, centres: np.ndarray, normals: np.ndarray, reach: np.ndarray, offset: float
) -> np.ndarray:
    """True for each (centre, normal) side whose light can leave: some probe ray gets farther
    than ``reach`` (the emitter's size)."""
    rng = np.random.default_rng(0)
    k = len(centres)
    local = _cosine_local(rng.random((PROBE_RAYS, 2)))
    tx, ty = _tangents(normals)
    dirs = (
        local[None, :, 0:1] * tx[:, None]
        + local[None, :, 1:2] * ty[:, None]
        + local[None, :, 2:3] * normals[:, None]
    ).reshape(-1, 3)
    origins = np.repeat(centres + offset * normals, PROBE_RAYS, axis=0)
    t, _, _ = scene.intersect(
        np.ascontiguousarray(origins, dtype=np.float32),
        np.ascontiguousarray(dirs, dtype=np.float32),
    )
    far = (t.reshape(k, PROBE_RAYS) > reach[:, None]).any(axis=1)
    return far


def emitter_lights(
    exported: ExportedScene, scene: vplace.Scene, *, seed: int = 0
) -> list[EmitterLight]:
    """The AREA lights that stand in for the emissive polygons of ``exported`` (module docs);
    ``scene`` is its native scene (for the probe rays)."""
    emission = exported.emission
    if len(emission) == 0 or not (emission.max(axis=1) > 0.0).any():
        return []
    emits = emission.max(axis=1) > 0.0
    emissive = np.flatnonzero(emits[exported.material_ids])
    shapes = _shapes(exported, emissive)
    if not shapes:
        return []
    centres = np.array([s.centre for s in shapes])
    normals = np.array([s.normal for s in shapes])
    sizes = np.array([max(s.size, s.size_y) for s in shapes])
    offset = 1e-3 * scene.scale
    sides = []
    for sign in (1.0, -1.0):
        open_ = _open_sides(scene, centres, sign * normals, sizes, 1e-2 * offset)
        sides += [(k, sign) for k in np.flatnonzero(open_)]
    lum = np.asarray(vplace.LUMINANCE, dtype=np.float64)
    power = np.array(
        [np.pi * shapes[k].area * emission[shapes[k].material].astype(np.float64) for k, _ in sides]
    ).reshape(-1, 3)
    chosen = np.arange(len(sides))
    scale = np.ones(len(sides))
    if len(sides) > MAX_EMITTER_LIGHTS:
        weight = np.maximum(power @ lum, 0.0)
        p = weight / weight.sum()
        draws = np.random.default_rng(seed).choice(len(sides), MAX_EMITTER_LIGHTS, p=p)
        chosen, counts = np.unique(draws, return_counts=True)
        scale = np.zeros(len(sides))
        scale[chosen] = counts / (MAX_EMITTER_LIGHTS * p[chosen])
    out = []
    for j in chosen:
        k, sign = sides[j]
        sh = shapes[k]
        n = sign * sh.normal
        out.append(
            EmitterLight(
                tuple(float(x) for x in sh.centre + offset * n),
                tuple(float(x) for x in n),
                tuple(float(x) for x in sh.tangent),
                sh.shape,
                float(sh.size),
                float(sh.size_y),
                tuple(float(x) for x in power[j] * scale[j]),
                exported.materials[sh.material].name,
            )
        )
    return out


#: A world's sun: the pixels within :data:`SUN_CONE` (radians) of the world's brightest
#: direction that are brighter than :data:`SUN_CONTRAST` times the brightest radiance outside
#: that cone; a world whose brightest pixel is not that bright has no sun.
SUN_CONE = math.radians(10.0)
SUN_CONTRAST = 20.0
#: The sun is written only when it lights at least this fraction of the covered pixels of some
#: captured view: a SUN light whose light cannot reach what the views see adds nothing but
#: EEVEE's shadow leaks (a closed room the sun cannot enter, ``/work/runs/userblend`` studio:
#: 2 % of the unshadowed sun leaked at the walls' joints, twice the room's direct light).
SUN_MIN_LIT = 1e-3
#: Pixels tested per view (evenly strided).
SUN_TEST_PIXELS = 20000


@dataclass(frozen=True)
class SunLight:
    """A world's sun as a Blender SUN light."""

    #: Unit direction toward the sun (world).
    direction: tuple[float, float, float]
    #: Irradiance per channel on a surface facing it (W/m^2, Blender's sun strength).
    irradiance: tuple[float, float, float]
    #: The sun's apparent diameter (radians).
    angle: float


class _WorldImage(NamedTuple):
    """A world image's radiance (RGB, colour applied), its pixels' world directions and the
    mask of its sun's pixels (all False without a sun)."""

    radiance: np.ndarray
    dirs: np.ndarray
    sun: np.ndarray


def _world_image(info: WorldInfo) -> _WorldImage | None:
    """The world image of ``info`` with its sun found (module docs of ``world_sun``'s
    constants); None without an image."""
    if info.image is None:
        return None
    img = info.image.astype(np.float64) * np.asarray(info.color, dtype=np.float64)
    h, w = img.shape[:2]
    theta = (np.arange(h) + 0.5) / h * np.pi
    phi = (0.5 - (np.arange(w) + 0.5) / w) * 2.0 * np.pi
    st = np.sin(theta)[:, None]
    dirs = np.stack(
        [st * np.cos(phi)[None, :], st * np.sin(phi)[None, :], np.cos(theta)[:, None] + 0 * phi],
        axis=-1,
    )
    if info.rotation is not None:  # image directions back to world directions
        dirs = dirs @ np.asarray(info.rotation, dtype=np.float64)
    lum = img @ np.asarray(vplace.LUMINANCE, dtype=np.float64)
    top = np.unravel_index(int(np.argmax(lum)), lum.shape)
    none = np.zeros(lum.shape, dtype=bool)
    if lum[top] <= 0.0:
        return _WorldImage(img, dirs, none)
    cos_cone = math.cos(SUN_CONE)
    near = dirs @ dirs[top] >= cos_cone
    rest = float(lum[~near].max()) if (~near).any() else 0.0
    sun = near & (lum > SUN_CONTRAST * rest)
    return _WorldImage(img, dirs, sun if sun[top] else none)


def sun_pixels(info: WorldInfo) -> np.ndarray:
    """(H, W) bool: the pixels of the world image of ``info`` that are its sun (none without
    one, or without an image: an empty mask)."""
    found = _world_image(info)
    return found.sun if found is not None else np.zeros((0, 0), dtype=bool)


def world_sun(info: WorldInfo | None) -> SunLight | None:
    """The sun of a world image (module docs of ``world_sun``'s constants), or None."""
    if info is None or not info.emits:
        return None
    found = _world_image(info)
    if found is None or not found.sun.any():
        return None
    img, dirs, sun = found
    lum = img @ np.asarray(vplace.LUMINANCE, dtype=np.float64)
    h, w = img.shape[:2]
    st = np.sin((np.arange(h) + 0.5) / h * np.pi)[:, None]
    d_omega = (2.0 * np.pi / w) * (np.pi / h) * np.broadcast_to(st, (h, w))
    weight = (lum * d_omega)[sun]
    direction = (dirs[sun] * weight[:, None]).sum(axis=0)
    direction /= np.linalg.norm(direction)
    irradiance = (img[sun] * d_omega[sun][:, None]).sum(axis=0)
    spread = float(np.arccos(np.clip(dirs[sun] @ direction, -1.0, 1.0)).max())
    angle = 2.0 * (spread + 0.5 * np.pi / h)
    for disc, diameter in info.suns:
        # A Sky Texture's disc among these pixels: its own direction and size. The pixels'
        # spread is the bake's, up to 3.5x the disc (the sky room's: 1.92 degrees against
        # 0.545), and EEVEE's shadows would blur the sun's patches by as much.
        exact = np.asarray(disc, dtype=np.float64)
        if exact @ direction >= math.cos(spread + np.pi / h):
            direction, angle = exact / np.linalg.norm(exact), diameter
            break
    return SunLight(
        tuple(float(x) for x in direction), tuple(float(x) for x in irradiance), float(angle)
    )


def sun_lit_fraction(
    scene: vplace.Scene,
    position: np.ndarray,
    normal: np.ndarray,
    covered: np.ndarray,
    sun: SunLight,
) -> float:
    """The fraction of a view's covered pixels (G-buffer ``position``, ``normal``) that face
    ``sun`` and see it unoccluded (tested on at most :data:`SUN_TEST_PIXELS` of them)."""
    ys, xs = np.nonzero(covered)
    if len(ys) == 0:
        return 0.0
    step = max(1, len(ys) // SUN_TEST_PIXELS)
    ys, xs = ys[::step], xs[::step]
    d = np.asarray(sun.direction, dtype=np.float32)
    n = normal[ys, xs].astype(np.float32)
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    facing = n @ d > 0.0
    if not facing.any():
        return 0.0
    eps = np.float32(1e-4 * scene.scale)
    origins = position[ys, xs][facing].astype(np.float32) + eps * n[facing]
    targets = origins + np.float32(2.0 * scene.diagonal) * d
    blocked = scene.occluded(np.ascontiguousarray(origins), np.ascontiguousarray(targets))
    return float((~blocked).sum()) / len(ys)


#: Glass surfaces a ray passes through before :func:`sky_seen` gives up on it.
GLASS_PASSES = 4
#: Rays from the captured views' surfaces that :func:`sky_seen` casts, all views together.
SKY_SURFACE_RAYS = 4096


def _escapes(
    scene: vplace.Scene,
    transmits: np.ndarray,
    material_ids: np.ndarray,
    o: np.ndarray,
    d: np.ndarray,
) -> bool:
    """Whether one of the rays ``o + t d`` leaves the scene, passing through at most
    :data:`GLASS_PASSES` surfaces that let light through (``transmits``, per material)."""
    step = np.float32(1e-4 * scene.scale)
    for _ in range(GLASS_PASSES + 1):
        if len(o) == 0:
            return False
        t, tri, _bary = scene.intersect(np.ascontiguousarray(o), np.ascontiguousarray(d))
        missed = ~np.isfinite(t)
        if missed.any():
            return True
        glass = transmits[material_ids[np.maximum(tri, 0)]]
        o = (o + d * (t[:, None] + step))[glass].astype(np.float32)
        d = d[glass]
    return False


def sky_seen(
    scene: vplace.Scene,
    exported: ExportedScene,
    surfaces: Sequence[tuple[np.ndarray, np.ndarray, np.ndarray]],
    eyes: Sequence[Sequence[float]],
) -> bool:
    """Whether the world reaches what the cameras work in: a ray leaves the scene, past at most
    :data:`GLASS_PASSES` surfaces that let light through (``MaterialInfo.transmits``: a glass
    window), from one of ``eyes`` (the directions of ``portals.openings``) or from the captured
    views' surfaces (``surfaces``: position, normal, covered; :data:`SKY_SURFACE_RAYS` cosine
    directions about the normal from random covered pixels, so that a window round a corner,
    which no eye sees but a wall the camera sees does, counts). Where none does, the world lights
    no surface a view sees directly, in Cycles, and its bounce off what it lights elsewhere is
    the light paths' VPLs (the world is one of their emitters): the room is closed."""
    transmits = np.array([m.transmits for m in exported.materials], dtype=bool)
    ids = exported.material_ids
    directions = vplace.coverage.fibonacci_sphere(portals.DIRECTIONS).astype(np.float32)
    for eye in eyes:
        o = np.repeat(np.asarray(eye, dtype=np.float32)[None], len(directions), axis=0)
        if _escapes(scene, transmits, ids, o, directions):
            return True
    rng = np.random.default_rng([0, 47])
    per_view = SKY_SURFACE_RAYS // max(len(surfaces), 1)
    eps = np.float32(1e-4 * scene.scale)
    for position, normal, covered in surfaces:
        ys, xs = np.nonzero(covered)
        if len(ys) == 0:
            continue
        pick = rng.integers(0, len(ys), per_view)
        p = position[ys[pick], xs[pick]].astype(np.float32)
        n = normal[ys[pick], xs[pick]].astype(np.float32)
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
        local = _cosine_local(rng.random((per_view, 2)))
        tx, ty = _tangents(n)
        d = local[:, 0:1] * tx + local[:, 1:2] * ty + local[:, 2:3] * n
        if _escapes(scene, transmits, ids, p + eps * n, d.astype(np.float32)):
            return True
    return False


@dataclass(frozen=True)
class StandIns:
    """The lights that stand in for what EEVEE does not light with: the emissive meshes and the
    sky portals (``emitters``; ``portals``), and the world's sun when it lights some of what the
    captured views see (``SUN_MIN_LIT``)."""

    emitters: list[EmitterLight]
    sun: SunLight | None
    #: The share of the eyes' rays that leave the scene (``portals.openings``).
    open_share: float = 0.0
    #: The world emits, but no ray from the eyes or the captured surfaces leaves the scene, not
    #: even through glass (:func:`sky_seen`): a closed room, whose surfaces the world does not
    #: light directly in Cycles. EEVEE's world must then light nothing
    #: (``eevee_setup.world_shut_out``), as with sky portals: EEVEE lights with the world
    #: through walls, and a probe volume does not stop it where the walls are single faces (a
    #: closed box room of my own: EEVEE's world light inside was 0.55x Cycles' whole direct
    #: light with vplace's volume baked, 0.83x without).
    closed: bool = False

    @property
    def portals(self) -> list[EmitterLight]:
        """The sky portals among :attr:`emitters`."""
        return [e for e in self.emitters if e.portal]

    @property
    def world_shut_out(self) -> bool:
        """Whether EEVEE's world must light nothing with these lights: the portals carry the
        sky's light in, or the room is :attr:`closed` (as ``eevee_setup.world_shut_out`` reads
        it from the written lights)."""
        return bool(self.portals) or self.closed


def stand_ins(
    exported: ExportedScene,
    scene: vplace.Scene,
    surfaces: Sequence[tuple[np.ndarray, np.ndarray, np.ndarray]],
    eyes: Sequence[Sequence[float]] = (),
) -> StandIns:
    """The stand-in lights of ``exported``; ``surfaces`` are the captured views' (position,
    normal, covered) arrays, which the sun must light somewhere; ``eyes`` the captured cameras'
    positions, from which the sky portals are found (none without eyes, or when the world
    sends no light)."""
    sun = world_sun(exported.world)
    if sun is not None:
        lit = max(sun_lit_fraction(scene, p, n, c, sun) for p, n, c in surfaces)
        sun = sun if lit >= SUN_MIN_LIT else None
    lights = emitter_lights(exported, scene)
    share, closed = 0.0, False
    world = exported.world
    if eyes and world is not None and world.emits:
        found, share = portals.openings(scene, eyes)
        closed = share == 0.0 and not sky_seen(scene, exported, surfaces, eyes)
        # The sun's pixels have their own light (the sun's stand-in, or none where the sun
        # reaches nothing the views see): the portals carry the rest of the sky.
        radiance = portals.sky_radiance(world, sun_pixels(world))
        rng = np.random.default_rng([0, 31])
        for k, o in enumerate(found):
            # In the opening's outer plane, where its reveals end (``portals``' module docs).
            o = dataclasses.replace(o, centre=o.outer_centre, reveal=0.0)
            power, heading = portals.sky_power(scene, radiance, o, rng)
            if power.max() > 0.0:
                # Facing the way the sky's light enters (downward through a window).
                tangent = o.tangent - (o.tangent @ heading) * heading
                lights.append(
                    EmitterLight(
                        tuple(float(c) for c in o.centre),
                        tuple(float(c) for c in heading),
                        tuple(float(c) for c in tangent / np.linalg.norm(tangent)),
                        "RECTANGLE",
                        o.size,
                        o.size_y,
                        tuple(float(c) for c in power),
                        f"sky portal {k + 1}",
                        portal=True,
                    )
                )
    return StandIns(lights, sun, share, closed)
