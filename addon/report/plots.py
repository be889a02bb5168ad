"""The report's PNG plots (matplotlib, Agg backend, imported only when a report runs)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from ..native import vplace

if TYPE_CHECKING:
    from .config import Row

COLOURS = {
    "uniform": "tab:blue",
    "rsm": "tab:orange",
    "vplace": "tab:green",
    "vplace+refit": "tab:red",
    "vplace (re-layout)": "tab:olive",
    "vplace+refit by capture spp": "tab:cyan",
    "eevee": "tab:purple",
    "eevee rt": "tab:pink",
    "eevee rt + volume": "tab:brown",
    "cycles+oidn": "black",
    "cycles": "black",
    "direct": "tab:gray",
}
_LUMINANCE = np.array(vplace.LUMINANCE)


def _views(rows: Sequence[Row]) -> list[tuple[str, str, str]]:
    seen: dict[tuple[str, str, str], None] = {}
    for r in rows:
        seen[(r.scene, r.view, r.role)] = None
    return list(seen)


def _colour(r: Row) -> str | None:
    base = r.method.split(" + ")[0]
    return COLOURS.get(base) or COLOURS.get(r.renderer)


def error_vs_time(out: Path, rows: Sequence[Row]) -> list[Path]:
    """Per view: 1 - SSIM against one frame's seconds (left) and against the one-time seconds
    (right), log-log: the evaluator's budgets joined per method, EEVEE's renders of the grid
    budget's lights and the alternatives as points, Cycles + OIDN's samples joined; direct light
    only as a horizontal line."""
    paths = []
    for scene, view, role in _views(rows):
        mine = [r for r in rows if r.scene == scene and r.view == view]
        fig, axes = plt.subplots(1, 2, figsize=(12, 4.4))
        for ax, cost, label in (
            (axes[0], "frame_seconds", "seconds per frame"),
            (axes[1], "one_time_seconds", "one-time seconds (captures, fit, layout, bake)"),
        ):
            for method, renderer in dict.fromkeys((r.method, r.renderer) for r in mine):
                series = [r for r in mine if (r.method, r.renderer) == (method, renderer)]
                if method == "direct":
                    ax.axhline(series[0].one_minus_ssim, color=COLOURS["direct"], ls=":",
                               label="direct only")  # fmt: skip
                    continue
                series.sort(key=lambda r: (r.n_vpls or 0, r.samples or 0))
                x = [max(getattr(r, cost), 1e-3) for r in series]
                y = [max(r.one_minus_ssim, 1e-6) for r in series]
                style = {"evaluator": "o-", "eevee": "D", "cycles": "s--"}[renderer]
                name = f"{method} ({renderer})"
                ax.plot(x, y, style, color=_colour(series[0]), label=name, ms=5,
                        mfc="none" if renderer == "eevee" else None)  # fmt: skip
                for r, xi, yi in zip(series, x, y, strict=True):
                    spp = r.samples and renderer != "eevee"  # Cycles', or the capture's
                    tag = f"{r.samples}spp" if spp else str(r.n_vpls or "")
                    ax.annotate(tag, (xi, yi), fontsize=6, xytext=(2, 2),
                                textcoords="offset points")  # fmt: skip
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.set_xlabel(label)
            ax.set_ylabel("1 - SSIM")
            ax.grid(True, which="both", alpha=0.3)
        axes[0].legend(fontsize=6)
        fig.suptitle(f"{scene}, {view} ({role} view): error against time")
        fig.tight_layout()
        path = out / f"error_vs_time_{scene}_{slug(view)}.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        paths.append(path)
    return paths


def error_vs_budget(path: Path, rows: Sequence[Row]) -> Path:
    """1 - SSIM and RMSE against the VPL count, one column per view."""
    rows = [r for r in rows if r.renderer in ("evaluator", "reference") and r.samples is None]
    views = _views([r for r in rows if r.n_vpls is not None])
    fig, axes = plt.subplots(2, max(len(views), 1), figsize=(3.6 * max(len(views), 1), 6.4))
    axes = np.asarray(axes).reshape(2, -1)
    for col, (scene, view, role) in enumerate(views):
        mine = [r for r in rows if r.scene == scene and r.view == view]
        for row_i, (metric, label) in enumerate((("one_minus_ssim", "1 - SSIM"), ("rmse", "RMSE"))):
            ax = axes[row_i, col]
            for method in dict.fromkeys(r.method for r in mine if r.n_vpls is not None):
                series = sorted((r for r in mine if r.method == method), key=lambda r: r.n_vpls)
                ax.plot(
                    [r.n_vpls for r in series],
                    [getattr(r, metric) for r in series],
                    "o-",
                    color=COLOURS.get(method),
                    label=method,
                    ms=4,
                )
            direct = [r for r in mine if r.method == "direct"]
            if direct:
                ax.axhline(
                    getattr(direct[0], metric), color=COLOURS["direct"], ls=":", label="direct"
                )
            ax.set_xscale("log", base=2)
            ax.set_yscale("log")
            ax.grid(True, which="both", alpha=0.3)
            if row_i == 0:
                ax.set_title(f"{scene}: {view}\n({role})", fontsize=8)
            if row_i == 1:
                ax.set_xlabel("VPLs")
            if col == 0:
                ax.set_ylabel(label)
    axes[0, 0].legend(fontsize=6)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _display(linear: np.ndarray) -> np.ndarray:
    return vplace.images.linear_to_srgb(np.asarray(linear, dtype=np.float64)[..., :3])


def image_grid(
    path: Path,
    truth: np.ndarray,
    direct: np.ndarray,
    methods: dict[str, np.ndarray],
    *,
    title: str,
) -> Path:
    """Top row: ground truth, direct only, each method (display images). Bottom row: the
    absolute luminance error against the ground truth, one shared colour scale."""
    names = ["ground truth", "direct only", *methods]
    pictures = [truth, direct, *methods.values()]
    lum = [np.asarray(p, dtype=np.float64)[..., :3] @ _LUMINANCE for p in pictures]
    errors = [np.abs(v - lum[0]) for v in lum]
    vmax = max(float(np.percentile(e, 99.5)) for e in errors[1:]) if len(errors) > 1 else 1.0
    h, w = truth.shape[:2]
    cols = len(names)
    fig, axes = plt.subplots(
        2, cols, figsize=(2.2 * cols + 1.0, 2.2 * 2 * h / w + 0.8), squeeze=False,
        layout="constrained",
    )  # fmt: skip
    im = None
    for i, (name, pic, err) in enumerate(zip(names, pictures, errors, strict=True)):
        axes[0, i].imshow(_display(pic))
        axes[0, i].set_title(name, fontsize=8)
        if i == 0:
            axes[1, i].axis("off")
        else:
            im = axes[1, i].imshow(err, cmap="inferno", vmin=0.0, vmax=max(vmax, 1e-6))
            axes[1, i].set_title(f"|error|, mean {err.mean():.4f}", fontsize=7)
        for ax in axes[:, i]:
            ax.set_xticks([])
            ax.set_yticks([])
    if im is not None:
        fig.colorbar(im, ax=axes[1, :].tolist(), shrink=0.8, label="luminance error (linear)")
    fig.suptitle(title, fontsize=9)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def difference_grid(
    path: Path, differences: dict[str, np.ndarray], *, scale: float, title: str
) -> Path:
    """Per method, a signed luminance difference (red: EEVEE brighter, blue: darker) on one
    symmetric colour scale of +-``scale`` (the report passes the truth's 99th percentile, so the
    colours read as a share of the scene's bright light)."""
    names = list(differences)
    lum = [np.asarray(d, dtype=np.float64)[..., :3] @ _LUMINANCE for d in differences.values()]
    h, w = lum[0].shape
    fig, axes = plt.subplots(
        1, len(names), figsize=(2.6 * len(names) + 1.0, 2.6 * h / w + 0.8), squeeze=False,
        layout="constrained",
    )  # fmt: skip
    vmax = max(scale, 1e-6)
    im = None
    for ax, name, d in zip(axes[0], names, lum, strict=True):
        im = ax.imshow(d, cmap="RdBu_r", vmin=-vmax, vmax=vmax)
        ax.set_title(f"{name}: mean {d.mean():+.4f}, |mean| {np.abs(d).mean():.4f}", fontsize=7)
        ax.set_xticks([])
        ax.set_yticks([])
    if im is not None:
        fig.colorbar(im, ax=axes[0, :].tolist(), shrink=0.8, label="luminance (linear)")
    fig.suptitle(title, fontsize=9)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def par2d_plot(path: Path, rows: Sequence[vplace.par2d_measure.Par2dRow]) -> Path:
    """PAR 2D: RMSE against exact over time for Monte Carlo at rising ray counts, and PAR."""
    fig, ax = plt.subplots(figsize=(5.5, 4))
    mc = sorted((r for r in rows if r.method == "monte_carlo"), key=lambda r: r.seconds)
    ax.plot([r.seconds for r in mc], [r.rmse for r in mc], "o-", label="Monte Carlo")
    for r in mc:
        ax.annotate(f"{r.rays} rays", (r.seconds, r.rmse), fontsize=6)
    for r in rows:
        if r.method == "par":
            y = max(r.rmse, 1e-12)
            ax.plot([r.seconds], [y], "*", ms=10, label=f"PAR (RMSE {r.rmse:.1e})")
        elif r.method == "exact":
            ax.axvline(r.seconds, color="black", ls=":", label="exact sweep (the reference)")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("seconds")
    ax.set_ylabel("RMSE against the exact sweep")
    ax.set_title("PAR 2D light map: error against time", fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def slug(name: str) -> str:
    """A file-name-safe lower-case form of ``name``."""
    return "".join(c.lower() if c.isalnum() else "_" for c in name).strip("_")
