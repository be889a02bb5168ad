"""Sky portals: AREA lights in a room's openings that carry the sky's light in, for EEVEE
(DESIGN: Write-back).

EEVEE lights a room with the world through its light probes: unoccluded, through the walls,
unless a probe volume occludes it, and then the sky reaching a room through its windows is
interpolated between probes (the sky-lit room: 0.6x Cycles' light in its sky-lit parts,
``docs/EEVEE_NOTES.md`` Q7). Cycles users know the fix as *portals*: vplace writes one AREA
rectangle in each opening through which the sky reaches the region the cameras work in, facing
in, shadowed, and lets the world light EEVEE's scene no more (``eevee_setup``: the world stays
what the camera sees through the windows, but lights nothing).

- **Where the openings are** (:func:`openings`). From each eye (the captured cameras), rays in
  :data:`DIRECTIONS` directions of a Fibonacci sphere; those that leave the scene see the sky.
  Each connected patch of them (neighbouring directions) is one opening seen from that eye; the
  rays next to the patch that do hit something hit its rim (the wall around a window, its
  reveals). The opening's plane is the rim's: the wall the rim hits lie on (their least-squares
  plane, which reveals and sills tilt, refined to the largest group of hits on one surface
  near it: ``_rim_planes``), facing out along the escaping rays; its extent is where the
  escaping rays cross that plane, widened by half a direction's spacing. Those crossings must
  lie within the rim (``_within_rim``), else the rim's least-squares plane is tried, else the
  patch is no opening. Patches of several
  eyes in one plane that overlap are one opening, a rectangle in that plane (its sides level
  and upright where the plane stands, else along the patch's longest axis). When more than
  :data:`MAX_OPEN` of all rays escape the scene is open (outdoors, a ruin): the world lights
  it directly and no portal is written.
- **Its outer plane** (:func:`_reveal_depth`, ``Opening.reveal``). The rim is the wall's inner
  face; a portal there leaves the window's reveals (the opening's sides through the wall)
  unlit, which the sky lights in Cycles, and lights the room at slants the reveals would
  shade. So the portal stands where the reveals end: rays sideways from points on the
  opening's axis, stepping out, meet the reveals until they pass the wall's outer face. The
  stand-ins' direct light rendered by Cycles against the truth's (the sky room's five views,
  192x108; with the sun's exact disc, ``stand_ins.world_sun``): RMSE 0.0474 / 0.0376 /
  0.0329 / 0.0376 / 0.0288 in the inner plane, 0.0343 / 0.0325 / 0.0277 / 0.0297 / 0.0303
  in the outer one.
- **What an opening lets in** (:func:`sky_power`). Rays from random points of the rectangle
  into the outside half-space, cosine-distributed: those that leave the scene bring the
  world's radiance (the sun's pixels left out: the sun has its own light,
  ``stand_ins.world_sun``). Their mean times ``pi`` is the irradiance the opening receives from
  the sky, ``E``; a Lambertian rectangle of area ``A`` emitting ``A E`` (Blender's AREA power
  ``P = pi A L``) lets in the same light, spread over the room as a Lambertian emitter spreads
  it (the sky's light through a window comes mostly from above: the floor gets less of it
  than Cycles gives, the ceiling more).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..native import vplace

if TYPE_CHECKING:
    from ..scene.world import WorldInfo

__all__ = ["DIRECTIONS", "MAX_OPEN", "Opening", "openings", "sky_power", "sky_radiance"]

#: Directions each eye casts to find the openings.
DIRECTIONS = 4096
#: Neighbours of a direction on the sphere (the patches' connectivity).
NEIGHBOURS = 6
#: Above this share of escaping rays the scene is open, not a room with openings.
MAX_OPEN = 0.35
#: Rim hits a patch needs for its plane.
MIN_RIM = 6
#: Escaping directions a patch needs to be an opening.
MIN_PATCH = 3
#: Two patches lie in one plane when their normals are within this angle (degrees) and their
#: planes this share of the scene's diagonal apart.
PLANE_ANGLE = 20.0
PLANE_GAP = 0.02
#: A rim surface whose normal is within this angle (degrees) of the rim's least-squares
#: plane's is the wall the opening is cut into, not a reveal (``_rim_planes``).
WALL_ANGLE = 45.0
#: A ray that hits something this share of its way beyond an opening's plane has passed
#: through the opening (the wall itself is hit on the plane).
PASS_MARGIN = 0.02
#: How far an opening's crossings may lie outside its rim's box, as a share of the box's
#: larger side (``_within_rim``).
RIM_MARGIN = 0.25
#: Depths at which :func:`_reveal_depth` probes for an opening's reveals, over its smaller side.
REVEAL_STEPS = 64
#: A lateral probe ray meets a reveal when it hits between ``1 / REVEAL_REACH`` and this
#: share of the opening's half side: the rim carried on through the wall (the opening is
#: widened by half a direction's spacing, so its reveals lie a little inside it), not a mullion
#: in the middle nor a roof's slope far off.
REVEAL_REACH = 1.25
#: The most portals written (the largest first).
MAX_PORTALS = 16
#: Rays per portal that measure the sky it lets in.
POWER_RAYS = 2048


@dataclass(frozen=True)
class Opening:
    """A rectangle through which the sky reaches the region, in world space."""

    centre: np.ndarray
    #: Unit normal, pointing out of the room.
    outward: np.ndarray
    #: Unit direction of the first side (``size`` long); the second is ``outward x tangent``.
    tangent: np.ndarray
    size: float
    size_y: float
    #: How far its reveals reach out beyond ``centre``, along ``outward`` (metres; the wall's
    #: thickness around a window, ``_reveal_depth``).
    reveal: float = 0.0

    @property
    def outer_centre(self) -> np.ndarray:
        """The centre of the opening's outer plane, where its reveals end."""
        return self.centre + self.reveal * self.outward

    @property
    def bitangent(self) -> np.ndarray:
        """Unit direction of the second side (``size_y`` long)."""
        return np.cross(self.outward, self.tangent)

    @property
    def area(self) -> float:
        """Square metres."""
        return self.size * self.size_y


@dataclass
class _Patch:
    """One eye's view of an opening: its plane and where its escaping rays cross it."""

    point: np.ndarray
    normal: np.ndarray
    crossings: np.ndarray
    pad: float


@functools.cache
def _sphere(n: int) -> tuple[np.ndarray, np.ndarray]:
    """``n`` Fibonacci directions and their :func:`_neighbours` (made once)."""
    dirs = vplace.coverage.fibonacci_sphere(n)
    return dirs, _neighbours(dirs)


def _neighbours(dirs: np.ndarray) -> np.ndarray:
    """(N, NEIGHBOURS) indices of each direction's nearest directions (itself left out), for
    ``dirs`` sorted by falling z (as ``fibonacci_sphere`` makes them). Each row is compared only
    with the directions within a band of z around it: two directions differ in z by no more
    than the chord between them, so where the band holds a row's neighbours nearer than its
    reach, none outside it is nearer (else the row is compared with every direction). Exact
    ties may come in another order than a search of every direction gives; their set is the
    same."""
    n = len(dirs)
    near = np.empty((n, NEIGHBOURS), dtype=np.int64)
    fall = -dirs[:, 2]
    reach = 4.0 * math.sqrt(4.0 * math.pi / max(n, 1))

    def nearest(rows: np.ndarray, lo: int, hi: int) -> tuple[np.ndarray, np.ndarray]:
        cos = rows @ dirs[lo:hi].T
        top = np.argpartition(-cos, NEIGHBOURS, axis=1)[:, : NEIGHBOURS + 1]
        order = np.take_along_axis(-cos, top, axis=1).argsort(axis=1)
        found = np.take_along_axis(top, order, axis=1)
        last = np.take_along_axis(cos, found[:, -1:], axis=1)
        return found + lo, np.sqrt(np.maximum(2.0 - 2.0 * last, 0.0))

    for start in range(0, n, 512):
        rows = dirs[start : start + 512]
        lo = int(np.searchsorted(fall, -(float(rows[:, 2].max()) + reach)))
        hi = int(np.searchsorted(fall, -(float(rows[:, 2].min()) - reach), side="right"))
        found, chord = nearest(rows, lo, hi) if hi - lo > NEIGHBOURS else (None, None)
        if found is None or not (chord < reach).all():
            found, _ = nearest(rows, 0, n)
        near[start : start + 512] = found[:, 1:]
    return near


def _grow(seeds: np.ndarray, mask: np.ndarray, near: np.ndarray) -> np.ndarray:
    """The directions ``mask`` marks that are connected to ``seeds`` (marked too), neighbours
    by ``near``: a boolean mask."""
    seen = np.zeros(len(mask), dtype=bool)
    seen[seeds] = True
    stack = [int(i) for i in seeds]
    while stack:
        for j in near[stack.pop()]:
            if mask[j] and not seen[j]:
                seen[j] = True
                stack.append(int(j))
    return seen


def _components(mask: np.ndarray, near: np.ndarray) -> list[np.ndarray]:
    """Connected sets of the directions ``mask`` marks, neighbours by ``near``."""
    done = np.zeros(len(mask), dtype=bool)
    out = []
    for seed in np.flatnonzero(mask):
        if not done[seed]:
            members = _grow(np.array([seed]), mask, near)
            done |= members
            out.append(np.flatnonzero(members))
    return out


def _patches(
    scene: vplace.Scene, eye: np.ndarray, dirs: np.ndarray, near: np.ndarray
) -> tuple[list[_Patch], int]:
    """The openings one eye sees, and how many of its rays escape."""
    origins = np.ascontiguousarray(np.broadcast_to(eye.astype(np.float32), dirs.shape))
    t, tri, _ = scene.intersect(origins, dirs)
    escaped = tri < 0
    spacing = math.sqrt(4.0 * math.pi / len(dirs))
    patches = []
    for members in _components(escaped, near):
        if len(members) < MIN_PATCH:
            continue
        rim = np.unique(near[members].ravel())
        rim = rim[~escaped[rim]]
        if len(rim) < MIN_RIM:
            continue
        hits = eye + dirs[rim].astype(np.float64) * t[rim, None]
        out = dirs[members].astype(np.float64)
        for point, normal in _rim_planes(scene, eye, hits, tri[rim]):
            if normal @ out.mean(axis=0) < 0.0:
                normal = -normal
            depth = float((point - eye) @ normal)
            if not (out @ normal > 1e-3).any() or depth <= 0.0:
                continue
            through = _through(members, escaped, t, dirs @ normal, depth, near)
            s = depth / (dirs[through] @ normal).astype(np.float64)
            crossings = eye + dirs[through].astype(np.float64) * s[:, None]
            if _within_rim(crossings, hits, normal):
                patches.append(_Patch(point, normal, crossings, 0.5 * spacing * float(s.mean())))
                break
    return patches, int(escaped.sum())


def _within_rim(crossings: np.ndarray, hits: np.ndarray, normal: np.ndarray) -> bool:
    """Whether an opening's ``crossings`` lie within its rim's ``hits`` (both seen along
    ``normal``, the box of the hits widened by :data:`RIM_MARGIN` of its larger side). A rim
    surrounds its opening; a plane that puts the crossings elsewhere is not the opening's (a
    window's sill, seen from below it, gave a plane at the sill's height whose crossings spread
    over the whole room: a 5.6 x 3.9 m "opening" facing up, half a metre over the floor)."""
    u, v = _basis(normal, hits)
    box = [(x.min(), x.max()) for x in (hits @ u, hits @ v)]
    pad = RIM_MARGIN * max(hi - lo for lo, hi in box)
    return all(
        x.min() >= lo - pad and x.max() <= hi + pad
        for x, (lo, hi) in zip((crossings @ u, crossings @ v), box, strict=True)
    )


def _through(
    members: np.ndarray,
    escaped: np.ndarray,
    t: np.ndarray,
    along: np.ndarray,
    depth: float,
    near: np.ndarray,
) -> np.ndarray:
    """The directions that pass through the opening the escaping ``members`` see: connected to
    them, crossing its plane (``depth`` away along its normal; ``along``: each direction's
    cosine to it) before they hit anything. Seen at a slant, a window's far reveal hides part
    of the sky, but the rays it stops have passed through the opening (the escaping rays alone
    gave 0.86 x 1.19 m of a 1.4 x 1.3 m window seen at a slant, in a room built to test it)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where(along > 1e-3, depth / along, np.inf)
    passed = escaped | (np.isfinite(s) & (t > s * (1.0 + PASS_MARGIN)))
    return np.flatnonzero(_grow(members, passed, near) & np.isfinite(s))


def _rim_planes(
    scene: vplace.Scene, eye: np.ndarray, hits: np.ndarray, tri: np.ndarray
) -> list[tuple[np.ndarray, np.ndarray]]:
    """The planes an opening's rim may lie in, best first, each a point on it and its unit
    normal: the wall's plane (below), then the least-squares plane of the rim's ``hits``
    (``_patches`` takes the first its opening lies within). The least-squares
    plane of the rim's ``hits`` is tilted by the reveals and the sill that the eye sees on some
    sides only (30 degrees by a sill seen from a far corner); the surface the opening is cut
    into is the largest group of hits whose triangles' normals lie within :data:`PLANE_ANGLE`
    of each other and within :data:`WALL_ANGLE` of that plane's (a reveal stands at 90
    degrees to its wall), and of those the ones at one depth. Without three such hits (a
    courtyard's rim is its walls), the least-squares plane alone."""
    point = hits.mean(axis=0)
    fitted = np.linalg.svd(hits - point, full_matrices=False)[2][-1]
    zeros = np.zeros((len(tri), 2), dtype=np.float32)
    normals = scene.normal_at(tri.astype(np.uint32), zeros).astype(np.float64)
    wall = np.abs(normals @ fitted) >= math.cos(math.radians(WALL_ANGLE))
    # One side of the fitted plane: a wall is one plane whichever way its triangles wind.
    normals *= np.where(normals @ fitted < 0.0, -1.0, 1.0)[:, None]
    near = normals @ normals.T >= math.cos(math.radians(PLANE_ANGLE))
    near &= wall[:, None] & wall[None, :]
    group = near[int(np.argmax(near.sum(axis=1)))]
    if group.sum() >= 3:
        # Of those, the ones in one plane (a cabinet's front beside a window faces the same
        # way): within PASS_MARGIN of the eye's distance of the median depth.
        normal = normals[group].mean(axis=0)
        normal /= np.linalg.norm(normal)
        depth = hits @ normal
        tol = PASS_MARGIN * float(np.median(np.linalg.norm(hits - eye, axis=1)))
        group &= np.abs(depth - np.median(depth[group])) <= tol
    if group.sum() < 3:
        return [(point, fitted)]
    normal = normals[group].mean(axis=0)
    return [(hits[group].mean(axis=0), normal / np.linalg.norm(normal)), (point, fitted)]


def _basis(normal: np.ndarray, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """In-plane axes of an opening: level and upright where the plane stands, else along the
    points' longest spread."""
    up = np.array([0.0, 0.0, 1.0])
    if abs(normal @ up) < 0.7:
        u = np.cross(up, normal)
    else:
        flat = points - points.mean(axis=0)
        flat -= np.outer(flat @ normal, normal)
        u = np.linalg.svd(flat, full_matrices=False)[2][0] if len(points) > 1 else up
        u = u - (u @ normal) * normal
    u /= np.linalg.norm(u)
    return u, np.cross(normal, u)


def _same_plane(a: _Patch, b: _Patch, gap: float) -> bool:
    if a.normal @ b.normal < math.cos(math.radians(PLANE_ANGLE)):
        return False
    if abs((b.point - a.point) @ a.normal) > gap:
        return False
    u, v = _basis(a.normal, a.crossings)
    boxes = []
    for p in (a, b):
        x, y = p.crossings @ u, p.crossings @ v
        boxes.append((x.min() - p.pad, x.max() + p.pad, y.min() - p.pad, y.max() + p.pad))
    (a0, a1, a2, a3), (b0, b1, b2, b3) = boxes
    return a0 <= b1 and b0 <= a1 and a2 <= b3 and b2 <= a3


def _reveal_depth(scene: vplace.Scene, o: Opening) -> float:
    """How far the opening's reveals reach out from its plane (the wall's thickness around a
    window; 0 where nothing surrounds the opening beyond its plane, a roof left open). From
    points on its axis at :data:`REVEAL_STEPS` depths up to its smaller side, rays along both
    of its sides' directions: a depth is within the reveals while at least two of the four
    hit at the half side's distance (within a factor :data:`REVEAL_REACH`); the reveals end
    at the first depth where they do not."""
    limit = min(o.size, o.size_y)
    step = limit / REVEAL_STEPS
    depths = step * (np.arange(REVEAL_STEPS) + 0.5)
    sides = np.array([o.tangent, -o.tangent, o.bitangent, -o.bitangent], dtype=np.float64)
    starts = o.centre + depths[:, None] * o.outward
    origins = np.repeat(starts, 4, axis=0)
    dirs = np.tile(sides, (REVEAL_STEPS, 1))
    t, tri, _ = scene.intersect(
        np.ascontiguousarray(origins, dtype=np.float32),
        np.ascontiguousarray(dirs, dtype=np.float32),
    )
    half = np.tile(0.5 * np.array([o.size, o.size, o.size_y, o.size_y]), REVEAL_STEPS)
    met = (tri >= 0) & (t <= REVEAL_REACH * half) & (t >= half / REVEAL_REACH)
    met = met.reshape(REVEAL_STEPS, 4)
    inside = met.sum(axis=1) >= 2
    outside = np.flatnonzero(~inside)
    return float(depths[outside[0]] - 0.5 * step) if len(outside) else limit


def openings(scene: vplace.Scene, eyes: Sequence[Sequence[float]]) -> tuple[list[Opening], float]:
    """The openings through which the sky reaches the eyes' surroundings (module docs), largest
    first, and the share of the eyes' rays that escape the scene. None when the scene is open
    (more than :data:`MAX_OPEN` escape) or closed."""
    dirs, near = _sphere(DIRECTIONS)
    patches: list[_Patch] = []
    escaped = 0
    for eye in eyes:
        found, n = _patches(scene, np.asarray(eye, dtype=np.float64), dirs, near)
        patches += found
        escaped += n
    share = escaped / max(1, len(eyes) * len(dirs))
    if share > MAX_OPEN or not patches:
        return [], share
    gap = PLANE_GAP * scene.scale
    group = list(range(len(patches)))

    def root(i: int) -> int:
        while group[i] != i:
            group[i] = group[group[i]]
            i = group[i]
        return i

    for i in range(len(patches)):
        for j in range(i + 1, len(patches)):
            if root(i) != root(j) and _same_plane(patches[i], patches[j], gap):
                group[root(j)] = root(i)
    found: list[Opening] = []
    for r in sorted({root(i) for i in range(len(patches))}):
        members = [p for i, p in enumerate(patches) if root(i) == r]
        weights = np.array([len(p.crossings) for p in members], dtype=np.float64)
        normal = sum(w * p.normal for w, p in zip(weights, members, strict=True))
        normal /= np.linalg.norm(normal)
        point = sum(w * p.point for w, p in zip(weights, members, strict=True)) / weights.sum()
        pts = np.concatenate([p.crossings for p in members])
        pts = pts - np.outer((pts - point) @ normal, normal)
        pad = float(np.mean([p.pad for p in members]))
        u, v = _basis(normal, pts)
        x, y = pts @ u, pts @ v
        x0, x1, y0, y1 = x.min() - pad, x.max() + pad, y.min() - pad, y.max() + pad
        centre = point - ((point @ u) - 0.5 * (x0 + x1)) * u - ((point @ v) - 0.5 * (y0 + y1)) * v
        o = Opening(centre, normal, u, float(x1 - x0), float(y1 - y0))
        found.append(dataclasses.replace(o, reveal=_reveal_depth(scene, o)))
    found.sort(key=lambda o: -o.area)
    return found[:MAX_PORTALS], share


def sky_radiance(
    info: WorldInfo, without: np.ndarray | None = None
) -> Callable[[np.ndarray], np.ndarray]:
    """The world's radiance in world directions, ``(N, 3) -> (N, 3)``; the pixels of its image
    that ``without`` marks (the sun's) give none."""
    color = np.asarray(info.color, dtype=np.float64)
    if info.image is None:
        return lambda d: np.broadcast_to(color, (len(d), 3))
    img = info.image.astype(np.float64) * color
    if without is not None and without.any():
        img[without] = 0.0
    h, w = img.shape[:2]
    rot = None if info.rotation is None else np.asarray(info.rotation, dtype=np.float64)

    def radiance(d: np.ndarray) -> np.ndarray:
        d = d if rot is None else d @ rot.T
        theta = np.arccos(np.clip(d[:, 2], -1.0, 1.0))
        phi = np.arctan2(d[:, 1], d[:, 0])
        i = np.clip((theta / math.pi * h).astype(np.int64), 0, h - 1)
        j = np.floor((0.5 - phi / (2.0 * math.pi)) * w).astype(np.int64) % w
        return img[i, j]

    return radiance


def sky_power(
    scene: vplace.Scene,
    radiance: Callable[[np.ndarray], np.ndarray],
    o: Opening,
    rng: np.random.Generator,
) -> tuple[np.ndarray, np.ndarray]:
    """The power (W per channel) the sky sends in through opening ``o``: ``pi`` times the mean
    ``radiance`` of :data:`POWER_RAYS` cosine-distributed rays from random points of the opening
    that leave the scene, times its area (module docs); and the unit mean direction of that
    light as it enters (weighted by luminance; ``-outward`` where none enters)."""
    u = rng.random((POWER_RAYS, 4))
    r, a = np.sqrt(u[:, 0]), 2.0 * math.pi * u[:, 1]
    t, b = o.tangent, o.bitangent
    dirs = (
        (r * np.cos(a))[:, None] * t
        + (r * np.sin(a))[:, None] * b
        + np.sqrt(1.0 - u[:, 0])[:, None] * o.outward
    )
    starts = (
        o.centre
        + ((u[:, 2] - 0.5) * o.size)[:, None] * t
        + ((u[:, 3] - 0.5) * o.size_y)[:, None] * b
    )
    _, tri, _ = scene.intersect(
        np.ascontiguousarray(starts, dtype=np.float32), np.ascontiguousarray(dirs, dtype=np.float32)
    )
    sky = radiance(dirs) * (tri < 0)[:, None]
    weight = sky @ np.asarray(vplace.LUMINANCE, dtype=np.float64)
    mean = -(weight[:, None] * dirs).sum(axis=0)
    norm = float(np.linalg.norm(mean))
    heading = mean / norm if norm > 0.0 else -o.outward
    return math.pi * sky.mean(axis=0) * o.area, heading
