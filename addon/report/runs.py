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

Costs are kept apart: ``one_time_seconds`` (the captures, the fit, the layout and refit, a
volume's bake) and ``frame_seconds`` (one frame: the evaluator's image, an EEVEE or a Cycles
render). The break-even table says after how many frames vplace's one-time cost plus its EEVEE
frames costs less than Cycles + OIDN frames of at least the same SSIM.

Written into ``--out``: ``results.csv`` and ``results.json`` (every row), ``report.md`` (tables,
the break-even, the target checks) and PNG plots. Renders are cached in ``out/cache``. The user's
.blend is never saved: the scene camera is switched through a settings guard, and the VPL
collection written for EEVEE is removed again.
"""

from __future__ import annotations

import contextlib
import csv
import json
import math
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import bpy
import numpy as np

from .. import job as pipeline
from ..capture import passes as capture
from ..capture.native_view import gloss_mask, view_of
from ..capture.views import ViewSpec
from ..errors import ReportError
from ..native import vplace
from ..scenes import registry as default_scene
from ..scenes import rooms as builtin_rooms
from ..settings import override
from ..writeback import apply, eevee_setup
from ..writeback import eevee_render as eevee

#: Seeds of the renders: the user's capture, the ground truth, Cycles' curve.
CAPTURE_SEED = 0
TRUTH_SEED = 7919
CURVE_SEED = 104729

METHODS = pipeline.METHODS
RELAYOUT = "vplace (re-layout)"
#: vplace+refit laid out from captures at other sample counts (``samples``: the capture's spp).
CAPTURE_CURVE = "vplace+refit by capture spp"
#: The suffix of a VPL method rendered with EEVEE's ray-traced reflections on.
WITH_RT = " + rt reflections"
#: The budget the image grids, EEVEE and the targets use (the nearest one run).
GRID_BUDGET = 256
#: The issues' margins: vplace's SSIM above each baseline, EEVEE with VPLs above EEVEE's own GI,
#: held-out views against the fit views' mean, EEVEE against the evaluator.
SSIM_MARGIN = 0.05
HELD_OUT_SPREAD = 0.03
EEVEE_SPREAD = 0.02
BRIGHTNESS_TOLERANCE = 0.03
FIT_VIEW_SSIM = 0.90
#: The default capture's layout against the curve's largest sample count.
CAPTURE_SPREAD = 0.01


@dataclass(frozen=True)
class ScenePreset:
    """A scene for the report: its views, capture size and sample counts."""

    name: str
    fit_views: tuple[str, ...]
    held_out_views: tuple[str, ...]
    resolution: tuple[int, int]
    capture_samples: int
    truth_samples: int
    #: A .blend path, or None for the built-in scene of this name.
    blend: Path | None = None


PRESETS = {
    "cornell": ScenePreset(
        "cornell",
        ("Cornell camera", "Cornell camera left", "Cornell camera high"),
        (default_scene.CORNELL_HELD_OUT_CAMERA, "Cornell camera (held out, low)"),
        (160, 160),
        256,
        2048,
    ),
    "sponza": ScenePreset(
        "sponza",
        (default_scene.SPONZA_CAMERA, "CameraBalcony", default_scene.SPONZA_WEST_CAMERA),
        (default_scene.SPONZA_HELD_OUT_CAMERA, "CameraAlcove"),
        (320, 180),
        128,
        1024,
    ),
    "skyroom": ScenePreset(
        "skyroom",
        tuple(builtin_rooms.SKYROOM_FIT),
        tuple(builtin_rooms.SKYROOM_HELD_OUT),
        (256, 144),
        16,
        1024,
    ),
    "panelroom": ScenePreset(
        "panelroom",
        tuple(builtin_rooms.PANELROOM_FIT),
        tuple(builtin_rooms.PANELROOM_HELD_OUT),
        (256, 144),
        16,
        1024,
    ),
}


@dataclass
class ReportConfig:
    """What the report runs. ``None`` fields take the scene preset's value."""

    scenes: Sequence[str] = ("cornell", "sponza", "skyroom", "panelroom")
    #: Any .blend instead of the built-in scenes, with its cameras.
    blend: Path | None = None
    fit_cameras: Sequence[str] = ()
    held_out_cameras: Sequence[str] = ()
    budgets: Sequence[int] = (16, 64, 256, 1024)
    methods: Sequence[str] = METHODS
    resolution: tuple[int, int] | None = None
    capture_samples: int | None = None
    truth_samples: int | None = None
    #: Cycles + OpenImageDenoise at these samples, the user's alternative.
    cycles_samples: Sequence[int] = (1, 4, 16, 64)
    alpha: float = 1.0
    iterations: int = 3
    cell_px: int = 16
    #: One of :data:`pipeline.FEATURE_MODES`.
    feature_mode: str = "auto"
    #: Seeds of the stochastic layouts (uniform, vplace); tables and plots show their mean.
    seeds: Sequence[int] = (0, 1, 2)
    #: Score the grid budget's lights with EEVEE, beside EEVEE's own GI.
    with_eevee: bool = True
    #: The methods whose lights EEVEE renders (each costs one EEVEE render per view).
    eevee_methods: Sequence[str] = ("uniform", "rsm", "vplace+refit")
    #: The alternatives of :data:`eevee.SETUPS` rendered per view (``cycles+oidn`` runs at
    #: ``cycles_samples``).
    alternatives: Sequence[str] = ("plain", "rt", "rt+volume", "vpl+rt", "cycles+oidn")
    eevee_samples: int = eevee.EEVEE_SAMPLES
    #: Capture sample counts to lay out vplace+refit from (at the grid budget), every view
    #: scored: layout quality against capture cost. Empty: no curve.
    capture_curve: Sequence[int] = ()
    #: Probes along the longest side of the baked light probe volumes (``rt+volume``, and the
    #: world's volume of the VPL renders when the world emits).
    volume_resolution: int = eevee_setup.VOLUME_PROBES
    par2d: bool = True
    cache_dir: Path | None = None

    def presets(self) -> list[ScenePreset]:
        """The scenes to run."""
        if self.blend is not None:
            return [
                ScenePreset(
                    Path(self.blend).stem,
                    tuple(self.fit_cameras),
                    tuple(self.held_out_cameras),
                    self.resolution or (320, 180),
                    self.capture_samples or 128,
                    self.truth_samples or 1024,
                    blend=Path(self.blend),
                )
            ]
        return [PRESETS[s] for s in self.scenes]

    def validate(self) -> None:
        """Raises :class:`ReportError` for an unusable configuration."""
        unknown = [m for m in self.methods if m not in METHODS]
        if unknown:
            raise ReportError(f"unknown methods {unknown}: choose from {list(METHODS)}")
        if not self.budgets or min(self.budgets) < 1:
            raise ReportError(f"budgets must be positive VPL counts, got {list(self.budgets)}")
        if max(self.budgets) > apply.MAX_VPLS:
            raise ReportError(f"budgets above {apply.MAX_VPLS} VPLs are not supported")
        if self.blend is not None:
            if not Path(self.blend).is_file():
                raise ReportError(f"no such .blend file: {self.blend}")
            if not self.fit_cameras:
                raise ReportError("a report on a .blend needs --fit-cameras")
        else:
            bad = [s for s in self.scenes if s not in PRESETS]
            if bad:
                raise ReportError(f"unknown scenes {bad}: choose from {sorted(PRESETS)}")
        if any(s < 1 for s in (*self.cycles_samples, *self.capture_curve)):
            raise ReportError("Cycles sample counts must be at least 1")
        if self.feature_mode not in pipeline.FEATURE_MODES:
            raise ReportError(f"feature mode must be one of {pipeline.FEATURE_MODES}")
        if self.volume_resolution < 1:
            raise ReportError("the light probe volume needs at least 1 probe along each side")
        if not self.seeds:
            raise ReportError("give at least one seed")
        bad = [a for a in self.alternatives if a not in eevee.SETUPS]
        if bad:
            raise ReportError(f"unknown alternatives {bad}: choose from {sorted(eevee.SETUPS)}")
        bad = [m for m in self.eevee_methods if m not in METHODS]
        if bad:
            raise ReportError(f"unknown EEVEE methods {bad}: choose from {list(METHODS)}")


@dataclass
class Row:
    """One scored image: a method (or an alternative) at a budget on a view, by a renderer."""

    scene: str
    view: str
    role: str  # "fit" or "held-out"
    method: str  # a METHODS name, RELAYOUT, an eevee.SETUPS name, or "direct"
    renderer: str  # "evaluator", "eevee", "cycles" or "reference"
    n_vpls: int | None
    samples: int | None
    rmse: float
    relative_mse: float
    ssim: float
    #: Mean luminance of the image over the ground truth's.
    brightness: float
    #: Paid once for every frame and view: captures, fit, layout, refit, a volume's bake.
    one_time_seconds: float
    #: One frame: the evaluator's image, an EEVEE or a Cycles render.
    frame_seconds: float
    shadow_rays: int = 0
    seed: int | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def one_minus_ssim(self) -> float:
        return 1.0 - self.ssim


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


@dataclass
class SceneData:
    """A scene exported once, its job, its fit views' captures and every view."""

    prepared: pipeline.Prepared
    job: pipeline.Job
    views: list[ViewData]
    resolution: tuple[int, int]
    capture_seconds: float


def load_scene(
    bl_scene: bpy.types.Scene,
    preset: ScenePreset,
    config: ReportConfig,
    cache_dir: Path,
    log: Callable[[str], None],
) -> SceneData:
    """Exports the scene once, captures the fit views, and renders every view's ground truth."""
    resolution = config.resolution or preset.resolution
    truth_samples = config.truth_samples or preset.truth_samples
    job = pipeline.Job(
        resolution=resolution,
        samples=config.capture_samples or preset.capture_samples,
        seed=CAPTURE_SEED,
        cell_px=config.cell_px,
        alpha=config.alpha,
        iterations=config.iterations,
        feature_mode=config.feature_mode,
        cache_dir=cache_dir,
    )
    cams = {}
    for name in (*preset.fit_views, *preset.held_out_views):
        cam = bpy.data.objects.get(name)
        if cam is None or cam.type != "CAMERA":
            raise ReportError(f"the scene has no camera object named {name!r}")
        cams[name] = cam
    timer = pipeline.StageTimer(log)
    specs = [ViewSpec(name, cams[name]) for name in preset.fit_views]
    prepared = pipeline.prepare(bl_scene, job, timer, views=specs)
    if prepared.skipped:
        raise ReportError(f"fit views left out: {prepared.skipped}")
    views = []
    for name in (*preset.fit_views, *preset.held_out_views):
        role = "fit" if name in preset.fit_views else "held-out"
        with timer.stage(f"ground truth {name} ({truth_samples} spp, cached)"):
            truth = capture.capture(
                bl_scene,
                camera=cams[name],
                resolution=resolution,
                samples=truth_samples,
                seed=TRUTH_SEED,
                cache_dir=cache_dir,
            )
        gloss = gloss_mask(prepared.scene, prepared.exported, truth)
        views.append(
            ViewData(name, role, cams[name], truth, view_of(truth, held_out=True, gloss=gloss))
        )
    seconds = sum(c.render_seconds for c in prepared.captures)
    return SceneData(prepared, job, views, resolution, seconds)


def _timed(fn: Callable[[], Any]) -> tuple[float, Any]:
    start = time.perf_counter()
    out = fn()
    return time.perf_counter() - start, out


def grid_budget(budgets: Sequence[int]) -> int:
    """The budget nearest GRID_BUDGET (the lower one on ties): image grids, EEVEE, targets."""
    return min(budgets, key=lambda n: (abs(n - GRID_BUDGET), n))


@dataclass
class LaidSet:
    """One method's VPLs at one budget and seed, and what they cost once."""

    method: str
    n_vpls: int
    seed: int | None
    vpls: vplace.VplSet
    one_time_seconds: float
    extra: dict[str, Any] = field(default_factory=dict)


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
                    )
                layout = guided.layout
                assert layout is not None
                t = base + fit_seconds + guided.layout_seconds
                extra: dict[str, Any] = {
                    "iteration_errors": layout.errors,
                    "best_iteration": layout.best,
                    "shared_pixels": layout.shared_pixels,
                }
                vpls = layout.vpls
                if method == "vplace+refit":
                    refitted = guided.refit
                    assert refitted is not None
                    t += guided.refit_seconds
                    vpls = refitted.vpls
                    extra.update(
                        refit_seconds=guided.refit_seconds,
                        refit_error_before=refitted.error_before,
                        refit_error_after=refitted.error_after,
                        switched_off=int((refitted.scales == 0).sum()),
                    )
                rows.append(LaidSet(method, n, seed, vpls, t, extra))
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
                extra=dict(s.extra),
                **pipeline.score(estimate, truth.gi),
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
                            extra={"out_of_range": outside},
                            **pipeline.score(estimate, truth.gi),
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
        prepared = pipeline.prepare(bl_scene, job, pipeline.quiet_timer(), views=specs)
        capture_seconds = sum(c.render_seconds for c in prepared.captures)
        fit_seconds, fitted = _timed(lambda j=job, p=prepared: pipeline.fit(p, j))
        for seed in config.seeds:
            laid = pipeline.lay_out(
                prepared,
                replace(job, n_vpls=grid_n, seed=seed, method="vplace+refit"),
                fitted=fitted,
            )
            once = capture_seconds + fit_seconds + laid.layout_seconds + laid.refit_seconds
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
                        extra={"capture_seconds": capture_seconds},
                        **pipeline.score(view.truth.direct + indirect, view.truth.gi),
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
            **pipeline.score(view.truth.direct, view.truth.gi),
        )
    ]


def eevee_rows(
    bl_scene: bpy.types.Scene,
    data: SceneData,
    sets: Sequence[LaidSet],
    config: ReportConfig,
    scene_name: str,
    cache_dir: Path,
    log: Callable[[str], None],
) -> tuple[list[Row], dict[str, dict[str, np.ndarray]]]:
    """The grid budget's lights of each of ``config.eevee_methods`` rendered by EEVEE on every
    view, and the alternatives; returns the rows and the images per view."""
    if apply.find_collection() is not None:
        raise ReportError(
            f"the scene already has a {apply.COLLECTION_NAME!r} collection; the report does "
            "not replace the user's VPLs (run it with --no-eevee, or on a copy)"
        )
    grid_n = grid_budget(config.budgets)
    diagonal = data.prepared.scene.diagonal
    rows: list[Row] = []
    images: dict[str, dict[str, np.ndarray]] = {v.name: {} for v in data.views}

    def add(
        view: ViewData,
        method: str,
        setup: str,
        img: eevee.EeveeImage,
        one_time: float,
        samples: int | None,
        extra: dict[str, Any] | None = None,
        seed: int | None = None,
    ) -> None:
        renderer = "cycles" if setup == "cycles+oidn" else "eevee"
        row = Row(
            scene_name,
            view.name,
            view.role,
            method,
            renderer,
            grid_n if setup.startswith("vpl") else None,
            samples,
            one_time_seconds=one_time,
            frame_seconds=img.seconds,
            seed=seed,
            extra={"setup": setup, **(extra or {})},
            **pipeline.score(img.image, view.truth.gi),
        )
        rows.append(row)
        log(
            f"[vplace]   {renderer} {view.name} {method:<18} SSIM {row.ssim:.4f} "
            f"brightness {row.brightness:.3f} {img.seconds:6.1f} s"
        )

    def each_view(setup: eevee.Setup, samples: int) -> Iterator[tuple[ViewData, eevee.EeveeImage]]:
        for view in data.views:
            yield (
                view,
                eevee.render(
                    bl_scene,
                    resolution=data.resolution,
                    camera=view.camera,
                    samples=samples,
                    setup=setup,
                    seed=CURVE_SEED,
                    cache_dir=cache_dir,
                ),
            )

    chosen = {
        s.method: s
        for s in sets
        if s.n_vpls == grid_n
        and s.seed in (config.seeds[0], None)
        and s.method in config.eevee_methods
    }

    def vpl_rows(method: str, s: LaidSet, world_bake: float) -> None:
        apply.write_vpls(
            bl_scene,
            s.vpls,
            scene_diagonal=diagonal,
            specular=data.prepared.vpl_specular,
            emitters=data.prepared.stand_ins.emitters,
            sun=data.prepared.stand_ins.sun,
        )
        try:
            names = ["vpl"] + (
                ["vpl+rt"] if method == "vplace+refit" and "vpl+rt" in config.alternatives else []
            )
            for name in names:
                label = method if name == "vpl" else method + WITH_RT
                for view, img in each_view(eevee.SETUPS[name], config.eevee_samples):
                    add(
                        view,
                        label,
                        name,
                        img,
                        s.one_time_seconds + world_bake,
                        config.eevee_samples,
                        seed=s.seed,
                    )
                    if name == "vpl":
                        images[view.name][method] = img.image
        finally:
            apply.clear_vpls()

    with contextlib.ExitStack() as stack:
        world_bake = 0.0
        if chosen:  # the world's light, occluded, as eevee_setup.set_up bakes it
            world_bake = stack.enter_context(
                eevee_setup.world_volume_for_render(bl_scene, probes=config.volume_resolution)
            )
        if world_bake:
            log(f"[vplace] the world's light probe volume baked in {world_bake:.1f} s")
        for method, s in chosen.items():
            vpl_rows(method, s, world_bake)
    for name in ("plain", "rt"):
        if name in config.alternatives:
            label = {"plain": "eevee", "rt": "eevee rt"}[name]
            for view, img in each_view(eevee.SETUPS[name], config.eevee_samples):
                add(view, label, name, img, 0.0, config.eevee_samples)
                images[view.name][label] = img.image
    if "rt+volume" in config.alternatives:
        with eevee_setup.temporary_volume(bl_scene, probes=config.volume_resolution) as bake:
            log(f"[vplace] light probe volume baked in {bake:.1f} s")
            for view, img in each_view(eevee.SETUPS["rt+volume"], config.eevee_samples):
                add(
                    view,
                    "eevee rt + volume",
                    "rt+volume",
                    img,
                    bake,
                    config.eevee_samples,
                    {"bake_seconds": bake},
                )
                images[view.name]["eevee rt + volume"] = img.image
    if "cycles+oidn" in config.alternatives:
        for spp in config.cycles_samples:
            for view, img in each_view(eevee.SETUPS["cycles+oidn"], spp):
                add(view, "cycles+oidn", "cycles+oidn", img, 0.0, spp)
                if spp == max(config.cycles_samples):
                    images[view.name][f"cycles+oidn {spp}"] = img.image
    return rows, images


def aggregate(rows: Sequence[Row]) -> list[Row]:
    """One row per (scene, view, method, renderer, budget or samples): the mean over seeds of
    every metric and time; ``extra`` holds ``seeds``, ``ssim_std`` and ``rmse_std``."""
    groups: dict[tuple[Any, ...], list[Row]] = {}
    for r in rows:
        key = (r.scene, r.view, r.method, r.renderer, r.n_vpls, r.samples)
        groups.setdefault(key, []).append(r)
    out = []
    keys = ("rmse", "relative_mse", "ssim", "brightness", "one_time_seconds", "frame_seconds")
    for members in groups.values():
        first = members[0]
        mean = {k: float(np.mean([getattr(r, k) for r in members])) for k in keys}
        kept = ("setup", "bake_seconds", "capture_seconds")
        extra = {k: v for k, v in first.extra.items() if k in kept}
        extra.update(
            seeds=len(members),
            by_seed={
                str(r.seed): {"ssim": r.ssim, "rmse": r.rmse, "brightness": r.brightness}
                for r in members
                if r.seed is not None
            },
            ssim_std=float(np.std([r.ssim for r in members])),
            rmse_std=float(np.std([r.rmse for r in members])),
        )
        out.append(
            Row(
                first.scene,
                first.view,
                first.role,
                first.method,
                first.renderer,
                first.n_vpls,
                first.samples,
                shadow_rays=int(np.mean([r.shadow_rays for r in members])),
                seed=first.seed if len(members) == 1 else None,
                extra=extra,
                **mean,
            )
        )
    return out


def same_lights(evaluator: Row, shown: Row) -> dict[str, float]:
    """The evaluator's scores for the very lights ``shown`` (an EEVEE row) rendered: the seed's
    run of an aggregated row, or the row itself for a deterministic method."""
    by_seed = evaluator.extra.get("by_seed", {})
    if shown.seed is not None and str(shown.seed) in by_seed:
        return dict(by_seed[str(shown.seed)])
    return {"ssim": evaluator.ssim, "rmse": evaluator.rmse, "brightness": evaluator.brightness}


def _at(
    rows: Sequence[Row], scene: str, view: str, method: str, renderer: str, n: int | None
) -> Row | None:
    return next(
        (
            r
            for r in rows
            if (r.scene, r.view, r.method, r.renderer, r.n_vpls)
            == (scene, view, method, renderer, n)
        ),
        None,
    )


def targets(rows: list[Row]) -> list[dict[str, Any]]:
    """The issues' targets on every scene of ``rows`` (means over seeds) at the grid budget."""
    checks: list[dict[str, Any]] = []

    def check(name: str, value: Any, met: bool, detail: str) -> None:
        checks.append({"check": name, "value": value, "met": bool(met), "detail": detail})

    for scene in dict.fromkeys(r.scene for r in rows):
        mine = [r for r in rows if r.scene == scene]
        budgets = sorted({r.n_vpls for r in mine if r.renderer == "evaluator" and r.n_vpls})
        if not budgets:
            continue
        n = grid_budget(budgets)
        views = list(dict.fromkeys((r.view, r.role) for r in mine))
        fit_views = [v for v, role in views if role == "fit"]
        held = [v for v, role in views if role == "held-out"]
        ours = {v: _at(mine, scene, v, "vplace+refit", "evaluator", n) for v, _ in views}
        if all(ours.values()):
            fit_mean = float(np.mean([ours[v].ssim for v in fit_views]))
            check(
                f"{scene} N={n}: the fit views reach SSIM {FIT_VIEW_SSIM}",
                fit_mean,
                fit_mean >= FIT_VIEW_SSIM,
                f"fit views' mean {fit_mean:.4f}",
            )
            for v in held:
                gap = fit_mean - ours[v].ssim
                check(
                    f"{scene} {v} (held out) N={n}: within {HELD_OUT_SPREAD} SSIM of the fit "
                    "views' mean",
                    gap,
                    gap <= HELD_OUT_SPREAD,
                    f"{ours[v].ssim:.4f} against {fit_mean:.4f}: {gap:+.4f}",
                )
        for v, role in views:
            us = ours.get(v)
            if us is None:
                continue
            for base in ("uniform", "rsm"):
                b = _at(mine, scene, v, base, "evaluator", n)
                if b is not None:
                    gap = us.ssim - b.ssim
                    check(
                        f"{scene} {v} ({role}) N={n}: vplace+refit SSIM >= {base} + {SSIM_MARGIN}",
                        gap,
                        gap >= SSIM_MARGIN,
                        f"{us.ssim:.4f} against {b.ssim:.4f}: {gap:+.4f}",
                    )
            uniform = _at(mine, scene, v, "uniform", "evaluator", n)
            if uniform is not None:
                check(
                    f"{scene} {v} ({role}) N={n}: not below uniform",
                    us.ssim - uniform.ssim,
                    us.ssim >= uniform.ssim,
                    f"{us.ssim:.4f} against {uniform.ssim:.4f}",
                )
            direct = _at(mine, scene, v, "direct", "reference", None)
            if role == "held-out" and direct is not None:
                check(
                    f"{scene} {v} (held out) N={n}: relative MSE below direct light's",
                    us.relative_mse,
                    us.relative_mse < direct.relative_mse,
                    f"{us.relative_mse:.5f} against {direct.relative_mse:.5f}",
                )
            shown = _at(mine, scene, v, "vplace+refit", "eevee", n)
            if shown is not None:
                evaluated = same_lights(us, shown)["ssim"]
                gap = evaluated - shown.ssim
                check(
                    f"{scene} {v} ({role}): EEVEE with the VPLs within {EEVEE_SPREAD} SSIM "
                    "of the evaluator (the same lights)",
                    gap,
                    abs(gap) <= EEVEE_SPREAD,
                    f"EEVEE {shown.ssim:.4f}, evaluator {evaluated:.4f}",
                )
                off = shown.brightness - 1
                detail = f"{shown.brightness:.4f}x"
                plain = _at(mine, scene, v, "eevee", "eevee", None)
                if plain is not None and direct is not None:
                    # EEVEE's own direct light against Cycles': a part vplace does not render.
                    own = plain.brightness / direct.brightness
                    detail += f"; EEVEE's direct light alone is {own:.3f}x Cycles' direct light"
                check(
                    f"{scene} {v} ({role}): EEVEE with the VPLs within "
                    f"{BRIGHTNESS_TOLERANCE:.0%} of the truth's brightness",
                    off,
                    abs(off) <= BRIGHTNESS_TOLERANCE,
                    detail,
                )
                volume = _at(mine, scene, v, "eevee rt + volume", "eevee", None)
                if volume is not None:
                    gap = shown.ssim - volume.ssim
                    check(
                        f"{scene} {v} ({role}): EEVEE with the VPLs >= EEVEE ray tracing + "
                        f"volume + {SSIM_MARGIN}",
                        gap,
                        gap >= SSIM_MARGIN,
                        f"{shown.ssim:.4f} against {volume.ssim:.4f}: {gap:+.4f}",
                    )
        curve = [r for r in mine if r.method == CAPTURE_CURVE and r.role == "fit"]
        spps = sorted({r.samples for r in curve if r.samples})
        default = pipeline.Job().samples
        if default in spps and spps[-1] > default:
            at = {spp: float(np.mean([r.ssim for r in curve if r.samples == spp])) for spp in spps}
            gap = at[spps[-1]] - at[default]
            check(
                f"{scene}: the default capture ({default} spp) within {CAPTURE_SPREAD} SSIM of "
                f"{spps[-1]} spp (fit views' mean)",
                gap,
                gap <= CAPTURE_SPREAD,
                f"{at[default]:.4f} against {at[spps[-1]]:.4f}: {-gap:+.4f}",
            )
    return checks


def break_even(rows: list[Row]) -> list[dict[str, Any]]:
    """Per view: after how many frames vplace+refit (one-time cost plus its EEVEE frames) costs
    less than Cycles + OIDN frames of at least the same SSIM (the fewest samples that reach it)."""
    out = []
    for r in rows:
        if r.method != "vplace+refit" or r.renderer != "eevee":
            continue
        cycles = sorted(
            (c for c in rows if (c.scene, c.view, c.method) == (r.scene, r.view, "cycles+oidn")),
            key=lambda c: c.samples or 0,
        )
        if not cycles:
            continue
        match = next((c for c in cycles if c.ssim >= r.ssim), None)
        entry: dict[str, Any] = {
            "scene": r.scene,
            "view": r.view,
            "role": r.role,
            "eevee_ssim": r.ssim,
            "one_time_seconds": r.one_time_seconds,
            "eevee_frame_seconds": r.frame_seconds,
        }
        if match is None:
            top = cycles[-1]
            entry.update(
                cycles_samples=None, cycles_ssim=top.ssim, cycles_frame_seconds=top.frame_seconds
            )
            gain = top.frame_seconds - r.frame_seconds
            entry["frames"] = None
            entry["note"] = (
                f"Cycles + OIDN at {top.samples} spp reaches only SSIM {top.ssim:.4f} in "
                f"{top.frame_seconds:.1f} s; more samples would cost more per frame"
                + (
                    f": break-even after fewer than {math.ceil(r.one_time_seconds / gain)} frames"
                    if gain > 0
                    else ""
                )
            )
        else:
            gain = match.frame_seconds - r.frame_seconds
            frames = math.ceil(r.one_time_seconds / gain) if gain > 0 else None
            entry.update(
                cycles_samples=match.samples,
                cycles_ssim=match.ssim,
                cycles_frame_seconds=match.frame_seconds,
                frames=frames,
            )
            entry["note"] = (
                f"break-even after {frames} frames"
                if frames
                else "never on this machine: an EEVEE frame costs at least a Cycles + OIDN frame"
            )
        out.append(entry)
    return out


def run_scene(
    preset: ScenePreset,
    config: ReportConfig,
    out: Path,
    cache_dir: Path,
    log: Callable[[str], None],
) -> tuple[list[Row], dict[str, Any]]:
    """Every view of one scene: rows, plus the fit summary and image paths."""
    from . import plots as report_plots

    blend = preset.blend or default_scene.builtin_scene(preset.name)
    bpy.ops.wm.open_mainfile(filepath=str(blend))
    log(f"[vplace] report: {preset.name} ({blend.name})")
    bl_scene = bpy.context.scene
    data = load_scene(bl_scene, preset, config, cache_dir, log)
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
    if config.with_eevee:
        more, shown = eevee_rows(bl_scene, data, sets, config, preset.name, cache_dir, log)
        rows += more
    else:
        shown = {v.name: {} for v in data.views}
    info: dict[str, Any] = {
        "fit": asdict(vplace.job.FitSummary.of(fitted)),
        "fit_seconds": fit_seconds,
        "capture_seconds": data.capture_seconds,
        "views": {},
    }
    for view in data.views:
        cap = view.truth
        info["views"][view.name] = {
            "role": view.role,
            "resolution": [cap.width, cap.height],
            "capture_samples": data.job.samples if view.role == "fit" else None,
            "truth_samples": cap.samples,
            "truth_seconds": cap.render_seconds,
            "triangles": data.prepared.scene.triangle_count,
        }
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
    return rows, info


def run_report(
    config: ReportConfig, out: Path, log: Callable[[str], None] = print
) -> dict[str, Any]:
    """Runs the report and writes its files into ``out``. Opens each scene's .blend (the current
    file is replaced in memory, never saved)."""
    from . import plots as report_plots

    config.validate()
    out.mkdir(parents=True, exist_ok=True)
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
        "targets": targets(means),
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


def row_dict(row: Row) -> dict[str, Any]:
    """A row as a flat JSON-ready dict (``extra`` kept nested)."""
    d = asdict(row)
    d["one_minus_ssim"] = row.one_minus_ssim
    return {k: (None if isinstance(v, float) and math.isnan(v) else v) for k, v in d.items()}


CSV_FIELDS = (
    "scene",
    "view",
    "role",
    "method",
    "renderer",
    "n_vpls",
    "samples",
    "rmse",
    "relative_mse",
    "ssim",
    "one_minus_ssim",
    "brightness",
    "one_time_seconds",
    "frame_seconds",
    "shadow_rays",
    "seed",
)


def write_csv(path: Path, rows: list[Row]) -> None:
    """The rows as CSV (without ``extra``)."""
    with path.open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=CSV_FIELDS, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow(row_dict(r))


def _fmt(value: float | None, spec: str) -> str:
    return (
        "-"
        if value is None or (isinstance(value, float) and math.isnan(value))
        else format(value, spec)
    )


def _sd(row: Row) -> str:
    seeds = row.extra.get("seeds", 1)
    return f" ({row.extra['ssim_std']:.3f})" if seeds > 1 else ""


def _capture_curve_lines(rows: Sequence[Row]) -> list[str]:
    """The table of :func:`capture_curve_rows` (mean SSIM over seeds), or nothing."""
    curve = [r for r in rows if r.method == CAPTURE_CURVE]
    if not curve:
        return []
    views = list(dict.fromkeys((r.view, r.role) for r in curve))
    lines = [
        f"### Capture samples against layout quality (vplace+refit, N={curve[0].n_vpls})",
        "",
        "The fit views captured at each sample count, the same fit, layout and refit, every view "
        "scored with the evaluator against the truth. One-time s: captures, fit, layout, refit.",
        "",
        "| capture spp | captures s | one-time s | fit views' SSIM | held-out SSIM | "
        + " | ".join(v for v, _ in views)
        + " |",
        "|---" * (5 + len(views)) + "|",
    ]
    for spp in sorted({r.samples for r in curve if r.samples}):
        mine = {r.view: r for r in curve if r.samples == spp}
        first = next(iter(mine.values()))

        def mean(role: str, mine: dict[str, Row] = mine) -> str:
            values = [r.ssim for r in mine.values() if r.role == role]
            return f"{np.mean(values):.4f}" if values else "-"

        lines.append(
            f"| {spp} | {first.extra['capture_seconds']:.1f} | {first.one_time_seconds:.1f} | "
            f"{mean('fit')} | {mean('held-out')} | "
            + " | ".join(f"{mine[v].ssim:.4f}" if v in mine else "-" for v, _ in views)
            + " |"
        )
    return [*lines, ""]


def markdown(result: dict[str, Any], rows: list[Row]) -> str:
    """The human-readable report."""
    lines = ["# vplace report", ""]
    lines += [
        "Each method lays out one set of lights for all the fit views at once; every view, fit or "
        "held out, is scored with those same lights. Evaluator rows: the ground truth's direct "
        "light plus the evaluator's VPL indirect light over the view's G-buffer. EEVEE rows: what "
        "a user sees, EEVEE rendering the written lights (float, Standard view, "
        f"{result['config']['eevee_samples']} samples), or the alternatives a Blender user would "
        "pick instead; Cycles + OIDN rows: Cycles at that many samples, denoised. Every image is "
        "scored against a high-sample Cycles render of the view. SSIM on display luminance "
        "(DESIGN: Metrics); RMSE and relative MSE on linear HDR; brightness is the mean luminance "
        "over the truth's. One-time seconds: the captures of the fit views, the fit, the layout "
        "and refit, or a volume's bake, paid once for every view and frame; frame seconds: one "
        "image. Stochastic layouts run with seeds "
        f"{list(result['config']['seeds'])}; rows show their mean (SSIM standard deviation in "
        "brackets); `results.csv` has every run. EEVEE here is software OpenGL on 2 CPU cores: "
        "its frame times are no measure of a GPU's.",
        "",
        f"Total report time: {result['seconds']:.0f} s.",
        "",
    ]
    for name, info in result["scenes"].items():
        fit = info["fit"]
        r2 = ", ".join(f"{v} {_fmt(x, '.3f')}" for v, x in fit["view_r2"].items())
        lines += [
            f"## {name}",
            "",
            f"Fit over {len(fit['view_r2'])} views: kept "
            + ", ".join(fit["kept"])
            + f" (R^2 {fit['r2']:.3f}; per view {r2}; {info['fit_seconds']:.2f} s). Captures of "
            f"the fit views: {info['capture_seconds']:.1f} s.",
            "",
        ]
        budgets = sorted({r.n_vpls for r in rows if r.scene == name and r.renderer == "evaluator"})
        for view, v in info["views"].items():
            mine = [r for r in rows if r.scene == name and r.view == view]
            lines += [
                f"### {view} ({v['role']} view)",
                "",
                f"{v['resolution'][0]}x{v['resolution'][1]} px, {v['triangles']} triangles; ground "
                f"truth {v['truth_samples']} spp in {v['truth_seconds']:.1f} s. Images: "
                + ", ".join(f"`{v[k]}`" for k in ("grid", "eevee_grid") if k in v)
                + ".",
                "",
                "Evaluator, SSIM (sd) / RMSE by VPL budget:",
                "",
                "| method | " + " | ".join(f"N={n}" for n in budgets) + " |",
                "|---|" + "---|" * len(budgets),
            ]
            tabled = (r.method for r in mine if r.renderer == "evaluator")
            for method in dict.fromkeys(m for m in tabled if m != CAPTURE_CURVE):
                cells = []
                for n in budgets:
                    r = next(
                        (
                            x
                            for x in mine
                            if x.method == method and x.renderer == "evaluator" and x.n_vpls == n
                        ),
                        None,
                    )
                    cells.append(f"{r.ssim:.3f}{_sd(r)} / {r.rmse:.4f}" if r else "-")
                lines.append(f"| {method} | " + " | ".join(cells) + " |")
            direct = next((x for x in mine if x.method == "direct"), None)
            if direct:
                lines += ["", f"Direct light only: SSIM {direct.ssim:.3f}, RMSE {direct.rmse:.4f}."]
            shown = [r for r in mine if r.renderer in ("eevee", "cycles")]
            if shown:
                lines += [
                    "",
                    "What a user sees (the grid budget's lights in EEVEE) and the alternatives:",
                    "",
                    "| image | SSIM | RMSE | brightness | evaluator, same lights: SSIM / "
                    "brightness | one-time s | frame s |",
                    "|---|---|---|---|---|---|---|",
                ]
                for r in shown:
                    label = f"{r.renderer}: {r.method}"
                    if r.n_vpls:
                        label += f", N={r.n_vpls}"
                    if r.seed is not None:
                        label += f", seed {r.seed}"
                    if r.renderer == "cycles":
                        label += f", {r.samples} spp"
                    base = r.method.removesuffix(WITH_RT)
                    ev = _at(mine, name, view, base, "evaluator", r.n_vpls) if r.n_vpls else None
                    same = (
                        "{ssim:.3f} / {brightness:.3f}".format(**same_lights(ev, r)) if ev else "-"
                    )
                    lines.append(
                        f"| {label} | {r.ssim:.3f} | {r.rmse:.4f} | {r.brightness:.3f} | {same} | "
                        f"{r.one_time_seconds:.1f} | {r.frame_seconds:.1f} |"
                    )
            lines.append("")
        lines += _capture_curve_lines([r for r in rows if r.scene == name])
    if result["break_even"]:
        lines += [
            "## Break-even: vplace + EEVEE against Cycles + OIDN",
            "",
            "Frames after which vplace's one-time cost plus its EEVEE frames costs less than "
            "Cycles + OIDN frames of at least the same SSIM (the fewest samples that reach it). "
            "EEVEE's frame time is software OpenGL on 2 cores; a GPU's is unknown here (no GPU "
            "was lent).",
            "",
            "| scene | view | EEVEE SSIM | one-time s | EEVEE frame s | Cycles spp | Cycles SSIM "
            "| Cycles frame s | frames |",
            "|---|---|---|---|---|---|---|---|---|",
        ]
        for b in result["break_even"]:
            lines.append(
                f"| {b['scene']} | {b['view']} ({b['role']}) | {b['eevee_ssim']:.3f} | "
                f"{b['one_time_seconds']:.1f} | {b['eevee_frame_seconds']:.1f} | "
                f"{b['cycles_samples'] or '-'} | {b['cycles_ssim']:.3f} | "
                f"{b['cycles_frame_seconds']:.1f} | {b['note']} |"
            )
        lines.append("")
    if result["targets"]:
        lines += ["## Targets", "", "| check | met | detail |", "|---|---|---|"]
        for c in result["targets"]:
            lines.append(f"| {c['check']} | {'yes' if c['met'] else '**no**'} | {c['detail']} |")
        lines.append("")
    if result["par2d"]:
        lines += [
            "## PAR 2D",
            "",
            "| method | rays | seconds | RMSE vs exact |",
            "|---|---|---|---|",
        ]
        for p in result["par2d"]:
            lines.append(
                f"| {p['method']} | {p['rays'] or '-'} | {p['seconds']:.3f} | {p['rmse']:.3e} |"
            )
        lines += ["", "Plot: `par2d_speed_error.png`.", ""]
    lines += ["## Files", "", *[f"- `{f}`" for f in result["files"]], ""]
    return "\n".join(lines)


__all__ = [
    "PRESETS",
    "ReportConfig",
    "ReportError",
    "Row",
    "ScenePreset",
    "aggregate",
    "break_even",
    "camera_view",
    "run_report",
    "targets",
]
