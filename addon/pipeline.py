"""The main job: capture -> scene export -> VPLs -> evaluator -> write-back -> report.

Every stage is timed and announced through ``log``. Used by the CLI (``python -m addon.cli``)
and by the operators.
"""

from __future__ import annotations

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


def run_main_job(
    bl_scene: bpy.types.Scene,
    out_dir: Path,
    *,
    n_vpls: int = 128,
    resolution: tuple[int, int] = (160, 160),
    samples: int = 256,
    seed: int = 0,
    profile: str = "cosine",
    r_min: float = 0.01,
    eevee: bool = True,
    cache_dir: Path | None = None,
    log: Callable[[str], None] = print,
) -> dict[str, Any]:
    """Runs the whole pipe on ``bl_scene`` and writes the results into ``out_dir``."""
    out_dir.mkdir(parents=True, exist_ok=True)
    timer = StageTimer(log)
    with timer.stage("export scene"):
        exported = export.export_scene(bl_scene)
    with timer.stage("build BVH"):
        scene = build_scene(exported)
    with timer.stage("capture (Cycles)"):
        last = [0.0]

        def on_progress(line: str) -> None:
            now = time.perf_counter()
            if now - last[0] > 2.0:
                last[0] = now
                log(f"[vplace]   {line}")

        cap = capture.capture(
            bl_scene,
            resolution=resolution,
            samples=samples,
            seed=seed,
            cache_dir=cache_dir if cache_dir is not None else out_dir / "cache",
            on_progress=on_progress,
        )
    with timer.stage(f"uniform VPLs (n={n_vpls})"):
        vpls = vpl_set(vplace.uniform_vpls(scene, n_vpls, seed))
    with timer.stage("evaluate VPLs"):
        indirect, stats = evaluate_capture(scene, cap, vpls, profile=profile, r_min=r_min)
    direct, gi = cap.direct, cap.gi
    estimate = (direct + indirect).astype(np.float32)
    metrics = {
        "rmse": vplace.rmse(estimate, gi),
        "relative_mse": vplace.relative_mse(estimate, gi),
        "rmse_direct_only": vplace.rmse(direct, gi),
        "relative_mse_direct_only": vplace.relative_mse(direct, gi),
        "rmse_indirect": vplace.rmse(indirect, cap.indirect),
    }
    with timer.stage("write back"):
        apply.write_vpls(bl_scene, vpls, profile=profile, scene_diagonal=scene.diagonal)
        blend_path = out_dir / "scene.blend"
        bpy.ops.wm.save_as_mainfile(filepath=str(blend_path), copy=True)
    images.save_png(out_dir / "cycles_gi.png", gi)
    images.save_png(out_dir / "direct.png", direct)
    images.save_png(out_dir / "direct_plus_vpl.png", estimate)
    if eevee:
        with timer.stage("EEVEE preview"):
            render_eevee_preview(bl_scene, out_dir / "eevee_vpl.png", resolution)
    np.savetxt(
        out_dir / "vpls.csv",
        np.hstack([vpls.position, vpls.normal, vpls.flux]),
        delimiter=",",
        header="x,y,z,nx,ny,nz,flux_r,flux_g,flux_b",
        comments="",
        fmt="%.6g",
    )
    report = {
        "scene": bl_scene.name,
        "triangles": scene.triangle_count,
        "lights": scene.light_count,
        "resolution": list(resolution),
        "samples": samples,
        "capture_render_seconds": cap.render_seconds,
        "n_vpls": n_vpls,
        "profile": profile,
        "r_min": r_min,
        "seed": seed,
        "stage_seconds": timer.seconds,
        "evaluator": stats,
        "metrics": metrics,
        "files": sorted(p.name for p in out_dir.iterdir() if p.is_file()),
    }
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
        f"{report['n_vpls']} uniform VPLs ({report['profile']}, r_min {report['r_min']} m)",
        "",
        "| stage | seconds |",
        "|---|---|",
        *[f"| {k} | {v:.2f} |" for k, v in report["stage_seconds"].items()],
        "",
        "| image vs Cycles GI | RMSE | relative MSE |",
        "|---|---|---|",
        f"| direct only | {m['rmse_direct_only']:.5f} | {m['relative_mse_direct_only']:.5f} |",
        f"| direct + VPL indirect | {m['rmse']:.5f} | {m['relative_mse']:.5f} |",
        "",
        f"Evaluator: {s['shadow_rays']} shadow rays in {s['seconds']:.3f} s "
        f"= {s['rays_per_second'] / 1e6:.2f} M rays/s",
        "",
    ]
    return "\n".join(lines)
