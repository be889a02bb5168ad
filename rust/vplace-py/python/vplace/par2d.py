"""Analytic 2D direct lighting: PAR, an exact angular sweep and a Monte Carlo baseline.

A 2D scene is a list of convex polygons, each a light (RGB emission ``>= 0``, not all zero) or
an occluder (emission zero). Every polygon is opaque, lights included. The quantity computed at
a point ``p`` is the fluence / 2 pi::

    L(p) = sum over lights of e_L * mu(visible part of Theta_L(p)) / (2 pi)

(no cosine term: the probability that a uniformly random ray from ``p`` first hits ``L``,
times ``e_L``). ``method`` picks the algorithm:

- ``"par"``: the paper's interval method (Qiu, "Probabilistic Angular Radiance") with its
  per-case depth tests. Exact when no polygon intersects a light; wrong when an occluder crosses
  a light (in front of it over part of its interval and behind it elsewhere).
- ``"exact"``: an angular sweep over all edges tracking the nearest one; exact for any layout.
- ``"monte_carlo"``: ``rays`` uniform random rays per point, deterministic per ``seed``.

Decisions: non-convex polygons are rejected with :class:`vplace.InputError` (split them into
convex parts first); either orientation is accepted; duplicate and collinear vertices are
dropped. Polygons are closed sets: a point on an edge or vertex is inside. A point inside an
occluder gets 0; otherwise a point inside lights gets the componentwise maximum of their
emissions.

Example::

    import numpy as np
    from vplace.par2d import Scene2D

    square = np.array([[2.0, -0.5], [3.0, -0.5], [3.0, 0.5], [2.0, 0.5]])
    scene = Scene2D.from_lights([square], emission=[[1.0, 1.0, 1.0]])
    scene.irradiance(np.zeros((1, 2)))  # 2 * atan(0.25) / (2 pi) per channel
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Literal

import numpy as np
import numpy.typing as npt

from vplace._native import InputError, Progress
from vplace._native import Scene2D as _NativeScene2D

Method = Literal["par", "exact", "monte_carlo"]
METHODS: tuple[Method, ...] = ("par", "exact", "monte_carlo")

__all__ = ["METHODS", "Method", "Scene2D", "irradiance", "light_map"]


def _polygon(poly: npt.ArrayLike, index: int) -> npt.NDArray[np.float64]:
    try:
        a = np.asarray(poly, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"polygon {index} must be an (n, 2) array of numbers: {exc}") from exc
    if a.ndim != 2 or a.shape[1] != 2 or a.shape[0] < 3:
        raise InputError(f"polygon {index} must have shape (n, 2) with n >= 3, got {a.shape}")
    return a


def _emission(emission: npt.ArrayLike, count: int) -> npt.NDArray[np.float64]:
    try:
        e = np.asarray(emission, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"emission must be a ({count}, 3) array of numbers: {exc}") from exc
    if e.shape != (count, 3):
        raise InputError(
            f"emission must have shape ({count}, 3), one row per polygon, got {e.shape}"
        )
    return np.ascontiguousarray(e)


class Scene2D:
    """Convex polygons, each a light or an occluder; immutable once built.

    Args:
        polygons: one ``(n_i, 2)`` array of vertices per polygon (any orientation, convex).
        emission: ``(P, 3)`` RGB emission per polygon, ``>= 0``; a zero row is an occluder.

    Raises:
        vplace.InputError: no polygons, wrong shapes, NaN or inf, negative emission,
            a non-convex or zero-area polygon.
    """

    def __init__(self, polygons: Sequence[npt.ArrayLike], emission: npt.ArrayLike) -> None:
        polys = [_polygon(p, i) for i, p in enumerate(polygons)]
        if not polys:
            raise InputError("polygons is empty: pass at least one polygon")
        e = _emission(emission, len(polys))
        vertices = np.ascontiguousarray(np.concatenate(polys, axis=0))
        self._native = _NativeScene2D(vertices, [len(p) for p in polys], e)
        self._emission = e

    @classmethod
    def from_lights(
        cls,
        lights: Sequence[npt.ArrayLike],
        emission: npt.ArrayLike,
        occluders: Sequence[npt.ArrayLike] = (),
    ) -> Scene2D:
        """A scene of ``lights`` (with ``(L, 3)`` ``emission``) followed by ``occluders``.

        Raises:
            vplace.InputError: as the constructor, and when there are no lights.
        """
        if len(lights) == 0:
            raise InputError("lights is empty: pass at least one light polygon")
        e = _emission(emission, len(lights))
        if np.all(np.nan_to_num(e, nan=1.0) == 0.0, axis=1).any():
            raise InputError("every light needs a positive emission in some channel")
        full = np.concatenate([e, np.zeros((len(occluders), 3))], axis=0)
        return cls([*lights, *occluders], full)

    @property
    def polygon_count(self) -> int:
        """Number of polygons."""
        return self._native.polygon_count

    @property
    def light_count(self) -> int:
        """Number of lights (polygons with some positive emission)."""
        return self._native.light_count

    @property
    def emission(self) -> npt.NDArray[np.float64]:
        """``(P, 3)`` emission per polygon (a copy)."""
        return self._emission.copy()

    def polygon(self, index: int) -> npt.NDArray[np.float64]:
        """The cleaned ``(n, 2)`` vertices of polygon ``index``, counter-clockwise."""
        return self._native.polygon(index)

    def irradiance(
        self,
        points: npt.ArrayLike,
        method: Method = "exact",
        *,
        rays: int = 1024,
        seed: int = 0,
        progress: Progress | None = None,
    ) -> npt.NDArray[np.float64]:
        """Fluence / 2 pi at ``points`` ``(N, 2)``; returns ``(N, 3)`` float64.

        ``rays`` and ``seed`` apply to ``"monte_carlo"`` only (point ``i`` uses random stream
        ``i``). ``progress`` counts points and can cancel the call.
        """
        pts = np.ascontiguousarray(np.asarray(points, dtype=np.float64))
        return self._native.irradiance(pts, method, rays, seed, progress)

    def light_map(
        self,
        bounds: tuple[float, float, float, float],
        width: int,
        height: int,
        method: Method = "exact",
        *,
        rays: int = 1024,
        seed: int = 0,
        progress: Progress | None = None,
    ) -> npt.NDArray[np.float64]:
        """A ``(height, width, 3)`` float64 image of ``bounds = (xmin, ymin, xmax, ymax)``.

        Row 0 is the top (largest y); each pixel is sampled at its centre. Parallel over rows.
        """
        if len(bounds) != 4:
            raise InputError(f"bounds must be (xmin, ymin, xmax, ymax), got {bounds!r}")
        b = (float(bounds[0]), float(bounds[1]), float(bounds[2]), float(bounds[3]))
        return self._native.light_map(b, width, height, method, rays, seed, progress)

    def __len__(self) -> int:
        return self.polygon_count

    def __repr__(self) -> str:
        return f"Scene2D(polygons={self.polygon_count}, lights={self.light_count})"


def irradiance(
    points: npt.ArrayLike,
    lights: Sequence[npt.ArrayLike],
    emission: npt.ArrayLike,
    occluders: Sequence[npt.ArrayLike] = (),
    method: Method = "exact",
    *,
    rays: int = 1024,
    seed: int = 0,
) -> npt.NDArray[np.float64]:
    """Fluence / 2 pi at ``points`` ``(N, 2)`` for one call; see :class:`Scene2D`."""
    scene = Scene2D.from_lights(lights, emission, occluders)
    return scene.irradiance(points, method, rays=rays, seed=seed)


def light_map(
    lights: Sequence[npt.ArrayLike],
    emission: npt.ArrayLike,
    occluders: Sequence[npt.ArrayLike],
    bounds: tuple[float, float, float, float],
    width: int,
    height: int,
    method: Method = "exact",
    *,
    rays: int = 1024,
    seed: int = 0,
) -> npt.NDArray[np.float64]:
    """A ``(height, width, 3)`` light map of ``bounds``; see :meth:`Scene2D.light_map`."""
    scene = Scene2D.from_lights(lights, emission, occluders)
    return scene.light_map(bounds, width, height, method, rays=rays, seed=seed)
