"""vplace: regression-guided virtual point light layout, at the numpy level.

Usable without Blender. Everything here is the Rust extension ``vplace._native`` (typed in
``_native.pyi``); this package re-exports it and adds the benchmarks (``python -m
vplace.bench_layout``, ``bench_fit``, ``bench_par2d``) and the PAR 2D wrapper
(:mod:`vplace.par2d`).

The pieces, in pipeline order:

- :class:`Scene` (triangles, per-material albedo and emission, :class:`Light` objects of
  every Blender kind: point, spot, area, sun and the world with its environment image; a BVH;
  optionally UVs, textures read through a :class:`TextureMap` per material and
  :class:`AlphaTest` cut-outs, so the albedo at a ray hit is the texture's and rays pass cut
  texels) and
  :class:`View` (one captured view: G-buffer, lighting passes, camera; checked once: a
  non-finite G-buffer value on a covered pixel is an :class:`InputError`, a non-finite lighting
  value masks the pixel and is counted in ``View.masked_pixels``). A view's ``indirect`` image
  is the light the VPLs must reproduce; a view without it (``View.without_indirect()``) is one
  the model has not seen.
- Each stage's settings are a frozen class with the core's defaults and named presets:
  :class:`FitParams`, :class:`LayoutParams` (``LayoutParams(budget=64, seed=1)``,
  ``LayoutParams.SINGLE_PASS``), :class:`RefitParams`; a call takes them as its third (fourth for
  :func:`refit`) argument.
- :func:`fit` fits one regression of the per-cell indirect luminance on the cells of every
  view; the :class:`Fit` predicts other views (``Fit.predict``), prints as a table and saves as
  JSON. :func:`fit_design` runs the same solver on a given design matrix.
- :func:`layout` lays out one world-space :class:`VplSet` for a list of views (strata over the
  cells of every view and the off-screen light paths, the budget split by predicted indirect
  light, then iterations against every view's indirect image); :func:`refit` refits the VPL
  powers against every view at once (non-negative least squares, each view's pixels weighed by
  the inverse of its light, ``Refit.view_weights``; ``coverage=`` views hold the VPLs lighting
  what no view saw); :func:`refit_frames` refits them on several frames whose
  light alone differs (the same G-buffers, ``Scene.same_occluders``), tracing the shadow rays
  once for all, each frame's result what :func:`refit` gives it; :func:`uniform_vpls` (Keller)
  and :func:`rsm_vpls` are the baselines.
- :func:`direct_light` estimates every light source's direct light over a view's G-buffer
  with shadow rays (irradiance / pi, what Cycles' DiffDir pass holds).
- :func:`evaluate` renders a VPL set's indirect light over a view's G-buffer with shadow rays.
  A :class:`VplSet` carries its ``profile`` (``"cosine"``: AREA disk lights, ``"omni"``: POINT
  lights) and near-field ``radius``: exactly the lights the add-on writes. For a set with
  ``VplSet.near_field`` (or with ``near_field=True``) it adds the light between nearby surfaces
  (a room's corners) that no VPL can carry, gathered from the view's pixels within
  :func:`near_field_distance` of the set's radii (``VplSet.near_field_distance``): what EEVEE's
  global-illumination fast GI gives within that distance with ray tracing on, as the
  write-back and EEVEE's set-up apply it for such a set. ``vplace.job.lay_out`` gives it to the
  regression-guided sets whose captures it brings closer (``vplace.job.choose_near_field``).
  :func:`near_field_light` gives that gather alone, from an image ``evaluate`` already made,
  and :func:`near_field_reach` where it can reach: the pixels that gather, and those whose
  light they read (with ``View.restricted``, ``evaluate`` shades only the pixels asked for).
- :func:`rmse`, :func:`relative_mse`, :func:`ssim`: the metrics of DESIGN.md;
  :func:`ssim_noise_free`, :func:`ssim_ceiling` and :func:`rmse_noise_free`: SSIM and RMSE seen
  through the truth's own noise, from two renders of the truth with different seeds.

Long calls release the GIL, report progress and cancel through a :class:`Progress`; a Rust
panic surfaces as :class:`InternalError`, never as a crash.
"""

from vplace import coverage as coverage
from vplace import par2d as par2d
from vplace._native import (
    DISK_PATCHES,
    LUMINANCE,
    MAX_BOUNCES,
    MAX_DIRECT_SAMPLES,
    MAX_RADIUS_FACTOR,
    NEAR_FIELD_FRACTION,
    REGION_MARGIN,
    SPACING_NEIGHBOURS,
    VPL_SURFACE_OFFSET,
    AlphaTest,
    CancelledError,
    CellFeatures,
    EvalStats,
    Fit,
    FitParams,
    InputError,
    InternalError,
    Layout,
    LayoutParams,
    Light,
    Progress,
    Refit,
    RefitParams,
    Scene,
    TextureMap,
    View,
    VplaceError,
    VplSet,
    __version__,
    direct_light,
    evaluate,
    extract_features,
    feature_registry,
    fit,
    fit_design,
    layout,
    linear_image,
    near_field_distance,
    near_field_light,
    near_field_reach,
    refit,
    refit_frames,
    relative_mse,
    rmse,
    rmse_noise_free,
    rsm_vpls,
    ssim,
    ssim_ceiling,
    ssim_noise_free,
    uniform_vpls,
)
from vplace.budget import PIXEL_BUDGET, REFIT_PIXEL_BUDGET, refit_stride_for, stride_for

__all__ = [
    "DISK_PATCHES",
    "LUMINANCE",
    "MAX_BOUNCES",
    "MAX_DIRECT_SAMPLES",
    "MAX_RADIUS_FACTOR",
    "NEAR_FIELD_FRACTION",
    "PIXEL_BUDGET",
    "REFIT_PIXEL_BUDGET",
    "REGION_MARGIN",
    "SPACING_NEIGHBOURS",
    "VPL_SURFACE_OFFSET",
    "AlphaTest",
    "CancelledError",
    "CellFeatures",
    "EvalStats",
    "Fit",
    "FitParams",
    "InputError",
    "InternalError",
    "Layout",
    "LayoutParams",
    "Light",
    "Progress",
    "Refit",
    "RefitParams",
    "Scene",
    "TextureMap",
    "View",
    "VplSet",
    "VplaceError",
    "__version__",
    "direct_light",
    "evaluate",
    "extract_features",
    "feature_registry",
    "fit",
    "fit_design",
    "layout",
    "linear_image",
    "near_field_distance",
    "near_field_light",
    "near_field_reach",
    "refit",
    "refit_frames",
    "refit_stride_for",
    "relative_mse",
    "rmse",
    "rmse_noise_free",
    "rsm_vpls",
    "ssim",
    "ssim_ceiling",
    "ssim_noise_free",
    "stride_for",
    "uniform_vpls",
]
