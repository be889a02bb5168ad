"""One job without Blender: the layout methods and their one dispatch, the fit, the evaluator,
the scores, and the typed results a run hands to its callers.

The Blender add-on exports the scene and captures the views (``vplace.Scene``, ``vplace.View``
and a :class:`Reference`), then calls :func:`compute`; the command line, the panel and the report
all go through :func:`lay_out`. Nothing here imports Blender, so every function may run on a
worker thread (``progress`` cancels the long calls).
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

import vplace
from vplace import images, markdown
from vplace.coverage import captures_of, is_coverage, is_rendered_coverage

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
        """Announces ``name``, times the block and announces its seconds."""
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
class LayoutSettings:
    """What the fit, the layout and the evaluator read of a job. The add-on's ``Job`` adds the
    capture's settings; the panel's and the command line's defaults are these."""

    n_vpls: int = 128
    seed: int = 0
    profile: str = "cosine"
    #: Near-field radius of the VPLs (scene units); None: the scene's (``NEAR_FIELD_FRACTION``
    #: of its working scale, ``Scene.scale``: VPL spacing grows with the scene).
    radius: float | None = None
    cell_px: int = 16
    #: One of :data:`METHODS`. The default is ``vplace+refit``: it beats the others in the
    #: report at equal N.
    method: str = "vplace+refit"
    alpha: float = 1.0
    iterations: int = 3
    #: One of :data:`FEATURE_MODES`.
    feature_mode: str = "auto"
    #: Give the regression-guided sets the near-field gather where their captures show it
    #: helps (:func:`choose_near_field`); False: never (EEVEE's fast GI stays ambient
    #: occlusion only, and ray tracing may stay off).
    near_field: bool = True

    def radius_in(self, scene: vplace.Scene) -> float:
        """The near-field radius in ``scene``: :attr:`radius`, or the scene's own."""
        return self.radius if self.radius is not None else scene.near_field_radius


def fit(scene: vplace.Scene, views: Sequence[vplace.View], settings: LayoutSettings) -> vplace.Fit:
    """The regression on ``views`` with the settings' cells and feature mode. Coverage views
    (``vplace.coverage``) are left out: the model learns from the captures only. (Fitted on the
    coverage views too, Sponza gained .002-.023 SSIM after the refit, but the L room's seed 0
    got 0.14 / 0.24 % hot pixels on its held-out views against 0.05 / 0.08 %: 192x108, 256
    VPLs, 8 seeds.)"""
    return vplace.fit(
        scene,
        captures_of(views),
        vplace.FitParams(
            cell_px=settings.cell_px,
            surface_only=settings.feature_mode == "auto",
            select=settings.feature_mode != "all",
        ),
    )


@dataclass
class NearFieldChoice:
    """Whether a set's light includes the near-field gather (``VplSet.near_field``), and the
    captures' evidence (:func:`choose_near_field`): the luminance RMSE of the VPLs' light
    against the captured views' indirect light (over the :data:`NEAR_FIELD_BLOCK`-pixel blocks
    where some pixel gathers), without and with the gather."""

    on: bool
    without: float
    with_gather: float
    #: The gather distance (``VplSet.near_field_distance``), scene units.
    distance: float
    #: The captured views it was judged on.
    views: int


@dataclass
class EeveeMatch:
    """What "Match EEVEE's direct light" gives the refit (the add-on's
    ``writeback.match_eevee``): ``views``, the captured views with EEVEE's smooth direct-light
    deficit (:func:`eevee_deficit`) added to the light the VPLs are fitted to on the views of
    ``matched`` (indices into ``views``), and ``plain``, the same captured views without it;
    ``error(vpls, i)``, the mean squared error EEVEE's image would have on matched view ``i``
    with a set of VPLs (EEVEE's own direct light, rendered, plus the VPLs' light, against the
    capture's light). The refit keeps the deficit only where it helps (:class:`MatchChoice`)."""

    views: list[vplace.View]
    plain: list[vplace.View]
    matched: list[int]
    error: Callable[[vplace.VplSet, int], float]


@dataclass
class MatchChoice:
    """Whether the refit kept EEVEE's direct-light deficit (:class:`EeveeMatch`), and the
    evidence: EEVEE's predicted RMSE on the matched views with the powers refitted to it and
    with the powers refitted without it. With two matched views or more each is judged left
    out (``held_out``): the powers refitted to the other views' deficit, on its own view, so
    that the deficit is kept only where it carries over to a view it was not fitted to (a view
    no capture saw, such as the sky room's held-out ceiling, is such a view); with one, on the
    view it was fitted to. It is kept where EEVEE's image comes out closer on every view judged
    (``per_view``). Where the deficit is sharp (a sun patch's edge, a texture EEVEE
    filters its own way) the smooth VPL light cannot follow it, and fitting its average raised
    EEVEE's error (the sky room: RMSE .1246 -> .1269 on the camera, .0567 -> .0666 on the
    held-out ceiling); where it is a lamp's light EEVEE darkens smoothly, it lowered it (the
    Cornell box's left view: .00452 -> .00352; README, "Match EEVEE's direct light, only where
    it helps")."""

    kept: bool
    with_match: float
    without: float
    held_out: bool = False
    #: Per matched view: EEVEE's predicted RMSE with the deficit and without.
    per_view: list[list[float]] = field(default_factory=list)


def choose_match(
    scene: vplace.Scene,
    views: Sequence[vplace.View],
    vpls: vplace.VplSet,
    plain: vplace.Refit,
    match: EeveeMatch,
    progress: vplace.Progress | None = None,
) -> tuple[MatchChoice, vplace.Refit | None]:
    """Whether ``match`` helps the refit of ``vpls`` (the layout's set; ``plain`` its refit
    without it), judged as :class:`MatchChoice` says, and the refit with it (None when it is
    left out)."""
    if not match.matched:
        return MatchChoice(False, math.nan, math.nan), None

    def refit(refit_views: Sequence[vplace.View]) -> vplace.Refit:
        return refit_powers(scene, views, vpls, refit_views=refit_views, progress=progress)

    held_out = len(match.matched) >= 2
    # Judged on the views it was fitted to, the refit with every deficit is the one judged;
    # judged left out, it is needed only where it is kept (below).
    matched = None if held_out else refit(match.views)
    with_match, without = [], []
    for i in match.matched:
        if matched is None:
            others = list(match.views)
            others[i] = match.plain[i]
            judged = refit(others)
        else:
            judged = matched
        with_match.append(match.error(judged.vpls, i))
        without.append(match.error(plain.vpls, i))
    a, b = math.sqrt(float(np.mean(with_match))), math.sqrt(float(np.mean(without)))
    per_view = [[math.sqrt(w), math.sqrt(o)] for w, o in zip(with_match, without, strict=True)]
    # Kept where it helps on every view judged, not on their mean alone: a mean gain of a few
    # parts in ten thousand, made of one view's gain and another's loss, is no evidence that
    # it carries over to a view no capture saw.
    kept = all(w < o for w, o in per_view)
    choice = MatchChoice(kept, a, b, held_out, per_view)
    if not kept:
        return choice, None
    return choice, matched if matched is not None else refit(match.views)


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
    #: Whether ``vpls`` include the near-field gather, and why (vplace methods).
    near_field: NearFieldChoice | None = None
    #: Seconds of that choice.
    near_field_seconds: float = 0.0
    #: With an :class:`EeveeMatch`: whether the refit kept it (vplace+refit).
    match: MatchChoice | None = None


#: :func:`choose_near_field` compares block means of this many pixels a side: the captures'
#: noise (16 spp: luminance RMSE .10-.15 per pixel in the sky and L rooms) averaged down,
#: the gather's light (a corner's band, a hem's line) kept. Per pixel, the sky room's four
#: seeds split two against two where the truth favours the gather on every view; over 4 x 4
#: blocks all four took it, and Sponza's four still left it out.
NEAR_FIELD_BLOCK = 4


def _block_means(image: np.ndarray, covered: np.ndarray, block: int) -> np.ndarray:
    """The mean of ``image`` over the covered pixels of each ``block x block`` block (0 where
    none is covered)."""
    if block == 1:
        return np.where(covered, image, 0.0)
    h, w = image.shape
    hb, wb = -(-h // block), -(-w // block)
    pad = ((0, hb * block - h), (0, wb * block - w))
    v = np.pad(np.where(covered, image, 0.0), pad).reshape(hb, block, wb, block)
    c = np.pad(covered.astype(np.float64), pad).reshape(hb, block, wb, block)
    n = c.sum(axis=(1, 3))
    return np.where(n > 0, v.sum(axis=(1, 3)) / np.maximum(n, 1), 0.0)


def choose_near_field(
    scene: vplace.Scene,
    views: Sequence[vplace.View],
    vpls: vplace.VplSet,
    *,
    progress: vplace.Progress | None = None,
) -> NearFieldChoice:
    """Whether the light of ``vpls`` should include the near-field gather
    (``vplace.evaluate(..., near_field=True)``: the light between nearby surfaces, a room's
    corners, that no VPL carries; EEVEE's fast GI within the same distance), judged on the
    views of ``views`` with an indirect image (the captures the VPLs were fitted to): on when
    the VPLs' light with it is closer to those images than without (luminance, squared error
    of the means of the covered pixels over :data:`NEAR_FIELD_BLOCK`-pixel blocks, summed over
    the views, over the blocks where some pixel gathers: elsewhere the two are the same). Ties,
    sets without a gather distance (points) and views without an indirect image leave it off.
    The VPLs are evaluated only where the choice reads their light (``vplace.near_field_reach``:
    those blocks, and the pixels their gather reads), which in the built-in rooms is a fraction
    of each capture.

    The gather and the VPLs both carry the light of a lit surface close to a receiver: on
    Sponza's main view the curtains' hems, 13 cm above the sunlit floor, got 0.74 from the
    VPLs and 0.35-0.44 from the gather where the path tracer gives 0.33 (RMSE .0116 -> .0197).
    The captures show that as the truth does (192 x 108, 256 VPLs, two seeds: per-pixel RMSE
    against the captures .0111 -> .0173 on the main view), and the built-in rooms' gains too:
    the captures judge, per scene, not a threshold."""
    judged = [v for v in views if v.has_indirect]
    distance = float(vpls.near_field_distance)
    if not judged or distance <= 0.0:
        return NearFieldChoice(False, 0.0, 0.0, distance, len(judged))
    lum = np.asarray(vplace.LUMINANCE, dtype=np.float64)
    sums = np.zeros(2)
    count = 0
    block = NEAR_FIELD_BLOCK
    for view in judged:
        covered = np.asarray(view.covered)
        h, w = covered.shape
        # Only the blocks where some pixel gathers differ between the two; the VPLs' light is
        # needed on them and on the pixels their gather reads, the rest of the view not at all.
        # (A receiver is covered, so each such block has covered pixels.)
        receivers, sources = vplace.near_field_reach(view, distance)
        weight = _block_means(receivers.astype(np.float64), covered, block) > 0
        if not weight.any():
            continue
        count += int(weight.sum())
        need = np.repeat(np.repeat(weight, block, axis=0), block, axis=1)[:h, :w] | sources
        shaded = view if need[covered].all() else view.restricted(need)
        target = _block_means(np.asarray(view.indirect, dtype=np.float64) @ lum, covered, block)
        # One evaluation: the gather is added to it as ``evaluate(near_field=True)`` adds it.
        plain, _ = vplace.evaluate(scene, shaded, vpls, near_field=False, progress=progress)
        gathered = plain + vplace.near_field_light(scene, view, plain, distance)
        for k, image in enumerate((plain, gathered)):
            mine = _block_means(np.asarray(image, dtype=np.float64) @ lum, covered, block)
            err = (mine - target)[weight]
            sums[k] += float((err**2).sum())
    without, with_gather = (math.sqrt(x / max(count, 1)) for x in sums)
    return NearFieldChoice(bool(sums[1] < sums[0]), without, with_gather, distance, len(judged))


def refit_powers(
    scene: vplace.Scene,
    views: Sequence[vplace.View],
    vpls: vplace.VplSet,
    *,
    refit_views: Sequence[vplace.View] | None = None,
    group: int | None = None,
    hold_unseen: bool = True,
    progress: vplace.Progress | None = None,
) -> vplace.Refit:
    """The power refit of ``vpls`` for ``views``, as every refitting caller runs it (the still
    layout, :func:`lay_out`, and, through :func:`refit_frame_powers`, each frame of
    ``vplace.temporal.shared_layout``): fitted to
    the captured views of ``views`` (or ``refit_views`` in their place) at
    ``vplace.refit_stride_for`` of them; ``group``: VPLs per power group (default
    ``RefitParams.DEFAULT``'s).

    The captures are fitted: a coverage view's target is itself light-path VPLs, and fitting
    powers to it fits that estimate's noise (the layout uses it to place). With
    ``hold_unseen`` its G-buffer says which surfaces no capture saw, and the VPLs lighting
    them are held near their powers (the coverage views' penalty): right where those powers
    are the light paths' of this light, as a still layout's are. A shared layout's union holds
    other frames' VPLs at their own frames' powers (over F), no estimate of this frame's light:
    held there, on a room whose lamp moves 3 m, the keyed lights' RMSE rose 9 % where without
    the hold it fell 6 % (README, "Each frame's refit is the still layout's"), so the frames
    refit without it (``hold_unseen=False``).

    Where the captures include coverage views rendered by Cycles (the add-on's default), no
    traced view holds what the user's cameras did not see, and the scales are bounded at
    :data:`REGION_MAX_SCALE` instead."""
    captured = captures_of(views) if refit_views is None else list(refit_views)
    return vplace.refit(
        scene,
        captured,
        vpls,
        _refit_params(captured, group),
        coverage=[v for v in views if is_coverage(v)] if hold_unseen else None,
        progress=progress,
    )


#: The refit's bound on the scales (``RefitParams.max_scale``: times the larger of 1 and what
#: they are pulled toward) where it fits coverage views rendered by Cycles. Fitted as captures,
#: those renders show room corners brighter than the evaluator's VPLs can light them, and the
#: refit reached for them with the VPLs beside them (the sky room: ceiling VPLs 3.5-3.9 times,
#: 0.20 / 0.31 % hot pixels on the held-out views); the traced views' hold kept them before.
#: Bounded at 2: at most 0.07 % on every built-in view (seeds 0-7), no view more than .0024
#: SSIM below the traced views' default, Sponza's held-out Alcove +.020 (3 left 0.15 / 0.16 %;
#: capping at 3 after the solve 0.07 / 0.10 % with .97-.99 of the light). Not with traced
#: views or none: the pull is then mostly toward 1, and Sponza's captures ask for more than
#: twice the light-path powers (bounded, its views fell .004 to .019 with traced views, up to
#: .006 with none). ARCHITECTURE.md, "Coverage views rendered by Cycles".
REGION_MAX_SCALE = 2.0


def _refit_params(captured: Sequence[vplace.View], group: int | None) -> vplace.RefitParams:
    """The refit's settings for ``captured`` (:func:`refit_powers`): its own stride, and the
    bound :data:`REGION_MAX_SCALE` where it fits rendered coverage views."""
    rendered = any(is_rendered_coverage(v) for v in captured)
    return vplace.RefitParams(
        stride=vplace.refit_stride_for(captured),
        group=group,
        max_scale=REGION_MAX_SCALE if rendered else None,
    )


def same_gbuffers(a: Sequence[vplace.View], b: Sequence[vplace.View]) -> bool:
    """True when views ``a`` and ``b`` are the same G-buffers, one for one, bit for bit (size,
    position, normal, albedo, covered pixels): what the refit reads of a view besides its
    target."""
    return len(a) == len(b) and all(
        (x.width, x.height) == (y.width, y.height)
        and all(
            np.array_equal(getattr(x, k), getattr(y, k))
            for k in ("position", "normal", "albedo", "covered")
        )
        for x, y in zip(a, b, strict=True)
    )


def refit_frame_powers(
    scenes: Sequence[vplace.Scene],
    views: Sequence[Sequence[vplace.View]],
    vpls: vplace.VplSet,
    *,
    group: int | None = None,
    progress: vplace.Progress | None = None,
) -> list[vplace.Refit]:
    """:func:`refit_powers` of the same ``vpls`` on each frame ``f`` (``scenes[f]``, its
    captured views of ``views[f]``), without the coverage views' hold (``hold_unseen=False``,
    as a shared layout refits: ``vplace.temporal.shared_layout``). The frames whose light alone
    differs (a moving sun or lamp: their captures' G-buffers, :func:`same_gbuffers`, and their
    scenes' occluders, ``Scene.same_occluders``, are the same) are refitted together
    (``vplace.refit_frames``): their shadow rays and Gram matrix are traced once, each frame's
    result the one :func:`refit_powers` gives it alone. A frame whose objects or camera move
    is refitted on its own."""
    if len(scenes) != len(views):
        raise ValueError(f"{len(scenes)} scenes for {len(views)} frames of views")
    captured = [captures_of(v) for v in views]
    groups: list[list[int]] = []
    for f in range(len(scenes)):
        for members in groups:
            first = members[0]
            if scenes[first].same_occluders(scenes[f]) and same_gbuffers(
                captured[first], captured[f]
            ):
                members.append(f)
                break
        else:
            groups.append([f])
    out: dict[int, vplace.Refit] = {}
    for members in groups:
        refits = vplace.refit_frames(
            [scenes[f] for f in members],
            [captured[f] for f in members],
            vpls,
            _refit_params(captured[members[0]], group),
            progress=progress,
        )
        out.update(zip(members, refits, strict=True))
    return [out[f] for f in range(len(scenes))]


def lay_out(
    scene: vplace.Scene,
    views: Sequence[vplace.View],
    settings: LayoutSettings,
    *,
    fitted: vplace.Fit | None = None,
    timer: StageTimer | None = None,
    progress: vplace.Progress | None = None,
    match: EeveeMatch | None = None,
    judge_near_field: bool = True,
) -> Laid:
    """The VPLs of ``settings.method`` (the one method dispatch). ``views`` are what the
    regression-guided layout places for and iterates against (views without an indirect image
    give a one-shot layout); ``fitted`` is the model (fitted here when None). The refit fits
    the captured views of ``views``; with ``match``, also ``match.views`` in their place (the
    captures with EEVEE's direct-light deficit added to their targets), and keeps the powers
    whose EEVEE image ``match.error`` predicts the closer (``Laid.match``). With
    ``judge_near_field`` the regression-guided sets take the near-field gather where the
    captures say it helps (:func:`choose_near_field`); without, they stay without it (keyed
    lights: EEVEE's fast GI is one setting for every frame)."""
    timer = timer or quiet_timer()
    n = settings.n_vpls
    radius = settings.radius_in(scene)
    views = list(views)
    profile = settings.profile
    start = time.perf_counter()
    if settings.method == "uniform":
        with timer.stage(f"uniform VPLs (n={n})"):
            vpls = vplace.uniform_vpls(
                scene,
                n,
                seed=settings.seed,
                bounces=vplace.MAX_BOUNCES,
                profile=profile,
                radius=radius,
            )
        return Laid(vpls, layout_seconds=time.perf_counter() - start)
    if settings.method == "rsm":
        with timer.stage(f"RSM VPLs (n={n})"):
            vpls = vplace.rsm_vpls(scene, n, profile=profile, radius=radius)
        return Laid(vpls, layout_seconds=time.perf_counter() - start)
    if fitted is None:
        with timer.stage("fit regression"):
            fitted = fit(scene, views, settings)
    stride = vplace.stride_for(views)  # the iteration's pixels, bounded
    with timer.stage(f"layout (n={n}, alpha={settings.alpha:g})"):
        laid = vplace.layout(
            scene,
            views,
            vplace.LayoutParams(
                budget=n,
                alpha=settings.alpha,
                cell_px=settings.cell_px,
                iterate=settings.iterations > 0,
                iterations=max(settings.iterations, 1),
                seed=settings.seed,
                stride=stride,
                profile=profile,
                radius=radius,
            ),
            fit=fitted,
            progress=progress,
        )
    out = Laid(laid.vpls, layout=laid, layout_seconds=time.perf_counter() - start)
    if settings.method == "vplace+refit" and all(v.has_indirect for v in views):
        with timer.stage("refit VPL powers"):
            start = time.perf_counter()
            out.refit = refit_powers(scene, views, laid.vpls, progress=progress)
            out.refit_seconds = time.perf_counter() - start
        if match is not None:
            with timer.stage("refit VPL powers to EEVEE's direct light"):
                start = time.perf_counter()
                out.match, matched = choose_match(
                    scene, views, laid.vpls, out.refit, match, progress=progress
                )
                if matched is not None:
                    out.refit = matched
                out.refit_seconds += time.perf_counter() - start
        out.vpls = out.refit.vpls
    if judge_near_field and settings.near_field and any(v.has_indirect for v in views):
        with timer.stage("near-field light: with or without"):
            start = time.perf_counter()
            judged = captures_of(views)
            if match is not None and out.match is not None and out.match.kept:
                judged = list(match.views)
            out.near_field = choose_near_field(scene, judged, out.vpls, progress=progress)
            out.vpls = out.vpls.with_near_field(out.near_field.on)
            out.near_field_seconds = time.perf_counter() - start
    return out


#: A hot-spot pixel: its luminance above this many times the truth's plus :data:`HOT_FLOOR`.
HOT_FACTOR = 2.0
#: The absolute floor of a hot-spot pixel (linear radiance, the scene's units).
HOT_FLOOR = 0.05
#: The outlier share: the share of the squared error in this fraction of the worst pixels.
WORST_FRACTION = 0.01


def outliers(image: np.ndarray, truth: np.ndarray) -> dict[str, float]:
    """How much of ``image``'s error sits in a few pixels: ``hot_pixels``, the share of pixels
    whose luminance exceeds :data:`HOT_FACTOR` times the truth's plus :data:`HOT_FLOOR`, and
    ``worst_share``, the share of the squared error (RGB) in the worst :data:`WORST_FRACTION`
    of pixels (0 for a perfect image)."""
    lum = np.asarray(vplace.LUMINANCE, dtype=np.float64)
    a = np.asarray(image, dtype=np.float64)[..., :3]
    b = np.asarray(truth, dtype=np.float64)[..., :3]
    hot = (a @ lum) > HOT_FACTOR * (b @ lum) + HOT_FLOOR
    err = np.sort(((a - b) ** 2).sum(axis=-1).ravel())[::-1]
    total = float(err.sum())
    worst = max(1, math.ceil(WORST_FRACTION * err.size))
    return {
        "hot_pixels": float(hot.mean()),
        "worst_share": float(err[:worst].sum()) / total if total > 0 else 0.0,
    }


#: The parts of :func:`attribute`, in its order.
ATTRIBUTION_PARTS = ("direct", "vpl", "rest")


@dataclass(frozen=True)
class Attribution:
    """Where an EEVEE image of the written lights departs from the truth (:func:`attribute`).

    ``rmse`` and ``share`` are keyed by :data:`ATTRIBUTION_PARTS`: ``direct``, EEVEE's direct
    light (the scene's lights and vplace's stand-ins, VPLs hidden) against Cycles'; ``vpl``,
    EEVEE's VPL light against the evaluator's for the same lights; ``rest``, the evaluator's
    own error (its VPL light plus Cycles' direct light, against the truth). The three parts add
    up to EEVEE's error exactly; a part's share is its projection on that error over the
    error's square (the shares add up to 1; a negative share cancels part of another's)."""

    rmse: dict[str, float]
    share: dict[str, float]
    #: Mean luminance of EEVEE's direct light over Cycles'.
    direct_brightness: float
    #: Mean luminance of EEVEE's VPL light over the evaluator's.
    vpl_brightness: float
    #: :func:`outliers` of EEVEE's VPL light against the evaluator's.
    vpl_hot_pixels: float
    vpl_worst_share: float
    #: SSIM against the truth with one part swapped back: EEVEE's VPL light over Cycles' direct
    #: light (what EEVEE's direct light costs is gone), and EEVEE's direct light plus the
    #: evaluator's VPL light (what EEVEE's VPL light costs is gone); NaN below 11 x 11 pixels.
    ssim_cycles_direct: float
    ssim_evaluator_vpl: float
    #: With a ``seen`` mask (:func:`seen_directly`): the share of pixels where the camera sees
    #: an emitter, the world or a lamp in a mirror, and the share of EEVEE's squared error
    #: that part ``direct`` holds in them (the emitters' edges and patterns, which EEVEE
    #: anti-aliases its own way, not light on surfaces); NaN without a mask.
    seen_pixels: float = float("nan")
    seen_share: float = float("nan")
    #: With ``stand_ins`` (Cycles rendering the same direct lights EEVEE renders): part
    #: ``direct`` split in two. ``stand_in_share`` is the share of EEVEE's squared error that
    #: the stand-ins' own light holds (``stand_ins - cycles_direct``: what vplace writes in
    #: place of the emissive meshes, the sky and the world's sun, however well rendered, and the
    #: sampling noise of both Cycles images); the rest of part ``direct``
    #: (``eevee_direct - stand_ins``) is EEVEE's rendering of those lights: its shadow maps,
    #: film and texture filtering. ``stand_in_rmse`` is the first's RMSE; NaN without.
    stand_in_share: float = float("nan")
    stand_in_rmse: float = float("nan")
    #: :func:`outliers`' hot-pixel share of the same two swaps as ``ssim_cycles_direct`` and
    #: ``ssim_evaluator_vpl``: EEVEE's VPL light over Cycles' direct light (the hot pixels that
    #: stay are the VPL light's), and EEVEE's direct light plus the evaluator's VPL light (those
    #: that stay are EEVEE's direct light's or the evaluator's own).
    hot_cycles_direct: float = float("nan")
    hot_evaluator_vpl: float = float("nan")
    #: With a ``cut`` mask (:func:`cut_by_lights`): the share of pixels whose surface's plane
    #: cuts one of the scene's lights (EEVEE's soft shadows darken them), the share of EEVEE's
    #: squared error that EEVEE's rendering of the lights holds in them (its direct light minus
    #: Cycles' render of the same lights: the stand-ins' where given, else Cycles' direct light),
    #: and EEVEE's direct light over that render there (mean luminance); NaN without a mask (the
    #: brightness also where no pixel is cut).
    cut_pixels: float = float("nan")
    cut_share: float = float("nan")
    cut_brightness: float = float("nan")
    #: With a ``colour`` part (:func:`colour_part`): the share of EEVEE's squared error that the
    #: surfaces' colour as EEVEE filters it holds (Cycles' diffuse light times EEVEE's Diffuse
    #: Color minus Cycles': its textures' mipmaps and its film filter at the edges), and that
    #: part's RMSE; NaN without.
    colour_share: float = float("nan")
    colour_rmse: float = float("nan")

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready."""
        return asdict(self)


#: A pixel is "seen directly" (:func:`seen_directly`) where the emission and the world the
#: camera sees make at least this share of Cycles' direct light there.
SEEN_SHARE = 0.5


def seen_directly(seen_light: np.ndarray, direct: np.ndarray) -> np.ndarray:
    """(H, W) bool: the pixels where the camera sees an emitter, the world or a lamp in a
    mirror, from Cycles' ``Emit + Env`` passes plus the glossy direct light of a lamp's mirror
    image (``seen_light``: the add-on's ``Capture.seen_light``) and its direct light (both
    (H, W, 3)): where their luminance is positive and at least :data:`SEEN_SHARE` of the
    direct light's."""
    a = np.asarray(seen_light, dtype=np.float64)
    b = np.asarray(direct, dtype=np.float64)
    if a.shape != b.shape or a.ndim != 3 or a.shape[-1] < 3:
        raise ValueError(
            f"seen_directly needs two (H, W, 3) images of one shape, got {a.shape}, {b.shape}"
        )
    lum = np.asarray(vplace.LUMINANCE, dtype=np.float64)
    la, lb = a[..., :3] @ lum, b[..., :3] @ lum
    return (la > 0.0) & (la >= SEEN_SHARE * lb)


@dataclass(frozen=True)
class LightShape:
    """A light's emitting shape, as :func:`cut_by_lights` tests it: points on its outline
    ((K, 3): an area light's edges, a sphere light's surface), its centre (3,) and the unit
    direction it emits towards (an area light's front), None where it lights every side."""

    outline: np.ndarray
    centre: np.ndarray
    facing: np.ndarray | None = None


def cut_by_lights(
    position: np.ndarray, normal: np.ndarray, shapes: Sequence[LightShape], tolerance: float
) -> np.ndarray:
    """(...) bool, for points ``position`` with unit normals ``normal`` (both (..., 3)): the
    points whose tangent plane cuts one of ``shapes``, with part of it in front of the plane
    and part behind, each by more than ``tolerance`` times the shape's radius (the farthest
    outline point from its centre), and the point in front of the light by as much (for a
    light that faces one way).

    EEVEE darkens such a point: its soft shadow traces rays to points all over the light, and
    the rays to the part behind the surface's own plane start into the surface and count as
    shadowed, on top of the part its shading already leaves out. Measured (Blender 5.0, four
    shadow rays): the Cornell box's tall block, whose faces' planes pass through the ceiling
    lamp, gets 0.80x Cycles' direct light in EEVEE, and 1.025x with the lamp's shadow off;
    every other surface 1.00x (``docs/EEVEE_NOTES.md``, Q11). A zero normal cuts nothing."""
    x = np.asarray(position, dtype=np.float64)
    n = np.asarray(normal, dtype=np.float64)
    if x.shape != n.shape or x.ndim < 1 or x.shape[-1] != 3:
        raise ValueError(
            f"cut_by_lights needs positions and normals of one shape (..., 3), got {x.shape}, "
            f"{n.shape}"
        )
    if not (np.isfinite(tolerance) and tolerance >= 0.0):
        raise ValueError(f"cut_by_lights: the tolerance must be finite and >= 0, got {tolerance}")
    if not (np.isfinite(x).all() and np.isfinite(n).all()):
        raise ValueError("cut_by_lights: the positions or normals hold NaN or infinity")
    out = np.zeros(x.shape[:-1], dtype=bool)
    has_normal = (n * n).sum(-1) > 0.25
    height = (x * n).sum(-1)
    for shape in shapes:
        outline = np.asarray(shape.outline, dtype=np.float64).reshape(-1, 3)
        if len(outline) == 0:
            continue
        centre = np.asarray(shape.centre, dtype=np.float64)
        margin = tolerance * float(np.sqrt(((outline - centre) ** 2).sum(-1).max()))
        lowest = np.full(out.shape, np.inf)
        highest = np.full(out.shape, -np.inf)
        for p in outline:
            d = n @ p - height
            np.minimum(lowest, d, out=lowest)
            np.maximum(highest, d, out=highest)
        cut = has_normal & (lowest < -margin) & (highest > margin)
        if shape.facing is not None:
            cut &= (x - centre) @ np.asarray(shape.facing, dtype=np.float64) > margin
        out |= cut
    return out


#: The share of a light's light on the surfaces tested, in the points whose plane cuts it
#: (:func:`cut_share`), from which EEVEE's darkening of them is worth making up for. EEVEE gives
#: those points 0.80-0.90x Cycles' light (``docs/EEVEE_NOTES.md``, Q11), so at 1 % the
#: shortfall is 0.1-0.2 % of the light on the surfaces. The Cornell box's cameras see 5.9-47 %
#: of their direct light on the blocks' cut faces; a sphere under a lamp has its planes pass
#: through the lamp only along its terminator, lit at grazing angles (0.04 % of a room's direct
#: light under a spot lamp).
CUT_SHARE = 0.01


def cut_share(
    position: np.ndarray,
    normal: np.ndarray,
    weight: np.ndarray,
    shape: LightShape,
    tolerance: float,
) -> float:
    """The share of ``weight`` ((...) float, >= 0: the light on each point, a capture's
    direct light) held by the points whose plane cuts ``shape`` (:func:`cut_by_lights`);
    0 where the weights sum to 0. How much of a light EEVEE's darkening can touch: a plane
    through a lamp at one grazing point is no cause to render EEVEE's direct light."""
    w = np.asarray(weight, dtype=np.float64)
    if w.shape != np.shape(position)[:-1]:
        raise ValueError(
            f"cut_share needs one weight per point, got {w.shape} for {np.shape(position)}"
        )
    if not (np.isfinite(w).all() and (w >= 0.0).all()):
        raise ValueError("cut_share: the weights must be finite and >= 0")
    total = float(w.sum())
    if total <= 0.0:
        return 0.0
    return float(w[cut_by_lights(position, normal, [shape], tolerance)].sum()) / total


def _box_sums(a: np.ndarray, size: int) -> np.ndarray:
    """The sum of ``a`` ((H, W) or (H, W, C)) over the ``size`` x ``size`` box around each
    pixel, cut at the image's edges (a summed-area table)."""
    h, w = a.shape[:2]
    table = np.zeros((h + 1, w + 1, *a.shape[2:]), dtype=np.float64)
    table[1:, 1:] = a.cumsum(axis=0).cumsum(axis=1)
    before = size // 2
    y, x = np.arange(h), np.arange(w)
    y0, y1 = np.clip(y - before, 0, h), np.clip(y - before + size, 0, h)
    x0, x1 = np.clip(x - before, 0, w), np.clip(x - before + size, 0, w)
    return table[y1][:, x1] - table[y0][:, x1] - table[y1][:, x0] + table[y0][:, x0]


def eevee_deficit(
    cycles_direct: np.ndarray, eevee_direct: np.ndarray, mask: np.ndarray, size: int
) -> np.ndarray:
    """(H, W, 3) float32: what EEVEE's direct light lacks against Cycles' in one view (both
    (H, W, 3)), the smooth part only: ``cycles_direct - eevee_direct`` averaged over the
    ``mask``ed pixels (the surfaces, not the emitters or the world seen directly) of the
    ``size`` x ``size`` box around each pixel; 0 outside the mask. Negative where EEVEE is the
    brighter. The VPLs' light is smooth: the sharp rest (a sun patch's edge, a texture EEVEE
    filters its own way) their powers cannot follow, and fitting it would only pull the refit
    around (README, "Can the VPL powers make up for EEVEE's direct light?")."""
    a = np.asarray(cycles_direct, dtype=np.float64)
    b = np.asarray(eevee_direct, dtype=np.float64)
    m = np.asarray(mask)
    if a.shape != b.shape or a.ndim != 3 or a.shape[-1] < 3 or m.shape != a.shape[:2]:
        raise ValueError(
            "eevee_deficit needs two (H, W, 3) images and an (H, W) mask of one size, got "
            f"{a.shape}, {b.shape}, {m.shape}"
        )
    if size < 1:
        raise ValueError(f"eevee_deficit: the box's size must be at least 1 pixel, got {size}")
    weight = m.astype(bool).astype(np.float64)
    diff = (a[..., :3] - b[..., :3]) * weight[..., None]
    if not np.isfinite(diff).all():
        raise ValueError("eevee_deficit: the images hold NaN or infinite values")
    count = _box_sums(weight, size)
    mean = _box_sums(diff, size) / np.maximum(count, 1.0)[..., None]
    return (mean * weight[..., None]).astype(np.float32)


def colour_part(
    diffuse_light: np.ndarray, eevee_colour: np.ndarray, cycles_colour: np.ndarray
) -> np.ndarray:
    """(H, W, 3) float64: the part of EEVEE's direct-light error that is the surfaces' colour as
    EEVEE filters it, ``diffuse_light * (eevee_colour - cycles_colour)``: Cycles' Diffuse
    Direct pass (the light, without the colour) times the difference of the two renders'
    Diffuse Color passes (all (H, W, 3) of one shape). EEVEE samples textures through their
    mipmaps and filters its film with a Gaussian where the truth has a one-pixel box, so the
    edges of everything, and a rug's pattern in a sun patch, differ under the same light
    (``docs/EEVEE_NOTES.md``, Q11)."""
    arrays = [np.asarray(a, dtype=np.float64) for a in (diffuse_light, eevee_colour, cycles_colour)]
    if (
        any(a.ndim != 3 or a.shape[-1] < 3 for a in arrays)
        or len({a[..., :3].shape for a in arrays}) != 1
    ):
        shapes = ", ".join(str(a.shape) for a in arrays)
        raise ValueError(f"colour_part needs three (H, W, 3) images of one shape, got {shapes}")
    light, ee, cy = (a[..., :3] for a in arrays)
    if not all(np.isfinite(a).all() for a in (light, ee, cy)):
        raise ValueError("colour_part: the images hold NaN or infinity")
    return light * (ee - cy)


def _rgb_like(name: str, image: np.ndarray | None, shape: tuple[int, ...]) -> np.ndarray | None:
    """``image`` checked as :func:`attribute`'s (H, W, 3) image ``name`` of ``shape``, finite,
    as float64 RGB (None stays None)."""
    if image is None:
        return None
    a = np.asarray(image, dtype=np.float64)
    if a.ndim != 3 or a.shape[-1] < 3 or a[..., :3].shape != shape:
        raise ValueError(
            f"attribute: {name} must be an (H, W, 3) image of shape {shape}, got {a.shape}"
        )
    a = a[..., :3]
    if not np.isfinite(a).all():
        raise ValueError(f"attribute: {name} holds NaN or infinity")
    return a


def _pixel_mask(name: str, mask: np.ndarray | None, shape: tuple[int, ...]) -> np.ndarray | None:
    """``mask`` checked as :func:`attribute`'s (H, W) bool mask ``name`` (None stays None)."""
    if mask is None:
        return None
    m = np.asarray(mask)
    if m.dtype != np.bool_ or m.shape != shape:
        raise ValueError(
            f"attribute: {name} must be an (H, W) = {shape} bool mask, got {m.dtype} {m.shape}"
        )
    return m


def attribute(
    eevee: np.ndarray,
    eevee_direct: np.ndarray,
    cycles_direct: np.ndarray,
    evaluator_vpl: np.ndarray,
    truth: np.ndarray,
    seen: np.ndarray | None = None,
    stand_ins: np.ndarray | None = None,
    cut: np.ndarray | None = None,
    colour: np.ndarray | None = None,
) -> Attribution:
    """Splits ``eevee - truth`` (RGB images of one view, the same shape) into the three parts of
    :class:`Attribution`: ``eevee_direct - cycles_direct``, ``(eevee - eevee_direct) -
    evaluator_vpl`` and ``cycles_direct + evaluator_vpl - truth``. EEVEE adds lights linearly,
    so ``eevee - eevee_direct`` is its image of the VPLs alone (up to its sampling noise).
    ``seen`` ((H, W) bool, :func:`seen_directly`) marks the pixels where the camera sees an
    emitter, the world or a lamp in a mirror: how much of part ``direct`` lies there is
    ``seen_share``.
    ``stand_ins`` (RGB, the same shape: Cycles rendering the lights EEVEE's direct light comes
    from) splits part ``direct`` into the stand-ins' own error and EEVEE's rendering of them
    (``stand_in_share``).
    ``cut`` ((H, W) bool, :func:`cut_by_lights`) marks the pixels whose surface's plane cuts a
    light: how much of EEVEE's rendering error lies there, and how bright EEVEE's direct light
    is there, are ``cut_share`` and ``cut_brightness``, both against Cycles' render of the same
    lights (``stand_ins`` where given, else ``cycles_direct``): the stand-ins' own error in
    those pixels is not EEVEE's darkening.
    ``colour`` (RGB, the same shape: :func:`colour_part`) is the part of ``eevee_direct -
    cycles_direct`` that EEVEE's filtering of the surfaces' colour makes (``colour_share``)."""
    arrays = [eevee, eevee_direct, cycles_direct, evaluator_vpl, truth]
    e, ed, cd, vx, t = (np.asarray(a, dtype=np.float64)[..., :3] for a in arrays)
    if not e.shape == ed.shape == cd.shape == vx.shape == t.shape or e.ndim != 3:
        shapes = ", ".join(str(np.shape(a)) for a in arrays)
        raise ValueError(f"attribute needs five (H, W, 3) images of one shape, got {shapes}")
    if not all(np.isfinite(a).all() for a in (e, ed, cd, vx, t)):
        raise ValueError("attribute: an image holds NaN or infinity")
    seen = _pixel_mask("seen", seen, e.shape[:2])
    cut = _pixel_mask("cut", cut, e.shape[:2])
    col = _rgb_like("colour", colour, e.shape)
    si = _rgb_like("stand_ins", stand_ins, e.shape)
    ve = e - ed
    parts = {"direct": ed - cd, "vpl": ve - vx, "rest": cd + vx - t}
    total = e - t
    sq = float((total * total).sum())
    model = si - cd if si is not None else None
    # The lights EEVEE renders, rendered by Cycles: what EEVEE's darkening is measured against.
    same = si if si is not None else cd
    lum = np.asarray(vplace.LUMINANCE, dtype=np.float64)

    def share_of(part: np.ndarray) -> float:
        """``part``'s projection on EEVEE's error over the error's square."""
        return float((part * total).sum()) / sq if sq > 0 else 0.0

    def ratio(a: np.ndarray, b: np.ndarray) -> float:
        below = float((b @ lum).mean())
        return float((a @ lum).mean()) / below if below > 1e-12 else float("nan")

    vpl_out = outliers(ve, vx)

    def ssim(image: np.ndarray) -> float:
        if min(t.shape[:2]) < 11:
            return float("nan")
        return vplace.ssim(
            np.ascontiguousarray(image, np.float32), np.ascontiguousarray(t, np.float32)
        )

    return Attribution(
        rmse={k: float(np.sqrt((d * d).mean())) for k, d in parts.items()},
        share={k: share_of(d) for k, d in parts.items()},
        direct_brightness=ratio(ed, cd),
        vpl_brightness=ratio(ve, vx),
        vpl_hot_pixels=vpl_out["hot_pixels"],
        vpl_worst_share=vpl_out["worst_share"],
        ssim_cycles_direct=ssim(cd + ve),
        ssim_evaluator_vpl=ssim(ed + vx),
        seen_pixels=float(seen.mean()) if seen is not None else float("nan"),
        seen_share=share_of(parts["direct"] * seen[..., None]) if seen is not None else math.nan,
        cut_pixels=float(cut.mean()) if cut is not None else math.nan,
        cut_share=share_of((ed - same) * cut[..., None]) if cut is not None else math.nan,
        cut_brightness=ratio(ed[cut], same[cut]) if cut is not None and cut.any() else math.nan,
        colour_share=share_of(col) if col is not None else math.nan,
        colour_rmse=float(np.sqrt((col * col).mean())) if col is not None else math.nan,
        stand_in_share=share_of(model) if model is not None else math.nan,
        stand_in_rmse=float(np.sqrt((model * model).mean())) if model is not None else float("nan"),
        hot_cycles_direct=outliers(cd + ve, t)["hot_pixels"],
        hot_evaluator_vpl=outliers(ed + vx, t)["hot_pixels"],
    )


def score(
    image: np.ndarray,
    truth: np.ndarray,
    *,
    other: np.ndarray | None = None,
    image_other: np.ndarray | None = None,
) -> dict[str, float]:
    """RMSE, relative MSE (linear HDR), SSIM (display luminance) of ``image`` against ``truth``,
    its brightness (mean luminance over the truth's) and its :func:`outliers`; SSIM is NaN
    below 11 x 11 pixels. ``other``, a second render of the truth with another seed, adds
    ``ssim_noise_free`` and ``rmse_noise_free``: SSIM and RMSE against the noise-free truth
    (:func:`vplace.ssim_noise_free`, NaN below 11 x 11 pixels; :func:`vplace.rmse_noise_free`,
    with ``image_other``: the same image built on ``other``'s passes where ``image`` is built on
    ``truth``'s, else ``image`` itself)."""
    image = np.ascontiguousarray(image, dtype=np.float32)
    truth = np.ascontiguousarray(truth, dtype=np.float32)
    sized = min(truth.shape[:2]) >= 11
    ssim = vplace.ssim(image, truth) if sized else float("nan")
    lum = np.asarray(vplace.LUMINANCE)
    mean_truth = max(float((truth[..., :3] @ lum).mean()), 1e-12)
    out = {
        "rmse": vplace.rmse(image, truth),
        "relative_mse": vplace.relative_mse(image, truth),
        "ssim": ssim,
        "brightness": float((image[..., :3] @ lum).mean()) / mean_truth,
        **outliers(image, truth),
    }
    if other is not None:
        other = np.ascontiguousarray(other, dtype=np.float32)
        out["ssim_noise_free"] = (
            vplace.ssim_noise_free(image, truth, other) if sized else float("nan")
        )
        twin = image if image_other is None else np.ascontiguousarray(image_other, np.float32)
        out["rmse_noise_free"] = vplace.rmse_noise_free(image, truth, twin, other)
    return out


def score_over_direct(
    indirect: np.ndarray,
    direct: np.ndarray,
    truth: np.ndarray,
    *,
    other: tuple[np.ndarray, np.ndarray] | None = None,
) -> dict[str, float]:
    """The evaluator's image, the truth's ``direct`` light plus ``indirect``, scored against
    ``truth`` (:func:`score`). ``other``: the second render's (direct, global illumination); its
    noise-free RMSE then pairs the image with its twin on that render, ``other`` direct plus
    ``indirect``, since the image shares the first render's noise."""
    image = direct + indirect
    if other is None:
        return score(image, truth)
    return score(image, truth, other=other[1], image_other=other[0] + indirect)


@dataclass
class Reference:
    """What a run is scored against: a Cycles render of a view, as arrays (its G-buffer is the
    view the evaluator shades), and what it is, in words."""

    view: vplace.View
    #: (H, W, 3) direct light and global illumination (direct + indirect) of the render.
    direct: np.ndarray
    gi: np.ndarray
    #: (H, W, 3) the indirect light vplace models (diffuse, and the rough glossy layers).
    modelled_indirect: np.ndarray
    label: str
    #: The camera's name and the render's samples.
    camera: str = ""
    samples: int = 0
    #: (H, W) bool, the pixels where the camera sees an emitter, the world or a lamp in a mirror
    #: (:func:`seen_directly`); None where the render's passes do not say.
    seen: np.ndarray | None = None
    #: (H, W, 3) the render's Diffuse Direct (the light, without the colour) and Diffuse Color
    #: passes, for :func:`colour_part`; None where the render's passes do not say.
    diffuse_direct: np.ndarray | None = None
    diffuse_color: np.ndarray | None = None


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
        """The VPLs to write (refitted when the method refits)."""
        return self.laid.vpls


def compute(
    scene: vplace.Scene,
    views: Sequence[vplace.View],
    settings: LayoutSettings,
    reference: Reference,
    *,
    timer: StageTimer | None = None,
    progress: vplace.Progress | None = None,
    fitted: vplace.Fit | None = None,
    match: EeveeMatch | None = None,
) -> Computed:
    """:func:`fit` (unless ``fitted``), :func:`lay_out` (its refit matching EEVEE's direct
    light with ``match`` where that helps), the evaluator on the reference view and the
    metrics against it."""
    timer = timer or quiet_timer()
    if fitted is None:
        with timer.stage("fit regression"):
            fitted = fit(scene, views, settings)
    laid = lay_out(
        scene,
        views,
        settings,
        fitted=fitted,
        timer=timer,
        progress=progress,
        match=match,
    )
    with timer.stage("evaluate VPLs"):
        indirect, stats = vplace.evaluate(scene, reference.view, laid.vpls, progress=progress)
    direct, gi = reference.direct, reference.gi
    ours = score(direct + indirect, gi)
    base = score(direct, gi)
    metrics = {
        **ours,
        **{f"{k}_direct_only": v for k, v in base.items()},
        "rmse_indirect": vplace.rmse(indirect, reference.modelled_indirect),
    }
    return Computed(laid, indirect, stats, metrics, fitted)


@dataclass
class FitSummary:
    """The fit's figures for reports and the panel."""

    r2: float
    adjusted_r2: float | None
    view_r2: dict[str, float | None]
    kept: list[str]
    weights: dict[str, float]
    #: Each dropped feature with the reason.
    dropped: dict[str, str]

    @classmethod
    def of(cls, fitted: vplace.Fit) -> FitSummary:
        """The summary of a fitted model."""
        return cls(
            fitted.r2,
            fitted.adjusted_r2,
            fitted.view_r2,
            fitted.kept,
            fitted.weights,
            fitted.dropped,
        )


@dataclass
class EvaluatorSummary:
    """The evaluator's work on the reference view, and the layout's iteration and refit."""

    shadow_rays: int
    pairs: int
    seconds: float
    rays_per_second: float
    #: The layout's error per iteration and the best one (vplace methods).
    iteration_errors: list[float] | None = None
    best_iteration: int | None = None
    #: The refit's error before and after (``vplace+refit``).
    refit_error: list[float] | None = None
    #: The refit's ridge and its cross-validation: ``[ridge, held-out RMSE]`` per ridge tried.
    refit_ridge: float | None = None
    refit_cv: list[list[float]] | None = None
    #: What the refit pulled the powers toward (1: the light-path powers; else the captures'
    #: gain, taken where the cross-validation preferred it) and that pull's validation.
    refit_gain: float | None = None
    refit_gain_cv: list[list[float]] | None = None
    #: Where the refit weighed its captured views unequally, the weight of each one's pixels
    #: (``Refit.view_weights``: the inverse of its light), by view name.
    refit_view_weights: dict[str, float] | None = None
    #: Whether the lights' light includes the near-field gather (:func:`choose_near_field`):
    #: ``on``, the captures' luminance RMSE ``without`` and ``with_gather``, the ``distance``.
    near_field: dict[str, Any] | None = None

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready, without the figures a method does not have."""
        return {k: v for k, v in asdict(self).items() if v is not None}


@dataclass
class Baseline:
    """Another method scored beside the job's, at the same budget."""

    metrics: dict[str, float]
    seconds: float


@dataclass
class ReferenceInfo:
    """What the images were scored against."""

    label: str
    samples: int
    view: str


@dataclass
class RegionSummary:
    """The region the lights were laid out for (``vplace.coverage``): the coverage views added,
    the region's radius around each camera (metres), the share of the region's surfaces the
    cameras' captures see and the share with the coverage views, and the seconds of the pick."""

    views: int
    radius_m: list[float]
    covered_before: float
    covered_after: float
    seconds: float

    def lines(self) -> list[str]:
        """The region in lines short enough for a panel row."""
        cameras = len(self.radius_m)
        radii = ", ".join(f"{r:.3g}" for r in self.radius_m)
        return [
            f"Region: {self.views} coverage view{'s' * (self.views != 1)} around "
            f"{cameras} camera{'s' * (cameras != 1)} (radius {radii} m)",
            f"  its surfaces seen: {markdown.percent(self.covered_before)} by the cameras, "
            f"{markdown.percent(self.covered_after)} with the coverage views",
        ]


@dataclass
class JobSummary:
    """One run: the scene, the settings, the stage times, the evaluator and the scores. The
    main job adds the reference, the EEVEE scores, the baselines and its files."""

    scene: str
    triangles: int
    lights: int
    views: list[str]
    skipped_views: dict[str, str]
    resolution: list[int]
    samples: int
    capture_render_seconds: float
    n_vpls: int
    lights_written: int
    emitter_lights_written: int
    method: str
    alpha: float
    iterations: int
    profile: str
    radius: float
    seed: int
    stage_seconds: dict[str, float]
    evaluator: EvaluatorSummary
    metrics: dict[str, float]
    #: Sky portals written (``addon.writeback.portals``): AREA lights in the openings that
    #: carry the sky in for EEVEE.
    portals_written: int = 0
    #: The cameras work in a closed room (no ray from their eyes leaves the scene): EEVEE's
    #: world lights nothing, as Cycles' lights nothing inside (``addon.writeback.stand_ins``).
    world_closed: bool = False
    #: Whether a SUN light stands in for the world's sun (``addon.writeback.stand_ins``).
    sun_written: bool = False
    #: The scene's working scale and its bounds' diagonal, scene units (``Scene.scale``,
    #: ``Scene.diagonal``): the scale is less where the cameras see a small part of the scene.
    working_scale: float = 0.0
    bounds_diagonal: float = 0.0
    #: Metres per scene unit (Blender's Unit Scale): the report writes lengths in metres.
    unit_scale: float = 1.0
    #: The coverage views rendered by Cycles (``coverage.RENDERED_PREFIX``), fitted as captures
    #: beside :attr:`views`, the user's.
    region_views: list[str] = field(default_factory=list)
    #: The region the lights were laid out for; None without coverage views.
    region: RegionSummary | None = None
    fit: FitSummary | None = None
    #: "Match EEVEE's direct light": per captured view the refit made up for, the mean of
    #: :func:`eevee_deficit` over the mean of Cycles' direct light (luminance; negative where
    #: EEVEE's direct light is the brighter). Empty when the job did not match.
    eevee_matched: dict[str, float] = field(default_factory=dict)
    #: Where the job asked to match: whether the refit kept it and EEVEE's predicted RMSE on
    #: the matched views with and without (:class:`MatchChoice`, as a dict); None otherwise.
    eevee_match: dict[str, Any] | None = None
    reference: ReferenceInfo | None = None
    eevee: dict[str, float] | None = None
    eevee_problems: list[str] = field(default_factory=list)
    #: What EEVEE shows of the user's own lamps differently from Cycles (the user's to change).
    eevee_lamp_notes: list[str] = field(default_factory=list)
    baselines: dict[str, Baseline] = field(default_factory=dict)
    files: list[str] = field(default_factory=list)

    def set_match(self, matched: dict[str, float], choice: MatchChoice | None) -> None:
        """Puts "Match EEVEE's direct light" in: ``matched`` (per captured view, the deficit
        the refit was offered) where the refit kept it (``choice``, ``Laid.match``), else
        nothing; and the choice itself."""
        self.eevee_matched = matched if choice is not None and choice.kept else {}
        self.eevee_match = asdict(choice) if choice is not None else None

    def to_dict(self, *, main_job: bool = False) -> dict[str, Any]:
        """JSON-ready; the main job's fields only with ``main_job``."""
        out = asdict(self)
        out["evaluator"] = self.evaluator.to_dict()
        if not main_job:
            # The panel keeps EEVEE's scores when "Check in EEVEE" made them.
            dropped = ["reference", "eevee_problems", "eevee_lamp_notes", "baselines", "files"]
            for key in dropped + (["eevee"] if self.eevee is None else []):
                del out[key]
        return out


@dataclass
class PanelReport:
    """What the panel shows of the last run (``Scene.vplace.last_report``, JSON): read by
    attribute, every part optional (a Fit alone stores no metrics)."""

    n_vpls: int = 0
    profile: str = ""
    metrics: dict[str, float] = field(default_factory=dict)
    fit: FitSummary | None = None
    stage_seconds: dict[str, float] = field(default_factory=dict)
    #: EEVEE's scores of the written lights ("Check in EEVEE"; ``JobSummary.eevee``).
    eevee: dict[str, float] = field(default_factory=dict)
    #: "Match EEVEE's direct light" (``JobSummary.eevee_matched``, ``JobSummary.eevee_match``).
    eevee_matched: dict[str, float] = field(default_factory=dict)
    eevee_match: dict[str, Any] | None = None
    #: The region the lights were laid out for (``JobSummary.region``).
    region: RegionSummary | None = None

    @classmethod
    def from_json(cls, text: str) -> PanelReport | None:
        """The report stored as ``text``; None when nothing is stored."""
        if not text:
            return None
        data = json.loads(text)
        fit = data.get("fit")
        region = data.get("region")
        return cls(
            n_vpls=data.get("n_vpls", 0),
            profile=data.get("profile", ""),
            metrics=data.get("metrics") or {},
            fit=FitSummary(**fit) if fit else None,
            stage_seconds=data.get("stage_seconds") or {},
            eevee=data.get("eevee") or {},
            eevee_matched=data.get("eevee_matched") or {},
            eevee_match=data.get("eevee_match"),
            region=RegionSummary(**region) if region else None,
        )

    def eevee_lines(self) -> list[str]:
        """What "Check in EEVEE" found, in lines short enough for a panel row: EEVEE's score
        against the capture beside the evaluator's, EEVEE's direct light against Cycles', and
        whose part EEVEE's error is (``attribute``): its direct light, split into vplace's
        stand-ins and EEVEE's rendering of the lights (not vplace's), its VPL light against
        the evaluator's, and the evaluator's own. Empty without a check."""
        e = self.eevee
        if not e:
            return []
        rmse = self.metrics.get("rmse")
        evaluator = f" (evaluator {rmse:.4f})" if rmse is not None else ""
        lines = [f"EEVEE: SSIM {e['ssim']:.3f}, RMSE {e['rmse']:.4f}{evaluator}"]
        if "direct_brightness" in e:
            lines.append(f"EEVEE's direct light: {e['direct_brightness']:.2f}x Cycles'")
        if "attribution_share_direct" in e:
            direct = e["attribution_share_direct"]
            lines.append(f"Of EEVEE's error, {markdown.percent(direct)} is its direct light:")
            model = e.get("attribution_stand_in_share")
            if model is not None and math.isfinite(model):
                lines.append(
                    f"  {markdown.percent(model)} vplace's stand-ins, "
                    f"{markdown.percent(direct - model)} EEVEE's rendering (not vplace's)"
                )
            colour = e.get("attribution_colour_share")
            if colour is not None and math.isfinite(colour):
                lines.append(
                    f"  {markdown.percent(colour)} the surfaces' colour as EEVEE filters it"
                )
            cut = e.get("attribution_cut_share")
            if cut is not None and math.isfinite(cut) and e.get("attribution_cut_pixels", 0) > 0:
                lines.append(
                    f"  {markdown.percent(cut)} where a surface's plane cuts a light "
                    f"({e['attribution_cut_brightness']:.2f}x Cycles' there)"
                )
            lines.append(
                f"{markdown.percent(e['attribution_share_vpl'])} its VPL light, "
                f"{markdown.percent(e['attribution_share_rest'])} the evaluator's own"
            )
        return lines


def compute_with_baselines(
    scene: vplace.Scene,
    views: Sequence[vplace.View],
    settings: LayoutSettings,
    reference: Reference,
    baselines: Sequence[str],
    *,
    timer: StageTimer | None = None,
    match: EeveeMatch | None = None,
) -> tuple[Computed, dict[str, Baseline]]:
    """:func:`compute` for the settings' method (with ``match`` when given), then each other
    method of ``baselines`` at the same budget, with the same fit and reference, timed apart
    and quietly."""
    computed = compute(scene, views, settings, reference, timer=timer, match=match)
    compared = {}
    for method in (b for b in baselines if b != settings.method):
        quiet = quiet_timer()
        other = compute(
            scene,
            views,
            replace(settings, method=method),
            reference,
            timer=quiet,
            fitted=computed.fit,
        )
        compared[method] = Baseline(other.metrics, sum(quiet.seconds.values()))
    return computed, compared


def write_files(
    out_dir: Path,
    summary: JobSummary,
    reference: Reference,
    computed: Computed,
    cell_px: int,
    log: Callable[[str], None] = print,
) -> None:
    """The main job's files in ``out_dir``: the reference's GI and direct light and the
    evaluator's image as PNG, the VPLs as CSV, the model as JSON, and the summary as JSON and
    Markdown (``summary.files`` is set to every file of the folder); ``cell_px`` is the fit's
    cell size, for the log."""
    images.save_png(out_dir / "cycles_gi.png", reference.gi)
    images.save_png(out_dir / "direct.png", reference.direct)
    images.save_png(out_dir / "direct_plus_vpl.png", reference.direct + computed.indirect)
    vpls = computed.vpls
    np.savetxt(
        out_dir / "vpls.csv",
        np.hstack([vpls.position, vpls.normal, vpls.flux, vpls.radii[:, None]]),
        delimiter=",",
        header="x,y,z,nx,ny,nz,flux_r,flux_g,flux_b,radius",
        comments="",
        fmt="%.6g",
    )
    if computed.fit is not None:
        (out_dir / "model.json").write_text(computed.fit.to_json())
        log(f"[vplace] fitted model (cells of {cell_px} px):\n{computed.fit}")
    summary.files = sorted({*(p.name for p in out_dir.iterdir() if p.is_file()), "report.json"})
    (out_dir / "report.json").write_text(json.dumps(summary.to_dict(main_job=True), indent=2))
    text = job_report(summary)
    (out_dir / "report.md").write_text(text)
    log(text)


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


#: EEVEE's direct light is called out when its brightness is this far from Cycles'.
DIRECT_NOTE = 0.05


def eevee_notes(e: dict[str, float], stand_ins: int = 0) -> list[str]:
    """What the main job says of EEVEE's image beyond its scores: how its direct light compares
    with Cycles', and where its error comes from. ``stand_ins``: the lights vplace wrote beside
    the VPLs (emissive meshes, the sun, sky portals); EEVEE's direct light is then partly
    vplace's, and the note says so rather than calling it Blender's alone."""
    lines = []
    d = e.get("direct_brightness")
    if d is not None:
        line = (
            f"EEVEE's own direct light (the scene's lights and vplace's stand-ins, VPLs hidden) "
            f"is {d:.2f}x Cycles'"
        )
        if abs(d - 1.0) > DIRECT_NOTE:
            line += (
                f": this part of EEVEE's difference is not the VPLs' but how EEVEE lights the "
                f"scene's lamps and vplace's {stand_ins} stand-in light{'s' * (stand_ins != 1)}"
                if stand_ins
                else ": this part of EEVEE's difference is Blender's, not vplace's"
            )
        lines.append(line + ".")
    if "attribution_share_vpl" in e:
        parts = ", ".join(
            f"{name} {e[f'attribution_rmse_{key}']:.4f} "
            f"({markdown.percent(e[f'attribution_share_{key}'], signed=True)})"
            for key, name in (
                ("direct", "EEVEE's direct light against Cycles'"),
                ("vpl", "EEVEE's VPL light against the evaluator's"),
                ("rest", "the evaluator's own error"),
            )
        )
        line = f"EEVEE's error, RMSE by part (share of its squared error): {parts}"
        seen = e.get("attribution_seen_share")
        if seen is not None and math.isfinite(seen) and e.get("attribution_seen_pixels", 0) > 0:
            line += (
                f"; of EEVEE's squared error, {markdown.percent(seen)} is its direct light in the "
                f"{e['attribution_seen_pixels']:.1%} of pixels that see an emitter, the world "
                "or a lamp in a mirror (their edges and patterns, anti-aliased EEVEE's way: not "
                "light on surfaces)"
            )
        model = e.get("attribution_stand_in_share")
        if model is not None and math.isfinite(model):
            rendering = e["attribution_share_direct"] - model
            line += (
                f"; {markdown.percent(model)} is vplace's stand-ins' own light against Cycles' "
                f"direct light (Cycles rendering them), {markdown.percent(rendering)} EEVEE's "
                "rendering of the lights"
            )
        line += _cut_clause(e)
        colour = e.get("attribution_colour_share")
        if colour is not None and math.isfinite(colour):
            line += (
                f"; {markdown.percent(colour)} is the surfaces' colour as EEVEE filters it "
                "(its Diffuse Color pass against Cycles' under Cycles' diffuse light: texture "
                "mipmaps and its film filter at the edges)"
            )
        lines.append(line + ".")
    return lines


def _cut_clause(e: dict[str, Any]) -> str:
    """The attribution's pixels whose plane cuts a light, as a clause ('' where none is)."""
    cut, pixels = e.get("attribution_cut_share"), e.get("attribution_cut_pixels", 0.0)
    if cut is None or not math.isfinite(cut) or not pixels > 0:
        return ""
    return (
        f"; {markdown.percent(cut)} is its direct light in the {pixels:.1%} of pixels whose "
        "surface's plane passes through a light, which EEVEE darkens "
        f"({e['attribution_cut_brightness']:.2f}x Cycles' there)"
    )


def stand_ins_written(report: JobSummary) -> int:
    """The lights vplace wrote beside the VPLs: for emissive meshes, the sun, the sky portals."""
    return report.emitter_lights_written + int(report.sun_written) + report.portals_written


def _stand_in_lines(report: JobSummary) -> list[str]:
    """What the write-back added beside the VPLs, for EEVEE."""
    parts = []
    if report.emitter_lights_written:
        n = report.emitter_lights_written
        parts.append(f"{n} light{'s' * (n != 1)} for emissive meshes")
    if report.sun_written:
        parts.append("a SUN light for the world's sun")
    if report.portals_written:
        n = report.portals_written
        parts.append(
            f"{n} sky portal{'s' * (n != 1)} (AREA lights in the openings that carry the sky's "
            "light in; EEVEE's world then lights nothing but shows to the camera)"
        )
    lines = [f"Written beside the VPLs: {'; '.join(parts)}.", ""] if parts else []
    if report.world_closed:
        lines += [
            "The cameras are in a closed room (no ray from them leaves the scene): the world "
            "lights nothing inside, in Cycles, so EEVEE's world lights nothing either and shows "
            "only to the camera (EEVEE would light the room with it through the walls).",
            "",
        ]
    return lines


def unwritten_vpls(report: JobSummary) -> int:
    """How many of the laid-out VPLs were not written: those of no power
    (``writeback.apply``)."""
    return max(report.n_vpls - report.lights_written, 0)


def _unwritten(report: JobSummary) -> str:
    """The header's note when fewer VPL lights were written than laid out, so that a user who
    asked for N sees why there are fewer lights in the file."""
    missing = unwritten_vpls(report)
    if not missing:
        return ""
    return (
        f"; {report.lights_written} written as lights, the other {missing} carry no power "
        f"({report.method}) and are not written"
    )


def _region(report: JobSummary) -> str:
    """The header's note when the VPLs' size follows the region the cameras see, not the
    scene's bounds (``Scene.scale``)."""
    if not 0.0 < report.working_scale < report.bounds_diagonal:
        return ""
    m = report.unit_scale
    return (
        f"; VPL sizes follow the region the cameras see ({report.working_scale * m:.3g} m), "
        f"not the scene's bounds ({report.bounds_diagonal * m:.3g} m across)"
    )


def eevee_matched_notes(
    matched: dict[str, float], choice: dict[str, Any] | None = None
) -> list[str]:
    """The main job's line on "Match EEVEE's direct light" (``JobSummary.eevee_matched``,
    ``JobSummary.eevee_match``): on which views the refit made up for EEVEE's direct light,
    and by how much, or that it left it out because it would not help (none without)."""
    judged = ""
    if choice is not None:
        judged = (
            f"EEVEE's image predicted on the captured views: RMSE {choice['with_match']:.4g} "
            f"with it, {choice['without']:.4g} without"
        )
        if not choice["kept"]:
            return [
                "Match EEVEE's direct light was left out: the VPLs' smooth light would not make "
                f"up for what EEVEE's direct light lacks here ({judged})."
            ]
    if not matched:
        return []
    # A tenth of a percent: the shortfall of a view where few pixels are cut is a fraction of
    # one (the Cornell box's camera: 0.3 %), which whole percents would write as +0%.
    views = ", ".join(
        f"{name} {markdown.percent(share, signed=True, digits=1)}"
        for name, share in matched.items()
    )
    return [
        "The VPL powers make up for EEVEE's direct light (Match EEVEE's direct light): its "
        f"smooth shortfall against Cycles' direct light, in the captured views: {views}"
        + (f" ({judged})." if judged else ".")
    ]


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
        f"near-field radius {report.radius * report.unit_scale:.3g} m){_unwritten(report)}"
        f"{_region(report)}",
        "",
        *markdown.table(
            ["stage", "seconds"], [[k, f"{v:.2f}"] for k, v in report.stage_seconds.items()]
        ),
        "",
        f"Every image is scored against {label}.",
        "",
        *markdown.table(["image", "RMSE", "relative MSE", "SSIM", "brightness"], rows),
        "",
        *_stand_in_lines(report),
        *[
            line
            for note in eevee_notes(report.eevee or {}, stand_ins_written(report))
            for line in (note, "")
        ],
        *[line for note in report.eevee_lamp_notes for line in (note + ".", "")],
        *[
            line
            for note in eevee_matched_notes(report.eevee_matched, report.eevee_match)
            for line in (note, "")
        ],
        *_region_lines(report.region),
        *_view_weight_lines(s.refit_view_weights),
        *_near_field_lines(s.near_field, report.unit_scale),
        f"Evaluator: {s.shadow_rays} shadow rays in {s.seconds:.3f} s "
        f"= {s.rays_per_second / 1e6:.2f} M rays/s",
        "",
    ]
    return "\n".join(lines)


def _region_lines(region: RegionSummary | None) -> list[str]:
    """What the report says of the region the lights were laid out for (``RegionSummary``;
    the write-back draws it in the ``vplace region`` collection)."""
    if region is None:
        return []
    first, second = region.lines()
    return [
        f"{first}; {second.strip()} ({region.seconds:.2f} s to choose them; the collection "
        "'vplace region' shows them).",
        "",
    ]


def _view_weight_lines(weights: dict[str, float] | None) -> list[str]:
    """What the report says of the refit's view weights (``RefitParams.balance_views``)."""
    if not weights or all(w == 1.0 for w in weights.values()):
        return []
    each = ", ".join(f"{name} {w:.2f}" for name, w in weights.items())
    return [
        "The refit weighed each captured view's pixels by the inverse of its indirect light, "
        f"so that a dim view's relative error counts as a bright one's: {each}.",
        "",
    ]


def _near_field_lines(near: dict[str, Any] | None, unit_scale: float) -> list[str]:
    """What the report says of the near-field gather (:func:`choose_near_field`)."""
    if near is None or near["views"] == 0:
        return []
    how = (
        f"on: EEVEE's fast GI gathers it within {near['distance'] * unit_scale:.3g} m"
        if near["on"]
        else "off"
    )
    return [
        f"Light between nearby surfaces (the near-field gather): {how}. Against the captures, "
        f"the lights' luminance RMSE without it {near['without']:.4f}, with it "
        f"{near['with_gather']:.4f} ({near['views']} views).",
        "",
    ]
