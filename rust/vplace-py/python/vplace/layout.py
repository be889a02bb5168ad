"""VPL layout at the numpy level (DESIGN: Layout).

``layout(scene, capture, ...)`` lays out a VPL budget for one captured view: candidate emitters
from the view's pixels (flux ``albedo * pi * DiffDir * footprint``) and from light rays the camera
does not see, strata = the image cells plus one off-screen stratum, the budget split by
``lerp(uniform, regression-guided, alpha)`` with largest remainder, then (when the capture has
``gi`` and ``direct``) a few evaluator iterations at reduced resolution that move budget toward
cells with a high residual against the indirect image ``gi - direct``. The best iteration is
returned. ``rsm_vpls`` is the reflective-shadow-map baseline at the same count.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from vplace import _native
from vplace.fit import _LUMINANCE, FitResult


def _get(capture: Any, name: str) -> Any:
    if isinstance(capture, Mapping):
        return capture.get(name)
    return getattr(capture, name, None)


def _need(capture: Any, name: str) -> Any:
    value = _get(capture, name)
    if value is None:
        raise _native.InputError(f"the capture has no {name!r}")
    return value


@dataclass(frozen=True)
class Layout:
    """A VPL layout: the VPLs (float32 (n, 3) each) and how it was reached."""

    position: np.ndarray
    normal: np.ndarray
    flux: np.ndarray
    counts: np.ndarray
    """VPLs drawn from each cell, int64 (cells_y, cells_x)."""
    offscreen_count: int
    """VPLs drawn from the off-screen strata."""
    pool_count: int
    """VPLs drawn jointly from the cells that hold flux but got no VPL of their own."""
    errors: list[float] = field(default_factory=list)
    """RMSE against the indirect image at each iteration (empty without iteration)."""
    best: int | None = None
    """The iteration the VPLs come from (the minimum of ``errors``)."""
    seconds: list[float] = field(default_factory=list)
    shadow_rays: list[int] = field(default_factory=list)
    """Shadow rays traced at each iteration."""
    reused_rays: list[int] = field(default_factory=list)
    """Pixel-VPL pairs at each iteration whose visibility came from the previous iteration (a VPL
    at the same position) instead of a shadow ray; the result is the same either way."""
    strata_flux: np.ndarray | None = None
    """Reflected flux of each cell's candidates, float32 (cells_y, cells_x, 3)."""
    offscreen_flux: list[float] = field(default_factory=list)
    """Total RGB flux of the off-screen strata."""
    offscreen_view_weight: list[float] = field(default_factory=list)
    """View weight of each off-screen stratum, by increasing view efficiency, then the dark one
    (0): how well its emitters light what the camera sees, relative to the on-screen ones."""
    candidates: int = 0
    light_hits_on_screen: int = 0
    indirect_source: str = "none"
    """Where the emitters' indirect irradiance came from: ``"captured"`` (the capture's
    ``diffuse_indirect``), ``"predicted"`` (the fit's per-cell prediction) or ``"none"``."""

    def __len__(self) -> int:
        return int(self.position.shape[0])

    @property
    def error(self) -> float | None:
        """The error of the returned layout, or None without iteration."""
        return None if self.best is None else self.errors[self.best]


def layout(
    scene: _native.Scene,
    capture: Any,
    *,
    camera_position: Any,
    world_to_clip: Any,
    fit: FitResult | None = None,
    budget: int = 256,
    alpha: float = 1.0,
    cell_px: int | None = None,
    iterate: bool = True,
    light_rays: int = 4096,
    seed: int = 0,
    stride: int = 4,
    iterations: int = 3,
    tolerance: float = 0.01,
    step: float = 0.5,
    profile: str = "cosine",
    r_min: float = 0.01,
    multi_bounce: bool = True,
    progress: _native.Progress | None = None,
) -> Layout:
    """Lays out ``budget`` VPLs for the captured view ``capture``.

    ``capture``: a mapping or object with float32 ``position``, ``normal``, ``albedo`` (DiffCol),
    ``diffuse_direct`` (DiffDir) (H, W, 3) and bool ``covered`` (H, W); for the iteration also
    ``gi`` and ``direct`` (or ``indirect``); for ``fit`` the passes :meth:`FitResult.predict` needs.
    ``camera_position``: (3,) world position; ``world_to_clip``: (4, 4) rows, OpenGL clip
    conventions (Blender: ``cam.calc_matrix_camera(depsgraph, x=W, y=H) @
    cam.matrix_world.inverted()``). ``fit``: a model whose per-cell prediction guides the
    allocation (``alpha`` blends uniform 0 and guided 1); without it the start is uniform.
    ``cell_px`` defaults to the fit's. ``stride``: evaluate every stride-th pixel (4 = quarter
    resolution); ``iterations``: at most this many evaluations; ``tolerance``: stop when the RMSE
    improves by less than this fraction; ``step``: how far each iteration moves toward the
    residual. ``iterate=False`` (or no ``gi``) returns the one-shot layout.

    ``multi_bounce``: a pixel emitter reflects all the light its surface receives, not only the
    direct light: ``E_p = pi * (DiffDir_p + DiffInd_p)``, so the VPLs carry the second and later
    bounces that Cycles measured at the surfaces the camera sees. ``DiffInd`` is the capture's
    ``diffuse_indirect`` when it has one; otherwise (a held-out view, which has no GI render) the
    fit's per-cell prediction of the indirect luminance ``dL_k`` stands in, as the grey
    irradiance ``dL_k / albedo_k`` (``albedo_k`` the cell's mean albedo luminance). The
    light-traced emitters of the off-screen stratum then come from every bounce of the light
    paths, not only the first (:func:`vplace.uniform_vpls` with ``bounces=MAX_BOUNCES``).
    """
    cell = cell_px or (fit.cell_px if fit is not None and fit.cell_px else 16)
    predicted = None
    if fit is not None:
        predicted = np.ascontiguousarray(fit.predict(capture), dtype=np.float64)
    indirect = None
    if iterate:
        indirect = _get(capture, "indirect")
        if indirect is None and _get(capture, "gi") is not None:
            indirect = np.asarray(_need(capture, "gi"), dtype=np.float32) - np.asarray(
                _need(capture, "direct"), dtype=np.float32
            )
        if indirect is not None:
            indirect = np.ascontiguousarray(
                np.nan_to_num(indirect, nan=0.0, posinf=0.0, neginf=0.0), dtype=np.float32
            )
    irradiance, source = _emitter_irradiance(capture, predicted, cell, multi_bounce)
    m = np.asarray(world_to_clip, dtype=np.float32)
    d = _native.layout(
        scene,
        _need(capture, "position"),
        _need(capture, "normal"),
        _need(capture, "albedo"),
        _need(capture, "covered"),
        irradiance,
        [float(v) for v in np.asarray(camera_position, dtype=np.float64).reshape(3)],
        [[float(v) for v in row] for row in m.reshape(4, 4)],
        indirect=indirect,
        predicted=predicted,
        budget=budget,
        alpha=alpha,
        cell_px=cell,
        light_rays=light_rays,
        bounces=_native.MAX_BOUNCES if multi_bounce else 1,
        seed=seed,
        stride=stride,
        iterations=iterations,
        tolerance=tolerance,
        step=step,
        profile=profile,
        r_min=r_min,
        progress=progress,
    )
    return Layout(**d, indirect_source=source)


def _emitter_irradiance(
    capture: Any, predicted: np.ndarray | None, cell: int, multi_bounce: bool
) -> tuple[Any, str]:
    """The irradiance / pi the pixel emitters reflect, and where its indirect part came from."""
    direct = _need(capture, "diffuse_direct")
    if not multi_bounce:
        return direct, "none"
    direct = np.asarray(direct, dtype=np.float32)
    captured = _get(capture, "diffuse_indirect")
    if captured is not None:
        captured = np.asarray(captured, dtype=np.float32)
        if captured.shape != direct.shape:
            raise _native.InputError(
                f"diffuse_indirect has shape {captured.shape}, diffuse_direct {direct.shape}"
            )
        ind = np.nan_to_num(captured, nan=0.0, posinf=0.0, neginf=0.0)
        return np.ascontiguousarray(direct + np.maximum(ind, 0.0)), "captured"
    if predicted is None:
        return direct, "none"
    h, w = direct.shape[:2]
    albedo = np.asarray(_need(capture, "albedo"), dtype=np.float64)[..., :3] @ _LUMINANCE
    covered = np.asarray(_need(capture, "covered"), dtype=bool) & np.isfinite(albedo)
    cy, cx = -(-h // cell), -(-w // cell)
    if predicted.shape != (cy, cx):
        raise _native.InputError(f"the prediction has shape {predicted.shape}, cells ({cy}, {cx})")
    pad = ((0, cy * cell - h), (0, cx * cell - w))
    a = np.pad(np.where(covered, albedo, 0.0), pad).reshape(cy, cell, cx, cell).sum((1, 3))
    k = np.pad(covered, pad).reshape(cy, cell, cx, cell).sum((1, 3))
    mean_albedo = np.where(k > 0, a / np.maximum(k, 1), 0.0)
    cell_irr = np.where(
        mean_albedo > 1e-3, np.maximum(predicted, 0.0) / np.maximum(mean_albedo, 1e-3), 0.0
    )
    per_pixel = np.repeat(np.repeat(cell_irr, cell, 0), cell, 1)[:h, :w]
    return np.ascontiguousarray(direct + per_pixel[..., None].astype(np.float32)), "predicted"
