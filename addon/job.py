"""The Blender side of the one job: export -> capture -> fit -> VPLs -> evaluator -> write-back.

Used by the operators, the command line (``python -m addon.cli``) and the report, which only
loops over views, budgets and seeds. The scene is handed forward, each stage entered once:

- :func:`prepare` (Blender, main thread): the scene stage (``scene.convert.export_native``:
  export, BVH), the capture stage (``capture.stage``: every view with Cycles, cached) and, for
  the main job, the reference.
- ``vplace.job`` (no bpy: safe on a worker thread): the fit, the one method dispatch of
  :data:`METHODS`, the evaluator and the scores; :func:`lay_out` and :func:`compute` call it
  on the prepared views.
- ``writeback.stage``: the VPLs and stand-in lights written, EEVEE scored.
- :func:`run_main_job`: all of it, and the files of the report (``vplace.job.write_files``).

Every stage is timed and announced through a :class:`StageTimer`.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import bpy
import numpy as np

from .capture import passes as capture
from .capture.native_view import vpl_unlit
from .capture.stage import (
    Captured,
    ReferenceRender,
    capture_views,
    own_reference,
    render_reference,
)
from .capture.views import ViewSet, ViewSpec, capture_resolution, eye_views
from .capture.views import specs as view_specs
from .compat import eevee_engine
from .errors import AddonError, CaptureError, output_folder, run_operator
from .native import vplace
from .scene import export
from .scene.convert import export_native
from .settings import measured_frame, override
from .writeback import apply, match_eevee
from .writeback import stage as writeback_stage
from .writeback.stand_ins import StandIns, stand_ins

#: Re-exported from ``vplace.job`` for the add-on's callers (the panel, the command line, the
#: report): the methods, the feature modes, the timer, and the typed results of a run.
METHODS = vplace.job.METHODS
FEATURE_MODES = vplace.job.FEATURE_MODES
#: ``Job.match_eevee``'s values.
MATCH_EEVEE = ("auto", "on", "off")
StageTimer = vplace.job.StageTimer
quiet_timer = vplace.job.quiet_timer
method_name = vplace.job.method_name
score = vplace.job.score
Laid = vplace.job.Laid
Computed = vplace.job.Computed
Reference = vplace.job.Reference


@dataclass
class Job(vplace.job.LayoutSettings):
    """The parameters of one run: the layout's (``vplace.job.LayoutSettings``) and the
    capture's. The panel (``ui/properties.py``), the command line and the report build it from
    their settings; its defaults are theirs."""

    #: Capture size: pixels on the long side, at the render's aspect ratio.
    size: int = 160
    #: An explicit capture size (W, H) instead of ``size`` (the report's presets).
    resolution: tuple[int, int] | None = None
    #: Cycles samples of each view's capture. 16: in the report's capture-spp curve a layout
    #: from 16 spp captures scored as well as one from 256 (Sponza fit views 0.826 against
    #: 0.824, Cornell 0.980 against 0.980) at a sixteenth of the render time.
    samples: int = 16
    #: The views the lights are laid out for.
    views: ViewSet = field(default_factory=ViewSet)
    cache_dir: Path | None = None
    #: Refit the powers so that EEVEE's direct light plus the VPLs' light matches the captures
    #: (``writeback.match_eevee``: an EEVEE render per captured view first, kept only where
    #: it helps), one of :data:`MATCH_EEVEE`: "on"; "off"; "auto", on only where surfaces
    #: the cameras see cut one of the user's lamps and hold at least
    #: ``vplace.job.CUT_SHARE`` of a view's direct light (``match_eevee.cut_lamps_seen``),
    #: which EEVEE darkens smoothly, so that the renders are paid only where they can help.
    match_eevee: str = "auto"

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
        if self.samples < 1:
            raise AddonError(f"samples must be at least 1, got {self.samples}")
        if not 0.0 <= self.alpha <= 1.0:
            raise AddonError(
                f"alpha must be 0 (uniform) to 1 (regression-guided), got {self.alpha:g}"
            )
        if self.iterations < 0:
            raise AddonError(f"layout iterations must be 0 (off) or more, got {self.iterations}")
        if self.radius is not None and not (self.radius >= 0 and math.isfinite(self.radius)):
            raise AddonError(f"the near-field radius must be 0 or more, got {self.radius:g}")
        if self.cell_px < 1:  # before anything renders (the match's boxes are cells too)
            raise AddonError(
                f"cell_px = {self.cell_px} is out of range: the regression's grid cell must be "
                "at least 1 pixel"
            )
        if self.match_eevee not in MATCH_EEVEE:
            raise AddonError(
                f"match_eevee must be one of {list(MATCH_EEVEE)}, got {self.match_eevee!r}"
            )
        self.views.validate()

    def in_scene_units(self, metres_per_unit: float) -> Job:
        """This job with its lengths given in metres (the command line's ``--radius``,
        ``--region-radius``, an orbit's radius) turned into the scene's units (Blender's Unit
        Scale: ``export.unit_scale``); the panel's are in scene units already."""
        if metres_per_unit == 1.0:
            return self
        k = 1.0 / metres_per_unit
        views = dataclasses.replace(
            self.views,
            orbit_radius=self.views.orbit_radius * k,
            region_radius=self.views.region_radius * k,
        )
        radius = None if self.radius is None else self.radius * k
        return dataclasses.replace(self, views=views, radius=radius)

    def capture_resolution(self, scene: bpy.types.Scene) -> tuple[int, int]:
        """The capture's (W, H) in ``scene``."""
        return self.resolution or capture_resolution(scene, self.size)

    @classmethod
    def from_settings(cls, settings: Any, cache_dir: Path | None = None) -> Job:
        """A job from ``Scene.vplace`` (see ui/properties.py)."""
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
            match_eevee=settings.match_eevee,
            near_field=settings.near_field,
        )


#: The one-time costs (a camera's captures, fit, layout and refit; a captured frame of keyed
#: lights) are weighed against Cycles + OIDN frames of this many samples, of the same size
#: (the report's and the animation's yardstick, issues 20 and 23).
COST_SAMPLES = 16
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
    #: Per capture, where its rough glossy layers are modelled (``native_view.gloss_mask``).
    gloss: list[np.ndarray | None] = field(default_factory=list)
    #: The main job's reference (``prepare(reference=...)``).
    reference: Reference | None = None
    #: The coverage views added for the region (``vplace.coverage``); they follow the
    #: captures' views in ``views``.
    coverage: vplace.coverage.Coverage | None = None
    #: The written VPLs' specular factor, decided on the captures (``Captured.specular``,
    #: ``capture.native_view.vpl_specular``; 0: no glossy layer modelled, ``gloss`` all None).
    vpl_specular: float = 0.0
    #: The user's lamps that EEVEE darkens on the surfaces the cameras see
    #: (``writeback.match_eevee.cut_lamps_seen``), found by :func:`eevee_match`, which every
    #: job runs after :func:`prepare`: what the write-back notes.
    cut_lamps: list[str] = field(default_factory=list)

    @property
    def vpl_unlit(self) -> list[str]:
        """The objects the written VPLs do not light (``capture.native_view.vpl_unlit``)."""
        return vpl_unlit(self.exported, self.vpl_specular)

    @property
    def capture(self) -> capture.Capture:
        """The first (main) view's capture."""
        return self.captures[0]

    @property
    def captured_views(self) -> list[vplace.View]:
        """The captures' own views: ``views`` without the coverage views that follow them."""
        return self.views[: len(self.captures)]

    @property
    def surfaces(self) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """Each capture's (position, normal, covered) arrays."""
        return [(c.position, c.normal, c.covered) for c in self.captures]

    @functools.cached_property
    def stand_ins(self) -> StandIns:
        """Lights that stand in for the scene's emissive meshes, the world's sun and the sky
        through the openings seen from the captured cameras and the coverage views' eyes in
        EEVEE (``writeback.stand_ins``)."""
        eyes = [
            vplace.coverage.camera_eye(self.scene, c.camera_position, c.world_to_clip)
            for c in self.captures
        ]
        if self.coverage is not None:
            eyes += [p.eye for p in self.coverage.poses]
        return stand_ins(self.exported, self.scene, self.surfaces, eyes)


def prepare(
    bl_scene: bpy.types.Scene,
    job: Job,
    timer: StageTimer,
    views: Sequence[ViewSpec] | None = None,
    reference: ReferenceRender | None = None,
    eyes: np.ndarray | None = None,
    looks: np.ndarray | None = None,
) -> Prepared:
    """The Blender stages, each entered once: the scene (export, check, BVH), then a capture of
    each view (default: the job's view set), then, with ``reference``, the main job's reference.
    Uses bpy: call it on Blender's main thread.

    A view that sees no geometry, or that renders exactly what an earlier view renders (the same
    capture key), is left out and said so in ``Prepared.skipped`` and the log; only when no view
    is left is it an error. A view set whose captures would take more than
    :data:`MAX_CAPTURE_BYTES` is refused before anything renders. ``eyes`` (N x 3) and where
    they look, ``looks`` (N x 3, or None), set the scene's working scale
    (``vplace.Scene.scale``; default: the views' cameras, :func:`capture.views.eye_views`)."""
    job.validate()
    with contextlib.ExitStack() as stack:
        specs = (
            list(views)
            if views is not None
            else stack.enter_context(view_specs(bl_scene, job.views))
        )
        resolution = job.resolution or capture_resolution(bl_scene, job.size)
        need = len(specs) * resolution[0] * resolution[1] * CAPTURE_BYTES_PER_PIXEL
        if need > MAX_CAPTURE_BYTES:
            raise CaptureError(
                f"{len(specs)} views of {resolution[0]}x{resolution[1]} pixels need about "
                f"{need / 2**30:.1f} GB of captures (at most {MAX_CAPTURE_BYTES / 2**30:.0f} GB): "
                "use fewer views or a smaller capture size"
            )
        if eyes is None:
            eyes, looks = eye_views(bl_scene, specs)
        region = job.views.region()
        exported, scene = export_native(bl_scene, timer.stage, timer.log, eyes, looks)
        captured = capture_views(
            bl_scene,
            scene,
            exported,
            specs,
            resolution=resolution,
            samples=job.samples,
            seed=job.seed,
            cache_dir=job.cache_dir,
            stage=timer.stage,
            log=timer.log,
            region=region,
            profile=job.profile,
            radius=job.radius,
            render_coverage=job.views.render_coverage,
        )
    cover = captured.coverage
    ref = None
    if reference is not None:
        ref = render_reference(
            bl_scene,
            scene,
            exported,
            captured,
            reference,
            capture_samples=job.samples,
            cache_dir=job.cache_dir,
            stage=timer.stage,
        )
    views = captured.views + (cover.views if cover is not None else [])
    return Prepared(
        scene,
        exported,
        captured.captures,
        views,
        captured.skipped,
        captured.gloss,
        ref,
        cover,
        captured.specular,
    )


def fit(prepared: Prepared, job: Job, views: Sequence[vplace.View] | None = None) -> vplace.Fit:
    """The regression on ``views`` (default: every prepared view)."""
    return vplace.job.fit(prepared.scene, views if views is not None else prepared.views, job)


def lay_out(
    prepared: Prepared,
    job: Job,
    *,
    fitted: vplace.Fit | None = None,
    views: Sequence[vplace.View] | None = None,
    timer: StageTimer | None = None,
    progress: vplace.Progress | None = None,
    match: vplace.job.EeveeMatch | None = None,
) -> Laid:
    """``vplace.job.lay_out`` (the one method dispatch) on the prepared scene and ``views``
    (default: every prepared view); the refit matches EEVEE's direct light with ``match``
    where that helps (:func:`eevee_match`). No bpy: safe on a worker thread; ``progress``
    cancels it."""
    job.validate()
    return vplace.job.lay_out(
        prepared.scene,
        views if views is not None else prepared.views,
        job,
        fitted=fitted,
        timer=timer,
        progress=progress,
        match=match,
    )


def eevee_match(
    bl_scene: bpy.types.Scene, prepared: Prepared, job: Job, timer: StageTimer
) -> tuple[vplace.job.EeveeMatch | None, dict[str, float]]:
    """With ``job.match_eevee`` on, or "auto" where a surface the cameras see cuts one of the
    user's lamps, and a method that refits: what the refit may fit instead of the captures
    (``writeback.match_eevee``: EEVEE's direct-light deficit added to their targets, and the
    judge of whether that helps) and per matched view its share of Cycles' direct light; else
    (None, {}). Left to "auto", a failed EEVEE render is logged and the layout goes on without
    the match. Whatever the setting, ``prepared.cut_lamps`` gets the lamps EEVEE darkens on
    what the cameras see, for the write-back's notes. Uses bpy: call it on Blender's main
    thread, after :func:`prepare`."""
    match, matched, prepared.cut_lamps = match_eevee.eevee_match(
        bl_scene,
        prepared.captures,
        prepared.captured_views,
        prepared.gloss,
        prepared.stand_ins,
        scene=prepared.scene,
        cell_px=job.cell_px,
        cache_dir=job.cache_dir,
        stage=timer.stage,
        mode=job.match_eevee if job.method == "vplace+refit" else "off",
        log=timer.log,
    )
    return match, matched


def capture_reference(prepared: Prepared, job: Job) -> Reference:
    """The first view's own capture: the reference of the panel's runs (no extra render)."""
    captured = Captured(prepared.captures, prepared.captured_views, prepared.gloss)
    return own_reference(captured, job.samples)


def compute(
    prepared: Prepared,
    job: Job,
    timer: StageTimer,
    progress: vplace.Progress | None = None,
    fitted: vplace.Fit | None = None,
    reference: Reference | None = None,
    match: vplace.job.EeveeMatch | None = None,
) -> Computed:
    """``vplace.job.compute`` (fit, lay out, evaluate, score) on the prepared views against the
    reference (default: the first view's capture). No bpy: safe on a worker thread;
    ``progress`` cancels it."""
    job.validate()
    return vplace.job.compute(
        prepared.scene,
        prepared.views,
        job,
        reference or capture_reference(prepared, job),
        timer=timer,
        progress=progress,
        fitted=fitted,
        match=match,
    )


def render_eevee_preview(
    bl_scene: bpy.types.Scene, path: Path, resolution: tuple[int, int]
) -> float:
    """Renders ``bl_scene`` with EEVEE to a PNG; every changed setting is restored."""
    with override() as g:
        r = bl_scene.render
        g.set(r, "engine", eevee_engine())
        g.set(r, "resolution_x", resolution[0])
        g.set(r, "resolution_y", resolution[1])
        g.set(r, "resolution_percentage", 100)
        g.set(r, "filepath", str(path))
        g.set(r, "use_compositing", False)
        g.set(r, "use_sequencer", False)
        measured_frame(g, bl_scene)
        g.set(bl_scene.view_settings, "view_transform", "Standard")
        g.set(bl_scene.view_settings, "look", "None")
        ims = r.image_settings
        g.remember(ims, capture.IMAGE_SETTINGS)
        g.image_format(ims, "PNG")
        g.set(ims, "color_mode", "RGB")
        g.set(ims, "color_depth", "8")
        start = time.perf_counter()
        run_operator(
            "render.render",
            f"the EEVEE preview of scene {bl_scene.name!r} did not finish",
            write_still=True,
            scene=bl_scene.name,
        )
        return time.perf_counter() - start


def scene_label(bl_scene: bpy.types.Scene) -> str:
    """The scene as its user knows it: the name of its .blend file (``cornell``, not Blender's
    default scene name ``Scene``), with the scene's own name when the file holds several; the
    scene's name alone in a file never saved."""
    if not bpy.data.filepath:
        return bl_scene.name
    stem = Path(bpy.data.filepath).stem
    return stem if len(bpy.data.scenes) == 1 else f"{stem} ({bl_scene.name})"


def summary(
    bl_scene: bpy.types.Scene,
    job: Job,
    prepared: Prepared,
    computed: Computed,
    timer: StageTimer,
    lights: StandIns | None = None,
) -> vplace.job.JobSummary:
    """The run's figures, typed (``to_dict()`` for JSON); ``lights``: the stand-ins written
    (default: the prepared scene's)."""
    laid, stats = computed.laid, computed.stats
    # The fields, not ``StandIns.portals``: the summary stays in this file and the library's.
    written = lights or prepared.stand_ins
    emitters = written.emitters
    portals = sum(1 for e in emitters if e.portal)
    evaluator = vplace.job.EvaluatorSummary(
        stats.shadow_rays, stats.pairs, stats.seconds, stats.rays_per_second
    )
    if laid.layout is not None:
        evaluator.iteration_errors = laid.layout.errors
        evaluator.best_iteration = laid.layout.best
    if laid.refit is not None:
        evaluator.refit_error = [laid.refit.error_before, laid.refit.error_after]
        evaluator.refit_ridge = laid.refit.ridge
        evaluator.refit_cv = [list(c) for c in laid.refit.cv] or None
        evaluator.refit_gain = laid.refit.gain
        evaluator.refit_gain_cv = [list(c) for c in laid.refit.gain_cv] or None
        weights = laid.refit.view_weights
        if any(w != 1.0 for w in weights):  # balanced (several captures, unequally lit)
            names = [v.name for v in prepared.captured_views]
            evaluator.refit_view_weights = dict(zip(names, weights, strict=True))
    if laid.near_field is not None:
        evaluator.near_field = dataclasses.asdict(laid.near_field)
    rendered = [vplace.coverage.is_rendered_coverage(v) for v in prepared.captured_views]
    cov = prepared.coverage
    metres = prepared.exported.unit_scale
    region = (
        vplace.job.RegionSummary(
            len(cov.poses),
            [r * metres for r in cov.radius],
            cov.covered_before,
            cov.covered_after,
            cov.seconds,
        )
        if cov is not None and cov.poses
        else None
    )
    return vplace.job.JobSummary(
        scene=scene_label(bl_scene),
        triangles=prepared.scene.triangle_count,
        lights=prepared.scene.light_count,
        views=[c.view for c, r in zip(prepared.captures, rendered, strict=True) if not r],
        region_views=[c.view for c, r in zip(prepared.captures, rendered, strict=True) if r],
        region=region,
        skipped_views=prepared.skipped,
        resolution=[prepared.views[0].width, prepared.views[0].height],
        samples=job.samples,
        capture_render_seconds=sum(c.render_seconds for c in prepared.captures),
        n_vpls=job.n_vpls,
        lights_written=int((computed.vpls.blender_power.max(axis=1) > 0).sum()),
        emitter_lights_written=len(emitters) - portals,
        portals_written=portals,
        world_closed=written.closed,
        sun_written=written.sun is not None,
        method=job.method,
        alpha=job.alpha,
        iterations=job.iterations,
        profile=job.profile,
        radius=computed.vpls.radius,
        seed=job.seed,
        working_scale=prepared.scene.scale,
        bounds_diagonal=prepared.scene.diagonal,
        unit_scale=prepared.exported.unit_scale,
        stage_seconds=dict(timer.seconds),
        evaluator=evaluator,
        metrics=computed.metrics,
        fit=None if computed.fit is None else vplace.job.FitSummary.of(computed.fit),
    )


#: The Cycles seed of the main job's reference renders (another noise than the capture's).
REFERENCE_SEED = 7919
#: The truth's second render (the report, ``demo --animate --truth-noise``): its noise is
#: independent of the first's, as the noise-free SSIM (``vplace.ssim_noise_free``) needs.
OTHER_REFERENCE_SEED = 7927


def reference_render(job: Job, truth_samples: int | None) -> ReferenceRender:
    """How the main job's reference is made: the scene camera at the current frame, rendered by
    Cycles at ``truth_samples`` (a ground truth); without it, the first view's own capture when
    that is the scene camera at the current frame, or else a render of it at the capture's
    samples."""
    return ReferenceRender(
        samples=truth_samples or job.samples,
        seed=REFERENCE_SEED,
        ground_truth=bool(truth_samples),
        own_capture_ok=not truth_samples and job.views.mode in ("active", "orbit"),
    )


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
) -> vplace.job.JobSummary:
    """Runs the whole pipe on ``bl_scene`` and writes the results into ``out_dir``. The scene is
    handed forward, each stage entered once: export and capture (:func:`prepare`, with the
    reference), fit, layout, evaluator and scores (``vplace.job``), write-back
    (``writeback.stage``), then the files.

    ``job_options`` are :class:`Job` fields, for a job built on the spot. Every image is scored
    on the scene camera against the reference (:func:`reference_render`: a Cycles truth at
    ``truth_samples`` when given). ``baselines``: the methods scored beside the job's at the
    same budget. With ``eevee`` (and ``write_back``) EEVEE renders the written lights and is
    scored the same way. Without ``write_back`` the scene is left as it is (and EEVEE, which
    would show the scene without the new VPLs, is skipped).
    """
    if job is None:
        job = Job(**job_options)
    if truth_samples is not None and truth_samples < 1:
        raise AddonError(f"truth samples must be at least 1, got {truth_samples}")
    if job.cache_dir is None:
        job.cache_dir = out_dir / "cache"
    output_folder(out_dir)
    timer = StageTimer(log)
    prepared = prepare(bl_scene, job, timer, reference=reference_render(job, truth_samples))
    reference = prepared.reference
    assert reference is not None  # prepare(reference=...) made it
    match, matched = eevee_match(bl_scene, prepared, job, timer)
    computed, compared = vplace.job.compute_with_baselines(
        prepared.scene,
        prepared.views,
        job,
        reference,
        baselines,
        timer=timer,
        match=match,
    )
    written = None
    if write_back:
        written = writeback_stage.write_back(
            bl_scene,
            computed.vpls,
            specular=prepared.vpl_specular,
            scene=prepared.scene,
            exported=prepared.exported,
            lights=prepared.stand_ins,
            cut_lamps=prepared.cut_lamps,
            coverage=prepared.coverage,
            blend_path=out_dir / "scene.blend",
            stage=timer.stage,
            log=log,
        )
    shown = None
    if eevee and written is not None:
        with timer.stage("EEVEE render"):
            shown = writeback_stage.score_eevee(
                bl_scene,
                reference,
                out_dir / "eevee_vpl.png",
                job.cache_dir,
                computed.indirect,
                prepared.exported.emissive_materials,
            )
    report = summary(
        bl_scene, job, prepared, computed, timer, written.stand_ins if written else None
    )
    report.reference = vplace.job.ReferenceInfo(
        reference.label, reference.samples, reference.camera
    )
    report.eevee = shown
    report.eevee_problems = written.problems if written else []
    report.eevee_lamp_notes = written.lamp_notes if written else []
    report.baselines = compared
    report.set_match(matched, computed.laid.match)
    vplace.job.write_files(out_dir, report, reference, computed, job.cell_px, log)
    return report
