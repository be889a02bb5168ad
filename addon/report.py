"""The speed-against-error report (DESIGN: Report): scenes x views x methods x VPL budgets.

``python -m addon.cli report --scenes cornell sponza --budgets 16 64 256 1024`` runs, for each
scene, two views: the *fit* view, where the regression is fitted on a Cycles capture, and a
*held-out* view, where the same model lays out VPLs from that view's G-buffer and direct pass
only. For each view and budget N it lays out N VPLs with every method (``uniform``, ``rsm``,
``vplace``, and ``vplace+refit`` on the fit view), renders their indirect light with the
evaluator over the capture's G-buffer, and scores ``ground-truth direct + VPL indirect`` against a
high-sample Cycles render of the same view (the ground truth, cached on disk). It also renders
Cycles itself at rising sample counts (the user's alternative) and scores those.

Written into ``--out``: ``results.csv`` and ``results.json`` (one row per view, method and
budget), ``report.md`` (tables and the target checks), and PNG plots: error (1 - SSIM and RMSE)
against time per view, error against N, an image grid per view (ground truth, direct only, each
method at the budget nearest 256, error maps), the EEVEE preview of the vplace layout, and the PAR
2D speed-against-error plot.

Times: a method's time is its layout (VPL placement; for vplace on the fit view also the fit,
whose cost is shared by every budget) plus the full-resolution evaluator render. The capture
that vplace needs (a Cycles render of the view at ``capture_samples``) is reported separately.
The user's .blend is never saved: the scene camera is switched through a settings guard, and the
EEVEE preview's VPL collection is removed again.
"""

from __future__ import annotations

import csv
import itertools
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

from . import apply, capture, default_scene, pipeline
from .errors import ReportError
from .native import bench_par2d, view_of, vplace
from .settings import override
from .views import ViewSpec

#: Seeds of the renders: the user's capture, the ground truth, Cycles at rising sample counts.
CAPTURE_SEED = 0
TRUTH_SEED = 7919
CURVE_SEED = 104729

METHODS = pipeline.METHODS
#: The budget the image grids and the targets use (the nearest one run).
GRID_BUDGET = 256
#: The issue's target: vplace SSIM at least this much above each baseline at GRID_BUDGET.
SSIM_MARGIN = 0.05


@dataclass(frozen=True)
class ScenePreset:
    """A built-in scene for the report: its two views, capture size and sample counts."""

    name: str
    fit_view: str
    held_out_view: str
    resolution: tuple[int, int]
    capture_samples: int
    truth_samples: int
    #: EEVEE preview size relative to the capture; 0: no preview. Software OpenGL (no GPU)
    #: renders 256 shadowed VPL lights over Sponza's 262k triangles in more than 10 minutes
    #: at 320x180 and at 160x90 alike (the shadow maps, not the pixels, cost), so the report
    #: previews only the Cornell box there.
    eevee_scale: float = 1.0


PRESETS = {
    "cornell": ScenePreset(
        "cornell", "Cornell camera", default_scene.CORNELL_HELD_OUT_CAMERA, (160, 160), 256, 2048
    ),
    "sponza": ScenePreset(
        "sponza",
        default_scene.SPONZA_CAMERA,
        default_scene.SPONZA_HELD_OUT_CAMERA,
        (320, 180),
        128,
        1024,
        eevee_scale=0.0,
    ),
}


@dataclass
class ReportConfig:
    """What the report runs. ``None`` fields take the scene preset's value."""

    scenes: Sequence[str] = ("cornell", "sponza")
    budgets: Sequence[int] = (16, 64, 256, 1024)
    methods: Sequence[str] = METHODS
    resolution: tuple[int, int] | None = None
    capture_samples: int | None = None
    truth_samples: int | None = None
    cycles_samples: Sequence[int] = (16, 64, 256)
    alpha: float = 1.0
    iterations: int = 3
    cell_px: int = 16
    #: Seeds of the stochastic layouts (uniform, vplace); tables and plots show their mean.
    seeds: Sequence[int] = (0, 1, 2)
    eevee: bool = True
    par2d: bool = True
    cache_dir: Path | None = None

    def validate(self) -> None:
        """Raises :class:`ReportError` for an unusable configuration."""
        unknown = [m for m in self.methods if m not in METHODS]
        if unknown:
            raise ReportError(f"unknown methods {unknown}: choose from {list(METHODS)}")
        if not self.budgets or min(self.budgets) < 1:
            raise ReportError(f"budgets must be positive VPL counts, got {list(self.budgets)}")
        if max(self.budgets) > apply.MAX_VPLS:
            raise ReportError(f"budgets above {apply.MAX_VPLS} VPLs are not supported")
        bad = [s for s in self.scenes if s not in PRESETS]
        if bad:
            raise ReportError(f"unknown scenes {bad}: choose from {sorted(PRESETS)}")
        if any(s < 1 for s in self.cycles_samples):
            raise ReportError("Cycles sample counts must be at least 1")
        if not self.seeds:
            raise ReportError("give at least one seed")


@dataclass
class Row:
    """One scored image: a method at a budget on a view (or Cycles at a sample count)."""

    scene: str
    view: str
    role: str  # "fit" or "held-out"
    method: str  # a METHODS name, "cycles" or "direct"
    n_vpls: int | None
    samples: int | None
    rmse: float
    relative_mse: float
    ssim: float
    layout_seconds: float
    evaluate_seconds: float
    seconds: float
    shadow_rays: int = 0
    seed: int | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def one_minus_ssim(self) -> float:
        return 1.0 - self.ssim


score = pipeline.score


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
    """A view of the scene: the user's capture as a ``vplace.View`` (without its GI passes on
    the held-out view), its ground truth and the Cycles curve."""

    name: str
    role: str
    capture: capture.Capture
    view: vplace.View
    truth: capture.Capture
    curve: list[capture.Capture]


@dataclass
class SceneData:
    """A scene exported once, its job settings and its fit and held-out views."""

    prepared: pipeline.Prepared
    job: pipeline.Job
    views: list[ViewData]


def load_scene(
    bl_scene: bpy.types.Scene,
    preset: ScenePreset,
    config: ReportConfig,
    cache_dir: Path,
    log: Callable[[str], None],
) -> SceneData:
    """Exports the scene once and captures each view, its ground truth and its Cycles curve."""
    resolution = config.resolution or preset.resolution
    truth_samples = config.truth_samples or preset.truth_samples
    job = pipeline.Job(
        resolution=resolution,
        samples=config.capture_samples or preset.capture_samples,
        seed=CAPTURE_SEED,
        cell_px=config.cell_px,
        alpha=config.alpha,
        iterations=config.iterations,
        cache_dir=cache_dir,
    )
    names = [(preset.fit_view, "fit"), (preset.held_out_view, "held-out")]
    cams = []
    for name, _ in names:
        cam = bpy.data.objects.get(name)
        if cam is None or cam.type != "CAMERA":
            raise ReportError(f"the scene has no camera object named {name!r}")
        cams.append(cam)
    timer = pipeline.StageTimer(log)
    specs = [ViewSpec(name, cam) for (name, _), cam in zip(names, cams, strict=True)]
    prepared = pipeline.prepare(bl_scene, job, timer, views=specs)
    views = []
    for (name, role), cam, cap in zip(names, cams, prepared.captures, strict=True):

        def render(samples: int, seed: int, cam: bpy.types.Object = cam) -> capture.Capture:
            return capture.capture(
                bl_scene,
                prepared.exported,
                camera=cam,
                resolution=resolution,
                samples=samples,
                seed=seed,
                cache_dir=cache_dir,
            )

        with timer.stage(f"ground truth {name} ({truth_samples} spp, cached)"):
            truth = render(truth_samples, TRUTH_SEED)
        curve = []
        for spp in config.cycles_samples:
            with timer.stage(f"Cycles {name} at {spp} spp (cached)"):
                curve.append(render(spp, CURVE_SEED))
        view = view_of(cap, held_out=role != "fit")
        views.append(ViewData(name, role, cap, view, truth, curve))
    return SceneData(prepared, job, views)


def _timed(fn: Callable[[], Any]) -> tuple[float, Any]:
    start = time.perf_counter()
    out = fn()
    return time.perf_counter() - start, out


def run_methods(
    data: SceneData,
    view: ViewData,
    fitted: vplace.Fit,
    fit_seconds: float,
    config: ReportConfig,
    scene_name: str,
    log: Callable[[str], None],
) -> tuple[list[Row], dict[str, np.ndarray], dict[str, vplace.VplSet]]:
    """Every method at every budget on one view; returns the rows, and the images and VPLs of
    the first seed at the grid budget (keyed by method).

    On the fit view the regression-guided layout iterates against the view's indirect image;
    ``vplace+refit`` is the same layout with its powers refitted (one layout serves both rows).
    On the held-out view the fit's model lays out VPLs from that view's G-buffer and direct
    passes alone (no iteration, no refit)."""
    prepared = data.prepared
    scene = prepared.scene
    truth_gi, truth_direct = view.truth.gi, view.truth.direct
    grid_n = grid_budget(config.budgets)
    fit_view = view.role == "fit"
    methods = [m for m in config.methods if fit_view or m != "vplace+refit"]
    rows: list[Row] = []
    images: dict[str, np.ndarray] = {}
    grid_vpls: dict[str, vplace.VplSet] = {}
    for n in config.budgets:
        for seed in config.seeds:
            guided: pipeline.Laid | None = None
            for method in methods:
                if method == "rsm" and seed != config.seeds[0]:
                    continue  # deterministic: one run
                job = replace(data.job, n_vpls=n, seed=seed, method=method)
                extra: dict[str, Any] = {}
                if method in ("uniform", "rsm"):
                    laid = pipeline.lay_out(prepared, job, views=[view.view])
                    t, vpls = laid.layout_seconds, laid.vpls
                else:
                    if guided is None:
                        both = "vplace+refit" in methods
                        guided = pipeline.lay_out(
                            prepared,
                            replace(job, method="vplace+refit" if both else "vplace"),
                            fitted=fitted,
                            views=[view.view],
                        )
                    layout = guided.layout
                    assert layout is not None
                    t = guided.layout_seconds + (fit_seconds if fit_view else 0.0)
                    extra = {
                        "iteration_errors": layout.errors,
                        "best_iteration": layout.best,
                        "indirect_source": layout.indirect_source[0],
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
                        )
                indirect, stats = vplace.evaluate(scene, view.view, vpls)
                estimate = truth_direct + indirect
                row = Row(
                    scene_name,
                    view.name,
                    view.role,
                    method,
                    n,
                    None,
                    layout_seconds=t,
                    evaluate_seconds=stats.seconds,
                    seconds=t + stats.seconds,
                    shadow_rays=stats.shadow_rays,
                    seed=seed if method != "rsm" else None,
                    extra=extra,
                    **score(estimate, truth_gi),
                )
                rows.append(row)
                log(
                    f"[vplace]   {view.name} {method:<13} N={n:<5} seed {seed} "
                    f"SSIM {row.ssim:.4f} RMSE {row.rmse:.5f} {row.seconds:7.2f} s"
                )
                if n == grid_n and seed == config.seeds[0]:
                    images[method] = estimate
                    grid_vpls[method] = vpls
    return rows, images, grid_vpls


def grid_budget(budgets: Sequence[int]) -> int:
    """The budget nearest GRID_BUDGET (the lower one on ties): image grids, preview, targets."""
    return min(budgets, key=lambda n: (abs(n - GRID_BUDGET), n))


def aggregate(rows: Sequence[Row]) -> list[Row]:
    """One row per (scene, view, method, budget or samples): the mean over seeds of every
    metric and time; ``extra`` holds ``seeds`` and ``ssim_std``, ``rmse_std`` (population)."""
    groups: dict[tuple[Any, ...], list[Row]] = {}
    for r in rows:
        groups.setdefault((r.scene, r.view, r.method, r.n_vpls, r.samples), []).append(r)
    out = []
    for members in groups.values():
        first = members[0]
        mean = {
            k: float(np.mean([getattr(r, k) for r in members]))
            for k in ("rmse", "relative_mse", "ssim", "layout_seconds", "evaluate_seconds",
                      "seconds")
        }  # fmt: skip
        out.append(
            Row(
                first.scene,
                first.view,
                first.role,
                first.method,
                first.n_vpls,
                first.samples,
                shadow_rays=int(np.mean([r.shadow_rays for r in members])),
                extra={
                    "seeds": len(members),
                    "ssim_std": float(np.std([r.ssim for r in members])),
                    "rmse_std": float(np.std([r.rmse for r in members])),
                },
                **mean,
            )
        )
    return out


def reference_rows(view: ViewData, scene_name: str) -> list[Row]:
    """Direct only and Cycles at rising sample counts, scored against the ground truth."""
    truth = view.truth.gi
    rows = [
        Row(
            scene_name, view.name, view.role, "direct", None, None,
            layout_seconds=0.0, evaluate_seconds=0.0, seconds=0.0,
            **score(view.truth.direct, truth),
        )
    ]  # fmt: skip
    for cap in view.curve:
        rows.append(
            Row(
                scene_name, view.name, view.role, "cycles", None, cap.samples,
                layout_seconds=0.0, evaluate_seconds=0.0, seconds=cap.render_seconds,
                **score(cap.gi, truth),
            )
        )  # fmt: skip
    return rows


@dataclass
class Preview:
    """The VPLs of an EEVEE preview, laid out while the scene was loaded."""

    scene: str
    camera: str
    vpls: vplace.VplSet
    diagonal: float
    resolution: tuple[int, int]


def eevee_preview(bl_scene: bpy.types.Scene, preview: Preview, path: Path) -> float:
    """Renders the scene with the preview's VPLs written back, then removes them again."""
    if apply.find_collection() is not None:
        raise ReportError(
            f"the scene already has a {apply.COLLECTION_NAME!r} collection; the report does "
            "not replace the user's VPLs (run it with --no-eevee, or on a copy)"
        )
    with camera_view(bl_scene, preview.camera):
        apply.write_vpls(bl_scene, preview.vpls, scene_diagonal=preview.diagonal)
        try:
            return pipeline.render_eevee_preview(bl_scene, path, preview.resolution)
        finally:
            apply.clear_vpls()


def run_scene(
    bl_scene: bpy.types.Scene,
    preset: ScenePreset,
    config: ReportConfig,
    out: Path,
    cache_dir: Path,
    log: Callable[[str], None],
) -> tuple[list[Row], dict[str, Any]]:
    """Both views of one scene: rows, plus the fit summary and image paths."""
    data = load_scene(bl_scene, preset, config, cache_dir, log)
    fit_view, held_out = data.views
    fit_seconds, fitted = _timed(lambda: pipeline.fit(data.prepared, data.job, [fit_view.view]))
    log(f"[vplace] {preset.name}: fitted on {fit_view.name} in {fit_seconds:.2f} s\n{fitted}")
    info: dict[str, Any] = {
        "fit": pipeline.fit_summary(fitted),
        "fit_seconds": fit_seconds,
        "views": {},
    }
    rows: list[Row] = []
    preview_vpls: vplace.VplSet | None = None
    from . import report_plots

    for view in (fit_view, held_out):
        rows += reference_rows(view, preset.name)
        method_rows, images, grid_vpls = run_methods(
            data, view, fitted, fit_seconds, config, preset.name, log
        )
        if view is fit_view and "vplace" in grid_vpls:
            preview_vpls = grid_vpls["vplace"]
        rows += method_rows
        cap = view.capture
        info["views"][view.name] = {
            "role": view.role,
            "resolution": [cap.width, cap.height],
            "capture_samples": cap.samples,
            "capture_seconds": cap.render_seconds,
            "truth_samples": view.truth.samples,
            "truth_seconds": view.truth.render_seconds,
            "triangles": data.prepared.scene.triangle_count,
        }
        stem = f"{preset.name}_{report_plots.slug(view.name)}"
        grid = report_plots.image_grid(
            out / f"grid_{stem}.png",
            view.truth.gi,
            view.truth.direct,
            images,
            title=f"{preset.name}, {view.name} ({view.role} view)",
        )
        info["views"][view.name]["grid"] = grid.name
    if config.eevee and preview_vpls is not None and preset.eevee_scale > 0:
        cap = fit_view.capture
        scale = preset.eevee_scale
        info["preview"] = Preview(
            preset.name,
            fit_view.name,
            preview_vpls,
            data.prepared.scene.diagonal,
            (max(1, round(cap.width * scale)), max(1, round(cap.height * scale))),
        )
    return rows, info


def targets(rows: list[Row], scene: str = "sponza") -> list[dict[str, Any]]:
    """The issue's targets on ``scene``: at the grid budget, vplace SSIM >= each baseline +
    SSIM_MARGIN on both views; and error falling as N grows for every method and view."""
    checks = []
    views = sorted({(r.view, r.role) for r in rows if r.scene == scene}, key=lambda v: v[1])
    budgets = sorted({r.n_vpls for r in rows if r.scene == scene and r.n_vpls is not None})
    if not budgets:
        return checks
    grid_n = grid_budget(budgets)
    for view, role in views:
        at = {
            r.method: r for r in rows if r.scene == scene and r.view == view and r.n_vpls == grid_n
        }
        if "vplace" in at:
            for base in ("rsm", "uniform"):
                if base in at:
                    gap = at["vplace"].ssim - at[base].ssim
                    checks.append(
                        {
                            "check": f"{scene} {view} ({role}) N={grid_n}: vplace SSIM >= "
                            f"{base} + {SSIM_MARGIN}",
                            "value": gap,
                            "met": bool(gap >= SSIM_MARGIN),
                            "detail": f"vplace {at['vplace'].ssim:.4f}, {base} "
                            f"{at[base].ssim:.4f}: difference {gap:+.4f}",
                        }
                    )
        methods = sorted({r.method for r in rows if r.view == view and r.n_vpls is not None})
        for method in methods:
            series = sorted(
                (r for r in rows if r.scene == scene and r.view == view and r.method == method),
                key=lambda r: r.n_vpls or 0,
            )
            for metric in ("rmse", "one_minus_ssim"):
                values = [getattr(r, metric) for r in series]
                rises = [
                    f"N {a.n_vpls}->{b.n_vpls}: {getattr(a, metric):.4g}->{getattr(b, metric):.4g}"
                    for a, b in itertools.pairwise(series)
                    if getattr(b, metric) > getattr(a, metric)
                ]
                checks.append(
                    {
                        "check": f"{scene} {view} ({role}) {method}: {metric} falls as N grows",
                        "value": values,
                        "met": not rises,
                        "detail": "falls at every step"
                        if not rises
                        else "rises at " + "; ".join(rises),
                    }
                )
    return checks


def run_report(
    config: ReportConfig, out: Path, log: Callable[[str], None] = print
) -> dict[str, Any]:
    """Runs the report and writes its files into ``out``. Opens each built-in scene's .blend
    (the current file is replaced in memory, never saved)."""
    from . import report_plots

    config.validate()
    out.mkdir(parents=True, exist_ok=True)
    cache_dir = config.cache_dir or out / "cache"
    start = time.perf_counter()
    rows: list[Row] = []
    scenes: dict[str, Any] = {}
    for name in config.scenes:
        preset = PRESETS[name]
        blend = default_scene.builtin_scene(name)
        bpy.ops.wm.open_mainfile(filepath=str(blend))
        log(f"[vplace] report: {name} ({blend.name})")
        scene_rows, info = run_scene(bpy.context.scene, preset, config, out, cache_dir, log)
        rows += scene_rows
        scenes[name] = info
    par_rows: list[dict[str, Any]] = []
    if config.par2d:
        # The benchmark scene of vplace.bench_par2d: 512x512, 8 lights, 64 occluders.
        par_rows, _ = bench_par2d.measure(size=512, rays=(4, 16, 64, 256))
        report_plots.par2d_plot(out / "par2d_speed_error.png", par_rows)
    previews = [info.pop("preview") for info in scenes.values() if "preview" in info]
    means = aggregate(rows)
    checks = targets(means)
    result = {
        "config": {
            **{k: v for k, v in asdict(config).items() if k != "cache_dir"},
            "cache_dir": str(cache_dir),
        },
        "seconds": time.perf_counter() - start,
        "scenes": scenes,
        "rows": [row_dict(r) for r in rows],
        "means": [row_dict(r) for r in means],
        "targets": checks,
        "par2d": par_rows,
    }
    write_csv(out / "results.csv", rows)
    report_plots.error_vs_time(out, means)
    report_plots.error_vs_budget(out / "error_vs_vpls.png", means)
    _write(out, result, means)
    # EEVEE last: the slowest step, and the tables are on disk before it starts.
    for preview in previews:
        blend = default_scene.builtin_scene(preview.scene)
        bpy.ops.wm.open_mainfile(filepath=str(blend))
        path = out / f"eevee_{preview.scene}.png"
        log(f"[vplace] EEVEE preview of {preview.scene} ({len(preview.vpls)} VPLs) ...")
        seconds = eevee_preview(bpy.context.scene, preview, path)
        log(f"[vplace] EEVEE preview: {seconds:.1f} s -> {path}")
        scenes[preview.scene]["eevee"] = {
            "file": path.name,
            "seconds": seconds,
            "n_vpls": len(preview.vpls),
            "resolution": list(preview.resolution),
        }
    if previews:
        result["seconds"] = time.perf_counter() - start
        _write(out, result, means)
    log(f"[vplace] report written to {out} in {result['seconds']:.0f} s")
    return result


def _write(out: Path, result: dict[str, Any], means: list[Row]) -> None:
    result["files"] = sorted(p.name for p in out.iterdir() if p.is_file())
    (out / "results.json").write_text(json.dumps(result, indent=2, default=_json_default))
    (out / "report.md").write_text(markdown(result, means))


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
    "scene", "view", "role", "method", "n_vpls", "samples", "rmse", "relative_mse", "ssim",
    "one_minus_ssim", "layout_seconds", "evaluate_seconds", "seconds", "shadow_rays", "seed",
)  # fmt: skip


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
    return f" ({row.extra['ssim_std']:.4f})" if seeds > 1 else ""


def markdown(result: dict[str, Any], rows: list[Row]) -> str:
    """The human-readable report."""
    lines = ["# vplace report", ""]
    lines += [
        "Images scored: ground-truth direct + VPL indirect (evaluator, full resolution) against "
        "a high-sample Cycles render of the same view. SSIM on display luminance (DESIGN: "
        "Metrics), RMSE and relative MSE on linear HDR. Time = layout (vplace on the fit view: "
        "with the regression fit) + evaluator; the Cycles capture vplace needs is listed per view. "
        "Cycles rows: its render time at that sample count, scored against the ground truth. "
        f"Stochastic layouts (uniform, vplace) run with seeds {list(result['config']['seeds'])}: "
        "each row is their mean (SSIM standard deviation in brackets); `results.csv` has every "
        "run.",
        "",
        f"Total report time: {result['seconds']:.0f} s.",
        "",
    ]
    for name, info in result["scenes"].items():
        lines += [f"## {name}", "", "Fit: kept " + ", ".join(info["fit"]["kept"]) +
                  f" (R^2 {info['fit']['r2']:.3f}, {info['fit_seconds']:.2f} s)", ""]  # fmt: skip
        for view, v in info["views"].items():
            lines += [
                f"### {view} ({v['role']} view)",
                "",
                f"{v['resolution'][0]}x{v['resolution'][1]} px, {v['triangles']} triangles; "
                f"capture {v['capture_samples']} spp in {v['capture_seconds']:.1f} s; ground "
                f"truth {v['truth_samples']} spp in {v['truth_seconds']:.1f} s. "
                f"Image grid: `{v['grid']}`.",
                "",
                "| method | N / spp | SSIM (sd over seeds) | 1 - SSIM | RMSE | rel. MSE | seconds "
                "| shadow rays |",
                "|---|---|---|---|---|---|---|---|",
            ]
            for r in rows:
                if r.scene != name or r.view != view:
                    continue
                count = (
                    r.n_vpls if r.n_vpls is not None else (f"{r.samples} spp" if r.samples else "-")
                )
                lines.append(
                    f"| {r.method} | {count} | {_fmt(r.ssim, '.4f')}{_sd(r)} "
                    f"| {_fmt(r.one_minus_ssim, '.4f')} | {r.rmse:.5f} | {r.relative_mse:.5f} "
                    f"| {r.seconds:.2f} | {r.shadow_rays} |"
                )
            lines.append("")
        if "eevee" in info:
            e = info["eevee"]
            lines += [
                f"EEVEE preview ({e['n_vpls']} vplace VPLs, {e['resolution'][0]}x"
                f"{e['resolution'][1]} px): `{e['file']}`, {e['seconds']:.1f} s.",
                "",
            ]
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
