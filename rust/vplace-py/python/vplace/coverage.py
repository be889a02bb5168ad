"""Coverage views: what a camera in the user's region can see, as views made without Blender.

A layout fitted to the pixels of one camera serves those pixels: surfaces no capture saw get
their VPLs from few, heavy off-screen draws, and a refit trades them away for the seen pixels
(issue 20: from a second camera, bright splotches where the first saw nothing). So a job adds
*coverage views*, chosen here, and lays out for all of them:

- **Region.** Around each user camera ``c`` (where it stands, :func:`camera_eye`: past its
  clip start where that passes a wall), a ball of radius ``r`` (the user's, or
  :data:`REGION_FRACTION` times the median distance rays from ``c`` travel before they hit a
  surface: the room the camera stands in, whatever the scene's units).
- **Candidates.** A cube of :data:`FACES` 90-degree views at ``c`` and at the points
  ``c + r u`` of the region (``u`` the 6 axes and 8 diagonals; a point is pulled back from a
  surface it would reach). A camera that stands inside something (most of its rays hit a
  surface) gets no point along a ray that escapes: that ray leaves through an opening (a
  window, a doorway to the sky), and a point beyond it stands outside the room, seeing the
  sunlit facade that no camera in the room sees (:func:`reach`).
- **Coverage.** Each candidate casts a :data:`PROBE` x :data:`PROBE` grid of rays; the surfaces
  it sees are voxels (:data:`VOXELS` along the scene's working scale, split by the normal's dominant
  axis and sign, so the two faces of a wall differ). The user's captures cover theirs already.
  Greedy set cover: the candidate that sees the most voxels not yet covered is added, until
  ``count`` views or until the best adds less than :data:`MIN_GAIN` of what the region sees.
- **The views.** Each picked view is a ``size`` x ``size`` G-buffer traced in the scene's BVH
  (position, the geometric normal facing the eye, albedo through the textures), its direct
  light from :func:`vplace.direct_light` (what Cycles' DiffDir holds), and as its indirect
  image the light reflected by :data:`TARGET_VPLS` light-path VPLs
  (:func:`vplace.uniform_vpls`, every bounce the scene's renderer follows; physically derived
  powers, no fitting): the iteration is held to it on the surfaces the captures did not see.
  The refit fits the captures only and reads the coverage views' G-buffers alone: the VPLs
  that light their pixels no capture sees are held near their light-path powers
  (``vplace.refit(..., coverage=...)``).

No Cycles render is made: a coverage view costs rays only (about ``size^2`` primary rays,
``samples`` shadow rays per pixel and emitter, and ``TARGET_VPLS`` shadow rays per pixel).

**Rendered instead (the add-on's default since stop 60).** The add-on renders the poses
:func:`pick` chooses with Cycles and fits them as captures
(``addon.capture.stage.rendered_coverage``, named :data:`RENDERED_PREFIX` ``k``): the traced
views' light-path VPLs read 0.6-0.9 of Cycles' light, and Sponza's held-out Alcove stood .043
below its fit views with them, .025 rendered. No traced view then holds the unseen surfaces;
the refit bounds the scales instead (``vplace.job.REGION_MAX_SCALE``).
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from vplace._native import MAX_BOUNCES, Scene, View, VplSet, direct_light, evaluate, uniform_vpls

#: Coverage views a job adds by default (the demo, the panel, the report).
DEFAULT_COUNT = 4
#: The region's default radius: this fraction of the median free distance around a camera.
REGION_FRACTION = 1.0
#: A candidate point is kept this fraction of the free distance away from the surface it meets.
WALL_MARGIN = 0.5
#: Rays per side of a candidate's coverage probe.
PROBE = 32
#: Voxels along the scene's working scale (``Scene.scale``) for the coverage count.
VOXELS = 96
#: Stop adding views when the best adds less than this share of what the region sees.
MIN_GAIN = 0.02
#: Light-path VPLs of a coverage view's indirect image.
TARGET_VPLS = 512
#: Direct-light samples per pixel and emitter.
DIRECT_SAMPLES = 16
#: Near and far clip of the coverage cameras, metres.
NEAR, FAR = 0.02, 1.0e4

#: The name of every coverage view starts with this.
PREFIX = "coverage "


#: The name of every coverage view rendered by Cycles (the add-on's default: captures, fitted
#: as the user's are, not coverage views) starts with this.
RENDERED_PREFIX = "region view "


def is_coverage(view: View) -> bool:
    """Whether ``view`` is a coverage view (made here, not captured)."""
    return view.name.startswith(PREFIX)


def is_rendered_coverage(view: View) -> bool:
    """Whether ``view`` is a coverage view's pose rendered by Cycles (a capture)."""
    return view.name.startswith(RENDERED_PREFIX)


def captures_of(views: Sequence[View]) -> list[View]:
    """The captured views of ``views`` (coverage views left out: their indirect image is itself
    an estimate, for placing, not a target to fit), or all of them when none is captured."""
    return [v for v in views if not is_coverage(v)] or list(views)


#: The six view directions of a cube (forward, up).
FACES: tuple[tuple[tuple[float, float, float], tuple[float, float, float]], ...] = (
    ((1.0, 0.0, 0.0), (0.0, 0.0, 1.0)),
    ((-1.0, 0.0, 0.0), (0.0, 0.0, 1.0)),
    ((0.0, 1.0, 0.0), (0.0, 0.0, 1.0)),
    ((0.0, -1.0, 0.0), (0.0, 0.0, 1.0)),
    ((0.0, 0.0, 1.0), (0.0, 1.0, 0.0)),
    ((0.0, 0.0, -1.0), (0.0, 1.0, 0.0)),
)


@dataclass(frozen=True)
class Region:
    """Where the user's camera may go, and how many coverage views stand for it."""

    #: Coverage views to add (0: none, the layout sees the user's views only).
    count: int = DEFAULT_COUNT
    #: Metres a camera may move from the user's; 0: :data:`REGION_FRACTION` of the free
    #: distance around it.
    radius: float = 0.0
    #: Pixels per side of each coverage view.
    size: int = 48

    def validate(self) -> None:
        """Raises ``ValueError`` for a region no job can use."""
        if self.count < 0 or self.count > 16:
            raise ValueError(f"coverage views must be 0 to 16, got {self.count}")
        if not (self.radius >= 0.0 and math.isfinite(self.radius)):
            raise ValueError(f"the region radius must be 0 (auto) or more, got {self.radius}")
        if self.size < 8:
            raise ValueError(f"coverage views must be at least 8 pixels, got {self.size}")


@dataclass(frozen=True)
class Pose:
    """A coverage view's eye, forward and up directions (world)."""

    eye: np.ndarray
    forward: np.ndarray
    up: np.ndarray

    def basis(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Unit forward, right and up vectors of the view (right-handed, up orthogonalized)."""
        f = self.forward / np.linalg.norm(self.forward)
        right = np.cross(f, self.up)
        right /= np.linalg.norm(right)
        return f, right, np.cross(right, f)

    def world_to_clip(self) -> np.ndarray:
        """(4, 4) OpenGL world-to-clip matrix of a 90-degree square view."""
        f, right, up = self.basis()
        view = np.eye(4)
        view[0, :3], view[1, :3], view[2, :3] = right, up, -f
        view[:3, 3] = -view[:3, :3] @ self.eye
        proj = np.zeros((4, 4))
        proj[0, 0] = proj[1, 1] = 1.0  # cot(45 degrees)
        proj[2, 2] = -(FAR + NEAR) / (FAR - NEAR)
        proj[2, 3] = -2.0 * FAR * NEAR / (FAR - NEAR)
        proj[3, 2] = -1.0
        return proj @ view

    def rays(self, size: int) -> tuple[np.ndarray, np.ndarray]:
        """Unit directions (size*size, 3) through the pixel centres (row 0 at the top), and the
        cosine of each with the forward axis (planar depth = distance x cosine)."""
        f, right, up = self.basis()
        s = (np.arange(size) + 0.5) / size * 2.0 - 1.0
        x, y = np.meshgrid(s, -s)
        d = f[None, :] + x.reshape(-1, 1) * right + y.reshape(-1, 1) * up
        norm = np.linalg.norm(d, axis=1, keepdims=True)
        return (d / norm).astype(np.float32), (1.0 / norm[:, 0]).astype(np.float32)


@dataclass
class Coverage:
    """The picked coverage views and what they cover."""

    #: The traced views (empty where the add-on rendered the poses: then they are captures).
    views: list[View]
    poses: list[Pose]
    #: Share of the region's surface voxels the user's views cover, then with the coverage views.
    covered_before: float
    covered_after: float
    radius: list[float] = field(default_factory=list)
    seconds: float = 0.0
    #: Where each user camera stands for its region (:func:`camera_eye`), as :attr:`radius`.
    eyes: list[np.ndarray] = field(default_factory=list)

    def describe(self, unit_scale: float = 1.0) -> str:
        """One line for the log and the report; ``unit_scale``: metres per scene unit."""
        return (
            f"{len(self.poses)} coverage views (region radius "
            + ", ".join(f"{r * unit_scale:.3g}" for r in self.radius)
            + f" m): the region's surfaces {self.covered_before:.0%} covered by the captures, "
            f"{self.covered_after:.0%} with them ({self.seconds:.2f} s)"
        )


def fibonacci_sphere(n: int) -> np.ndarray:
    """``n`` unit directions spread evenly over the sphere (a Fibonacci lattice), float32."""
    i = np.arange(n) + 0.5
    z = 1.0 - 2.0 * i / n
    phi = i * math.pi * (3.0 - math.sqrt(5.0))
    rxy = np.sqrt(1.0 - z * z)
    return np.stack([rxy * np.cos(phi), rxy * np.sin(phi), z], axis=1).astype(np.float32)


def view_eye(world_to_clip: np.ndarray) -> np.ndarray:
    """Where a camera's view begins (float32 (3,)): the centre of its near clip plane, its
    position moved along its axis by its clip start (OpenGL conventions: NDC ``(0, 0, -1)``
    brought back to the world)."""
    p = np.linalg.inv(np.asarray(world_to_clip, dtype=np.float64)) @ np.array([0.0, 0.0, -1.0, 1.0])
    return (p[:3] / p[3]).astype(np.float32)


def camera_eye(scene: Scene, position: Sequence[float], world_to_clip: np.ndarray) -> np.ndarray:
    """Where a camera stands for its region, its coverage views, the held-out views made around
    it and the sky portals (float32 (3,)): its position, or where its view begins
    (:func:`view_eye`) when a surface lies between the two. A camera outside a wall whose clip
    start passes the wall sees the room behind it, and stands there; one whose clip start passes
    nothing keeps its position. (``capture.views.eye_positions`` in the add-on applies the same
    rule with Blender's ray cast, before this scene exists.)"""
    p = np.asarray(position, dtype=np.float32)
    near = view_eye(world_to_clip)
    if np.array_equal(near, p):
        return p
    blocked = scene.occluded(p[None, :], near[None, :])[0]  # either side of a surface
    return near if blocked else p


def trace(scene: Scene, origin: np.ndarray, dirs: np.ndarray) -> np.ndarray:
    """Hit distances of rays from ``origin`` (inf where they escape)."""
    origins = np.ascontiguousarray(np.broadcast_to(origin.astype(np.float32), dirs.shape))
    t, tri, _ = scene.intersect(origins, np.ascontiguousarray(dirs))
    return np.where(tri >= 0, t, np.inf)


def median_free_distance(scene: Scene, eye: np.ndarray) -> float:
    """Median distance rays from ``eye`` travel before a surface (inf when most escape)."""
    return float(np.median(trace(scene, eye, fibonacci_sphere(256))))


def free_distance(scene: Scene, eye: np.ndarray) -> float:
    """:func:`median_free_distance`, the scene's working scale when most rays escape."""
    return min(median_free_distance(scene, eye), scene.scale)


def enclosed(scene: Scene, eye: np.ndarray) -> bool:
    """Whether ``eye`` stands inside something: most rays from it hit a surface."""
    return math.isfinite(median_free_distance(scene, eye))


def _region(scene: Scene, eye: np.ndarray, radius: float) -> tuple[float, bool]:
    """The region's radius around ``eye`` (``radius``, or :data:`REGION_FRACTION` of the free
    distance) and whether ``eye`` is :func:`enclosed`, from one set of rays."""
    median = median_free_distance(scene, eye)
    r = radius or REGION_FRACTION * min(median, scene.scale)
    return r, math.isfinite(median)


def region_radius(scene: Scene, eye: np.ndarray, radius: float = 0.0) -> float:
    """The radius of the region around a camera standing at ``eye`` (scene units): ``radius``
    where given, else :data:`REGION_FRACTION` of the median free distance around it (at most
    the working scale), as :func:`pick` takes it."""
    return _region(scene, np.asarray(eye, dtype=np.float32), radius)[0]


def reach(radius: float, hit: float, inside: bool) -> float:
    """How far a region point may stand from its camera along a ray that meets a surface at
    ``hit`` (inf: it escapes): the region's ``radius``, pulled back by :data:`WALL_MARGIN` from
    the surface; 0 along a ray that escapes from a camera that stands ``inside`` (the ray
    leaves through an opening, and beyond it is outside the room)."""
    if not math.isfinite(hit):
        return 0.0 if inside else radius
    return min(radius, WALL_MARGIN * hit)


def _candidates(
    scene: Scene, eyes: Sequence[np.ndarray], radii: Sequence[float], inside: Sequence[bool]
) -> list[Pose]:
    axes = np.eye(3, dtype=np.float32)
    diag = np.array(
        [[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=np.float32
    ) / np.float32(math.sqrt(3.0))
    dirs = np.concatenate([axes, -axes, diag])
    points: list[np.ndarray] = []
    for eye, r, indoors in zip(eyes, radii, inside, strict=True):
        points.append(eye)
        t = trace(scene, eye, dirs)
        for u, ti in zip(dirs, t, strict=True):
            far = reach(r, float(ti), indoors)
            if far > 0.1 * r:
                points.append(eye + far * u)
    for i, a in enumerate(eyes):  # between the user's cameras, where nothing blocks the way
        for b in eyes[i + 1 :]:
            d = b - a
            length = float(np.linalg.norm(d))
            way = (d / max(length, 1e-12))[None, :].astype(np.float32)
            if length > 0 and trace(scene, a, way)[0] > length:
                points.append((a + b) / 2.0)
    return [
        Pose(np.asarray(p, dtype=np.float64), np.array(f), np.array(u))
        for p in points
        for f, u in FACES
    ]


def _voxels(scene: Scene, points: np.ndarray, normals: np.ndarray) -> set[int]:
    lo, hi = (np.asarray(b, dtype=np.float32) for b in scene.bounds)
    cell = scene.scale / VOXELS
    ijk = np.floor((points - lo) / cell).astype(np.int64) + 1
    axis = np.abs(normals).argmax(axis=1)
    sign = np.take_along_axis(normals, axis[:, None], axis=1)[:, 0] > 0
    n = int(np.ceil(float((hi - lo).max()) / cell)) + 3
    keys = ((ijk[:, 0] * n + ijk[:, 1]) * n + ijk[:, 2]) * 6 + axis * 2 + sign
    return set(np.unique(keys).tolist())


def _hits(
    scene: Scene, tris: np.ndarray, pose: Pose, size: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Position, geometric normal facing the eye, triangle and barycentrics of a pose's rays."""
    return _hits_of(scene, tris, [pose], size)[0]


def _hits_of(
    scene: Scene, tris: np.ndarray, poses: Sequence[Pose], size: int
) -> list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
    """:func:`_hits` of each of ``poses``, their rays traced together (one parallel call)."""
    if not poses:
        return []
    rays = [pose.rays(size) for pose in poses]
    dirs = np.concatenate([d for d, _ in rays])
    cos = np.concatenate([c for _, c in rays])
    origins = np.ascontiguousarray(
        np.concatenate(
            [
                np.broadcast_to(p.eye.astype(np.float32), d.shape)
                for p, (d, _) in zip(poses, rays, strict=True)
            ]
        )
    )
    t, tri, bary = scene.intersect(origins, dirs)
    hit = (tri >= 0) & (t * cos > NEAR)
    pos = origins + dirs * np.where(hit, t, 0.0)[:, None]
    normal = np.zeros_like(dirs)
    if hit.any():
        corners = tris[tri[hit]]
        n = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-20)
        facing = np.sum(n * dirs[hit], axis=1) > 0
        n[facing] *= -1.0
        normal[hit] = n
    pos, normal, depth = pos.astype(np.float32), normal.astype(np.float32), t * cos
    step = size * size
    return [
        (hit[s], pos[s], normal[s], tri[s], bary[s], depth[s])
        for s in (slice(k * step, (k + 1) * step) for k in range(len(poses)))
    ]


def pick(
    scene: Scene,
    triangles: np.ndarray,
    user_views: Sequence[View],
    region: Region,
) -> tuple[list[Pose], float, float, list[float], list[np.ndarray]]:
    """The coverage poses for ``user_views`` (greedy set cover, see the module docs), the share
    of the region's voxels covered before and after, and per view the region's radius and where
    its camera stands (:func:`camera_eye`).
    ``triangles``: (T, 3, 3) float32 corners of the scene's triangles."""
    eyes = [camera_eye(scene, v.camera_position, v.world_to_clip) for v in user_views]
    regions = [_region(scene, e, region.radius) for e in eyes]
    radii = [r for r, _ in regions]
    covered: set[int] = set()
    for v in user_views:
        mask = v.covered.ravel()
        covered |= _voxels(scene, v.position.reshape(-1, 3)[mask], v.normal.reshape(-1, 3)[mask])
    sets = []
    poses = _candidates(scene, eyes, radii, [inside for _, inside in regions])
    for hit, pos, normal, *_ in _hits_of(scene, triangles, poses, PROBE):
        sets.append(_voxels(scene, pos[hit], normal[hit]))
    universe = set().union(covered, *sets)
    seen_before = len(covered & universe) / max(len(universe), 1)
    chosen: list[Pose] = []
    while len(chosen) < region.count and sets:
        gains = [len(s - covered) for s in sets]
        best = int(np.argmax(gains))
        if gains[best] < MIN_GAIN * len(universe):
            break
        chosen.append(poses[best])
        covered |= sets[best]
        del sets[best], poses[best]
    return chosen, seen_before, len(covered & universe) / max(len(universe), 1), radii, eyes


def coverage_view(
    scene: Scene,
    triangles: np.ndarray,
    pose: Pose,
    size: int,
    target: VplSet,
    *,
    name: str,
    seed: int = 0,
) -> View:
    """A coverage view of ``pose``: traced G-buffer, direct light, ``target``'s indirect image."""
    hit, pos, normal, tri, bary, depth = _hits(scene, triangles, pose, size)
    albedo = np.zeros_like(pos)
    if hit.any():
        albedo[hit] = scene.albedo_at(
            np.ascontiguousarray(tri[hit].astype(np.uint32)), np.ascontiguousarray(bary[hit])
        )
    shape = (size, size)
    zeros = np.zeros((*shape, 3), np.float32)
    common = dict(
        position=pos.reshape(*shape, 3),
        normal=normal.reshape(*shape, 3),
        albedo=albedo.reshape(*shape, 3),
        covered=hit.reshape(shape),
        depth=np.where(hit, depth, 1e10).astype(np.float32).reshape(shape),
        camera_position=tuple(float(c) for c in pose.eye),
        world_to_clip=pose.world_to_clip().astype(np.float32),
        name=name,
    )
    bare = View(direct=zeros, diffuse_direct=zeros, **common)
    diffuse_direct = direct_light(scene, bare, samples=DIRECT_SAMPLES, seed=seed)
    direct = diffuse_direct * common["albedo"]
    lit = View(direct=direct, diffuse_direct=diffuse_direct, **common)
    indirect, _ = evaluate(scene, lit, target)
    rho = common["albedo"]
    diffuse_indirect = np.where(rho > 1e-6, indirect / np.maximum(rho, 1e-6), 0.0).astype(
        np.float32
    )
    return View(
        direct=direct,
        diffuse_direct=diffuse_direct,
        diffuse_indirect=diffuse_indirect,
        indirect=np.ascontiguousarray(indirect, dtype=np.float32),
        **common,
    )


def cover(
    scene: Scene,
    triangles: np.ndarray,
    user_views: Sequence[View],
    region: Region,
    *,
    seed: int = 0,
    profile: str = "cosine",
    radius: float | None = None,
) -> Coverage:
    """The coverage views of the region around ``user_views`` (see the module docs)."""
    region.validate()
    start = time.perf_counter()
    if region.count == 0 or not user_views:
        return Coverage([], [], 1.0, 1.0)
    poses, before, after, radii, eyes = pick(scene, triangles, user_views, region)
    views = []
    if poses:
        target = uniform_vpls(
            scene,
            TARGET_VPLS,
            seed=seed + 7717,
            bounces=MAX_BOUNCES,
            profile=profile,
            radius=radius,
        )
        for i, pose in enumerate(poses):
            views.append(
                coverage_view(
                    scene, triangles, pose, region.size, target, name=f"{PREFIX}{i + 1}", seed=seed
                )
            )
    return Coverage(views, poses, before, after, radii, time.perf_counter() - start, eyes)


#: The held-out poses' distance from the camera, as fractions of the region's radius.
HELD_OUT_REACH = (0.3, 0.8)
#: The held-out poses' turn about the world's up axis away from the camera's heading, degrees.
HELD_OUT_TURN = (30.0, 90.0)


def held_out_poses(
    scene: Scene,
    eye: Sequence[float],
    forward: Sequence[float],
    count: int,
    *,
    seed: int = 0,
    radius: float = 0.0,
) -> list[Pose]:
    """``count`` camera poses a user may take next in the region around a camera at ``eye``
    looking along ``forward`` (world, z up), which no capture and no coverage view takes: each
    stands a random :data:`HELD_OUT_REACH` share of the region's radius (``radius``, or the
    default of :class:`Region`) away in a random, mostly horizontal direction (pulled back from
    the surface it would reach by :data:`WALL_MARGIN`), and turns a random
    :data:`HELD_OUT_TURN` away from the camera's heading, level pitch kept. Deterministic for
    ``seed``; a pose whose centre ray escapes the scene, or that would stand beyond an opening
    of the room (:func:`reach`), is drawn again (up to 64 draws each)."""
    e = np.asarray(eye, dtype=np.float64)
    f0 = np.asarray(forward, dtype=np.float64)
    f0 = f0 / max(float(np.linalg.norm(f0)), 1e-12)
    r, inside = _region(scene, e.astype(np.float32), radius)
    rng = np.random.default_rng([seed, 20])
    z = np.array([0.0, 0.0, 1.0])
    poses: list[Pose] = []
    for _ in range(count):
        for _draw in range(64):
            u = rng.normal(size=3) * np.array([1.0, 1.0, 0.3])
            u /= max(float(np.linalg.norm(u)), 1e-12)
            hit = float(trace(scene, e.astype(np.float32), u[None, :].astype(np.float32))[0])
            far = reach(r * rng.uniform(*HELD_OUT_REACH), hit, inside)
            turn = math.radians(rng.uniform(*HELD_OUT_TURN)) * rng.choice([-1.0, 1.0])
            c, s = math.cos(turn), math.sin(turn)
            f = np.array([c * f0[0] - s * f0[1], s * f0[0] + c * f0[1], f0[2]])
            p = e + far * u
            sees = trace(scene, p.astype(np.float32), f[None, :].astype(np.float32))[0]
            if far >= 0.1 * r and np.isfinite(sees) and abs(float(f @ z)) < 0.95:
                poses.append(Pose(p, f, z))
                break
    return poses
