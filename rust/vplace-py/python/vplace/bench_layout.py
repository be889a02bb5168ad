"""Benchmark of the whole layout for one or more views, and of the evaluator's shadow rays (BVH
against brute force).

Run: ``python -m vplace.bench_layout [--width 640 --height 360 --budget 256 --views 4
--repeat 5]``.

The scene is procedural and deterministic: a room 4 x 4 x 2.5 m with walls subdivided into a
grid of quads (``--grid``), a pillar in the middle, a point light; each view's G-buffer, DiffDir
pass (with the pillar's shadow) and direct image are ray cast in numpy from cameras spread around
the room, so they agree with the scene the native side traces. The indirect images stand in for
Cycles with an evaluator render of many uniform VPLs.

Printed: the median time of the whole layout for all the views at once (features and one fit
over every view, strata and allocation, three evaluator iterations at quarter resolution
against every view), of its parts, of the refit of the VPL powers against every view
(``vplace.refit``, stride 4), of layout plus refit (what "Lay out and apply" computes), the
process's peak memory, and the shadow rays per second of the evaluator with the BVH beside the
brute-force evaluator (every triangle tested) in the same run, on a strided sub-image for the
brute force so it finishes.
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import time
from collections.abc import Callable
from typing import Any

import numpy as np

import vplace
from vplace import _native

ROOM = (np.array([-2.0, -2.0, 0.0]), np.array([2.0, 2.0, 2.5]))
PILLAR = (np.array([-0.3, -0.3, 0.0]), np.array([0.3, 0.3, 1.4]))
LIGHT = np.array([1.0, 1.2, 2.2])
POWER = np.array([300.0, 280.0, 240.0])


def _quads(lo: np.ndarray, hi: np.ndarray, k: int, inward: bool) -> list[np.ndarray]:
    """The six faces of a box, each a k x k grid of quads (4 corners each)."""
    out = []
    for axis in range(3):
        a, b = [i for i in range(3) if i != axis]
        for side, value in ((0, lo[axis]), (1, hi[axis])):
            for i in range(k):
                for j in range(k):
                    corners = []
                    for di, dj in ((0, 0), (1, 0), (1, 1), (0, 1)):
                        p = np.empty(3)
                        p[axis] = value
                        p[a] = lo[a] + (hi[a] - lo[a]) * (i + di) / k
                        p[b] = lo[b] + (hi[b] - lo[b]) * (j + dj) / k
                        corners.append(p)
                    q = np.array(corners)
                    # Outward normal of (a, b) order is +axis when side == 1 for a right-handed
                    # (axis, a, b); flip as needed: orientation only matters for consistency.
                    if (side == 1) == inward:
                        q = q[::-1]
                    out.append(q)
    return out


def build_scene(grid: int) -> tuple[_native.Scene, int]:
    """The room (walls `grid` x `grid` quads each) and the pillar; returns it and its triangles."""
    quads = _quads(*ROOM, grid, inward=True) + _quads(*PILLAR, max(1, grid // 4), inward=False)
    verts = np.concatenate(quads).astype(np.float32)
    n = len(quads)
    base = 4 * np.arange(n, dtype=np.uint32)[:, None]
    tris = np.concatenate([base + np.uint32([0, 1, 2]), base + np.uint32([0, 2, 3])])
    ids = np.zeros(len(tris), np.uint32)
    wall = np.array([[0.7, 0.7, 0.7]], np.float32)
    scene = _native.Scene(
        verts, tris, ids, wall, [_native.Light.point(LIGHT.tolist(), POWER.tolist())]
    )
    return scene, len(tris)


def _slab(o: np.ndarray, d: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> tuple[Any, Any, Any]:
    with np.errstate(divide="ignore", invalid="ignore"):
        t1 = (lo - o) / d
        t2 = (hi - o) / d
    tmin, tmax = np.minimum(t1, t2), np.maximum(t1, t2)
    return tmin.max(-1), tmax.min(-1), (tmin.argmax(-1), tmax.argmin(-1))


def camera(
    width: int, height: int, cam: np.ndarray, target: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Camera position, world_to_clip (OpenGL) and the unit view ray of every pixel of a camera
    at ``cam`` looking at ``target`` (Z up, 60 degrees vertical field of view)."""
    f = (target - cam) / np.linalg.norm(target - cam)
    s = np.cross(f, [0.0, 0.0, 1.0])
    s /= np.linalg.norm(s)
    u = np.cross(s, f)
    tan_y = math.tan(math.radians(60.0) / 2)
    tan_x = tan_y * width / height
    near, far = 0.05, 50.0
    proj = np.array(
        [
            [1 / tan_x, 0, 0, 0],
            [0, 1 / tan_y, 0, 0],
            [0, 0, (far + near) / (near - far), 2 * far * near / (near - far)],
            [0, 0, -1, 0],
        ]
    )
    view = np.eye(4)
    view[0, :3], view[1, :3], view[2, :3] = s, u, -f
    view[:3, 3] = -view[:3, :3] @ cam
    x = ((np.arange(width) + 0.5) / width * 2 - 1) * tan_x
    y = (1 - (np.arange(height) + 0.5) / height * 2) * tan_y
    gx, gy = np.meshgrid(x, y)
    d = f + gx[..., None] * s + gy[..., None] * u
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    return cam, proj @ view, d


def cameras(n: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """``n`` cameras inside the room, 1.9 m from its centre at 1.2 m height, spread around it,
    each looking at the far side of the room; the first is the single-view benchmark's."""
    out = []
    for k in range(n):
        a = -math.pi / 2 + 2 * math.pi * k / max(n, 1)
        cam = np.array([1.9 * math.cos(a), 1.9 * math.sin(a), 1.2])
        if k == 0:
            cam = np.array([0.2, -1.9, 1.2])
        out.append((cam, np.array([-cam[0] * 0.1, -cam[1], 1.2])))
    return out


def synthetic_capture(
    width: int, height: int, cam: np.ndarray | None = None, target: np.ndarray | None = None
) -> dict[str, Any]:
    """G-buffer, DiffDir, direct image and camera of the room, ray cast in numpy (default: the
    first camera of :func:`cameras`)."""
    if cam is None or target is None:
        cam, target = cameras(1)[0]
    cam, world_to_clip, d = camera(width, height, cam, target)
    o = np.broadcast_to(cam, d.shape)
    _, t_room, (_, exit_axis) = _slab(o, d, *ROOM)
    t_near, t_far, (near_axis, _) = _slab(o, d, *PILLAR)
    hit_pillar = (t_near <= t_far) & (t_near > 0)
    t = np.where(hit_pillar, t_near, t_room)
    axis = np.where(hit_pillar, near_axis, exit_axis)
    pos = cam + d * t[..., None]
    normal = np.zeros_like(pos)
    sign = -np.sign(np.take_along_axis(d, axis[..., None], -1))[..., 0]
    np.put_along_axis(normal, axis[..., None], sign[..., None], -1)
    albedo = np.full(pos.shape, 0.7)
    # Direct light of the point light, with the pillar's shadow.
    to_l = LIGHT - pos
    dist = np.linalg.norm(to_l, axis=-1)
    ldir = to_l / dist[..., None]
    cos = np.maximum((normal * ldir).sum(-1), 0.0)
    origin = pos + normal * 1e-4
    sn, sf, _ = _slab(origin, ldir, *PILLAR)
    shadow = (sn <= sf) & (sn > 1e-4) & (sn < dist)
    irr = np.where(shadow, 0.0, cos / (4 * math.pi * dist**2))[..., None] * POWER
    diffdir = irr / math.pi
    direct = diffdir * albedo
    forward = (target - cam) / np.linalg.norm(target - cam)
    depth = (d @ forward) * t
    f32 = np.float32
    return {
        "position": pos.astype(f32),
        "normal": normal.astype(f32),
        "albedo": albedo.astype(f32),
        "diffuse_direct": diffdir.astype(f32),
        "direct": direct.astype(f32),
        "depth": depth.astype(f32),
        "covered": np.ones(t.shape, bool),
        "light_position": LIGHT.tolist(),
        "camera_position": cam,
        "world_to_clip": world_to_clip,
    }


def median_time(fn: Callable[[], Any], repeat: int) -> tuple[float, Any]:
    times, out = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), out


def views_of(scene: _native.Scene, caps: list[dict[str, Any]]) -> list[vplace.View]:
    """The captures as views, each with an indirect image: an evaluator render of 1,024 uniform
    VPLs of every bounce (standing in for Cycles)."""
    ref = vplace.uniform_vpls(scene, 1024, seed=11, bounces=vplace.MAX_BOUNCES)
    out = []
    for i, cap in enumerate(caps):
        geometry = {
            k: cap[k]
            for k in (
                "position",
                "normal",
                "albedo",
                "covered",
                "depth",
                "direct",
                "diffuse_direct",
                "camera_position",
                "world_to_clip",
            )
        }
        bare = vplace.View(**geometry, name=f"view {i}")
        ind, _ = vplace.evaluate(scene, bare, ref)
        diffuse_indirect = (ind / cap["albedo"]).astype(np.float32)
        out.append(
            vplace.View(
                **geometry,
                diffuse_indirect=diffuse_indirect,
                indirect=ind,
                name=f"view {i}",
            )
        )
    return out


def full_resolution_rmse(
    scene: _native.Scene, views: list[vplace.View], vpls: vplace.VplSet
) -> float:
    """RMSE of the VPL indirect image against each view's indirect image over every covered
    pixel of every view."""
    sq, n = 0.0, 0
    for view in views:
        img, _ = vplace.evaluate(scene, view, vpls)
        covered = view.covered
        diff = (img - view.indirect)[covered]
        sq += float((diff.astype(np.float64) ** 2).sum())
        n += diff.size
    return math.sqrt(sq / max(n, 1))


def peak_memory_mb() -> float:
    """The process's peak resident memory so far, MB."""
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--width", type=int, default=640)
    ap.add_argument("--height", type=int, default=360)
    ap.add_argument("--budget", type=int, default=256)
    ap.add_argument("--views", type=int, default=1, help="views laid out for at once")
    ap.add_argument("--grid", type=int, default=12, help="quads per wall side")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--brute-stride", type=int, default=8)
    args = ap.parse_args(argv)

    scene, triangles = build_scene(args.grid)
    caps = [synthetic_capture(args.width, args.height, c, t) for c, t in cameras(args.views)]
    views = views_of(scene, caps)
    before = peak_memory_mb()

    def fit() -> vplace.Fit:
        return vplace.fit(scene, views, vplace.FitParams(cell_px=16))

    t_fit, model = median_time(fit, args.repeat)

    stride = vplace.stride_for(views)  # as "Lay out and apply" samples these views

    def lay_out(at: int = stride) -> vplace.Layout:
        return vplace.layout(
            scene,
            views,
            vplace.LayoutParams(budget=args.budget, iterations=3, tolerance=0.0, stride=at),
            fit=fit(),
        )

    def lay_out_and_refit(at: int = stride) -> tuple[vplace.Layout, vplace.Refit]:
        laid = lay_out(at)
        return laid, vplace.refit(scene, views, laid.vpls, vplace.RefitParams(stride=at))

    t_alloc, _ = median_time(
        lambda: vplace.layout(
            scene, views, vplace.LayoutParams(budget=args.budget, iterate=False), fit=model
        ),
        args.repeat,
    )
    t_whole, out = median_time(lay_out, args.repeat)
    t_both, (_, refitted) = median_time(lay_out_and_refit, args.repeat)
    peak = peak_memory_mb()
    # What the pixel budget costs in quality: the full-resolution error of layout + refit at the
    # budget's stride and at the finest stride, every view, in this run.
    quality = {at: full_resolution_rmse(scene, views, lay_out_and_refit(at)[1].vpls)
               for at in sorted({stride, vplace.budget.MIN_STRIDE})}  # fmt: skip

    vpls = vplace.uniform_vpls(scene, args.budget, seed=3)
    t_refit, fitted = median_time(
        lambda: vplace.refit(scene, views, vpls, vplace.RefitParams(stride=4)), args.repeat
    )
    threads = os.environ.get("RAYON_NUM_THREADS") or str(os.cpu_count())
    print(
        f"vplace layout benchmark: {args.views} view(s) of {args.width}x{args.height}, "
        f"{args.budget} VPLs, {triangles} triangles, {threads} threads, median of {args.repeat}"
    )
    print(f"{'step':<56} {'seconds':>10}")
    print(f"{'features + one fit over every view (vplace.fit)':<56} {t_fit:>10.3f}")
    print(f"{'predict + strata + allocation (no iteration)':<56} {t_alloc:>10.3f}")
    print(f"{f'whole layout (fit + allocation + 3 iterations @ 1/{stride})':<56} {t_whole:>10.3f}")
    print(
        f"  iteration errors (RMSE): {', '.join(f'{e:.4g}' for e in out.errors)}; best {out.best}"
    )
    pairs = zip(out.shadow_rays, out.reused_rays, strict=True)
    traced = [f"{t} (+{r} reused)" if r else str(t) for t, r in pairs]
    print(f"  iteration shadow rays: {', '.join(traced)}")
    print(f"  iteration seconds: {', '.join(f'{x:.3f}' for x in out.seconds)}")
    print(f"{'layout + refit of its powers (Lay out and apply)':<56} {t_both:>10.3f}")
    print(
        f"  refit: {refitted.pixels} pixels, RMSE {refitted.error_before:.4g} -> "
        f"{refitted.error_after:.4g}"
    )
    print(
        "  full-resolution RMSE of layout + refit, every view: "
        + ", ".join(f"stride {at}: {e:.4g}" for at, e in quality.items())
        + f" (stride {stride}: the pixel budget of {vplace.PIXEL_BUDGET} over all views)"
    )
    print(f"{f'refit of {args.budget} uniform VPLs (NNLS @ 1/4)':<56} {t_refit:>10.3f}")
    print(
        f"  refit: {fitted.pixels} pixels, {fitted.shadow_rays} shadow rays, RMSE "
        f"{fitted.error_before:.4g} -> {fitted.error_after:.4g}, "
        f"{int((fitted.scales == 0).sum())} VPLs switched off"
    )
    print(
        f"peak memory: {peak:.0f} MB (the views' captures and the scene: {before:.0f} MB before "
        "the layout)"
    )
    print()
    print_evaluator(scene, views[0], caps[0], vpls, args)


def print_evaluator(
    scene: vplace.Scene,
    first: vplace.View,
    c: dict[str, np.ndarray],
    vpls: vplace.VplSet,
    args: argparse.Namespace,
) -> None:
    """The evaluator's table: the BVH at full resolution and at ``--brute-stride``, against the
    brute-force loop over every triangle."""
    t_bvh, (_, st_bvh) = median_time(lambda: vplace.evaluate(scene, first, vpls), args.repeat)
    s = args.brute_stride
    sub = vplace.View(
        **{
            k: np.ascontiguousarray(c[k][::s, ::s])
            for k in ("position", "normal", "albedo", "covered", "depth", "direct")
        },
        diffuse_direct=np.ascontiguousarray(c["diffuse_direct"][::s, ::s]),
        camera_position=c["camera_position"],
        world_to_clip=c["world_to_clip"],
    )
    _, st_sub = vplace.evaluate(scene, sub, vpls)
    t_brute, (_, st_brute) = median_time(
        lambda: vplace.evaluate(scene, sub, vpls, brute_force=True), 1
    )

    print(f"{'evaluator':<40} {'pixels':>9} {'shadow rays':>12} {'seconds':>9} {'rays/s':>12}")
    npx = args.width * args.height
    print(
        f"{'BVH (full resolution)':<40} {npx:>9} {st_bvh.shadow_rays:>12} "
        f"{t_bvh:>9.3f} {st_bvh.shadow_rays / t_bvh:>12.3e}"
    )
    n_sub = sub.width * sub.height
    print(
        f"{f'BVH (stride {s})':<40} {n_sub:>9} "
        f"{st_sub.shadow_rays:>12} {st_sub.seconds:>9.3f} {st_sub.rays_per_second:>12.3e}"
    )
    print(
        f"{f'brute force, all triangles (stride {s})':<40} {n_sub:>9} "
        f"{st_brute.shadow_rays:>12} {t_brute:>9.3f} {st_brute.shadow_rays / t_brute:>12.3e}"
    )
    speedup = st_sub.rays_per_second / (st_brute.shadow_rays / t_brute)
    print(f"BVH / brute force: {speedup:.1f}x rays/s")


if __name__ == "__main__":
    main()
