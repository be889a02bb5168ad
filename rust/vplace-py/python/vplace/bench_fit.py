"""Benchmark of feature extraction and the fit: native (Rust) against numpy, in the same run.

Run: ``python -m vplace.bench_fit [--width 1920 --height 1080 --repeat 15]``. Prints a table of
median times and the numpy / native ratios. The numpy side implements the same per-cell
extraction (``numpy_extract``) and the same plain least-squares fit (``numpy_fit``: Min-Max
normalization, standardized columns, ``numpy.linalg.lstsq``); the tests check that both agree
with the native results.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from vplace import _native

_LUM = np.array(_native.LUMINANCE, dtype=np.float64)


def synthetic_capture(width: int, height: int, seed: int = 42) -> dict[str, Any]:
    """A deterministic synthetic view: floor and back wall, checker albedo, 4% background; its
    ``indirect`` image is ``gi - direct`` and its point light sits at ``light_position``."""
    rng = np.random.default_rng(seed)
    v, u = np.meshgrid(
        (np.arange(height) + 0.5) / height, (np.arange(width) + 0.5) / width, indexing="ij"
    )
    covered = ~((u > 0.92) & (v < 0.5))
    floor = v > 0.6
    normal = np.zeros((height, width, 3), np.float32)
    normal[..., 2] = floor
    normal[..., 1] = np.where(floor, 0.0, -1.0)
    position = np.stack(
        [u * 4 - 2, np.where(floor, 4 * (v - 0.6), 3.0), np.where(floor, 0.0, 3 * (1 - v))], -1
    ).astype(np.float32)
    x, y = np.meshgrid(np.arange(width), np.arange(height))
    alb = np.where((x // 64 + y // 64) % 2 == 0, 0.8, 0.3)
    albedo = np.repeat(alb[..., None], 3, -1).astype(np.float32)
    d = 0.5 * alb * np.maximum(normal[..., 2], 0.2) + 0.05 * rng.random((height, width))
    g = d + 0.1 * alb * (1 - v) + 0.02 * rng.random((height, width))
    direct = np.repeat(d[..., None], 3, -1).astype(np.float32)
    gi = np.repeat(g[..., None], 3, -1).astype(np.float32)
    depth = np.where(covered, 1 + 5 * (1 - v) + u, 1e10).astype(np.float32)
    for a in (position, normal, albedo, direct, gi):
        a[~covered] = 0.0
    return {
        "position": position,
        "normal": normal,
        "albedo": albedo,
        "depth": depth,
        "direct": direct,
        "diffuse_direct": direct,
        "indirect": gi - direct,
        "covered": covered,
        "light_position": [0.0, 1.0, 2.5],
    }


#: An invertible camera matrix for synthetic views (the features do not use the camera).
_CAMERA = [[1.0, 0, 0, 0], [0, 1.0, 0, 0], [0, 0, -1.02, -0.2], [0, 0, -1.0, 0]]


def synthetic_view(capture: dict[str, Any], *, indirect: bool = True) -> _native.View:
    """The :class:`vplace.View` of :func:`synthetic_capture` (without its indirect image when
    ``indirect`` is false)."""
    return _native.View(
        **{k: capture[k] for k in ("position", "normal", "albedo", "covered", "depth", "direct")},
        diffuse_direct=capture["diffuse_direct"],
        indirect=capture.get("indirect") if indirect else None,
        specular=capture.get("specular"),
        camera_position=[0.0, 0.0, 10.0],
        world_to_clip=_CAMERA,
        name=capture.get("name", "synthetic"),
    )


def light_scene(capture: dict[str, Any]) -> _native.Scene:
    """A scene holding only a small triangle and the capture's point light (the strongest light
    of its views)."""
    v = np.array([[0, 0, -50], [0.1, 0, -50], [0, 0.1, -50]], np.float32)
    t = np.array([[0, 1, 2]], np.uint32)
    light = _native.Light.point(list(capture["light_position"]), [10.0, 10.0, 10.0])
    return _native.Scene(v, t, np.zeros(1, np.uint32), np.full((1, 3), 0.5, np.float32), [light])


def numpy_extract(capture: dict[str, Any], cell_px: int = 16) -> dict[str, Any]:
    """The native ``extract_features`` in numpy (point light from ``light_position``)."""
    pos = capture["position"].astype(np.float64)
    nrm = capture["normal"].astype(np.float64)
    alb = capture["albedo"].astype(np.float64)
    dep = capture["depth"].astype(np.float64)
    dl = capture["direct"].astype(np.float64) @ _LUM
    ind = capture.get("indirect")
    h, w = dep.shape
    cx, cy = -(-w // cell_px), -(-h // cell_px)
    finite = np.isfinite(pos).all(-1) & np.isfinite(nrm).all(-1) & np.isfinite(alb).all(-1)
    finite &= np.isfinite(dep) & np.isfinite(dl)
    if ind is not None:
        il = ind.astype(np.float64) @ _LUM
        finite &= np.isfinite(il)
    ok = capture["covered"] & finite
    yy, xx = np.nonzero(ok)
    cell = (yy // cell_px) * cx + xx // cell_px
    ncell = cx * cy
    count = np.bincount(cell, minlength=ncell).astype(np.float64)
    ty = np.minimum(cell_px, h - np.arange(cy) * cell_px)
    tx = np.minimum(cell_px, w - np.arange(cx) * cell_px)
    total = np.outer(ty, tx).reshape(-1).astype(np.float64)
    p, n = pos[yy, xx], nrm[yy, xx]
    light = np.asarray(capture["light_position"], np.float64)
    to_l = light - p
    ln = np.linalg.norm(to_l, axis=1)
    cos = np.where(ln > 0, np.maximum((n * to_l).sum(1) / np.where(ln > 0, ln, 1), 0), 0)
    d = dep[yy, xx]
    cols = [n[:, 0], n[:, 1], n[:, 2], alb[yy, xx] @ _LUM, d, p[:, 0], p[:, 1], p[:, 2], cos]
    cols += [np.zeros_like(d), dl[yy, xx]]
    nonempty = np.nonzero(count)[0]
    c = count[nonempty]
    means = [np.bincount(cell, col, ncell)[nonempty] / c for col in cols]
    nn = np.bincount(cell, (n * n).sum(1), ncell)[nonempty] / c
    nvar = np.maximum(nn - means[0] ** 2 - means[1] ** 2 - means[2] ** 2, 0)
    dmean = np.bincount(cell, d, ncell) / np.maximum(count, 1)
    dvar = np.bincount(cell, (d - dmean[cell]) ** 2, ncell)[nonempty] / c
    values = np.stack([*means, c / total[nonempty], nvar, dvar], 1)
    label = None
    if ind is not None:
        label = np.bincount(cell, np.abs(il[yy, xx]), ncell)[nonempty] / c
    return {"cells": nonempty, "values": values, "label": label}


def numpy_fit(values: np.ndarray, label: np.ndarray) -> dict[str, Any]:
    """Plain least squares on Min-Max normalized, standardized columns (constants dropped)."""
    lo, hi = values.min(0), values.max(0)
    x = np.where(hi > lo, (values - lo) / np.where(hi > lo, hi - lo, 1), 0.0)
    mean, std = x.mean(0), x.std(0)
    keep = std > 1e-13 * np.abs(x).max(0)
    xs = (x[:, keep] - mean[keep]) / std[keep]
    a = np.column_stack([np.ones(len(label)), xs])
    sol, *_ = np.linalg.lstsq(a, label, rcond=None)
    coef = np.zeros(values.shape[1])
    coef[keep] = sol[1:] / std[keep]
    intercept = sol[0] - (coef[keep] * mean[keep]).sum()
    total = np.abs(coef).sum()
    weights = np.abs(coef) / total if total > 0 else np.zeros_like(coef)
    fitted = intercept + x @ coef
    sst = ((label - label.mean()) ** 2).sum()
    r2 = 1 - ((label - fitted) ** 2).sum() / sst
    return {"coefficients": coef, "intercept": intercept, "weights": weights, "r2": r2}


def _median_ms(f: Callable[[], Any], repeat: int) -> tuple[float, float]:
    """Median wall-clock and process CPU time (all threads) of ``f``, in ms."""
    f()
    walls, cpus = [], []
    for _ in range(repeat):
        t, c = time.perf_counter(), time.process_time()
        f()
        walls.append(time.perf_counter() - t)
        cpus.append(time.process_time() - c)
    return statistics.median(walls) * 1e3, statistics.median(cpus) * 1e3


def main() -> None:
    """Times both implementations and prints the table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--width", type=int, default=1920)
    ap.add_argument("--height", type=int, default=1080)
    ap.add_argument("--cell-px", type=int, default=16)
    ap.add_argument("--repeat", type=int, default=15)
    args = ap.parse_args()
    cap = synthetic_capture(args.width, args.height)
    view, scene = synthetic_view(cap), light_scene(cap)

    def native_extract() -> dict[str, Any]:
        return _native.extract_features(scene, view, cell_px=args.cell_px)

    cells = native_extract()
    lo, hi = cells.values.min(0), cells.values.max(0)
    x = np.where(hi > lo, (cells.values - lo) / np.where(hi > lo, hi - lo, 1), 0.0)
    x = np.ascontiguousarray(x)
    y = np.ascontiguousarray(cells.label)
    plain = {"select": False, "collinear_rtol": 0.0, "ridge_above": float("inf")}
    rows = [
        (
            f"extract {args.width}x{args.height}, cell {args.cell_px}",
            _median_ms(native_extract, args.repeat),
            _median_ms(lambda: numpy_extract(cap, args.cell_px), args.repeat),
        ),
        (
            f"plain OLS fit {x.shape[0]} x {x.shape[1]}",
            _median_ms(
                lambda: _native.fit_design(x, y, _native.FitParams(**plain)), args.repeat * 4
            ),
            _median_ms(lambda: numpy_fit(cells.values, y), args.repeat * 4),
        ),
        (
            "full fit (collinear + 5-fold CV selection)",
            _median_ms(lambda: _native.fit_design(x, y), args.repeat * 4),
            None,
        ),
    ]
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(
        f"vplace.bench_fit: median of {args.repeat}+ runs, {os.cpu_count()} CPUs,"
        f" load average {load:.1f}; wall ms (CPU ms, all threads)"
    )
    print(f"{'what':<44} {'native':>16} {'numpy':>16} {'numpy/native':>13}")
    for name, nat, ref in rows:
        ref_s = "n/a" if ref is None else f"{ref[0]:.2f} ({ref[1]:.2f})"
        ratio = "n/a" if ref is None else f"{ref[0] / nat[0]:.1f}x"
        print(f"{name:<44} {f'{nat[0]:.2f} ({nat[1]:.2f})':>16} {ref_s:>16} {ratio:>13}")


if __name__ == "__main__":
    main()
