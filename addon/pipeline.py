"""The one job pipeline: export -> capture -> fit -> VPLs -> evaluator -> write-back -> report.

Used by the operators, the command line (``python -m addon.cli``) and the report, which only
loops over views, budgets and seeds. The stages:

- :func:`prepare` (Blender, main thread): export the scene, build the native scene with its BVH,
  capture every view with Cycles (cached).
- :func:`lay_out` (no bpy: safe on a worker thread): the one method dispatch of :data:`METHODS`.
- :func:`compute`: :func:`lay_out`, then the evaluator and the metrics on the first view.
- :func:`run_main_job`: all of it, the write-back, and the files of the report.

Every stage is timed and announced through a :class:`StageTimer`.
"""

from __future__ import annotations

import contextlib
import functools
import json
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import bpy
import numpy as np

from . import apply, capture, eevee_setup, export, images
from .emitter_lights import (
    SUN_MIN_LIT,
    EmitterLight,
    SunLight,
    emitter_lights,
    sun_lit_fraction,
    world_sun,
)
from .errors import AddonError, CaptureError, ExportError
from .native import build_scene, gloss_mask, view_of, vplace
from .settings import override
from .views import ViewSet, ViewSpec, capture_resolution
from .views import specs as view_specs

#: The layout methods, in the report's order: Keller's light paths, reflective shadow maps, the
#: regression-guided layout, and the same with its VPL powers refitted to the captured light.
METHODS = ("uniform", "rsm", "vplace", "vplace+refit")
#: How the regression picks its features: "auto", the surface's features (the same from every
#: view) with those that do not raise CV R^2 dropped; "view", also the view's features (depth,
#: coverage, normal and depth spread); "all", every usable feature, no selection.
FEATURE_MODES = ("auto", "view", "all")


@dataclass
class StageTimer:
    """Wall time per named stage, in the order they ran."""

    log: Callable[[str], None] = print
    seconds: dict[str, float] = field(default_factory=dict)

    @contextmanager
    def stage(self, name: str) -> Iterator[None]:
        self.log(f"[vplace] {name} ...")
        start = time.perf_counter()
        try:
            yield
        finally:
            self.seconds[name] = time.perf_counter() - start
            self.log(f"[vplace] {name}: {self.seconds[name]:.2f} s")


def quiet_timer() -> StageTimer:
    """A timer that logs nothing."""
    return StageTimer(log=lambda _line: None)


def method_name(method: str, refit: bool) -> str:
    """The :data:`METHODS` name of a layout method with or without the power refit (the panel and
    the command line set them apart)."""
    return "vplace+refit" if method == "vplace" and refit else method


@dataclass
class Job:
    """The parameters of one run. The panel (``properties.py``), the command line and the report
    build it from their settings; its defaults are theirs."""

    n_vpls: int = 128
    #: Capture size: pixels on the long side, at the render's aspect ratio.
    size: int = 160
    #: An explicit capture size (W, H) instead of ``size`` (the report's presets).
    resolution: tuple[int, int] | None = None
    #: Cycles samples of each view's capture. 16: in the report's capture-spp curve a layout
    #: from 16 spp captures scored as well as one from 256 (Sponza fit views 0.826 against
    #: 0.824, Cornell 0.980 against 0.980) at a sixteenth of the render time.
    samples: int = 16
    seed: int = 0
    profile: str = "cosine"
    #: Near-field radius of the VPLs (m); None: the scene's (``NEAR_FIELD_FRACTION`` of its
    #: diagonal: VPL spacing grows with the scene).
    radius: float | None = None
    cell_px: int = 16
    #: One of :data:`METHODS`. The default is ``vplace+refit``: it beats the others in the
    #: report at equal N.
    method: str = "vplace+refit"
    alpha: float = 1.0
    iterations: int = 3
    #: One of :data:`FEATURE_MODES`.
    feature_mode: str = "auto"
    #: The views the lights are laid out for.
    views: ViewSet = field(default_factory=ViewSet)
    cache_dir: Path | None = None

    def validate(self) -> None:
        """Raises :class:`AddonError` for settings no stage can run with."""
        if self.method not in METHODS:
            raise AddonError(f"method must be one of {list(METHODS)}, got {self.method!r}")
        if self.n_vpls < 1 or self.n_vpls > apply.MAX_VPLS:
            raise AddonError(f"the VPL budget must be 1 to {apply.MAX_VPLS}, got {self.n_vpls}")
        if self.feature_mode not in FEATURE_MODES:
            raise AddonError(
                f"feature mode must be one of {FEATURE_MODES}, got {self.feature_mode!r}"
            )
        if self.size < 8:
            raise AddonError(f"the capture size must be at least 8 pixels, got {self.size}")
        self.views.validate()

    def capture_resolution(self, scene: bpy.types.Scene) -> tuple[int, int]:
        """The capture's (W, H) in ``scene``."""
        return self.resolution or capture_resolution(scene, self.size)

    @classmethod
    def from_settings(cls, settings: Any, cache_dir: Path | None = None) -> Job:
        """A job from ``Scene.vplace`` (see properties.py)."""
        return cls(
            n_vpls=settings.vpl_budget,
            size=settings.capture_size,
            samples=settings.samples,
            seed=settings.seed,
            profile=settings.profile,
            cell_px=settings.cell_px,
            method=method_name(settings.method, settings.refit),
            alpha=settings.alpha,
            iterations=settings.iterations,
            feature_mode=settings.feature_mode,
            views=settings.view_set(),
            cache_dir=cache_dir,
        )


#: The most capture memory (bytes) a job may hold: about 15 float32 values per pixel and view.
MAX_CAPTURE_BYTES = 4 << 30
CAPTURE_BYTES_PER_PIXEL = 15 * 4


@dataclass
class Prepared:
    """What the Blender side hands to the native side: the scene and the captured views."""

    scene: vplace.Scene
    exported: export.ExportedScene
    captures: list[capture.Capture]
    views: list[vplace.View]
    #: Views left out, with the reason (a camera that sees nothing, a duplicate view).
    skipped: dict[str, str] = field(default_factory=dict)
    #: Per capture, where its rough glossy layers are modelled (``native.gloss_mask``).
    gloss: list[np.ndarray | None] = field(default_factory=list)

    @property
    def capture(self) -> capture.Capture:
        """The first (main) view's capture."""
        return self.captures[0]

    @functools.cached_property
    def emitter_lights(self) -> list[EmitterLight]:
        """Lights that stand in for the scene's emissive meshes in EEVEE (``emitter_lights``)."""
        return emitter_lights(self.exported, self.scene)

    @functools.cached_property
    def world_sun(self) -> SunLight | None:
        """The world's sun as a SUN light for EEVEE (``emitter_lights.world_sun``), when it
        lights some of what the captured views see (``SUN_MIN_LIT``)."""
        sun = world_sun(self.exported.world)
        if sun is None:
            return None
        lit = max(
            sun_lit_fraction(self.scene, c.position, c.normal, c.covered, sun)
            for c in self.captures
        )
        return sun if lit >= SUN_MIN_LIT else None

    @property
    def vpl_specular(self) -> float:
        """The written VPLs' specular factor: 1 when some material has a rough glossy layer
        (the evaluator counts the VPLs' light on it), else 0 (``apply``'s module docs)."""
        return 1.0 if self.exported.rough_gloss.any() else 0.0

    def radius(self, job: Job) -> float:
        """The job's near-field radius in this scene."""
        return job.radius if job.radius is not None else self.scene.near_field_radius


def check_lights(exported: export.ExportedScene) -> None:
    """Refuses a scene where nothing emits light: no light with power, a black world (or none)
    and no emissive material. A scene lit by the world or by emissive meshes alone is fine."""
    if exported.emitters():
        return
    if exported.lights:
        raise ExportError(
            "every light has zero power, the world is black and no material emits: "
            "there is no light to bounce"
        )
    raise ExportError(
        "the scene has no lights that render: no light object, a black world and no emissive "
        "material (add a light, a world colour or texture, or an Emission shader)"
    )


def prepare(
    bl_scene: bpy.types.Scene,
    job: Job,
    timer: StageTimer,
    views: Sequence[ViewSpec] | None = None,
) -> Prepared:
    """Export, BVH and a capture of each view (default: the job's view set). Uses bpy: call it
    on Blender's main thread.

    A view that sees no geometry, or that renders exactly what an earlier view renders (the same
    capture key), is left out and said so in ``Prepared.skipped`` and the log; only when no view
    is left is it an error. A view set whose captures would take more than
    :data:`MAX_CAPTURE_BYTES` is refused before anything renders."""
    job.validate()
    with timer.stage("export scene"):
        exported = export.export_scene(bl_scene)
    for warning in exported.warnings:
        timer.log(f"[vplace] warning: {warning}")
    check_lights(exported)
    with timer.stage("build BVH"):
        scene = build_scene(exported)
    with contextlib.ExitStack() as stack:
        specs = (
            list(views)
            if views is not None
            else stack.enter_context(view_specs(bl_scene, job.views))
        )
        resolution = job.capture_resolution(bl_scene)
        need = len(specs) * resolution[0] * resolution[1] * CAPTURE_BYTES_PER_PIXEL
        if need > MAX_CAPTURE_BYTES:
            raise CaptureError(
                f"{len(specs)} views of {resolution[0]}x{resolution[1]} pixels need about "
                f"{need / 2**30:.1f} GB of captures (at most {MAX_CAPTURE_BYTES / 2**30:.0f} GB): "
                "use fewer views or a smaller capture size"
            )
        last = [0.0]

        def on_progress(line: str) -> None:
            now = time.perf_counter()
            if now - last[0] > 2.0:
                last[0] = now
                timer.log(f"[vplace]   {line}")

        captures: list[capture.Capture] = []
        skipped: dict[str, str] = {}
        for spec in specs:
            with timer.stage(f"capture {spec.name} (Cycles)"):
                cap = capture.capture(
                    bl_scene,
                    camera=spec.camera,
                    frame=spec.frame,
                    name=spec.name,
                    resolution=resolution,
                    samples=job.samples,
                    seed=job.seed,
                    cache_dir=job.cache_dir,
                    on_progress=on_progress,
                )
            same = next((c.view for c in captures if c.key == cap.key), None)
            if same is not None:
                skipped[spec.name] = f"the same view as {same!r}"
            elif not cap.covered.any():
                skipped[spec.name] = "the camera sees no geometry (only background)"
            else:
                captures.append(cap)
                continue
            timer.log(f"[vplace] view {spec.name!r} left out: {skipped[spec.name]}")
    if not captures:
        names = ", ".join(repr(n) for n in skipped)
        raise CaptureError(
            f"no view is left to lay out VPLs for ({names}: "
            + "; ".join(skipped.values())
            + "): aim the camera at the scene"
        )
    gloss = [gloss_mask(scene, exported, c) for c in captures]
    native_views = [view_of(c, gloss=g) for c, g in zip(captures, gloss, strict=True)]
    return Prepared(scene, exported, captures, native_views, skipped, gloss)


def fit(prepared: Prepared, job: Job, views: Sequence[vplace.View] | None = None) -> vplace.Fit:
    """The regression on ``views`` (default: every prepared view)."""
    return vplace.fit(
        prepared.scene,
        list(views if views is not None else prepared.views),
        vplace.FitParams(
            cell_px=job.cell_px,
            surface_only=job.feature_mode == "auto",
            select=job.feature_mode != "all",
        ),
    )


@dataclass
class Laid:
    """The VPLs of one method, and how they were made."""

    vpls: vplace.VplSet
    #: The regression-guided layout before the refit (vplace methods).
    layout: vplace.Layout | None = None
    refit: vplace.Refit | None = None
    #: Seconds of the layout (placement) and of the refit.
    layout_seconds: float = 0.0
    refit_seconds: float = 0.0


def lay_out(
    prepared: Prepared,
    job: Job,
    *,
    fitted: vplace.Fit | None = None,
    views: Sequence[vplace.View] | None = None,
    timer: StageTimer | None = None,
    progress: vplace.Progress | None = None,
) -> Laid:
    """The VPLs of ``job.method`` (the one method dispatch). ``views`` (default: every prepared
    view) are what the regression-guided layout places for and iterates against (views without
    an indirect image give a one-shot layout); ``fitted`` is the model (fitted here when None).
    No bpy: safe on a worker thread; ``progress`` cancels it."""
    job.validate()
    timer = timer or quiet_timer()
    scene, n, radius = prepared.scene, job.n_vpls, prepared.radius(job)
    views = list(views if views is not None else prepared.views)
    kind = dict(profile=job.profile, radius=radius)
    start = time.perf_counter()
    if job.method == "uniform":
        with timer.stage(f"uniform VPLs (n={n})"):
            vpls = vplace.uniform_vpls(scene, n, seed=job.seed, bounces=vplace.MAX_BOUNCES, **kind)
        return Laid(vpls, layout_seconds=time.perf_counter() - start)
    if job.method == "rsm":
        with timer.stage(f"RSM VPLs (n={n})"):
            vpls = vplace.rsm_vpls(scene, n, **kind)
        return Laid(vpls, layout_seconds=time.perf_counter() - start)
    if fitted is None:
        with timer.stage("fit regression"):
            fitted = fit(prepared, job, views)
    stride = vplace.stride_for(views)  # the iteration's and the refit's pixels, bounded
    with timer.stage(f"layout (n={n}, alpha={job.alpha:g})"):
        laid = vplace.layout(
            scene,
            views,
            vplace.LayoutParams(
                budget=n,
                alpha=job.alpha,
                cell_px=job.cell_px,
                iterate=job.iterations > 0,
                iterations=max(job.iterations, 1),
                seed=job.seed,
                stride=stride,
                **kind,
            ),
            fit=fitted,
            progress=progress,
        )
    out = Laid(laid.vpls, layout=laid, layout_seconds=time.perf_counter() - start)
    if job.method == "vplace+refit" and all(v.has_indirect for v in views):
        with timer.stage("refit VPL powers"):
            start = time.perf_counter()
            out.refit = vplace.refit(
                scene, views, laid.vpls, vplace.RefitParams(stride=stride), progress=progress
            )
            out.refit_seconds = time.perf_counter() - start
        out.vpls = out.refit.vpls
    return out


def score(image: np.ndarray, truth: np.ndarray) -> dict[str, float]:
    """RMSE, relative MSE (linear HDR), SSIM (display luminance) of ``image`` against ``truth``,
    and its brightness (mean luminance over the truth's); SSIM is NaN below 11 x 11 pixels."""
    image = np.ascontiguousarray(image, dtype=np.float32)
    truth = np.ascontiguousarray(truth, dtype=np.float32)
    ssim = vplace.ssim(image, truth) if min(truth.shape[:2]) >= 11 else float("nan")
    lum = np.asarray(vplace.LUMINANCE)
    mean_truth = max(float((truth[..., :3] @ lum).mean()), 1e-12)
    return {
        "rmse": vplace.rmse(image, truth),
        "relative_mse": vplace.relative_mse(image, truth),
        "ssim": ssim,
        "brightness": float((image[..., :3] @ lum).mean()) / mean_truth,
    }


@dataclass
class Reference:
    """What a run is scored against: a Cycles render of a view (its G-buffer is the view the
    evaluator shades) and what it is, in words."""

    capture: capture.Capture
    view: vplace.View
    label: str
    #: Where its rough glossy layers are modelled (``native.gloss_mask``).
    gloss: np.ndarray | None = None


def capture_reference(prepared: Prepared, job: Job) -> Reference:
    """The first view's own capture: the reference of the panel's runs (no extra render)."""
    return Reference(
        prepared.capture,
        prepared.views[0],
        f"its own capture ({job.samples} spp; the capture's noise lowers every score)",
        prepared.gloss[0] if prepared.gloss else None,
    )


@dataclass
class Computed:
    """A method's VPLs, their indirect image on the reference view, evaluator stats and
    metrics against the reference."""

    laid: Laid
    indirect: np.ndarray
    stats: vplace.EvalStats
    metrics: dict[str, float]
    fit: vplace.Fit | None = None

    @property
    def vpls(self) -> vplace.VplSet:
        return self.laid.vpls


def compute(
    prepared: Prepared,
    job: Job,
    timer: StageTimer,
    progress: vplace.Progress | None = None,
    fitted: vplace.Fit | None = None,
    reference: Reference | None = None,
) -> Computed:
    """:func:`lay_out`, the evaluator on the reference view (default: the first view's
    capture) and the metrics against it. No bpy: safe on a worker thread; ``progress`` cancels
    it."""
    if fitted is None:
        with timer.stage("fit regression"):
            fitted = fit(prepared, job)
    laid = lay_out(prepared, job, fitted=fitted, timer=timer, progress=progress)
    ref = reference or capture_reference(prepared, job)
    with timer.stage("evaluate VPLs"):
        indirect, stats = vplace.evaluate(prepared.scene, ref.view, laid.vpls, progress=progress)
    cap = ref.capture
    direct, gi = cap.direct, cap.gi
    ours = score(direct + indirect, gi)
    base = score(direct, gi)
    metrics = {
        **ours,
        **{f"{k}_direct_only": v for k, v in base.items()},
        "rmse_indirect": vplace.rmse(indirect, cap.modelled_indirect(ref.gloss)),
    }
    return Computed(laid, indirect, stats, metrics, fitted)


def render_eevee_preview(
    bl_scene: bpy.types.Scene, path: Path, resolution: tuple[int, int]
) -> float:
    """Renders ``bl_scene`` with EEVEE to a PNG; every changed setting is restored."""
    with override() as g:
        r = bl_scene.render
        g.set(r, "engine", "BLENDER_EEVEE")
        g.set(r, "resolution_x", resolution[0])
        g.set(r, "resolution_y", resolution[1])
        g.set(r, "resolution_percentage", 100)
        g.set(r, "filepath", str(path))
        g.set(r, "use_compositing", False)
        g.set(r, "use_sequencer", False)
        g.set(bl_scene.view_settings, "view_transform", "Standard")
        g.set(bl_scene.view_settings, "look", "None")
        ims = r.image_settings
        g.remember(ims, capture.IMAGE_SETTINGS)
        g.set(ims, "media_type", "IMAGE")
        g.set(ims, "file_format", "PNG")
        g.set(ims, "color_mode", "RGB")
        g.set(ims, "color_depth", "8")
        start = time.perf_counter()
        bpy.ops.render.render(write_still=True, scene=bl_scene.name)
        return time.perf_counter() - start


def fit_summary(fitted: vplace.Fit) -> dict[str, Any]:
    """The fit's figures for reports and the panel."""
    return {
        "r2": fitted.r2,
        "adjusted_r2": fitted.adjusted_r2,
        "view_r2": fitted.view_r2,
        "kept": fitted.kept,
        "weights": fitted.weights,
        "dropped": fitted.dropped,
    }


def summary(
    bl_scene: bpy.types.Scene, job: Job, prepared: Prepared, computed: Computed, timer: StageTimer
) -> dict[str, Any]:
    """The run's report as a JSON-ready dict."""
    laid, stats = computed.laid, computed.stats
    evaluator: dict[str, Any] = {
        "shadow_rays": stats.shadow_rays,
        "pairs": stats.pairs,
        "seconds": stats.seconds,
        "rays_per_second": stats.rays_per_second,
    }
    if laid.layout is not None:
        evaluator["iteration_errors"] = laid.layout.errors
        evaluator["best_iteration"] = laid.layout.best
    if laid.refit is not None:
        evaluator["refit_error"] = [laid.refit.error_before, laid.refit.error_after]
    return {
        "scene": bl_scene.name,
        "triangles": prepared.scene.triangle_count,
        "lights": prepared.scene.light_count,
        "views": [c.view for c in prepared.captures],
        "skipped_views": prepared.skipped,
        "resolution": [prepared.capture.width, prepared.capture.height],
        "samples": job.samples,
        "capture_render_seconds": sum(c.render_seconds for c in prepared.captures),
        "n_vpls": job.n_vpls,
        "lights_written": int((computed.vpls.blender_power.max(axis=1) > 0).sum()),
        "emitter_lights_written": len(prepared.emitter_lights),
        "method": job.method,
        "alpha": job.alpha,
        "iterations": job.iterations,
        "profile": job.profile,
        "radius": computed.vpls.radius,
        "seed": job.seed,
        "stage_seconds": dict(timer.seconds),
        "evaluator": evaluator,
        "metrics": computed.metrics,
        "fit": None if computed.fit is None else fit_summary(computed.fit),
    }


#: The Cycles seed of the main job's reference renders (another noise than the capture's).
REFERENCE_SEED = 7919


def main_reference(
    bl_scene: bpy.types.Scene,
    prepared: Prepared,
    job: Job,
    timer: StageTimer,
    truth_samples: int | None,
) -> Reference:
    """What the main job scores against: the scene camera at the current frame, rendered by
    Cycles at ``truth_samples`` (a ground truth); without it, the first view's own capture when
    that is the scene camera at the current frame, or else a render of it at the capture's
    samples."""
    cam = bl_scene.camera
    first = prepared.capture
    if not truth_samples and job.views.mode in ("active", "orbit") and first.camera == cam.name:
        return capture_reference(prepared, job)
    samples = truth_samples or job.samples
    with timer.stage(f"reference render {cam.name} ({samples} spp, cached)"):
        ref = capture.capture(
            bl_scene,
            camera=cam,
            resolution=(first.width, first.height),
            samples=samples,
            seed=REFERENCE_SEED,
            cache_dir=job.cache_dir,
        )
    kind = (
        "a ground truth"
        if truth_samples
        else "as noisy as the capture: give truth samples for a ground truth"
    )
    gloss = gloss_mask(prepared.scene, prepared.exported, ref)
    return Reference(
        ref,
        view_of(ref, held_out=True, gloss=gloss),
        f"Cycles at {samples} spp of {cam.name} ({kind})",
        gloss,
    )


def score_eevee(
    bl_scene: bpy.types.Scene, reference: Reference, path: Path, cache_dir: Path | None
) -> dict[str, float]:
    """Renders the written lights with EEVEE from the scene camera (float, Standard view, the
    scored set-up), scores the image against the reference, and saves it as a PNG picture.

    As "Set up EEVEE for vplace" would: when the world emits and the scene has no vplace probe
    volume, one is baked for the render (without indirect light, removed after), or EEVEE
    would light closed rooms with the world through their walls; its bake seconds are
    reported apart from the frame's."""
    from . import eevee

    cap = reference.capture
    with eevee_setup.world_volume_for_render(bl_scene) as bake:
        img = eevee.render(
            bl_scene,
            resolution=(cap.width, cap.height),
            samples=eevee.EEVEE_SAMPLES,
            setup=eevee.SETUPS["vpl"],
            cache_dir=cache_dir,
        )
    images.save_png(path, img.image)
    return {
        **score(img.image, cap.gi),
        "seconds": img.seconds,
        "samples": eevee.EEVEE_SAMPLES,
        "world_volume_bake_seconds": bake,
    }


def run_main_job(
    bl_scene: bpy.types.Scene,
    out_dir: Path,
    *,
    job: Job | None = None,
    eevee: bool = True,
    write_back: bool = True,
    truth_samples: int | None = None,
    baselines: Sequence[str] = METHODS,
    log: Callable[[str], None] = print,
    **job_options: Any,
) -> dict[str, Any]:
    """Runs the whole pipe on ``bl_scene`` and writes the results into ``out_dir``.

    ``job_options`` are :class:`Job` fields, for a job built on the spot. Every image is scored
    on the scene camera against :func:`main_reference` (a Cycles truth at ``truth_samples``
    when given). ``baselines``: the methods scored beside the job's at the same budget. With
    ``eevee`` (and ``write_back``) EEVEE renders the written lights and is scored the same way.
    Without ``write_back`` the scene is left as it is (and EEVEE, which would show the scene
    without the new VPLs, is skipped).
    """
    if job is None:
        job = Job(**job_options)
    if truth_samples is not None and truth_samples < 1:
        raise AddonError(f"truth samples must be at least 1, got {truth_samples}")
    if job.cache_dir is None:
        job.cache_dir = out_dir / "cache"
    out_dir.mkdir(parents=True, exist_ok=True)
    timer = StageTimer(log)
    prepared = prepare(bl_scene, job, timer)
    reference = main_reference(bl_scene, prepared, job, timer, truth_samples)
    computed = compute(prepared, job, timer, reference=reference)
    compared = {}
    for method in (b for b in baselines if b != job.method):
        quiet = quiet_timer()
        other = compute(
            prepared, replace(job, method=method), quiet, fitted=computed.fit, reference=reference
        )
        compared[method] = {"metrics": other.metrics, "seconds": sum(quiet.seconds.values())}
    problems: list[str] = []
    if write_back:
        with timer.stage("write back"):
            apply.write_vpls(
                bl_scene,
                computed.vpls,
                scene_diagonal=prepared.scene.diagonal,
                specular=prepared.vpl_specular,
                emitters=prepared.emitter_lights,
                sun=prepared.world_sun,
            )
            bpy.ops.wm.save_as_mainfile(filepath=str(out_dir / "scene.blend"), copy=True)
        problems = [str(p) for p in eevee_setup.problems(bl_scene)]
        for problem in problems:
            log(f"[vplace] warning: EEVEE: {problem} (Set up EEVEE for vplace fixes it)")
    ref, vpls = reference.capture, computed.vpls
    images.save_png(out_dir / "cycles_gi.png", ref.gi)
    images.save_png(out_dir / "direct.png", ref.direct)
    images.save_png(out_dir / "direct_plus_vpl.png", ref.direct + computed.indirect)
    shown = None
    if eevee and write_back:
        with timer.stage("EEVEE render"):
            shown = score_eevee(bl_scene, reference, out_dir / "eevee_vpl.png", job.cache_dir)
    np.savetxt(
        out_dir / "vpls.csv",
        np.hstack([vpls.position, vpls.normal, vpls.flux]),
        delimiter=",",
        header="x,y,z,nx,ny,nz,flux_r,flux_g,flux_b",
        comments="",
        fmt="%.6g",
    )
    if computed.fit is not None:
        (out_dir / "model.json").write_text(computed.fit.to_json())
        log(f"[vplace] fitted model (cells of {job.cell_px} px):\n{computed.fit}")
    report = summary(bl_scene, job, prepared, computed, timer)
    report["reference"] = {"label": reference.label, "samples": ref.samples, "view": ref.view}
    report["eevee"] = shown
    report["eevee_problems"] = problems
    report["baselines"] = compared
    report["files"] = sorted({*(p.name for p in out_dir.iterdir() if p.is_file()), "report.json"})
    (out_dir / "report.json").write_text(json.dumps(report, indent=2))
    (out_dir / "report.md").write_text(report_markdown(report))
    log(report_markdown(report))
    return report


def report_markdown(report: dict[str, Any]) -> str:
    """The short human-readable report."""
    m, s = report["metrics"], report["evaluator"]
    lines = [
        f"# vplace report: {report['scene']}",
        "",
        f"{report['triangles']} triangles, {report['lights']} lights, "
        f"{report['resolution'][0]}x{report['resolution'][1]} px, {report['samples']} spp Cycles, "
        f"{report['n_vpls']} VPLs by {report['method']} ({report['profile']}, "
        f"near-field radius {report['radius']:.3g} m)",
        "",
        "| stage | seconds |",
        "|---|---|",
        *[f"| {k} | {v:.2f} |" for k, v in report["stage_seconds"].items()],
        "",
        f"Every image is scored against {report['reference']['label']}.",
        "",
        "| image | RMSE | relative MSE | SSIM | brightness |",
        "|---|---|---|---|---|",
        f"| direct only | {m['rmse_direct_only']:.5f} | {m['relative_mse_direct_only']:.5f} "
        f"| {m['ssim_direct_only']:.4f} | {m['brightness_direct_only']:.3f} |",
        f"| evaluator: direct + VPL indirect ({report['method']}) | {m['rmse']:.5f} | "
        f"{m['relative_mse']:.5f} | {m['ssim']:.4f} | {m['brightness']:.3f} |",
        *[
            f"| evaluator: direct + VPL indirect ({name}, same N) | {b['metrics']['rmse']:.5f} | "
            f"{b['metrics']['relative_mse']:.5f} | {b['metrics']['ssim']:.4f} | "
            f"{b['metrics']['brightness']:.3f} |"
            for name, b in report.get("baselines", {}).items()
        ],
        *(
            [
                f"| EEVEE with the written lights ({e['samples']} samples, {e['seconds']:.1f} s"
                + (
                    f"; the world's probe volume baked in {b:.1f} s"
                    if (b := e.get("world_volume_bake_seconds"))
                    else ""
                )
                + ") "
                f"| {e['rmse']:.5f} | {e['relative_mse']:.5f} | {e['ssim']:.4f} | "
                f"{e['brightness']:.3f} |"
            ]
            if (e := report.get("eevee"))
            else []
        ),
        "",
        f"Evaluator: {s['shadow_rays']} shadow rays in {s['seconds']:.3f} s "
        f"= {s['rays_per_second'] / 1e6:.2f} M rays/s",
        "",
    ]
    return "\n".join(lines)
