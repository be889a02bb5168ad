"""The main job: capture -> scene export -> VPLs -> evaluator -> write-back -> report.

Every stage is timed and announced through ``log``. Used by the CLI (``python -m addon.cli``)
and by the operators.
"""

from __future__ import annotations

import dataclasses
import json
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import bpy
import numpy as np

from . import apply, capture, export, images
from .native import build_scene, vplace
from .settings import override


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


def vpl_set(d: dict[str, np.ndarray]) -> apply.VplSet:
    """A write-back VPL set from the native dict of arrays."""
    return apply.VplSet(d["position"], d["normal"], d["flux"])


def evaluate_capture(
    scene: vplace.Scene,
    cap: capture.Capture,
    vpls: apply.VplSet,
    *,
    profile: str = "cosine",
    r_min: float = 0.01,
    progress: vplace.Progress | None = None,
) -> tuple[np.ndarray, dict[str, Any]]:
    """The evaluator's indirect image of ``vpls`` over the capture's G-buffer."""
    covered = cap.covered & np.isfinite(cap.position).all(axis=-1)
    return vplace.evaluate(
        scene,
        np.ascontiguousarray(cap.position),
        np.ascontiguousarray(cap.normal),
        np.ascontiguousarray(cap.albedo),
        np.ascontiguousarray(covered),
        np.ascontiguousarray(vpls.position, dtype=np.float32),
        np.ascontiguousarray(vpls.normal, dtype=np.float32),
        np.ascontiguousarray(vpls.flux, dtype=np.float32),
        profile=profile,
        r_min=r_min,
        progress=progress,
    )


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


#: Default distance clamp as a fraction of the scene diagonal.
R_MIN_FRACTION = 0.01


@dataclass
class Job:
    """The parameters of one run (the panel's settings, or the CLI's options)."""

    n_vpls: int = 128
    resolution: tuple[int, int] = (160, 160)
    samples: int = 256
    seed: int = 0
    profile: str = "cosine"
    #: Distance clamp (m); None: 1% of the scene's diagonal (VPL spacing grows with the scene).
    r_min: float | None = None
    cell_px: int = 16
    #: "vplace" (regression-guided layout; the default: it beats the others in the report at
    #: equal N), "uniform" (Keller's light paths) or "rsm".
    method: str = "vplace"
    alpha: float = 1.0
    #: vplace only: refit the VPL powers to the captured indirect image (non-negative LS).
    refit: bool = True
    iterations: int = 3
    #: "auto": drop features that do not raise CV R^2; "all": keep every usable feature.
    feature_mode: str = "auto"
    cache_dir: Path | None = None

    @classmethod
    def from_settings(cls, settings: Any, cache_dir: Path | None = None) -> Job:
        """A job from ``Scene.vplace`` (see properties.py)."""
        return cls(
            n_vpls=settings.vpl_budget,
            resolution=(settings.resolution_x, settings.resolution_y),
            samples=settings.samples,
            seed=settings.seed,
            profile=settings.profile,
            cell_px=settings.cell_px,
            method=settings.method,
            alpha=settings.alpha,
            refit=settings.refit,
            iterations=settings.iterations,
            feature_mode=settings.feature_mode,
            cache_dir=cache_dir,
        )


@dataclass
class Prepared:
    """What the Blender side hands to the native side: the core scene and the capture."""

    scene: vplace.Scene
    capture: capture.Capture
    exported: export.ExportedScene
    camera_position: np.ndarray
    world_to_clip: np.ndarray


@dataclass
class Computed:
    """The native side's results: VPLs, their indirect image, evaluator stats, metrics."""

    vpls: apply.VplSet
    indirect: np.ndarray
    stats: dict[str, Any]
    metrics: dict[str, float]
    fit: vplace.FitResult | None = None


def prepare(bl_scene: bpy.types.Scene, job: Job, timer: StageTimer) -> Prepared:
    """Export, BVH and capture. Uses bpy: call it on Blender's main thread."""
    with timer.stage("export scene"):
        exported = export.export_scene(bl_scene)
    if not exported.lights:
        raise export.ExportError(
            "the scene has no lights that render: VPLs are traced from light objects "
            "(emissive meshes are not light sources for vplace yet)"
        )
    if all(max(light.power) <= 0.0 for light in exported.lights):
        raise export.ExportError("every light has zero power: there is no light to bounce")
    with timer.stage("build BVH"):
        scene = build_scene(exported)
    with timer.stage("capture (Cycles)"):
        last = [0.0]

        def on_progress(line: str) -> None:
            now = time.perf_counter()
            if now - last[0] > 2.0:
                last[0] = now
                timer.log(f"[vplace]   {line}")

        cap = capture.capture(
            bl_scene,
            resolution=job.resolution,
            samples=job.samples,
            seed=job.seed,
            cache_dir=job.cache_dir,
            on_progress=on_progress,
        )
    if not cap.covered.any():
        raise capture.CaptureError(
            "the camera sees no geometry (only background): aim it at the scene"
        )
    cam = bl_scene.camera
    w, h = job.resolution
    depsgraph = bpy.context.evaluated_depsgraph_get()
    projection = cam.calc_matrix_camera(depsgraph, x=w, y=h)
    world_to_clip = np.array(projection @ cam.matrix_world.inverted(), dtype=np.float64)
    camera_position = np.array(cam.matrix_world.translation, dtype=np.float64)
    return Prepared(scene, cap, exported, camera_position, world_to_clip)


def compute(
    prepared: Prepared,
    job: Job,
    timer: StageTimer,
    progress: vplace.Progress | None = None,
) -> Computed:
    """VPLs, evaluator and metrics. No bpy: safe on a worker thread; ``progress`` cancels it."""
    scene, cap = prepared.scene, prepared.capture
    r_min = job.r_min if job.r_min is not None else R_MIN_FRACTION * scene.diagonal
    layout_info: dict[str, Any] = {}
    with timer.stage("fit regression"):
        fitted = vplace.fit(
            fit_input(prepared), cell_px=job.cell_px, select=job.feature_mode == "auto"
        )
    if job.method == "vplace":
        with timer.stage(f"layout (n={job.n_vpls}, alpha={job.alpha:g})"):
            laid = vplace.layout(
                scene,
                layout_input(prepared),
                camera_position=prepared.camera_position,
                world_to_clip=prepared.world_to_clip,
                fit=fitted,
                budget=job.n_vpls,
                alpha=job.alpha,
                cell_px=job.cell_px,
                iterate=job.iterations > 0,
                iterations=max(job.iterations, 1),
                seed=job.seed,
                profile=job.profile,
                r_min=r_min,
                progress=progress,
            )
        vpls = apply.VplSet(laid.position, laid.normal, laid.flux)
        layout_info = {"iteration_errors": list(laid.errors), "best_iteration": laid.best}
        if job.refit:
            with timer.stage("refit VPL powers"):
                refitted = vplace.refit(
                    scene, layout_input(prepared), laid, profile=job.profile, r_min=r_min
                )
            vpls = apply.VplSet(refitted.position, refitted.normal, refitted.flux)
            layout_info["refit_error"] = [refitted.error_before, refitted.error_after]
    elif job.method == "uniform":
        with timer.stage(f"uniform VPLs (n={job.n_vpls})"):
            vpls = vpl_set(
                vplace.uniform_vpls(scene, job.n_vpls, job.seed, bounces=vplace.MAX_BOUNCES)
            )
    elif job.method == "rsm":
        with timer.stage(f"RSM VPLs (n={job.n_vpls})"):
            vpls = vpl_set(vplace.rsm_vpls(scene, job.n_vpls))
    else:
        raise vplace.InputError(f"method must be vplace, uniform or rsm, got {job.method!r}")
    with timer.stage("evaluate VPLs"):
        indirect, stats = evaluate_capture(
            scene, cap, vpls, profile=job.profile, r_min=r_min, progress=progress
        )
    stats["r_min"] = r_min
    stats.update(layout_info)
    direct, gi = cap.direct, cap.gi
    estimate = (direct + indirect).astype(np.float32)
    metrics = {
        "rmse": vplace.rmse(estimate, gi),
        "relative_mse": vplace.relative_mse(estimate, gi),
        "ssim": vplace.ssim(estimate, gi) if min(gi.shape[:2]) >= 11 else float("nan"),
        "rmse_direct_only": vplace.rmse(direct, gi),
        "relative_mse_direct_only": vplace.relative_mse(direct, gi),
        "ssim_direct_only": vplace.ssim(direct, gi) if min(gi.shape[:2]) >= 11 else float("nan"),
        "rmse_indirect": vplace.rmse(indirect, cap.indirect),
    }
    return Computed(vpls, indirect, stats, metrics, fitted)


def layout_input(prepared: Prepared) -> dict[str, Any]:
    """The capture as ``vplace.layout`` reads it (with the fit's passes)."""
    cap = prepared.capture
    return {
        **fit_input(prepared),
        "diffuse_direct": cap.diffuse_direct,
        "diffuse_indirect": cap.diffuse_indirect,
    }


def fit_input(prepared: Prepared) -> dict[str, Any]:
    """The capture as ``vplace.fit`` reads it, with the scene's lights."""
    cap = prepared.capture
    return {
        "position": cap.position,
        "normal": cap.normal,
        "albedo": cap.albedo,
        "specular": cap.glossy_color,
        "depth": cap.depth,
        "direct": cap.direct,
        "gi": cap.gi,
        "covered": cap.covered,
        "lights": prepared.exported.lights,
    }


def fit_summary(fitted: vplace.FitResult) -> dict[str, Any]:
    """The fit's figures for reports and the panel."""
    return {
        "r2": fitted.r2,
        "adjusted_r2": fitted.adjusted_r2,
        "kept": list(fitted.kept),
        "weights": dict(fitted.weights),
        "dropped": dict(fitted.dropped),
    }


def summary(
    bl_scene: bpy.types.Scene, job: Job, prepared: Prepared, computed: Computed, timer: StageTimer
) -> dict[str, Any]:
    """The run's report as a JSON-ready dict."""
    return {
        "scene": bl_scene.name,
        "triangles": prepared.scene.triangle_count,
        "lights": prepared.scene.light_count,
        "resolution": list(job.resolution),
        "samples": job.samples,
        "capture_render_seconds": prepared.capture.render_seconds,
        "n_vpls": job.n_vpls,
        "method": job.method,
        "alpha": job.alpha,
        "iterations": job.iterations,
        "profile": job.profile,
        "r_min": computed.stats["r_min"],
        "seed": job.seed,
        "stage_seconds": dict(timer.seconds),
        "evaluator": computed.stats,
        "metrics": computed.metrics,
        "fit": None if computed.fit is None else fit_summary(computed.fit),
    }


def run_main_job(
    bl_scene: bpy.types.Scene,
    out_dir: Path,
    *,
    job: Job | None = None,
    eevee: bool = True,
    write_back: bool = True,
    baselines: tuple[str, ...] = ("uniform", "vplace", "rsm"),
    log: Callable[[str], None] = print,
    **job_options: Any,
) -> dict[str, Any]:
    """Runs the whole pipe on ``bl_scene`` and writes the results into ``out_dir``.

    ``job_options`` are :class:`Job` fields, for a job built on the spot. Without
    ``write_back`` the scene is left as it is (a report only; no EEVEE preview then, as it
    would show the scene without the new VPLs).
    """
    if job is None:
        job = Job(**job_options)
    if job.cache_dir is None:
        job.cache_dir = out_dir / "cache"
    out_dir.mkdir(parents=True, exist_ok=True)
    timer = StageTimer(log)
    prepared = prepare(bl_scene, job, timer)
    computed = compute(prepared, job, timer)
    compared = {}
    for method in (b for b in baselines if b != job.method):
        quiet = StageTimer(log=lambda _line: None)
        other = compute(prepared, dataclasses.replace(job, method=method), quiet)
        compared[method] = {"metrics": other.metrics, "seconds": sum(quiet.seconds.values())}
    if write_back:
        with timer.stage("write back"):
            apply.write_vpls(
                bl_scene, computed.vpls, profile=job.profile, scene_diagonal=prepared.scene.diagonal
            )
            bpy.ops.wm.save_as_mainfile(filepath=str(out_dir / "scene.blend"), copy=True)
    cap, vpls = prepared.capture, computed.vpls
    images.save_png(out_dir / "cycles_gi.png", cap.gi)
    images.save_png(out_dir / "direct.png", cap.direct)
    images.save_png(out_dir / "direct_plus_vpl.png", cap.direct + computed.indirect)
    if eevee and write_back:
        with timer.stage("EEVEE preview"):
            render_eevee_preview(bl_scene, out_dir / "eevee_vpl.png", job.resolution)
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
    report["baselines"] = compared
    (out_dir / "report.json").write_text(json.dumps(report, indent=2))
    report["files"] = sorted(p.name for p in out_dir.iterdir() if p.is_file())
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
        f"r_min {report['r_min']:.3g} m)",
        "",
        "| stage | seconds |",
        "|---|---|",
        *[f"| {k} | {v:.2f} |" for k, v in report["stage_seconds"].items()],
        "",
        "| image vs Cycles GI | RMSE | relative MSE | SSIM |",
        "|---|---|---|---|",
        f"| direct only | {m['rmse_direct_only']:.5f} | {m['relative_mse_direct_only']:.5f} "
        f"| {m['ssim_direct_only']:.4f} |",
        f"| direct + VPL indirect ({report['method']}) | {m['rmse']:.5f} | "
        f"{m['relative_mse']:.5f} | {m['ssim']:.4f} |",
        *[
            f"| direct + VPL indirect ({name}, same N) | {b['metrics']['rmse']:.5f} | "
            f"{b['metrics']['relative_mse']:.5f} | {b['metrics']['ssim']:.4f} |"
            for name, b in report.get("baselines", {}).items()
        ],
        "",
        f"Evaluator: {s['shadow_rays']} shadow rays in {s['seconds']:.3f} s "
        f"= {s['rays_per_second'] / 1e6:.2f} M rays/s",
        "",
    ]
    return "\n".join(lines)
