"""Markdown for the reports: one table writer, and the main job's short report.

The full report (the add-on's ``report`` package) writes its tables with :func:`table` too, so
every Markdown table of vplace is written here.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from vplace.job import JobSummary


def table(header: Sequence[str], rows: Iterable[Sequence[object]]) -> list[str]:
    """The lines of a Markdown table: the header, the rule, one line per row (cells already
    formatted; any object is written with ``str``)."""
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return lines


def _scores(label: str, m: dict[str, float], suffix: str = "") -> list[str]:
    return [
        label,
        f"{m['rmse' + suffix]:.5f}",
        f"{m['relative_mse' + suffix]:.5f}",
        f"{m['ssim' + suffix]:.4f}",
        f"{m['brightness' + suffix]:.3f}",
    ]


def _eevee_label(e: dict[str, float]) -> str:
    bake = e.get("world_volume_bake_seconds")
    baked = f"; the world's probe volume baked in {bake:.1f} s" if bake else ""
    return f"EEVEE with the written lights ({e['samples']} samples, {e['seconds']:.1f} s{baked})"


def job_report(report: JobSummary) -> str:
    """The main job's short human-readable report."""
    m, s = report.metrics, report.evaluator
    rows = [
        _scores("direct only", m, "_direct_only"),
        _scores(f"evaluator: direct + VPL indirect ({report.method})", m),
        *[
            _scores(f"evaluator: direct + VPL indirect ({name}, same N)", b.metrics)
            for name, b in report.baselines.items()
        ],
    ]
    if report.eevee:
        rows.append(_scores(_eevee_label(report.eevee), report.eevee))
    label = report.reference.label if report.reference is not None else "its own capture"
    lines = [
        f"# vplace report: {report.scene}",
        "",
        f"{report.triangles} triangles, {report.lights} lights, "
        f"{report.resolution[0]}x{report.resolution[1]} px, {report.samples} spp Cycles, "
        f"{report.n_vpls} VPLs by {report.method} ({report.profile}, "
        f"near-field radius {report.radius:.3g} m)",
        "",
        *table(["stage", "seconds"], [[k, f"{v:.2f}"] for k, v in report.stage_seconds.items()]),
        "",
        f"Every image is scored against {label}.",
        "",
        *table(["image", "RMSE", "relative MSE", "SSIM", "brightness"], rows),
        "",
        f"Evaluator: {s.shadow_rays} shadow rays in {s.seconds:.3f} s "
        f"= {s.rays_per_second / 1e6:.2f} M rays/s",
        "",
    ]
    return "\n".join(lines)
