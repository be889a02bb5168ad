"""The report's summary: the rows averaged over seeds, the target checks, the break-even, and
the Markdown report (its tables through ``vplace.markdown.table``)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from .. import job as pipeline
from ..native import vplace
from ..writeback import eevee_setup
from .config import (
    BRIGHTNESS_TOLERANCE,
    CAPTURE_CURVE,
    CAPTURE_SPREAD,
    COST_FRAMES,
    COST_SAMPLES,
    EEVEE_RMSE_RATIO,
    EEVEE_SPREAD,
    FIT_VIEW_SSIM,
    HELD_OUT_SPREAD,
    HOT_SHARE,
    SSIM_MARGIN,
    WITH_RT,
    Row,
    RowDetails,
    grid_budget,
)

#: What a target check says when it is scored against the noise-free truth (estimated from the
#: view's two truth renders, ``vplace.ssim_noise_free``), not against the truth itself.
NOISE_FREE = "(noise-free truth)"
#: Below this SSIM between a view's two truth renders the noise-free estimate reads low by about
#: .01 or more (ARCHITECTURE, "SSIM against the noise-free truth"); the report says so.
NOISY_TRUTH = 0.8

#: A share as a whole percentage, never "-0%" (``vplace.markdown.percent``).
pct = vplace.markdown.percent


def aggregate(rows: Sequence[Row]) -> list[Row]:
    """One row per (scene, view, method, renderer, budget or samples): the mean over seeds of
    every metric and time; its details hold ``seeds``, ``by_seed``, ``ssim_std`` and
    ``rmse_std``."""
    groups: dict[tuple[Any, ...], list[Row]] = {}
    for r in rows:
        key = (r.scene, r.view, r.method, r.renderer, r.n_vpls, r.samples)
        groups.setdefault(key, []).append(r)
    out = []
    keys = (
        "rmse",
        "relative_mse",
        "ssim",
        "ssim_noise_free",
        "rmse_noise_free",
        "brightness",
        "hot_pixels",
        "worst_share",
        "one_time_seconds",
        "frame_seconds",
    )
    for members in groups.values():
        first = members[0]
        mean = {k: float(np.mean([getattr(r, k) for r in members])) for k in keys}
        d = first.details
        details = RowDetails(
            setup=d.setup,
            bake_seconds=d.bake_seconds,
            capture_seconds=d.capture_seconds,
            match_seconds=d.match_seconds,
            attribution=d.attribution if len(members) == 1 else None,
            seeds=len(members),
            by_seed={
                str(r.seed): {
                    "ssim": r.ssim,
                    "rmse": r.rmse,
                    "brightness": r.brightness,
                    "hot_pixels": r.hot_pixels,
                    **_noise_free(r),
                }
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
                details=details,
                **mean,
            )
        )
    return out


def _noise_free(row: Row) -> dict[str, float]:
    """The row's SSIM and RMSE against the noise-free truth, where it has them (JSON has no
    NaN)."""
    scores = {"ssim_noise_free": row.ssim_noise_free, "rmse_noise_free": row.rmse_noise_free}
    return {k: v for k, v in scores.items() if math.isfinite(v)}


def same_lights(evaluator: Row, shown: Row) -> dict[str, float]:
    """The evaluator's scores for the very lights ``shown`` (an EEVEE row) rendered: the seed's
    run of an aggregated row, or the row itself for a deterministic method."""
    by_seed = evaluator.details.by_seed or {}
    if shown.seed is not None and str(shown.seed) in by_seed:
        return dict(by_seed[str(shown.seed)])
    return {
        "ssim": evaluator.ssim,
        "ssim_noise_free": evaluator.ssim_noise_free,
        "rmse_noise_free": evaluator.rmse_noise_free,
        "rmse": evaluator.rmse,
        "brightness": evaluator.brightness,
        "hot_pixels": evaluator.hot_pixels,
    }


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


def _attribution_detail(a: dict[str, Any] | None) -> dict[str, str]:
    """What a target's detail adds from an EEVEE row's attribution (``vplace.job.Attribution``):
    whose part of the error it is, in words (empty without one)."""
    if not a:
        return {"rmse": "", "ssim": "", "hot": ""}
    share = a["share"]
    seen = ""
    if math.isfinite(a.get("seen_share", math.nan)):
        seen = (
            f" ({pct(a['seen_share'])} in the {a['seen_pixels']:.1%} of pixels where the camera "
            "sees an emitter, the world or a lamp in a mirror: their edges and patterns, "
            "anti-aliased EEVEE's way)"
        )
    colour = a.get("colour_share", math.nan)
    if math.isfinite(colour):
        seen += (
            f" ({pct(colour)} in the surfaces' colour as EEVEE filters it: its Diffuse Color "
            "pass against Cycles' under Cycles' diffuse light)"
        )
    cut = a.get("cut_share", math.nan)
    if math.isfinite(cut) and a.get("cut_pixels", 0.0) > 0:
        seen += (
            f" ({pct(cut)} in the {a['cut_pixels']:.1%} of pixels whose surface's plane passes "
            f"through a light, which EEVEE darkens: {a['cut_brightness']:.2f}x Cycles' there)"
        )
    model = a.get("stand_in_share", math.nan)
    if math.isfinite(model):
        seen += (
            f" (of it, {pct(model)} the stand-ins' own light as Cycles renders it, "
            f"{pct(share['direct'] - model)} EEVEE's rendering of the lights)"
        )
    return {
        "rmse": f"; of EEVEE's squared error {pct(share['direct'])} is EEVEE's direct light "
        f"against Cycles' (the scene's lamps and vplace's stand-ins, not the VPLs){seen}, "
        f"{pct(share['vpl'])} its VPL light against the "
        f"evaluator's, {pct(share['rest'])} the evaluator's own error",
        "ssim": f"; with Cycles' direct light under EEVEE's VPL light {a['ssim_cycles_direct']:.4f}"
        f", with the evaluator's VPL light over EEVEE's direct light "
        f"{a['ssim_evaluator_vpl']:.4f}",
        "hot": _hot_swaps(
            a,
            "; with Cycles' direct light under EEVEE's VPL light {}, with the "
            "evaluator's VPL light over EEVEE's direct light {}",
            ".3%",
        ),
    }


def _hot_swaps(a: dict[str, Any], template: str, spec: str) -> str:
    """``template`` filled with the hot-pixel shares of the attribution's two swaps (EEVEE's VPL
    light over Cycles' direct light, the evaluator's over EEVEE's direct light); empty where
    the attribution predates them."""
    swaps = [a.get("hot_cycles_direct", math.nan), a.get("hot_evaluator_vpl", math.nan)]
    if not all(math.isfinite(x) for x in swaps):
        return ""
    return template.format(*(format(x, spec) for x in swaps))


def targets(
    rows: list[Row], inside: Mapping[str, Mapping[str, bool]] | None = None
) -> list[dict[str, Any]]:
    """The issues' targets on every scene of ``rows`` (means over seeds) at the grid budget.
    ``inside`` (per scene, per held-out view: whether it stands inside the region its lights
    were laid out for, ``runs._regions``) names each held-out check's place: issue 20's bound is
    for the views a camera in that region can take, and a view outside it asks more."""
    checks: list[dict[str, Any]] = []

    def held_out(scene: str, view: str) -> str:
        where = (inside or {}).get(scene, {}).get(view)
        if where is None:
            return "held out"
        return f"held out, {'inside' if where else 'outside'} the region"

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
                    f"{scene} {v} ({held_out(scene, v)}) N={n}: within {HELD_OUT_SPREAD} SSIM of "
                    "the fit views' mean",
                    gap,
                    gap <= HELD_OUT_SPREAD,
                    f"{ours[v].ssim:.4f} against {fit_mean:.4f}: {gap:+.4f}",
                )
            free = {v: r.ssim_noise_free for v, r in ours.items()}
            if all(math.isfinite(x) for x in free.values()):
                # The same checks against the noise-free truth: a view whose truth is noisier
                # (a dim one lit by bounce light alone) scores lower against it whatever the
                # lights.
                free_mean = float(np.mean([free[v] for v in fit_views]))
                check(
                    f"{scene} N={n}: the fit views reach SSIM {FIT_VIEW_SSIM} {NOISE_FREE}",
                    free_mean,
                    free_mean >= FIT_VIEW_SSIM,
                    f"fit views' mean {free_mean:.4f} (against the truth {fit_mean:.4f})",
                )
                for v in held:
                    gap = free_mean - free[v]
                    check(
                        f"{scene} {v} ({held_out(scene, v)}) N={n}: within {HELD_OUT_SPREAD} "
                        f"SSIM of the fit views' mean {NOISE_FREE}",
                        gap,
                        gap <= HELD_OUT_SPREAD,
                        f"{free[v]:.4f} against {free_mean:.4f}: {gap:+.4f}",
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
                gap = us.ssim_noise_free - uniform.ssim_noise_free
                if math.isfinite(gap):
                    check(
                        f"{scene} {v} ({role}) N={n}: not below uniform {NOISE_FREE}",
                        gap,
                        gap >= 0,
                        f"{us.ssim_noise_free:.4f} against {uniform.ssim_noise_free:.4f}",
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
                lights = {"rmse": us.rmse, "hot_pixels": us.hot_pixels, **same_lights(us, shown)}
                ratio = shown.rmse / max(lights["rmse"], 1e-12)
                parts = _attribution_detail(shown.details.attribution)
                check(
                    f"{scene} {v} ({role}): EEVEE's RMSE at most {EEVEE_RMSE_RATIO}x the "
                    "evaluator's (the same lights)",
                    ratio,
                    ratio <= EEVEE_RMSE_RATIO,
                    f"EEVEE {shown.rmse:.4f}, evaluator {lights['rmse']:.4f}{parts['rmse']}",
                )
                free_rmse = lights.get("rmse_noise_free", math.nan)
                if math.isfinite(free_rmse) and math.isfinite(shown.rmse_noise_free):
                    ratio = shown.rmse_noise_free / max(free_rmse, 1e-12)
                    check(
                        f"{scene} {v} ({role}): EEVEE's RMSE at most {EEVEE_RMSE_RATIO}x the "
                        f"evaluator's (the same lights) {NOISE_FREE}",
                        ratio,
                        ratio <= EEVEE_RMSE_RATIO,
                        f"EEVEE {shown.rmse_noise_free:.4f}, evaluator {free_rmse:.4f}",
                    )
                check(
                    f"{scene} {v} ({role}): EEVEE's hot-spot pixels at most {HOT_SHARE:.1%}",
                    shown.hot_pixels,
                    shown.hot_pixels <= HOT_SHARE,
                    f"EEVEE {shown.hot_pixels:.3%}, evaluator "
                    f"{lights.get('hot_pixels', float('nan')):.3%}{parts['hot']}",
                )
                evaluated = lights["ssim"]
                gap = evaluated - shown.ssim
                check(
                    f"{scene} {v} ({role}): EEVEE with the VPLs within {EEVEE_SPREAD} SSIM "
                    "of the evaluator (the same lights)",
                    gap,
                    abs(gap) <= EEVEE_SPREAD,
                    f"EEVEE {shown.ssim:.4f}, evaluator {evaluated:.4f}{parts['ssim']}",
                )
                evaluated = lights.get("ssim_noise_free", math.nan)
                if math.isfinite(evaluated) and math.isfinite(shown.ssim_noise_free):
                    gap = evaluated - shown.ssim_noise_free
                    check(
                        f"{scene} {v} ({role}): EEVEE with the VPLs within {EEVEE_SPREAD} SSIM "
                        f"of the evaluator (the same lights) {NOISE_FREE}",
                        gap,
                        abs(gap) <= EEVEE_SPREAD,
                        f"EEVEE {shown.ssim_noise_free:.4f}, evaluator {evaluated:.4f}",
                    )
                off = shown.brightness - 1
                detail = f"{shown.brightness:.4f}x"
                plain = _at(mine, scene, v, "eevee", "eevee", None)
                attribution = shown.details.attribution or {}
                if "direct_brightness" in attribution:
                    # EEVEE's direct light as vplace renders it (the scene's lamps and vplace's
                    # stand-ins, the VPLs hidden) against Cycles': a part the VPLs do not carry.
                    own = attribution["direct_brightness"]
                    detail += f"; EEVEE's direct light (VPLs hidden) is {own:.3f}x Cycles'"
                elif plain is not None and direct is not None:
                    # EEVEE without vplace (the world's light its own way) against Cycles'
                    # direct light: no stand-ins, so not what vplace's EEVEE set-up renders.
                    own = plain.brightness / direct.brightness
                    detail += f"; EEVEE without vplace is {own:.3f}x Cycles' direct light"
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
                    gap = shown.ssim_noise_free - volume.ssim_noise_free
                    if math.isfinite(gap):
                        check(
                            f"{scene} {v} ({role}): EEVEE with the VPLs >= EEVEE ray tracing + "
                            f"volume + {SSIM_MARGIN} {NOISE_FREE}",
                            gap,
                            gap >= SSIM_MARGIN,
                            f"{shown.ssim_noise_free:.4f} against "
                            f"{volume.ssim_noise_free:.4f}: {gap:+.4f}",
                        )
                # Like for like: the set-up "Set up EEVEE for vplace" leaves (ray tracing on,
                # its fast GI ambient occlusion only) against EEVEE's own GI with ray tracing.
                # Where sharp metal, glass or a glossy floor show, only ray tracing reflects
                # the room, in both images.
                traced = _at(mine, scene, v, "vplace+refit" + WITH_RT, "eevee", n)
                if volume is not None and traced is not None:
                    for free, ours_, theirs in (
                        ("", traced.ssim, volume.ssim),
                        (f" {NOISE_FREE}", traced.ssim_noise_free, volume.ssim_noise_free),
                    ):
                        gap = ours_ - theirs
                        if math.isfinite(gap):
                            check(
                                f"{scene} {v} ({role}): EEVEE with the VPLs and ray tracing (the "
                                f"set-up vplace applies) >= EEVEE ray tracing + volume + "
                                f"{SSIM_MARGIN}{free}",
                                gap,
                                gap >= SSIM_MARGIN,
                                f"{ours_:.4f} against {theirs:.4f}: {gap:+.4f}",
                            )
        once = [ours[v] for v in fit_views if ours.get(v) is not None]
        cycles = [
            r
            for r in mine
            if r.method == "cycles+oidn" and r.samples == COST_SAMPLES and r.view in fit_views
        ]
        if once and cycles:
            # Captures, fit, layout and refit (coverage views included), per fit camera.
            per_camera = once[0].one_time_seconds / len(fit_views)
            frame = float(np.mean([r.frame_seconds for r in cycles]))
            matching = once[0].details.match_seconds
            check(
                f"{scene} N={n}: one-time cost per camera at most {COST_FRAMES} Cycles + OIDN "
                f"{COST_SAMPLES} spp frames",
                per_camera / frame,
                per_camera <= COST_FRAMES * frame,
                f"{per_camera:.2f} s per camera against {frame:.2f} s a frame"
                + (
                    f"; of it {matching / len(fit_views):.2f} s the EEVEE renders of 'Match "
                    "EEVEE's direct light' (this machine's OpenGL)"
                    if matching is not None
                    else ""
                ),
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
    less than Cycles + OIDN frames of at least the same SSIM (the fewest samples that reach it).
    SSIM against the noise-free truth where every row compared has it (``noise_free``): against
    a noisy truth every image's SSIM is capped alike, and the samples that reach EEVEE's score
    are fewer than the image needs."""
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
        free = all(math.isfinite(x.ssim_noise_free) for x in (r, *cycles))

        def quality(x: Row, free: bool = free) -> float:
            return x.ssim_noise_free if free else x.ssim

        match = next((c for c in cycles if quality(c) >= quality(r)), None)
        entry: dict[str, Any] = {
            "scene": r.scene,
            "view": r.view,
            "role": r.role,
            "eevee_ssim": quality(r),
            "noise_free": free,
            "one_time_seconds": r.one_time_seconds,
            "eevee_frame_seconds": r.frame_seconds,
        }
        if match is None:
            top = cycles[-1]
            entry.update(
                cycles_samples=None,
                cycles_ssim=quality(top),
                cycles_frame_seconds=top.frame_seconds,
            )
            gain = top.frame_seconds - r.frame_seconds
            entry["frames"] = None
            entry["note"] = (
                f"Cycles + OIDN at {top.samples} spp reaches only SSIM {quality(top):.4f} in "
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
                cycles_ssim=quality(match),
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


def _fmt(value: float | None, spec: str) -> str:
    return (
        "-"
        if value is None or (isinstance(value, float) and math.isnan(value))
        else format(value, spec)
    )


def _sd(row: Row) -> str:
    seeds = row.details.seeds or 1
    return f" ({row.details.ssim_std:.3f})" if seeds > 1 else ""


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
        "scored with the evaluator against the truth. Captures s: the scene's export and the "
        "captures; one-time s: those, the fit, layout, refit and near-field choice.",
        "",
        *vplace.markdown.table(
            ["capture spp", "captures s", "one-time s", "fit views' SSIM", "held-out SSIM"]
            + [v for v, _ in views],
            [],
        ),
    ]
    for spp in sorted({r.samples for r in curve if r.samples}):
        mine = {r.view: r for r in curve if r.samples == spp}
        first = next(iter(mine.values()))

        def mean(role: str, mine: dict[str, Row] = mine) -> str:
            values = [r.ssim for r in mine.values() if r.role == role]
            return f"{np.mean(values):.4f}" if values else "-"

        lines.append(
            f"| {spp} | {first.details.capture_seconds:.1f} | {first.one_time_seconds:.1f} | "
            f"{mean('fit')} | {mean('held-out')} | "
            + " | ".join(f"{mine[v].ssim:.4f}" if v in mine else "-" for v, _ in views)
            + " |"
        )
    return [*lines, ""]


def _intro(result: dict[str, Any]) -> list[str]:
    return [
        "# vplace report",
        "",
        "Each method lays out one set of lights for all the fit views at once; every view, fit or "
        "held out, is scored with those same lights. Evaluator rows: the ground truth's direct "
        "light plus the evaluator's VPL indirect light over the view's G-buffer. EEVEE rows: what "
        "a user sees, EEVEE rendering the written lights (float, Standard view, "
        f"{result['config']['eevee_samples']} samples, soft shadows traced with "
        f"{eevee_setup.SHADOW_RAYS} rays as vplace's set-up has them), or the alternatives a "
        "Blender user would pick instead, with the same shadows (EEVEE's own GI with the world's "
        "sun as a lamp where the world has one: "
        "EEVEE extracts next to nothing from a sky); Cycles + OIDN rows: Cycles at that many "
        "samples, denoised. Every image is scored against a high-sample Cycles render of the "
        "view, and, where the truth was rendered twice (two seeds), against the noise-free "
        "truth estimated from both: the truth's own noise caps SSIM, by as much as each view "
        "states. SSIM on display luminance (DESIGN: Metrics); RMSE and relative MSE on linear "
        "HDR; brightness is the mean luminance over the truth's. One-time seconds: the scene's "
        "export and the captures of the fit views, the fit, the layout and refit, or a "
        "volume's bake, paid once for "
        "every view and frame; frame seconds: one image. The captures and the Cycles + OIDN "
        "frames are rendered in this run, never read from the cache, so the cost check sets "
        "seconds timed on the machine as it is now against each other (the truths' and EEVEE's "
        "renders are cached). Stochastic layouts run with seeds "
        f"{list(result['config']['seeds'])}; rows show their mean (SSIM standard deviation in "
        "brackets); `results.csv` has every run. EEVEE here is software OpenGL on 2 CPU cores: "
        "its frame times are no measure of a GPU's." + _eevee_views_note(result),
        "",
        f"Total report time: {result['seconds']:.0f} s.",
        "",
    ]


def _eevee_views_note(result: dict[str, Any]) -> str:
    """The intro's sentence on the views EEVEE rendered, where ``--eevee-views`` chose them."""
    chosen = result["config"].get("eevee_views") or []
    if not chosen:
        return ""
    names = ", ".join(repr(n) for n in chosen)
    return f" EEVEE rendered only the views named {names} (`--eevee-views`)."


def _evaluator_table(mine: Sequence[Row], budgets: Sequence[int]) -> list[str]:
    """SSIM (sd) / RMSE of each evaluator method by VPL budget."""
    tabled = (r.method for r in mine if r.renderer == "evaluator")
    body = []
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
        body.append([method, *cells])
    return vplace.markdown.table(["method", *(f"N={n}" for n in budgets)], body)


def _shown_table(mine: Sequence[Row], name: str, view: str) -> list[str]:
    """What a user sees (EEVEE with the grid budget's lights) and the alternatives."""
    shown = [r for r in mine if r.renderer in ("eevee", "cycles")]
    if not shown:
        return []
    body = []
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
        same = "{ssim:.3f} / {brightness:.3f}".format(**same_lights(ev, r)) if ev else "-"
        body.append(
            [
                label,
                f"{r.ssim:.3f}",
                f"{r.rmse:.4f}",
                f"{r.brightness:.3f}",
                same,
                f"{r.one_time_seconds:.1f}",
                f"{r.frame_seconds:.1f}",
            ]
        )
    header = ["image", "SSIM", "RMSE", "brightness"]
    header += ["evaluator, same lights: SSIM / brightness", "one-time s", "frame s"]
    return [
        "",
        "What a user sees (the grid budget's lights in EEVEE) and the alternatives:",
        "",
        *vplace.markdown.table(header, body),
    ]


def _noise_lines(mine: Sequence[Row], noise: dict[str, float], budgets: Sequence[int]) -> list[str]:
    """The truth's own noise (a second render with another seed), and every image at the grid
    budget scored against the noise-free truth as well (``vplace.ssim_noise_free``)."""
    if not noise:
        return []
    n = grid_budget(budgets) if budgets else None
    body = []
    for r in mine:
        if not math.isfinite(r.ssim_noise_free) or (r.n_vpls and r.n_vpls != n):
            continue
        if r.method == CAPTURE_CURVE:
            continue
        label = f"{r.renderer}: {r.method}"
        if r.renderer == "cycles":
            label += f", {r.samples} spp"
        body.append(
            [
                label,
                f"{r.ssim:.3f}",
                f"{r.ssim_noise_free:.3f}",
                f"{r.rmse:.4f}",
                f"{r.rmse_noise_free:.4f}",
            ]
        )
    noisy = ""
    if noise["truths_ssim"] < NOISY_TRUTH:
        noisy = (
            f" The two renders agree below {NOISY_TRUTH}: here the noise-free estimate itself "
            "reads low, for every image alike (a noise-free image read .94-.98 where a sky-lit "
            "room's renders agreed at .47-.67, `docs/noise_free/simulate.py`), so a gap to a "
            "view whose truth is less noisy is partly the estimate's; more truth samples "
            "(`--truth-samples`) take it away."
        )
    return [
        "",
        f"The truth's own noise: a second render of it (another seed) scores SSIM "
        f"{noise['truths_ssim']:.3f} against it, and the noise-free image would score "
        f"{noise['ceiling']:.3f} (`vplace.ssim_ceiling`): no image scores higher against this "
        "truth. Against the noise-free truth, estimated from the two renders "
        "(`vplace.ssim_noise_free`; `vplace.rmse_noise_free`, the root of the mean of the two "
        f"renders' cross products of the error).{noisy}",
        "",
        *vplace.markdown.table(
            ["image", "SSIM", "SSIM, noise-free truth", "RMSE", "RMSE, noise-free truth"], body
        ),
    ]


def _attribution_table(mine: Sequence[Row], name: str, view: str) -> list[str]:
    """Where each EEVEE image of written lights departs from the truth
    (``vplace.job.Attribution``), beside the evaluator's error and outliers for the same
    lights."""
    body = []
    for r in mine:
        a = r.details.attribution
        if r.renderer != "eevee" or not a:
            continue
        ev = _at(mine, name, view, r.method, "evaluator", r.n_vpls)
        parts = [
            f"{a['rmse'][k]:.4f} ({pct(a['share'][k], signed=True)})"
            for k in vplace.job.ATTRIBUTION_PARTS
        ]
        body.append(
            [
                f"{r.method}, N={r.n_vpls}",
                f"{r.rmse:.4f} / {ev.rmse:.4f}" if ev else f"{r.rmse:.4f} / -",
                *parts,
                f"{a['direct_brightness']:.3f}",
                f"{a['vpl_brightness']:.3f}",
                f"{r.hot_pixels:.2%} / {ev.hot_pixels:.2%}" if ev else f"{r.hot_pixels:.2%} / -",
                f"{r.worst_share:.2f} / {ev.worst_share:.2f}" if ev else f"{r.worst_share:.2f}",
                f"{a['vpl_hot_pixels']:.2%}",
                _hot_swaps(a, "{} / {}", ".2%") or "-",
                f"{a['ssim_cycles_direct']:.3f} / {a['ssim_evaluator_vpl']:.3f}",
                _seen_cell(a),
                _stand_in_cell(a),
                _cut_cell(a),
                _share_cell(a, "colour_share"),
            ]
        )
    if not body:
        return []
    header = ["lights", "RMSE: EEVEE / evaluator", "(a) direct", "(b) VPL light", "(c) rest"]
    header += ["direct: EEVEE / Cycles", "VPL light: EEVEE / evaluator"]
    header += ["hot pixels: EEVEE / evaluator", "worst 1 %: EEVEE / evaluator", "(b) hot"]
    header += ["hot pixels without (a) / without (b)"]
    header += ["SSIM without (a) / without (b)", "(a) where emitters are seen"]
    header += ["(a): the stand-ins / EEVEE's rendering", "(a) where a light's plane is cut"]
    header += ["(a) in the surfaces' colour"]
    return [
        "",
        "Where EEVEE's error comes from, RMSE of each part (its share of EEVEE's squared error):"
        " (a) EEVEE's direct light (the scene's lights and vplace's stand-ins, VPLs hidden) "
        "against Cycles', (b) EEVEE's VPL light against the evaluator's for the same lights, "
        "(c) the evaluator's own error. Brightness is mean luminance over mean luminance; hot "
        "pixels are brighter than twice the truth plus 0.05, worst 1 % is the share of the "
        "squared error in the worst 1 % of pixels, (b) hot counts EEVEE's VPL light against "
        "the evaluator's. SSIM and hot pixels without (a) put Cycles' direct light under "
        "EEVEE's VPL light, without (b) the evaluator's VPL light over EEVEE's direct light: "
        "hot pixels that go without (a) are EEVEE's direct light's. (a) where emitters "
        "are seen: the share of EEVEE's squared error that (a) holds in the pixels where the "
        "camera sees an emitter, the world or a lamp in a mirror (Cycles' emission and "
        "environment passes, and a lamp's glossy highlight above 20 times the view's mean "
        "direct light, at least half its direct light there), and how many pixels those are: "
        "edges and patterns "
        "EEVEE anti-aliases its own way, not light on surfaces. (a) split by Cycles rendering "
        "the same lights (the stand-ins, the emissive meshes lighting nothing, the world "
        "lighting nothing where sky portals stand in for it): the stand-ins' own light against "
        "Cycles' direct light (what vplace writes), and EEVEE's rendering of those lights "
        "against Cycles' (its shadow maps, film and texture filtering). (a) where a light's "
        "plane is cut: the share of EEVEE's squared error that (a) holds in the pixels whose "
        "surface's plane passes through one of the scene's shadowed lights or stand-ins, less "
        "those that see an emitter (EEVEE's soft shadows count the part of the light behind "
        "that plane as shadowed), how "
        "many pixels those are, and EEVEE's direct light over Cycles' in them. (a) in the "
        "surfaces' colour: the share of EEVEE's squared error in Cycles' diffuse light times "
        "EEVEE's Diffuse Color pass minus Cycles' (EEVEE's texture mipmaps and its film filter "
        "at every edge), not light.",
        "",
        *vplace.markdown.table(header, body),
    ]


def _stand_in_cell(a: dict[str, Any]) -> str:
    """The attribution table's split of (a) ("-" without Cycles' rendering of the lights)."""
    model = a.get("stand_in_share", math.nan)
    if not math.isfinite(model):
        return "-"
    return f"{pct(model, signed=True)} / {pct(a['share']['direct'] - model, signed=True)}"


def _share_cell(a: dict[str, Any], key: str) -> str:
    """A signed share of EEVEE's squared error from the attribution ("-" where it is NaN)."""
    share = a.get(key, math.nan)
    return pct(share, signed=True) if math.isfinite(share) else "-"


def _cut_cell(a: dict[str, Any]) -> str:
    """The attribution table's "(a) where a light's plane is cut" cell: the share of EEVEE's
    squared error, the pixels, EEVEE's direct light over Cycles' there ("-" without a mask)."""
    share, pixels = a.get("cut_share", math.nan), a.get("cut_pixels", math.nan)
    if not math.isfinite(share):
        return "-"
    if not pixels > 0:
        return "none"
    return f"{pct(share, signed=True)} in {pixels:.1%}, {a['cut_brightness']:.3f}x"


def _seen_cell(a: dict[str, Any]) -> str:
    """The attribution table's "(a) where emitters are seen" cell ("-" without a mask)."""
    share, pixels = a.get("seen_share", math.nan), a.get("seen_pixels", math.nan)
    return f"{pct(share, signed=True)} in {pixels:.1%}" if math.isfinite(share) else "-"


def _light_lines(info: dict[str, Any]) -> list[str]:
    """The written VPLs' specular factor and the objects they do not light
    (``native_view.vpl_specular``, ``vpl_unlit``), where the run recorded them."""
    if "vpl_specular" not in info:
        return []
    text = f"The written VPLs' specular factor: {info['vpl_specular']:g}"
    unlit = info.get("vpl_unlit") or []
    if unlit:
        names = ", ".join(f"'{n}'" for n in unlit)
        text += (
            f"; they do not light {names} (sharp metal or glass, Light Linking), whose "
            "reflections are EEVEE's ray tracing's"
        )
    return [text + ".", ""]


def region_sentence(region: dict[str, Any] | None) -> str:
    """A held-out view's place against the region its lights were laid out for (``runs.
    _regions``), as a sentence to follow its header line ('' without)."""
    if not region:
        return ""
    where = "inside" if region["inside"] else "outside"
    return (
        f" It stands {region['distance']:.2g} m from {region['camera']}, {where} the region "
        f"around it (radius {region['radius']:.2g} m), which the coverage views stand for."
    )


def matched_shares(matched: dict[str, float]) -> str:
    """``--match-eevee``'s deficit per matched view, of Cycles' direct light: "A +0.6%, B
    -0.6%" ("none" where no view was matched)."""
    views = (f"{view} {pct(share, signed=True, digits=1)}" for view, share in matched.items())
    return ", ".join(views) or "none"


def _matched_lines(info: dict[str, Any]) -> list[str]:
    """With ``--match-eevee``: what vplace+refit's powers make up for, per captured view."""
    matched = info.get("eevee_deficit_matched")
    if matched is None:
        return []
    shares = matched_shares(matched)
    return [
        "vplace+refit may match EEVEE's direct light (`--match-eevee`; by default where a "
        "surface the fit cameras see cuts one of the scene's lamps): its refit is offered "
        f"what EEVEE's direct light lacks against Cycles', of Cycles' direct light: {shares}, "
        "and keeps it where EEVEE's image predicted on those views comes out closer (each "
        "row's `eevee_match` in results.json). The EEVEE renders this takes count in the "
        "captures' time.",
        "",
    ]


def _scene_lines(name: str, info: dict[str, Any], rows: Sequence[Row]) -> list[str]:
    """One scene's section: the fit, then per view the evaluator's and the renderers' tables."""
    fit = info["fit"]
    r2 = ", ".join(f"{v} {_fmt(x, '.3f')}" for v, x in fit["view_r2"].items())
    lines = [
        f"## {name}",
        "",
        f"Fit over {len(fit['view_r2'])} views: kept "
        + ", ".join(fit["kept"])
        + f" (R^2 {fit['r2']:.3f}; per view {r2}; {info['fit_seconds']:.2f} s). Captures of "
        f"the fit views, with the scene's export: {info['capture_seconds']:.1f} s.",
        "",
        *[line for note in info.get("lamp_notes", []) for line in (f"Note: {note}.", "")],
        *_matched_lines(info),
        *_light_lines(info),
    ]
    budgets = sorted({r.n_vpls for r in rows if r.scene == name and r.renderer == "evaluator"})
    for view, v in info["views"].items():
        mine = [r for r in rows if r.scene == name and r.view == view]
        lines += [
            f"### {view} ({v['role']} view)",
            "",
            f"{v['resolution'][0]}x{v['resolution'][1]} px, {v['triangles']} triangles; ground "
            f"truth {v['truth_samples']} spp in {v['truth_seconds']:.1f} s. Images: "
            + ", ".join(f"`{v[k]}`" for k in ("grid", "eevee_grid", "vpl_difference") if k in v)
            + "."
            + region_sentence(v.get("region")),
            "",
            "Evaluator, SSIM (sd) / RMSE by VPL budget:",
            "",
            *_evaluator_table(mine, budgets),
        ]
        direct = next((x for x in mine if x.method == "direct"), None)
        if direct:
            lines += ["", f"Direct light only: SSIM {direct.ssim:.3f}, RMSE {direct.rmse:.4f}."]
        lines += _shown_table(mine, name, view)
        lines += _noise_lines(mine, v.get("truth_noise") or {}, budgets)
        lines += _attribution_table(mine, name, view)
        lines.append("")
    return lines + _capture_curve_lines([r for r in rows if r.scene == name])


def _break_even_lines(found: Sequence[dict[str, Any]]) -> list[str]:
    if not found:
        return []
    header = ["scene", "view", "EEVEE SSIM", "one-time s", "EEVEE frame s", "Cycles spp"]
    header += ["Cycles SSIM", "Cycles frame s", "frames"]
    body = [
        [
            b["scene"],
            f"{b['view']} ({b['role']})",
            f"{b['eevee_ssim']:.3f}" + (" (noise-free truth)" if b.get("noise_free") else ""),
            f"{b['one_time_seconds']:.1f}",
            f"{b['eevee_frame_seconds']:.1f}",
            b["cycles_samples"] or "-",
            f"{b['cycles_ssim']:.3f}",
            f"{b['cycles_frame_seconds']:.1f}",
            b["note"],
        ]
        for b in found
    ]
    return [
        "## Break-even: vplace + EEVEE against Cycles + OIDN",
        "",
        "Frames after which vplace's one-time cost plus its EEVEE frames costs less than "
        "Cycles + OIDN frames of at least the same SSIM (the fewest samples that reach it), "
        "against the noise-free truth where the view's truth was rendered twice: against a "
        "noisy truth every SSIM is capped alike, so fewer samples seem to reach EEVEE's score "
        "than the image needs. EEVEE's frame time is this machine's (software OpenGL where it "
        "has no GPU). On an "
        "NVIDIA H200 (docs/EEVEE_NOTES.md, Q8), Sponza at 1920x1080 and 16 samples took 1.9 s "
        "without VPLs, 25.9 s with 256 and 79 s with 800; at 1 sample 1.85 s with 256. Cycles + "
        "OIDN on that GPU (OptiX) took 0.74 / 1.01 / 1.37 s at 1 / 4 / 16 spp for the same "
        "frame, after a one-time kernel build of 285 s: on such a GPU, Cycles + OIDN costs less "
        "per frame than EEVEE with 256 VPLs at any sample count measured, so vplace does not "
        "pay off there on Sponza.",
        "",
        *vplace.markdown.table(header, body),
        "",
    ]


def _targets_lines(found: Sequence[dict[str, Any]]) -> list[str]:
    if not found:
        return []
    body = [[c["check"], "yes" if c["met"] else "**no**", c["detail"]] for c in found]
    return ["## Targets", "", *vplace.markdown.table(["check", "met", "detail"], body), ""]


def _par2d_lines(found: Sequence[dict[str, Any]]) -> list[str]:
    if not found:
        return []
    body = [
        [p["method"], p["rays"] or "-", f"{p['seconds']:.3f}", f"{p['rmse']:.3e}"] for p in found
    ]
    header = ["method", "rays", "seconds", "RMSE vs exact"]
    return [
        "## PAR 2D",
        "",
        *vplace.markdown.table(header, body),
        "",
        "Plot: `par2d_speed_error.png`.",
        "",
    ]


def markdown(result: dict[str, Any], rows: list[Row]) -> str:
    """The human-readable report."""
    lines = _intro(result)
    for name, info in result["scenes"].items():
        lines += _scene_lines(name, info, rows)
    lines += _break_even_lines(result["break_even"])
    lines += _targets_lines(result["targets"])
    lines += _par2d_lines(result["par2d"])
    lines += ["## Files", "", *[f"- `{f}`" for f in result["files"]], ""]
    return "\n".join(lines)
