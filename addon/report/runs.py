"""The speed-against-error report (DESIGN: Report): scenes x views x methods x VPL budgets, scored
with the evaluator and with EEVEE, beside what a Blender user would pick instead.

``python -m addon.cli report`` runs, for each scene (a built-in preset, or any .blend with
``--blend FILE --fit-cameras A B --held-out-cameras C``):

1. A capture of each *fit* view (Cycles, ``capture_samples``), one regression fitted over all of
   them, and for every VPL budget and seed one world-space VPL set per method
   (:data:`pipeline.METHODS`; the regression-guided layout iterates and refits against every fit
   view at once).
2. Every view, fit or *held out* (never captured for the layout, never laid out again), scored
   with the same lights: the evaluator's indirect light over the view's G-buffer plus the ground
   truth's direct light, against a high-sample Cycles render of the view (the ground truth,
   cached). On a held-out view the old per-view re-layout (the fit's model laying out VPLs from
   that view's G-buffer alone) is its own row, ``vplace (re-layout)``.
3. With ``eevee``: at the grid budget, the lights of each method written back and rendered by
   EEVEE on every view (float, Standard view, :data:`eevee.EEVEE_SAMPLES` samples), and the
   alternatives (:data:`eevee.SETUPS`): EEVEE without help, EEVEE's ray tracing, ray tracing
   with a baked light probe volume, the VPLs with ray-traced reflections, and Cycles with
   OpenImageDenoise at ``cycles_samples``; all scored against the same ground truth.

Costs are kept apart: ``one_time_seconds`` (the scene's export and the captures, the fit, the
layout and refit, the near-field choice, the EEVEE match, a volume's bake) and ``frame_seconds``
(one frame: the evaluator's image, an EEVEE or a Cycles render). The break-even table says after
how many frames vplace's one-time cost plus its EEVEE frames costs less than Cycles + OIDN frames
of at least the same SSIM. The captures, the match's EEVEE renders and the Cycles + OIDN frames
are rendered on every run, never read from the cache (all deterministic, and cheap beside the
truths): a cached render keeps the seconds of the run that made it, on a machine that may have
been busier or idler, and the cost check compares them (:data:`UNCACHED`).

Written into ``--out``: ``results.csv`` and ``results.json`` (every row), ``report.md`` (tables,
the break-even, the target checks) and PNG plots. The truths and EEVEE's renders are cached in
``out/cache``. The user's .blend is never saved: the scene camera is switched through a settings
guard, and the VPL collection written for EEVEE is removed again.
"""

from __future__ import annotations

import contextlib
import json
import math
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field, replace
from functools import partial
from pathlib import Path
from typing import Any

import bpy
import numpy as np
from mathutils import Vector

from .. import job as pipeline
from ..capture import passes as capture
from ..capture.native_view import gloss_mask, view_of
from ..capture.views import (
    ViewSet,
    ViewSpec,
    capture_resolution,
    eye_positions,
    pose_matrix,
    remove_camera,
)
from ..errors import ReportError, output_folder
from ..native import vplace
from ..scene import export
from ..scenes import registry as default_scene
from ..settings import override
from ..writeback import apply, cut_lights, eevee_setup
from ..writeback import eevee_render as eevee
from .config import (
    CAPTURE_CURVE,
    CAPTURE_SEED,
    CURVE_SEED,
    GENERATED_CLIP_START,
    GENERATED_PREFIX,
    OTHER_TRUTH_SEED,
    RELAYOUT,
    TRUTH_SEED,
    UNCACHED,
    WITH_RT,
    ReportConfig,
    Row,
    RowDetails,
    ScenePreset,
    grid_budget,
    row_dict,
    write_csv,
)
from .summary import aggregate, break_even, markdown, matched_shares, pct, targets


@contextmanager
def camera_view(bl_scene: bpy.types.Scene, camera_name: str) -> Iterator[bpy.types.Object]:
    """Makes ``camera_name`` the scene camera for the block; the old one comes back after."""
    cam = bpy.data.objects.get(camera_name)
    if cam is None or cam.type != "CAMERA":
        raise ReportError(f"the scene has no camera object named {camera_name!r}")
    with override() as g:
        g.set(bl_scene, "camera", cam)
        yield cam


@dataclass
class ViewData:
    """A view of the scene: its camera, role, ground truth and the truth's G-buffer as a view."""

    name: str
    role: str
    camera: bpy.types.Object
    truth: capture.Capture
    view: vplace.View
    #: The truth rendered again with another seed (``ReportConfig.truth_noise``), for the
    #: scores against the noise-free truth; None without.
    other: capture.Capture | None = None

    def score(self, image: np.ndarray) -> dict[str, float]:
        """``image`` (independent of the truth's renders: EEVEE, Cycles) scored against the
        view's truth (``vplace.job.score``), and against the noise-free truth where the view has
        the second render."""
        other = None if self.other is None else self.other.gi
        return pipeline.score(image, self.truth.gi, other=other)

    def score_over_direct(self, indirect: np.ndarray) -> dict[str, float]:
        """The truth's direct light plus ``indirect`` (the evaluator's image) scored as
        :meth:`score` does; its noise-free RMSE pairs it with the second render's direct light
        plus ``indirect`` (``vplace.rmse_noise_free``)."""
        other = None if self.other is None else (self.other.direct, self.other.gi)
        return vplace.job.score_over_direct(indirect, self.truth.direct, self.truth.gi, other=other)

    def truth_noise(self) -> dict[str, float]:
        """What the truth's own noise does to SSIM: the two renders' SSIM against each other,
        and the ceiling (``vplace.ssim_ceiling``: what the noise-free image scores against the
        truth); empty without the second render or below 11 x 11 pixels."""
        truth = np.ascontiguousarray(self.truth.gi, dtype=np.float32)
        if self.other is None or min(truth.shape[:2]) < 11:
            return {}
        other = np.ascontiguousarray(self.other.gi, dtype=np.float32)
        return {
            "truths_ssim": vplace.ssim(other, truth),
            "ceiling": vplace.ssim_ceiling(truth, other),
        }


@dataclass
class SceneData:
    """A scene exported once, its job, its fit views' captures and every view."""

    prepared: pipeline.Prepared
    job: pipeline.Job
    views: list[ViewData]
    resolution: tuple[int, int]
    capture_seconds: float
    #: With ``ReportConfig.match_eevee``: what ``vplace+refit``'s refit may fit (the captures
    #: with EEVEE's direct-light deficit added, and the judge of whether it helps) and, per
    #: matched view, the deficit's share of Cycles' direct light (``pipeline.eevee_match``).
    match: vplace.job.EeveeMatch | None = None
    matched: dict[str, float] = field(default_factory=dict)
    #: The match's seconds (its EEVEE renders), part of :attr:`capture_seconds`.
    match_seconds: float = 0.0


def generate_held_out(
    bl_scene: bpy.types.Scene,
    prepared: pipeline.Prepared,
    camera: bpy.types.Object,
    count: int,
    radius: float,
) -> list[bpy.types.Object]:
    """``count`` new cameras (copies of ``camera``'s lens) at the poses of
    ``vplace.coverage.held_out_poses`` around where ``camera`` stands (:func:`eye_positions`:
    past its clip start where that passes a wall), within ``radius`` scene units of it (0: the
    room it stands in; the job's ``views.region_radius``), linked to ``bl_scene``; named
    :data:`GENERATED_PREFIX` ``k``; where the camera's clip start passes a wall, theirs is at most
    :data:`GENERATED_CLIP_START` (they stand past that wall). :func:`remove_generated` takes them
    out again."""
    eye = eye_positions(bl_scene, [ViewSpec(camera.name, camera)])[0]
    moved = (Vector(eye.tolist()) - camera.matrix_world.translation).length
    through_wall = moved > 0.5 * camera.data.clip_start
    forward = list(camera.matrix_world.to_3x3() @ Vector((0.0, 0.0, -1.0)))
    poses = vplace.coverage.held_out_poses(
        prepared.scene,
        eye,
        forward,
        count,
        seed=0,
        radius=radius,
    )
    if len(poses) < count:
        raise ReportError(
            f"only {len(poses)} of {count} held-out views fit around {camera.name!r} "
            "(set --generated-views or name --held-out-cameras)"
        )
    made = []
    for k, pose in enumerate(poses, start=1):
        data = camera.data.copy()
        if through_wall:
            data.clip_start = min(data.clip_start, GENERATED_CLIP_START)
        obj = bpy.data.objects.new(f"{GENERATED_PREFIX}{k}", data)
        obj.matrix_world = pose_matrix(pose)
        bl_scene.collection.objects.link(obj)
        made.append(obj)
    return made


def remove_generated() -> None:
    """Removes the cameras :func:`generate_held_out` made (and their camera data)."""
    for obj in [o for o in bpy.data.objects if o.name.startswith(GENERATED_PREFIX)]:
        remove_camera(obj)


def view_size(
    bl_scene: bpy.types.Scene, preset: ScenePreset, config: ReportConfig
) -> tuple[int, int]:
    """Every view's size: ``--resolution``, else the preset's; a .blend's views keep its
    render's shape (its pixel aspect too), as the demo's do, at the preset's long side."""
    if config.resolution is not None:
        return config.resolution
    if preset.blend is not None:
        return capture_resolution(bl_scene, max(preset.resolution))
    return preset.resolution


def load_scene(
    bl_scene: bpy.types.Scene,
    preset: ScenePreset,
    config: ReportConfig,
    cache_dir: Path,
    log: Callable[[str], None],
) -> SceneData:
    """Exports the scene once, captures the fit views, and renders every view's ground truth."""
    resolution = view_size(bl_scene, preset, config)
    truth_samples = config.truth_samples or preset.truth_samples
    job = pipeline.Job(
        resolution=resolution,
        samples=config.capture_samples or preset.capture_samples,
        seed=CAPTURE_SEED,
        cell_px=config.cell_px,
        alpha=config.alpha,
        iterations=config.iterations,
        feature_mode=config.feature_mode,
        near_field=config.near_field,
        cache_dir=cache_dir,
        views=ViewSet(
            coverage=config.coverage,
            region_radius=config.region_radius,
            render_coverage=config.render_coverage,
        ),
        radius=config.radius,
        match_eevee=config.match_eevee,
    ).in_scene_units(export.unit_scale(bl_scene))
    cams = {}
    for name in (*preset.fit_views, *preset.held_out_views):
        cam = bpy.data.objects.get(name)
        if cam is None or cam.type != "CAMERA":
            raise ReportError(f"the scene has no camera object named {name!r}")
        cams[name] = cam
    timer = pipeline.StageTimer(log)
    specs = [ViewSpec(name, cams[name]) for name in preset.fit_views]
    start = time.perf_counter()
    prepared = pipeline.prepare(bl_scene, replace(job, cache_dir=None), timer, views=specs)
    # What a user waits for before the fit: the export and its BVH, the coverage views' choice
    # and every capture (Blender's set-up of each render included, as in a Cycles frame's).
    seconds = time.perf_counter() - start
    if prepared.skipped:
        raise ReportError(f"fit views left out: {prepared.skipped}")
    held_out = list(preset.held_out_views)
    made = config.generated_for(preset)
    if made:
        for cam in generate_held_out(
            bl_scene, prepared, cams[preset.fit_views[0]], made, job.views.region_radius
        ):
            cams[cam.name] = cam
            held_out.append(cam.name)
        log(f"[vplace] {made} held-out views made in the region: {held_out[-made:]}")
    views = []
    for name in (*preset.fit_views, *held_out):
        role = "fit" if name in preset.fit_views else "held-out"
        truth_of = partial(
            capture.capture,
            bl_scene,
            camera=cams[name],
            resolution=resolution,
            samples=truth_samples,
            cache_dir=cache_dir,
        )
        with timer.stage(f"ground truth {name} ({truth_samples} spp, cached)"):
            truth = truth_of(seed=TRUTH_SEED)
        other = None
        if config.truth_noise:
            with timer.stage(f"second truth {name} (seed {OTHER_TRUTH_SEED}, cached)"):
                other = truth_of(seed=OTHER_TRUTH_SEED)
        gloss = (
            gloss_mask(prepared.scene, prepared.exported, truth) if prepared.vpl_specular else None
        )
        view = view_of(truth, held_out=True, gloss=gloss, scene=prepared.scene)
        views.append(ViewData(name, role, cams[name], truth, view, other))
    # Every run: it also finds the lamps EEVEE darkens (``prepared.cut_lamps``), for the notes.
    # Its EEVEE renders count in the one-time cost, so they are timed here, never cached.
    refit = "vplace+refit" in config.methods
    start = time.perf_counter()
    asked = replace(job, cache_dir=None)
    asked = replace(asked, method="vplace+refit") if refit else replace(asked, match_eevee="off")
    match, matched = pipeline.eevee_match(bl_scene, prepared, asked, timer)
    matching = time.perf_counter() - start
    if refit:
        seconds += matching
        if match is not None:
            log(
                "[vplace] EEVEE's direct-light deficit offered to the refit: "
                f"{matched_shares(matched)}"
            )
    return SceneData(prepared, job, views, resolution, seconds, match, matched, matching)


def _timed(fn: Callable[[], Any]) -> tuple[float, Any]:
    start = time.perf_counter()
    out = fn()
    return time.perf_counter() - start, out


@dataclass
class LaidSet:
    """One method's VPLs at one budget and seed, and what they cost once."""

    method: str
    n_vpls: int
    seed: int | None
    vpls: vplace.VplSet
    one_time_seconds: float
    details: RowDetails = field(default_factory=lambda: RowDetails())


def lay_out_all(
    data: SceneData,
    fitted: vplace.Fit,
    fit_seconds: float,
    config: ReportConfig,
) -> list[LaidSet]:
    """Every method's one VPL set for all fit views, at every budget and seed (RSM, which is
    deterministic, once per budget). ``vplace`` and ``vplace+refit`` share one layout."""
    prepared, rows = data.prepared, []
    base = data.capture_seconds
    for n in config.budgets:
        for seed in config.seeds:
            guided: pipeline.Laid | None = None
            for method in config.methods:
                if method == "rsm" and seed != config.seeds[0]:
                    continue
                job = replace(data.job, n_vpls=n, seed=seed, method=method)
                if method in ("uniform", "rsm"):
                    laid = pipeline.lay_out(prepared, job)
                    rows.append(
                        LaidSet(
                            method,
                            n,
                            seed if method != "rsm" else None,
                            laid.vpls,
                            laid.layout_seconds,
                        )
                    )
                    continue
                if guided is None:
                    both = "vplace+refit" in config.methods
                    guided = pipeline.lay_out(
                        prepared,
                        replace(job, method="vplace+refit" if both else "vplace"),
                        fitted=fitted,
                        match=data.match,
                    )
                layout = guided.layout
                assert layout is not None
                t = base + fit_seconds + guided.layout_seconds
                details = RowDetails(
                    iteration_errors=layout.errors,
                    best_iteration=layout.best,
                    shared_pixels=layout.shared_pixels,
                )
                if method == "vplace+refit":
                    refitted = guided.refit
                    assert refitted is not None
                    t += guided.refit_seconds + guided.near_field_seconds
                    vpls, near = guided.vpls, guided.near_field
                    details = replace(
                        details,
                        refit_seconds=guided.refit_seconds,
                        refit_error_before=refitted.error_before,
                        refit_error_after=refitted.error_after,
                        refit_ridge=refitted.ridge,
                        refit_gain=refitted.gain,
                        switched_off=int((refitted.scales == 0).sum()),
                        eevee_match=asdict(guided.match) if guided.match is not None else None,
                        match_seconds=data.match_seconds if data.match is not None else None,
                    )
                elif guided.refit is None:
                    vpls, near = guided.vpls, guided.near_field
                    t += guided.near_field_seconds
                else:
                    # The layout's own set, judged on its own (lay_out judged the refitted one).
                    start = time.perf_counter()
                    near = vplace.job.choose_near_field(
                        prepared.scene, vplace.coverage.captures_of(prepared.views), layout.vpls
                    )
                    vpls = layout.vpls.with_near_field(near.on)
                    t += time.perf_counter() - start
                if near is not None:
                    details = replace(
                        details,
                        near_field=near.on,
                        near_field_without=near.without,
                        near_field_with=near.with_gather,
                    )
                rows.append(LaidSet(method, n, seed, vpls, t, details))
    return rows


def evaluator_rows(
    data: SceneData,
    sets: Sequence[LaidSet],
    fitted: vplace.Fit,
    config: ReportConfig,
    scene_name: str,
    log: Callable[[str], None],
) -> tuple[list[Row], dict[str, dict[str, np.ndarray]]]:
    """Every VPL set scored on every view with the evaluator, and the held-out views' re-layout;
    returns the rows and, per view, the images of the first seed at the grid budget."""
    scene = data.prepared.scene
    grid_n = grid_budget(config.budgets)
    rows: list[Row] = []
    images: dict[str, dict[str, np.ndarray]] = {v.name: {} for v in data.views}
    for view in data.views:
        truth = view.truth
        for s in sets:
            indirect, stats = vplace.evaluate(scene, view.view, s.vpls)
            estimate = truth.direct + indirect
            row = Row(
                scene_name,
                view.name,
                view.role,
                s.method,
                "evaluator",
                s.n_vpls,
                None,
                one_time_seconds=s.one_time_seconds,
                frame_seconds=stats.seconds,
                shadow_rays=stats.shadow_rays,
                seed=s.seed,
                details=replace(s.details),
                **view.score_over_direct(indirect),
            )
            rows.append(row)
            if s.n_vpls == grid_n and s.seed in (config.seeds[0], None):
                images[view.name][s.method] = estimate
        if view.role == "held-out" and "vplace" in config.methods:
            # Where the held-out view's cells lie outside the fit's range (the model holds
            # them at its edge), per kept feature.
            outside = dict(fitted.out_of_range(view.view))
            for n in config.budgets:
                for seed in config.seeds:
                    job = replace(data.job, n_vpls=n, seed=seed, method="vplace")
                    laid = pipeline.lay_out(data.prepared, job, fitted=fitted, views=[view.view])
                    indirect, stats = vplace.evaluate(scene, view.view, laid.vpls)
                    estimate = truth.direct + indirect
                    rows.append(
                        Row(
                            scene_name,
                            view.name,
                            view.role,
                            RELAYOUT,
                            "evaluator",
                            n,
                            None,
                            one_time_seconds=laid.layout_seconds,
                            frame_seconds=stats.seconds,
                            shadow_rays=stats.shadow_rays,
                            seed=seed,
                            details=RowDetails(out_of_range=outside),
                            **view.score_over_direct(indirect),
                        )
                    )
                    if n == grid_n and seed == config.seeds[0]:
                        images[view.name][RELAYOUT] = estimate
        mine = [r for r in rows if r.view == view.name and r.n_vpls == grid_n]
        for r in mine:
            if r.seed in (config.seeds[0], None):
                log(
                    f"[vplace]   {view.name} ({view.role}) {r.method:<18} N={r.n_vpls:<5} "
                    f"SSIM {r.ssim:.4f} RMSE {r.rmse:.5f}"
                )
    return rows, images


def capture_curve_rows(
    bl_scene: bpy.types.Scene,
    data: SceneData,
    config: ReportConfig,
    scene_name: str,
    log: Callable[[str], None],
) -> list[Row]:
    """vplace+refit at the grid budget, laid out from the fit views captured at each of
    ``config.capture_curve`` samples, scored on every view: what a cheaper capture costs in
    quality. One-time seconds: those captures, the fit, the layout and the refit."""
    grid_n = grid_budget(config.budgets)
    specs = [ViewSpec(v.name, v.camera) for v in data.views if v.role == "fit"]
    rows: list[Row] = []
    for spp in config.capture_curve:
        job = replace(data.job, samples=spp)
        start = time.perf_counter()
        prepared = pipeline.prepare(
            bl_scene, replace(job, cache_dir=None), pipeline.quiet_timer(), views=specs
        )
        capture_seconds = time.perf_counter() - start
        fit_seconds, fitted = _timed(lambda j=job, p=prepared: pipeline.fit(p, j))
        for seed in config.seeds:
            laid = pipeline.lay_out(
                prepared,
                replace(job, n_vpls=grid_n, seed=seed, method="vplace+refit"),
                fitted=fitted,
            )
            once = capture_seconds + fit_seconds + laid.layout_seconds + laid.refit_seconds
            once += laid.near_field_seconds
            for view in data.views:
                indirect, stats = vplace.evaluate(prepared.scene, view.view, laid.vpls)
                rows.append(
                    Row(
                        scene_name,
                        view.name,
                        view.role,
                        CAPTURE_CURVE,
                        "evaluator",
                        grid_n,
                        spp,
                        one_time_seconds=once,
                        frame_seconds=stats.seconds,
                        shadow_rays=stats.shadow_rays,
                        seed=seed,
                        details=RowDetails(capture_seconds=capture_seconds),
                        **view.score_over_direct(indirect),
                    )
                )
        mine = [r for r in rows if r.samples == spp and r.role == "fit"]
        log(
            f"[vplace]   capture {spp:>4} spp ({capture_seconds:.1f} s): vplace+refit N={grid_n} "
            f"fit views' SSIM {np.mean([r.ssim for r in mine]):.4f}"
        )
    return rows


def reference_rows(view: ViewData, scene_name: str) -> list[Row]:
    """Direct light only, scored against the ground truth."""
    return [
        Row(
            scene_name,
            view.name,
            view.role,
            "direct",
            "reference",
            None,
            None,
            one_time_seconds=0.0,
            frame_seconds=0.0,
            **view.score_over_direct(np.zeros_like(view.truth.direct)),
        )
    ]


def colour_of(truth: capture.Capture, eevee_colour: np.ndarray | None) -> np.ndarray | None:
    """Attribution part ``direct``'s share in the surfaces' colour (``vplace.job.colour_part``):
    the truth's diffuse light times EEVEE's Diffuse Color minus the truth's; None without
    EEVEE's pass."""
    if eevee_colour is None:
        return None
    return vplace.job.colour_part(truth.diffuse_direct, eevee_colour, truth.diffuse_color)


def eevee_views(data: SceneData, config: ReportConfig) -> list[ViewData]:
    """The views of ``data`` that EEVEE renders: those ``config.eevee_views`` names (every view
    where it names none). Raises :class:`ReportError` where it names views and none of them is
    one of this scene's, before anything is rendered."""
    wanted = config.eevee_views
    chosen = [v for v in data.views if not wanted or v.name in wanted]
    if not chosen:
        names = ", ".join(repr(v.name) for v in data.views)
        raise ReportError(
            f"none of the EEVEE views {list(wanted)} is a view of this scene: its views are {names}"
        )
    return chosen


@dataclass
class _EeveeRun:
    """The EEVEE (and Cycles + OIDN) renders of one scene's report: every view of each setup,
    scored into rows, with the images kept per view."""

    bl_scene: bpy.types.Scene
    data: SceneData
    config: ReportConfig
    scene_name: str
    cache_dir: Path
    log: Callable[[str], None]
    grid_n: int
    rows: list[Row] = field(default_factory=list)
    images: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)
    #: Per view, EEVEE's direct light: the ``vpl`` set-up with the VPLs hidden (the scene's
    #: lights, vplace's stand-ins and the world's volume on), rendered once for every method.
    direct: dict[str, np.ndarray] = field(default_factory=dict)
    #: Per view, Cycles rendering the same lights (``eevee_setup.cycles_as_eevee_lights``):
    #: what splits attribution part ``direct`` into the stand-ins' own error and EEVEE's
    #: rendering of them. Empty where the world lights EEVEE.
    stand_ins: dict[str, np.ndarray] = field(default_factory=dict)
    #: Per view, the Diffuse Color pass of :attr:`direct`'s render (attribution part ``direct``'s
    #: share in the surfaces' colour as EEVEE filters it; None where the render had none).
    direct_colour: dict[str, np.ndarray | None] = field(default_factory=dict)
    #: Per view and method, EEVEE's VPL light minus the evaluator's (attribution part ``vpl``).
    vpl_differences: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)

    def add(
        self,
        view: ViewData,
        method: str,
        setup: str,
        img: eevee.EeveeImage,
        one_time: float,
        samples: int | None,
        bake_seconds: float | None = None,
        seed: int | None = None,
        attribution: vplace.job.Attribution | None = None,
    ) -> None:
        """Scores ``img`` against the view's truth as a row."""
        renderer = "cycles" if setup == "cycles+oidn" else "eevee"
        row = Row(
            self.scene_name,
            view.name,
            view.role,
            method,
            renderer,
            self.grid_n if setup.startswith("vpl") else None,
            samples,
            one_time_seconds=one_time,
            frame_seconds=img.seconds,
            seed=seed,
            details=RowDetails(
                setup=setup,
                bake_seconds=bake_seconds,
                attribution=attribution.to_dict() if attribution is not None else None,
            ),
            **view.score(img.image),
        )
        self.rows.append(row)
        self.log(
            f"[vplace]   {renderer} {view.name} {method:<18} SSIM {row.ssim:.4f} "
            f"brightness {row.brightness:.3f} {img.seconds:6.1f} s"
        )
        if attribution is not None:
            a = attribution
            self.log(
                "[vplace]     RMSE by part: "
                + ", ".join(f"{k} {a.rmse[k]:.4f} ({pct(a.share[k], signed=True)})" for k in a.rmse)
                + f"; direct {a.direct_brightness:.3f}x Cycles', VPL light "
                f"{a.vpl_brightness:.3f}x the evaluator's; SSIM with Cycles' direct light "
                f"{a.ssim_cycles_direct:.4f}, with the evaluator's VPL light "
                f"{a.ssim_evaluator_vpl:.4f}; (a) in the {a.seen_pixels:.1%} of pixels that "
                "see an emitter, the world or a lamp in a mirror: "
                f"{pct(a.seen_share, signed=True)} of the squared error; (a) the stand-ins' own "
                "light (Cycles rendering them) "
                f"{pct(a.stand_in_share, signed=True)}, EEVEE's rendering of them "
                f"{pct(a.share['direct'] - a.stand_in_share, signed=True)}"
                + (
                    f"; (a) in the {a.cut_pixels:.1%} of pixels whose plane cuts a light: "
                    f"{pct(a.cut_share, signed=True)}, EEVEE's direct light "
                    f"{a.cut_brightness:.3f}x Cycles' there"
                    if a.cut_pixels > 0
                    else "; no pixel's plane cuts a light"
                )
                + (
                    "; (a) in the surfaces' colour as EEVEE filters it (Cycles' diffuse light "
                    "times EEVEE's Diffuse Color minus Cycles'): "
                    f"{pct(a.colour_share, signed=True)}"
                    if math.isfinite(a.colour_share)
                    else ""
                )
            )

    def each_view(
        self, setup: eevee.Setup, samples: int, diffuse_color: bool = False
    ) -> Iterator[tuple[ViewData, eevee.EeveeImage]]:
        """Every view EEVEE renders (:func:`eevee_views`) with ``setup`` at ``samples`` (cached
        unless the set-up is in :data:`UNCACHED`; with its Diffuse Color pass where
        ``diffuse_color``)."""
        for view in eevee_views(self.data, self.config):
            yield (
                view,
                eevee.render(
                    self.bl_scene,
                    resolution=self.data.resolution,
                    camera=view.camera,
                    samples=samples,
                    setup=setup,
                    seed=CURVE_SEED,
                    cache_dir=None if setup.name in UNCACHED else self.cache_dir,
                    diffuse_color=diffuse_color,
                ),
            )

    def render_direct(self) -> None:
        """EEVEE's direct light on every view (:attr:`direct`), with the lights just written:
        their VPLs hidden for the render, vplace's stand-ins kept."""
        with override() as g:
            apply.hide_vpl_lights(g, self.bl_scene)
            for view, img in self.each_view(
                eevee.SETUPS["vpl"], self.config.eevee_samples, diffuse_color=True
            ):
                self.direct[view.name] = img.image
                self.direct_colour[view.name] = img.diffuse_color
                self.log(f"[vplace]   eevee {view.name} direct light only {img.seconds:6.1f} s")
            emissive = self.data.prepared.exported.emissive_materials
            if not eevee_setup.cycles_as_eevee_lights(g, self.bl_scene, emissive):
                return
            for view in eevee_views(self.data, self.config):
                t0 = time.perf_counter()
                c = capture.capture(
                    self.bl_scene,
                    camera=view.camera,
                    resolution=self.data.resolution,
                    samples=eevee_setup.STAND_IN_SAMPLES,
                    seed=CURVE_SEED,
                    include_vpls=True,
                )
                self.stand_ins[view.name] = c.direct
                self.log(
                    f"[vplace]   cycles {view.name} the same lights (stand-ins) "
                    f"{time.perf_counter() - t0:6.1f} s"
                )

    def attribute(
        self, view: ViewData, method: str, s: LaidSet, img: eevee.EeveeImage
    ) -> vplace.job.Attribution:
        """``img`` (EEVEE with the lights of ``s``) split by ``vplace.job.attribute``."""
        vpl_light, _ = vplace.evaluate(self.data.prepared.scene, view.view, s.vpls)
        direct = self.direct[view.name]
        self.vpl_differences.setdefault(view.name, {})[method] = img.image - direct - vpl_light
        truth = view.truth
        seen = vplace.job.seen_directly(truth.seen_light, truth.direct)
        return vplace.job.attribute(
            img.image,
            direct,
            truth.direct,
            vpl_light,
            truth.gi,
            seen,
            self.stand_ins.get(view.name),
            cut_lights.cut_pixels(self.bl_scene, view.view, seen),
            colour_of(truth, self.direct_colour.get(view.name)),
        )

    def vpl_rows(self, method: str, s: LaidSet, world_bake: float, portals: bool) -> None:
        """The lights of ``s`` written (the sky portals with ``portals``), rendered on every view
        (and with ray tracing for ``vplace+refit``), and removed again; the ``vpl`` renders are
        attributed."""
        config, prepared = self.config, self.data.prepared
        apply.write_vpls(
            self.bl_scene,
            s.vpls,
            scene_diagonal=prepared.scene.scale,
            region=prepared.scene.region,
            specular=prepared.vpl_specular,
            unlit=prepared.vpl_unlit,
            emitters=[e for e in prepared.stand_ins.emitters if portals or not e.portal],
            sun=prepared.stand_ins.sun,
            closed=prepared.stand_ins.closed,
        )
        try:
            if not self.direct:
                self.render_direct()
            names = ["vpl"] + (
                ["vpl+rt"] if method == "vplace+refit" and "vpl+rt" in config.alternatives else []
            )
            for name in names:
                label = method if name == "vpl" else method + WITH_RT
                for view, img in self.each_view(eevee.SETUPS[name], config.eevee_samples):
                    self.add(
                        view,
                        label,
                        name,
                        img,
                        s.one_time_seconds + world_bake,
                        config.eevee_samples,
                        seed=s.seed,
                        attribution=self.attribute(view, method, s, img) if name == "vpl" else None,
                    )
                    if name == "vpl":
                        self.images[view.name][method] = img.image
        finally:
            apply.clear_vpls(scene=self.bl_scene)

    def methods(self, chosen: dict[str, LaidSet]) -> None:
        """The chosen methods' lights, with the world's probe volume baked once for all."""
        # Sky portals where the world can be kept from lighting EEVEE (else, as without them,
        # the world's volume); in a closed room the world lights nothing, as in Cycles.
        lights = self.data.prepared.stand_ins
        shut = lights.world_shut_out
        shut = shut and eevee_setup.camera_only_blocker(self.bl_scene.world) is None
        portals = bool(lights.portals) and shut
        with contextlib.ExitStack() as stack:
            world_bake = 0.0
            if chosen:  # the world's light, occluded, as eevee_setup.set_up bakes it
                world_bake = stack.enter_context(
                    eevee_setup.world_for_render(
                        self.bl_scene, probes=self.config.volume_resolution, portals=shut
                    )
                )
            if world_bake:
                self.log(f"[vplace] the world's light probe volume baked in {world_bake:.1f} s")
            for method, s in chosen.items():
                self.vpl_rows(method, s, world_bake, portals)

    def alternatives(self) -> None:
        """What a Blender user would pick instead: EEVEE plain, with ray tracing, with a baked
        probe volume (each with the world's sun as a lamp where the world has one:
        ``eevee_setup.users_sun``), and Cycles + OpenImageDenoise."""
        sun = self.data.prepared.stand_ins.sun
        with eevee_setup.users_sun(self.bl_scene, [sun]) as lamp:
            if lamp:
                self.log("[vplace] EEVEE's own GI is scored with the world's sun as a lamp")
            self.eevee_alternatives()
        if "cycles+oidn" in self.config.alternatives:
            for spp in self.config.cycles_samples:
                for view, img in self.each_view(eevee.SETUPS["cycles+oidn"], spp):
                    self.add(view, "cycles+oidn", "cycles+oidn", img, 0.0, spp)
                    if spp == max(self.config.cycles_samples):
                        self.images[view.name][f"cycles+oidn {spp}"] = img.image

    def eevee_alternatives(self) -> None:
        """EEVEE plain, with ray tracing, and with a probe volume baked for them."""
        config, images = self.config, self.images
        for name in ("plain", "rt"):
            if name in config.alternatives:
                label = {"plain": "eevee", "rt": "eevee rt"}[name]
                for view, img in self.each_view(eevee.SETUPS[name], config.eevee_samples):
                    self.add(view, label, name, img, 0.0, config.eevee_samples)
                    images[view.name][label] = img.image
        if "rt+volume" in config.alternatives:
            with eevee_setup.temporary_volume(
                self.bl_scene,
                probes=config.volume_resolution,
                region=self.data.prepared.scene.region,
            ) as bake:
                self.log(f"[vplace] light probe volume baked in {bake:.1f} s")
                for view, img in self.each_view(eevee.SETUPS["rt+volume"], config.eevee_samples):
                    self.add(
                        view,
                        "eevee rt + volume",
                        "rt+volume",
                        img,
                        bake,
                        config.eevee_samples,
                        bake_seconds=bake,
                    )
                    images[view.name]["eevee rt + volume"] = img.image


def eevee_rows(
    bl_scene: bpy.types.Scene,
    data: SceneData,
    sets: Sequence[LaidSet],
    config: ReportConfig,
    scene_name: str,
    cache_dir: Path,
    log: Callable[[str], None],
) -> _EeveeRun:
    """The grid budget's lights of each of ``config.eevee_methods`` rendered by EEVEE on every
    view it renders (:func:`eevee_views`), and the alternatives; returns the run: its rows, the
    images per view and the attribution's VPL differences."""
    if apply.find_collection(scene=bl_scene) is not None:
        raise ReportError(
            f"the scene already has a {apply.COLLECTION_NAME!r} collection; the report does "
            "not replace the user's VPLs (run it with --no-eevee, or on a copy)"
        )
    grid_n = grid_budget(config.budgets)
    run = _EeveeRun(bl_scene, data, config, scene_name, cache_dir, log, grid_n)
    run.images = {v.name: {} for v in data.views}
    chosen = {
        s.method: s
        for s in sets
        if s.n_vpls == grid_n
        and s.seed in (config.seeds[0], None)
        and s.method in config.eevee_methods
    }
    run.methods(chosen)
    run.alternatives()
    return run


def run_scene(
    preset: ScenePreset,
    config: ReportConfig,
    out: Path,
    cache_dir: Path,
    log: Callable[[str], None],
) -> tuple[list[Row], dict[str, Any]]:
    """Every view of one scene: rows, plus the fit summary and image paths."""

    blend = preset.blend or default_scene.builtin_scene(preset.name)
    default_scene.open_blend(blend)
    log(f"[vplace] report: {preset.name} ({blend.name})")
    bl_scene = bpy.context.scene
    try:
        return _run_scene(bl_scene, preset, config, out, cache_dir, log)
    finally:
        remove_generated()


def _run_scene(
    bl_scene: bpy.types.Scene,
    preset: ScenePreset,
    config: ReportConfig,
    out: Path,
    cache_dir: Path,
    log: Callable[[str], None],
) -> tuple[list[Row], dict[str, Any]]:
    """:func:`run_scene` on the opened scene."""
    from . import plots as report_plots

    data = load_scene(bl_scene, preset, config, cache_dir, log)
    if config.with_eevee:
        eevee_views(data, config)  # a name that matches no view fails before any work
    fit_seconds, fitted = _timed(lambda: pipeline.fit(data.prepared, data.job))
    log(
        f"[vplace] {preset.name}: fitted on {len(preset.fit_views)} views in {fit_seconds:.2f} s\n"
        f"{fitted}"
    )
    sets = lay_out_all(data, fitted, fit_seconds, config)
    rows, images = evaluator_rows(data, sets, fitted, config, preset.name, log)
    for view in data.views:
        rows += reference_rows(view, preset.name)
    if config.capture_curve:
        rows += capture_curve_rows(bl_scene, data, config, preset.name, log)
    shown: dict[str, dict[str, np.ndarray]] = {v.name: {} for v in data.views}
    differences: dict[str, dict[str, np.ndarray]] = {}
    if config.with_eevee:
        run = eevee_rows(bl_scene, data, sets, config, preset.name, cache_dir, log)
        rows += run.rows
        shown, differences = run.images, run.vpl_differences
    info: dict[str, Any] = {
        "fit": asdict(vplace.job.FitSummary.of(fitted)),
        "fit_seconds": fit_seconds,
        "capture_seconds": data.capture_seconds,
        "eevee_deficit_matched": data.matched if data.match is not None else None,
        "views": {},
        "lamp_notes": (
            eevee_setup.lamp_notes(bl_scene, data.prepared.cut_lamps) if config.with_eevee else []
        ),
        "vpl_specular": data.prepared.vpl_specular,
        "vpl_unlit": data.prepared.vpl_unlit,
    }
    regions = _regions(data)
    for view in data.views:
        cap = view.truth
        info["views"][view.name] = {
            "role": view.role,
            "resolution": [cap.width, cap.height],
            "capture_samples": data.job.samples if view.role == "fit" else None,
            "truth_samples": cap.samples,
            "truth_seconds": cap.render_seconds,
            "truth_noise": view.truth_noise(),
            "triangles": data.prepared.scene.triangle_count,
        }
        if view.name in regions:
            info["views"][view.name]["region"] = regions[view.name]
        stem = f"{preset.name}_{report_plots.slug(view.name)}"
        for key, prefix, pictures, what in (
            ("grid", "grid", images[view.name], "the evaluator"),
            ("eevee_grid", "eevee", shown[view.name], "EEVEE and the alternatives"),
        ):
            if pictures:
                grid = report_plots.image_grid(
                    out / f"{prefix}_{stem}.png",
                    view.truth.gi,
                    view.truth.direct,
                    pictures,
                    title=f"{preset.name}, {view.name} ({view.role} view): {what}",
                )
                info["views"][view.name][key] = grid.name
        if differences.get(view.name):
            picture = report_plots.difference_grid(
                out / f"vpl_difference_{stem}.png",
                differences[view.name],
                scale=float(np.percentile(view.truth.gi, 99)),
                title=f"{preset.name}, {view.name}: EEVEE's VPL light minus the evaluator's",
            )
            info["views"][view.name]["vpl_difference"] = picture.name
    return rows, info


def _regions(data: SceneData) -> dict[str, dict[str, Any]]:
    """Per held-out view, the fit camera whose region it stands deepest in (the least distance
    from eye to eye, ``vplace.coverage.camera_eye``, over that camera's region radius,
    ``vplace.coverage.region_radius``), the distance and the radius in metres, and whether it
    stands inside: whether the view is one a camera in the region the lights were laid out for
    can take."""
    scene, metres = data.prepared.scene, data.prepared.exported.unit_scale

    def eye(v: ViewData) -> np.ndarray:
        return vplace.coverage.camera_eye(scene, v.truth.camera_position, v.truth.world_to_clip)

    fits = [
        (v.name, e, vplace.coverage.region_radius(scene, e, data.job.views.region_radius))
        for v in data.views
        if v.role == "fit"
        for e in (eye(v),)
    ]
    out: dict[str, dict[str, Any]] = {}
    for v in data.views:
        if v.role != "held-out" or not fits:
            continue
        at = eye(v)
        name, distance, radius = min(
            ((n, float(np.linalg.norm(e - at)), r) for n, e, r in fits),
            key=lambda f: f[1] / max(f[2], 1e-9),
        )
        out[v.name] = {
            "camera": name,
            "distance": distance * metres,
            "radius": radius * metres,
            "inside": distance <= radius,
        }
    return out


def _inside(scenes: dict[str, Any]) -> dict[str, dict[str, bool]]:
    """Per scene, per held-out view: whether it stands inside the region (``_regions``)."""
    return {
        name: {
            view: bool(v["region"]["inside"])
            for view, v in info.get("views", {}).items()
            if "region" in v
        }
        for name, info in scenes.items()
    }


def run_report(
    config: ReportConfig, out: Path, log: Callable[[str], None] = print
) -> dict[str, Any]:
    """Runs the report and writes its files into ``out``. Opens each scene's .blend (the current
    file is replaced in memory, never saved)."""
    from . import plots as report_plots

    config.validate()
    output_folder(out)
    cache_dir = config.cache_dir or out / "cache"
    start = time.perf_counter()
    rows: list[Row] = []
    scenes: dict[str, Any] = {}
    for preset in config.presets():
        scene_rows, info = run_scene(preset, config, out, cache_dir, log)
        rows += scene_rows
        scenes[preset.name] = info
    par_rows: list[vplace.par2d_measure.Par2dRow] = []
    if config.par2d:
        # vplace.par2d_measure's scene: 512x512, 8 lights, 64 occluders.
        par_rows, _ = vplace.par2d_measure.measure(size=512, rays=(4, 16, 64, 256))
        report_plots.par2d_plot(out / "par2d_speed_error.png", par_rows)
    means = aggregate(rows)
    result = {
        "config": {
            **{k: v for k, v in asdict(config).items() if k != "cache_dir"},
            "cache_dir": str(cache_dir),
        },
        "seconds": time.perf_counter() - start,
        "scenes": scenes,
        "rows": [row_dict(r) for r in rows],
        "means": [row_dict(r) for r in means],
        "targets": targets(means, _inside(scenes)),
        "break_even": break_even(means),
        "par2d": [asdict(r) for r in par_rows],
    }
    write_csv(out / "results.csv", rows)
    report_plots.error_vs_time(out, means)
    report_plots.error_vs_budget(out / "error_vs_vpls.png", means)
    result["files"] = sorted(p.name for p in out.iterdir() if p.is_file())
    (out / "results.json").write_text(json.dumps(result, indent=2, default=_json_default))
    (out / "report.md").write_text(markdown(result, means))
    log(f"[vplace] report written to {out} in {result['seconds']:.0f} s")
    return result


def _json_default(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, (np.ndarray, tuple)):
        return list(value)
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"cannot write {type(value).__name__} to JSON")
