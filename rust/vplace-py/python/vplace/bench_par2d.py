"""Benchmark of vplace.par2d: speed against error for a 2D light map (not a timed test).

Run ``python -m vplace.bench_par2d``. Prints one table:

1. A ``size x size`` light map (default 512) of ``[-1, 1]^2`` with 8 lights and 64 occluders:
   the time of ``par`` and ``exact`` (and par's RMSE against exact), then Monte Carlo at rising
   ray counts over the full image with its RMSE against ``exact``.
2. Monte Carlo at higher ray counts on a strided subset of the same pixels (every
   ``stride``-th row and column), until its RMSE against ``exact`` is at most 1e-3; the time is
   scaled by the pixel ratio to a full-image equivalent (labelled as such).
3. The ratio of Monte Carlo's (full-image-equivalent) time at RMSE <= 1e-3 to exact's time.
4. ``exact``'s time with 64, 256 and 1024 occluders.

RMSE is over all pixels and the three channels.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from vplace.par2d_measure import BOUNDS, measure, random_scene, rmse, timed_map

TARGET_RMSE = 1e-3


def main(argv: list[str] | None = None) -> None:
    """Runs the benchmark and prints the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=512, help="light map width = height")
    parser.add_argument("--full-rays", type=int, nargs="+", default=[16, 64, 256])
    parser.add_argument("--stride", type=int, default=16, help="subset stride for high ray counts")
    parser.add_argument("--max-rays", type=int, default=1 << 20, help="stop the subset here")
    args = parser.parse_args(argv)
    size = args.size
    scene = random_scene(8, 64, seed=1)
    print(f"vplace.par2d benchmark: {size}x{size} light map of {BOUNDS}, 8 lights, 64 occluders")
    print(f"threads: {os.cpu_count()} logical CPUs (rayon default)")
    print()
    print(f"{'method':<14}{'rays':>9}{'pixels':>10}{'time [s]':>12}{'RMSE vs exact':>16}  note")
    rows, exact = measure(size, tuple(args.full_rays), seed=1)
    t_exact = rows[0].seconds
    reached: tuple[int, float] | None = None
    above: tuple[int, float, float] | None = None  # last (rays, time, rmse) above the target
    for row in rows:
        rays, t, err = row.rays, row.seconds, row.rmse
        print(f"{row.method:<14}{rays or '-':>9}{size * size:>10}{t:>12.3f}{err:>16.3e}")
        if row.method != "monte_carlo":
            continue
        if reached is None and err <= TARGET_RMSE:
            reached = (rays, t)
        elif reached is None:
            above = (rays, t, err)
    # Higher ray counts on a strided subset of the same pixel centres.
    s = args.stride
    xs = BOUNDS[0] + (np.arange(size) + 0.5) / size * (BOUNDS[2] - BOUNDS[0])
    ys = BOUNDS[3] - (np.arange(size) + 0.5) / size * (BOUNDS[3] - BOUNDS[1])
    sub_x, sub_y = xs[::s], ys[::s]
    pts = np.stack(np.meshgrid(sub_x, sub_y), axis=-1).reshape(-1, 2)
    ref = exact[::s, ::s].reshape(-1, 3)
    scale = size * size / len(pts)
    rays = args.full_rays[-1] * 4
    while reached is None and rays <= args.max_rays:
        t0 = time.perf_counter()
        est = scene.irradiance(pts, "monte_carlo", rays=rays, seed=7)
        t = (time.perf_counter() - t0) * scale
        err = rmse(est, ref)
        note = f"subset 1/{s}^2, time x{scale:.0f}"
        print(f"{'monte_carlo':<14}{rays:>9}{len(pts):>10}{t:>12.3f}{err:>16.3e}  {note}")
        if err <= TARGET_RMSE:
            reached = (rays, t)
        else:
            above = (rays, t, err)
        rays *= 4
    print()
    if reached is None:
        print(f"Monte Carlo did not reach RMSE {TARGET_RMSE:g} within {args.max_rays} rays")
    else:
        r, t = reached
        print(
            f"Monte Carlo reaches RMSE <= {TARGET_RMSE:g} at {r} rays/pixel: {t:.1f} s "
            f"(full-image equivalent) = {t / t_exact:.0f}x the exact sweep ({t_exact:.3f} s)"
        )
    if above is not None:
        # RMSE ~ rays^-1/2 and time ~ rays: the ray count where RMSE meets the target exactly.
        r0, t0, e0 = above
        k = (e0 / TARGET_RMSE) ** 2
        print(
            f"interpolated from {r0} rays (RMSE {e0:.3e}): RMSE {TARGET_RMSE:g} at "
            f"~{r0 * k:.0f} rays/pixel, ~{t0 * k:.0f} s = ~{t0 * k / t_exact:.0f}x exact"
        )
    print()
    print(f"exact scaling ({size}x{size}, 8 lights):")
    print(f"{'occluders':>10}{'time [s]':>12}{'per pixel [us]':>16}")
    for n in (64, 256, 1024):
        sc = random_scene(8, n, seed=2)
        t, _ = timed_map(sc, size, "exact")
        print(f"{n:>10}{t:>12.3f}{t / (size * size) * 1e6:>16.2f}")


if __name__ == "__main__":
    main()
