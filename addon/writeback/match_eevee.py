"""Match EEVEE's direct light: VPL powers that make up for what EEVEE's own direct light lacks.

EEVEE renders the scene's lamps and vplace's stand-ins differently from Cycles (its shadow maps,
film and texture filtering; ``docs/EEVEE_NOTES.md``, Q9), and the refit fits the VPL powers to
Cycles' indirect light, so the part of EEVEE's error that is its direct light stays. With
``Job.match_eevee`` EEVEE renders that direct light first: on every captured view that is its
camera at the current frame, with the scene's lamps and the stand-ins this job writes (the VPLs
none), as the scored renders do. The refit then fits each such view's indirect light plus the
smooth part of Cycles' direct light minus EEVEE's (``vplace.job.eevee_deficit``, averaged over
boxes of the fit's cell size on the surfaces), so that EEVEE's direct light plus the VPLs' light
matches the capture. Only the powers change: the layout places for Cycles' light as before.

Only where it helps (stop 68): the refit is run both ways, and the matched powers are kept only
where EEVEE's image predicted on the matched views (its rendered direct light plus the VPLs'
light as the evaluator computes it, against the capture: :func:`predicted_error`) comes out
closer than with the plain powers (``vplace.job.MatchChoice``). On the Cornell box, whose faces
EEVEE darkens where their plane cuts the lamp, it is kept and EEVEE's RMSE fell 1-22 % on six of
seven views (+1 % on one); in the sky room, whose shortfall is the sun patches' sharp edges and
textures, it raised EEVEE's RMSE (seed 0: +1.9 % on the camera, +17.5 % on the held-out
ceiling) and is left out on three seeds of four (kept on one by gains of a few parts in ten
thousand, where the ceiling's RMSE rose 1.4 %; README, "Match EEVEE's direct light, only where
it helps").

Measured (EEVEE's own image of the refitted lights, on a GPU; README, "Can the VPL powers make
up for EEVEE's direct light?"): on the Cornell box, whose lamp EEVEE renders 0.91-0.96x as bright
as Cycles on two views, EEVEE's luminance RMSE fell 5-28 % on every view, held-out ones
included; in the panel and L-shaped rooms it moved by -3.3..+0.5 %; in the sky room by
-2.4..-0.1 % on four views and +4.3 % on the held-out view of the ceiling, which no capture
sees. It costs an EEVEE render per captured view at the capture size and
:data:`MATCH_SAMPLES` samples, a fraction of a second on a GPU and 2.3-2.7 s a view on these
CPU-only machines (llvmpipe, the Cornell box at 192x108; 6 s at 16 samples, as it rendered
until stop 71, for the same powers to a part in a thousand of EEVEE's RMSE). So by
default (``Job.match_eevee`` "auto", stop 69) it runs only where surfaces the
cameras see cut one of the user's lamps (:func:`cut_lamps_seen`), the smooth shortfall it
fixes, and hold at least ``vplace.job.CUT_SHARE`` of a view's direct light (stop 70: a ball's
terminator cuts every lamp, lit edge on); elsewhere nothing renders.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable, Sequence
from contextlib import AbstractContextManager
from pathlib import Path
from typing import TYPE_CHECKING

import bpy
import numpy as np

from ..capture.native_view import view_of
from ..errors import AddonError
from ..native import vplace
from ..settings import override
from . import apply, cut_lights, eevee_setup
from . import eevee_render as eevee

if TYPE_CHECKING:
    from ..capture.passes import Capture
    from .stand_ins import StandIns

#: EEVEE's samples for the direct-light render: what the match uses of it is averaged over the
#: fit's cells, and EEVEE's fixed cost per frame on a CPU is about a sample's (Cornell box,
#: 192x108, llvmpipe: 6.5 s at 16 samples, 2.3 s at 4, 1.35 s at 1; the same at half the size).
MATCH_SAMPLES = 4
#: The collection the stand-ins live in while EEVEE renders the direct light (removed after).
COLLECTION = apply.COLLECTION_NAME + " (matching EEVEE)"


def eevee_match(
    bl_scene: bpy.types.Scene,
    captures: Sequence[Capture],
    views: Sequence[vplace.View],
    gloss: Sequence[np.ndarray | None],
    stand_ins: StandIns,
    *,
    scene: vplace.Scene,
    cell_px: int,
    cache_dir: Path | None,
    stage: Callable[[str], AbstractContextManager[None]],
    mode: str = "on",
    log: Callable[[str], None] = print,
) -> tuple[vplace.job.EeveeMatch | None, dict[str, float], list[str]]:
    """What the refit may fit (``vplace.job.lay_out(match=...)``) in place of the captured
    ``views`` (one per capture of ``captures``, ``gloss`` their glossy masks): each
    view whose capture is its camera at the current frame with EEVEE's direct-light deficit
    (boxes of ``cell_px``) added to its target, the others as they are, with the error EEVEE's
    image of a set of VPLs would have on those views (:func:`predicted_error`); and per matched
    view, the deficit's mean over Cycles' direct light's (luminance). EEVEE lights the scene with
    ``stand_ins``, written into :data:`COLLECTION` and removed after; any vplace collection
    already in the scene is hidden for the renders, and every setting is restored, even on
    error. ``scene`` (the job's ``vplace.Scene``) gives the stand-ins' size and region, and
    lights a rough metal's pixels as the captured views do (``native_view.metal_irradiance``).

    The third value, whatever the mode, is the user's lamps EEVEE darkens on what the cameras
    see (:func:`cut_lamps_seen`): the write-back notes them (``Prepared.cut_lamps``).

    ``mode`` (``Job.match_eevee``): "on" always; "off" never (None, {}); "auto" only where
    those lamps are (``log`` says which), else (None, {}) with nothing rendered, and where
    EEVEE then fails to render, ``log`` says so and it is (None, {}): the layout goes on
    without it. Under "on" a failed render is the error it is."""
    lamps = cut_lamps_seen(bl_scene, captures)
    if mode == "off" or (mode == "auto" and not lamps):
        return None, {}, lamps
    if mode == "auto":
        log(
            f"[vplace] Match EEVEE's direct light (auto): the plane of a surface the cameras "
            f"see passes through {len(lamps)} of your lamps (e.g. {lamps[0]!r}), which EEVEE "
            "darkens there; the refit makes up for it where that helps"
        )
    nothing = vplace.VplSet(
        np.zeros((1, 3), np.float32),
        np.array([[0.0, 0.0, 1.0]], np.float32),
        np.zeros((1, 3), np.float32),
        radius=0.01,
    )
    lum = np.asarray(vplace.LUMINANCE, dtype=np.float64)
    plain = list(views)
    views = list(views)
    region = scene.region
    matched: dict[str, float] = {}
    judged: dict[int, tuple[vplace.View, np.ndarray, np.ndarray, np.ndarray]] = {}
    # Lit as this run's lights will be (its region), not by what an earlier run's collection
    # keeps: the second run of a file renders as the first.
    setup = dataclasses.replace(eevee.SETUPS["vpl"], collection=COLLECTION)
    with override() as g:
        old = apply.find_collection(scene=bl_scene)
        if old is not None:
            for obj in list(old.all_objects):  # a list: hiding one rebuilds all_objects
                g.set(obj, "hide_render", True)
        apply.write_vpls(
            bl_scene,
            nothing,
            scene_diagonal=scene.scale,
            region=region,
            emitters=stand_ins.emitters,
            sun=stand_ins.sun,
            closed=stand_ins.closed,
            name=COLLECTION,
        )
        try:
            with eevee_setup.world_for_render(
                bl_scene, portals=stand_ins.world_shut_out, region=region
            ):
                for i, cap in enumerate(captures):
                    if not _matchable(cap):  # another frame's view, or no camera
                        continue
                    camera = bpy.data.objects[cap.camera]
                    try:
                        with stage(f"EEVEE's direct light {cap.view}"):
                            img = eevee.render(
                                bl_scene,
                                resolution=(cap.width, cap.height),
                                camera=camera,
                                samples=MATCH_SAMPLES,
                                setup=setup,
                                cache_dir=cache_dir,
                            )
                    except AddonError as exc:
                        if mode != "auto":
                            raise
                        log(f"[vplace] warning: Match EEVEE's direct light (auto) left out: {exc}")
                        return None, {}, lamps
                    seen = vplace.job.seen_directly(cap.seen_light, cap.direct)
                    deficit = vplace.job.eevee_deficit(
                        cap.direct, img.image, cap.covered & ~seen, cell_px
                    )
                    mask = gloss[i] if gloss else None
                    views[i] = view_of(cap, gloss=mask, offset=deficit, scene=scene)
                    # EEVEE's image of the VPLs would be its direct light plus their light; the
                    # capture's light is Cycles' direct light plus the indirect light they fit.
                    target = cap.direct[..., :3] + cap.modelled_indirect(mask)[..., :3]
                    judged[i] = (plain[i], img.image[..., :3], target, cap.covered & ~seen)
                    direct = float((cap.direct[..., :3] @ lum).mean())
                    matched[cap.view] = (
                        float((deficit @ lum).mean()) / direct if direct > 0 else 0.0
                    )
        finally:
            apply.clear_vpls(COLLECTION, bl_scene)
    error = functools.partial(predicted_error, scene, judged)
    return vplace.job.EeveeMatch(views, plain, sorted(judged), error), matched, lamps


def _matchable(cap: Capture) -> bool:
    """Whether EEVEE can render ``cap``'s view: its camera, at the current frame."""
    return cap.view == cap.camera and bpy.data.objects.get(cap.camera) is not None


def cut_lamps_seen(bl_scene: bpy.types.Scene, captures: Sequence[Capture]) -> list[str]:
    """The user's lamps that EEVEE darkens on the views :func:`eevee_match` would render: those
    whose shape the planes of surfaces one of those captures sees pass through, where those
    surfaces hold at least ``vplace.job.CUT_SHARE`` of its direct light
    (``cut_lights.lamps_cut_in``; the pixels that see an emitter left out). Where there are
    none, the match has nothing smooth to make up for that vplace knows of, and ``Job``'s
    "auto" leaves it (and its EEVEE renders) out."""
    return cut_lights.lamps_cut_in(
        bl_scene,
        (_surfaces_lit(c) for c in captures if _matchable(c)),
    )


def _surfaces_lit(c: Capture) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``c``'s positions, normals, the surface pixels to test (covered, finite, not seeing an
    emitter) and their direct light's luminance (0 where it is not finite or below 0)."""
    lum = np.asarray(c.direct, dtype=np.float64)[..., :3] @ np.asarray(vplace.LUMINANCE)
    finite = np.isfinite(c.position).all(-1) & np.isfinite(c.normal).all(-1)
    mask = c.covered & finite & ~vplace.job.seen_directly(c.seen_light, c.direct)
    return c.position, c.normal, mask, np.where(np.isfinite(lum), np.maximum(lum, 0.0), 0.0)


def predicted_error(
    scene: vplace.Scene,
    judged: dict[int, tuple[vplace.View, np.ndarray, np.ndarray, np.ndarray]],
    vpls: vplace.VplSet,
    index: int,
) -> float:
    """EEVEE's predicted mean squared error on matched view ``index`` of ``judged`` (each: the
    captured view, EEVEE's direct light rendered on it, the capture's light, and its surface
    pixels) with ``vpls``: EEVEE's direct light plus the VPLs' light as the evaluator computes
    it (EEVEE's image of the VPLs is within 1.5 % of it, ``docs/EEVEE_NOTES.md`` Q7), against
    the capture's light, over the surfaces (the emitters and the world seen directly are left
    out: the VPLs do not light them). No bpy: the refit's judge on a worker thread."""
    view, eevee_direct, target, mask = judged[index]
    if not mask.any():
        return 0.0
    light, _ = vplace.evaluate(scene, view, vpls)
    diff = (eevee_direct + np.asarray(light)[..., :3] - target)[mask].astype(np.float64)
    return float((diff**2).mean())
