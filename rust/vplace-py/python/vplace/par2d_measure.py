"""Speed against error of the PAR 2D light-map methods on a random scene of lights and occluders.

The measurement the report plots and ``python -m vplace.bench_par2d`` prints: ``exact`` (the
reference), ``par`` and Monte Carlo at several ray counts on one ``size`` x ``size`` map of
``[-1, 1]^2``. RMSE is over all pixels and the three channels.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from vplace.par2d import Method, Scene2D

BOUNDS = (-1.0, -1.0, 1.0, 1.0)


@dataclass(frozen=True)
class Par2dRow:
    """One method's time and error on the light map."""

    method: Method
    #: Rays per pixel (Monte Carlo); None for the deterministic methods.
    rays: int | None
    pixels: int
    seconds: float
    #: RMSE against ``exact`` (0 for ``exact`` itself).
    rmse: float


def random_scene(lights: int, occluders: int, seed: int) -> Scene2D:
    """Random regular n-gons in ``[-1, 1]^2``: lights of radius 0.03-0.08, emission 0.5-2,
    occluders of radius 0.01 to ``0.6 / sqrt(occluders)`` (they may overlap)."""
    rng = np.random.default_rng(seed)
    polys = []
    emission = np.zeros((lights + occluders, 3))
    max_r = 0.6 / math.sqrt(max(occluders, 1))
    for k in range(lights + occluders):
        light = k < lights
        centre = rng.uniform(-0.9, 0.9, size=2)
        r = rng.uniform(0.03, 0.08) if light else rng.uniform(0.01, max(max_r, 0.01))
        n = int(rng.integers(3, 9))
        a = rng.uniform(0.0, 2.0 * math.pi) + 2.0 * math.pi * np.arange(n) / n
        polys.append(centre + r * np.stack([np.cos(a), np.sin(a)], axis=1))
        if light:
            emission[k] = rng.uniform(0.5, 2.0, size=3)
    return Scene2D(polys, emission)


def timed_map(
    scene: Scene2D, size: int, method: Method, rays: int = 1
) -> tuple[float, npt.NDArray[np.float64]]:
    """The seconds and the ``size`` x ``size`` light map of ``method`` (seed 7)."""
    t0 = time.perf_counter()
    img = scene.light_map(BOUNDS, size, size, method, rays=rays, seed=7)
    return time.perf_counter() - t0, img


def rmse(a: npt.NDArray[np.float64], b: npt.NDArray[np.float64]) -> float:
    """Root mean square difference over every pixel and channel."""
    return float(np.sqrt(np.mean((a - b) ** 2)))


def measure(
    size: int = 256, rays: tuple[int, ...] = (16, 64, 256), seed: int = 1
) -> tuple[list[Par2dRow], npt.NDArray[np.float64]]:
    """Speed against error on a ``size`` x ``size`` map of the 8-light, 64-occluder scene: one
    row per method (``exact``, ``par``, ``monte_carlo`` at each ray count); and the exact map."""
    scene = random_scene(8, 64, seed=seed)
    pixels = size * size
    t_exact, exact = timed_map(scene, size, "exact")
    rows = [Par2dRow("exact", None, pixels, t_exact, 0.0)]
    t_par, par = timed_map(scene, size, "par")
    rows.append(Par2dRow("par", None, pixels, t_par, rmse(par, exact)))
    for n in rays:
        t, img = timed_map(scene, size, "monte_carlo", n)
        rows.append(Par2dRow("monte_carlo", n, pixels, t, rmse(img, exact)))
    return rows, exact
