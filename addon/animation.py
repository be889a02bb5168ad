"""The animated job (issue 23, ``demo --animate START END STEP``): lights keyed over frames.

For each captured frame ``START, START + STEP, ..., END`` (at most
:data:`MAX_ANIMATED_FRAMES`) the scene is set to that frame and the one job runs on it as on a
still (:func:`job.prepare`: export and capture of the scene camera at the job's capture
samples, cached by what Blender renders, so a frame that renders as an earlier one reuses its
capture; then fit, layout and refit with the job's seed, the same on every frame, so the same
light paths and random numbers; each frame's refit is its own: a refit pulled toward the
previous frame's refitted scales was measured worse, README). The lights to key
(:func:`lay_out_frames`) share their positions over the captured frames, each frame with its
own powers (``vplace.temporal.shared_layout``; other methods than ``vplace+refit``: each
frame's own layout); they are matched into slots (``vplace.temporal.track``) and written as
ONE set of lights keyed over the captured frames (``writeback.keyed``; linear keys, a dark
slot keyed to 0 W), replacing only the ``vplace VPLs`` collection. Each frame's own still
layout is kept for the scores. The scene's frame is put back.

Then every frame from ``START`` to ``END`` (captured or between; ``score_between``) or only the
captured ones is scored against a Cycles truth of that frame (``truth_samples``): the
evaluator's image of the keyed lights at that frame (``vplace.temporal.at_frame``: what
Blender's linear keys give there), the evaluator's image of a still layout laid out for that
frame alone, the direct light alone, and, when asked, Cycles + OpenImageDenoise at a few
samples (its seed the frame's, as Cycles' animated seed), EEVEE with the keyed lights, and
EEVEE's ray tracing with a light probe volume baked once at the first scored frame or baked
again on every scored frame (its seconds then the bake's and the render's), and the truth
rendered again with another seed (``truth_noise``: its own noise, what any image's SSIM and
temporal error carry from the truth; a noise-free image would have about 1 / sqrt(2) of its
temporal error, and each image's SSIM against the noise-free truth is scored too). Per
image and frame: SSIM, RMSE, brightness; per image: the temporal error
(``vplace.temporal.temporal_error``) over the scored frames. Files: ``results.csv`` (a
``frame`` column), ``animation.json``, ``animation.md``, ``scene.blend`` (a copy with the
keyed lights).
"""

from __future__ import annotations

import csv
import json
import time
from collections.abc import Callable, Sequence
from contextlib import ExitStack
from dataclasses import asdict, dataclass, field
from pathlib import Path

import bpy
import numpy as np

from .capture.passes import Capture, capture, cycles_session, hide_vpls
from .capture.stage import Captured, render_reference
from .capture.views import ViewSpec, eye_views
from .errors import AddonError, WriteBackError, output_folder, run_operator
from .job import (
    COST_SAMPLES,
    OTHER_REFERENCE_SEED,
    Job,
    Prepared,
    StageTimer,
    prepare,
    reference_render,
)
from .native import vplace
from .settings import override
from .writeback import apply, eevee_render, eevee_setup, keyed

#: The most frames one animated layout captures: each costs a capture and a layout, and every
#: frame's lights are keyed on every slot.
MAX_ANIMATED_FRAMES = 120
#: The image kinds scored per frame, in the tables' order.
KEYED = "vplace keyed (evaluator)"
STILL = "vplace still (evaluator)"
DIRECT = "direct only"
EEVEE = "EEVEE + keyed VPLs"
EEVEE_STILL = "EEVEE + still VPLs of the frame"
VOLUME_ONCE = "EEVEE RT + volume baked once"
VOLUME_PER_FRAME = "EEVEE RT + volume baked per frame"
TRUTH_AGAIN = "the truth, another seed"


def cycles_kind(samples: int) -> str:
    """The image kind of Cycles + OpenImageDenoise at ``samples``."""
    return f"Cycles + OIDN {samples} spp"


def animated_frames(start: int, end: int, step: int) -> list[int]:
    """The captured frames ``start, start + step, ..., end`` (``end`` always included), or an
    :class:`AddonError` for an empty or reversed range, a step below 1 or more than
    :data:`MAX_ANIMATED_FRAMES` frames."""
    if step < 1:
        raise AddonError(f"the animation step must be at least 1 frame, got {step}")
    if end < start:
        raise AddonError(f"the frame range {start}..{end} is empty: the end comes before the start")
    frames = list(range(start, end + 1, step))
    if frames[-1] != end:
        frames.append(end)
    if len(frames) > MAX_ANIMATED_FRAMES:
        raise AddonError(
            f"frames {start}..{end} step {step} are {len(frames)} frames, more than the "
            f"{MAX_ANIMATED_FRAMES} an animated layout takes: use a larger step"
        )
    return frames


@dataclass
class FrameCost:
    """One captured frame's one-time seconds: export and capture (wall, and Cycles' own render
    seconds of the captures, as when first rendered), then fit + layout + refit."""

    frame: int
    prepare_seconds: float
    capture_render_seconds: float
    layout_seconds: float

    @property
    def total(self) -> float:
        """Export, capture, fit, layout and refit."""
        return self.prepare_seconds + self.layout_seconds


@dataclass
class AnimationSummary:
    """What an animated run measured (``to_dict`` for JSON)."""

    scene: str
    frames: list[int]
    scored_frames: list[int]
    resolution: list[int]
    n_vpls: int
    slots: int
    truth: str
    #: One dict per (frame, image): frame, captured, image, ssim, rmse, brightness, seconds.
    rows: list[dict[str, float | int | str | bool]] = field(default_factory=list)
    #: Image -> temporal error over the scored frames, and its term at each step (frame t of
    #: the scored frames against the one before).
    temporal_error: dict[str, float] = field(default_factory=dict)
    temporal_steps: dict[str, list[float]] = field(default_factory=dict)
    costs: list[FrameCost] = field(default_factory=list)
    #: Image -> seconds of one frame of it (mean over the scored frames).
    seconds_per_frame: dict[str, float] = field(default_factory=dict)
    #: Where EEVEE's temporal error comes from (:func:`attribute_flicker`), when EEVEE was
    #: scored: part -> its temporal error, each over the truth's mean luminance.
    flicker: dict[str, float] = field(default_factory=dict)
    #: Per scored frame: EEVEE's direct light (VPLs hidden) over Cycles' direct light (mean
    #: luminance), when EEVEE was scored.
    eevee_direct_brightness: list[float] = field(default_factory=list)
    #: Seconds of the keyed lights' layout over all captured frames (:func:`lay_out_frames`).
    keyed_layout_seconds: float = 0.0

    def to_dict(self) -> dict[str, object]:
        """The summary as plain JSON values."""
        return asdict(self)

    def mean(self, image: str, metric: str) -> float:
        """The mean of ``metric`` of ``image`` over the scored frames."""
        vals = [float(r[metric]) for r in self.rows if r["image"] == image and metric in r]
        return float(np.mean(vals)) if vals else float("nan")


@dataclass
class _Frame:
    """One frame's capture, reference and still layout (kept for the scores and the keys)."""

    frame: int
    prepared: Prepared
    reference: vplace.job.Reference
    computed: vplace.job.Computed


def frame_eyes(
    bl_scene: bpy.types.Scene, frames: Sequence[int]
) -> tuple[np.ndarray, np.ndarray] | tuple[None, None]:
    """The scene camera's position at each of ``frames`` and where it looks there
    (:func:`capture.views.eye_views`; None, None without a camera, which the capture refuses):
    every frame's scene gets the working scale of the region seen from all of them
    (``vplace.Scene.scale``), so a moving camera keeps one VPL size over the frames."""
    cam = bl_scene.camera
    if cam is None:
        return None, None
    return eye_views(bl_scene, [ViewSpec(cam.name, cam, f) for f in frames])


def _run_frame(
    bl_scene: bpy.types.Scene,
    frame: int,
    job: Job,
    truth_samples: int | None,
    timer: StageTimer,
    eyes: np.ndarray | None = None,
    looks: np.ndarray | None = None,
) -> tuple[_Frame, FrameCost]:
    """The still job at ``frame``: capture, reference, fit, layout, refit, evaluator; ``eyes``
    and ``looks`` (:func:`frame_eyes`) set the scene's working scale."""
    bl_scene.frame_set(frame)
    start = time.perf_counter()
    prepared = prepare(bl_scene, job, timer, eyes=eyes, looks=looks)
    prepare_seconds = time.perf_counter() - start
    n = len(prepared.captures)
    reference = render_reference(
        bl_scene,
        prepared.scene,
        prepared.exported,
        Captured(prepared.captures, prepared.views[:n], prepared.gloss),
        reference_render(job, truth_samples),
        capture_samples=job.samples,
        cache_dir=job.cache_dir,
        stage=timer.stage,
    )
    start = time.perf_counter()
    computed = vplace.job.compute(prepared.scene, prepared.views, job, reference, timer=timer)
    laid_seconds = time.perf_counter() - start - computed.stats.seconds
    cost = FrameCost(
        frame,
        prepare_seconds,
        sum(c.render_seconds for c in prepared.captures),
        laid_seconds,
    )
    return _Frame(frame, prepared, reference, computed), cost


def check_animation(job: Job, frame_range: tuple[int, int, int]) -> list[int]:
    """The captured frames of ``frame_range`` (:func:`animated_frames`), after checking the job
    can animate: valid, and its views the scene camera."""
    frames = animated_frames(*frame_range)
    job.validate()
    if job.views.mode != "active":
        raise AddonError("an animated layout captures the scene camera at each frame only")
    return frames


def capture_frames(
    bl_scene: bpy.types.Scene, frames: Sequence[int], job: Job, timer: StageTimer
) -> list[Prepared]:
    """:func:`job.prepare` (export and capture, cached) at each of ``frames``, each scene with
    the working scale of all of them (:func:`frame_eyes`); the scene's frame is put back. Cycles
    keeps its scene from frame to frame (``passes.cycles_session``): each frame's captures sync
    what moved. Uses bpy: the main thread (the panel's first half)."""
    original = bl_scene.frame_current
    eyes, looks = frame_eyes(bl_scene, frames)
    try:
        out = []
        with cycles_session(bl_scene):
            for f in frames:
                bl_scene.frame_set(f)
                out.append(prepare(bl_scene, job, timer, eyes=eyes, looks=looks))
        return out
    finally:
        bl_scene.frame_set(original)


def lay_out_frames(
    prepared: Sequence[Prepared],
    job: Job,
    progress: vplace.Progress | None = None,
) -> list[vplace.VplSet]:
    """The VPLs to key, one set per captured frame (the job's seed on every frame: the same
    random numbers). With the refit (``vplace+refit``, the default), one shared set of
    positions with each frame's powers (``vplace.temporal.shared_layout``): the keyed lights
    stand still and only their powers change. Other methods: each frame's own layout, matched
    into slots by ``key_lights``. No bpy: safe on a worker thread (the panel's second half)."""
    if job.method == "vplace+refit":
        return vplace.temporal.shared_layout(
            [p.scene for p in prepared], [p.views for p in prepared], job, progress=progress
        )
    return [
        vplace.job.lay_out(p.scene, p.views, job, progress=progress, judge_near_field=False).vpls
        for p in prepared
    ]


def key_lights(
    bl_scene: bpy.types.Scene,
    frames: Sequence[int],
    prepared: Sequence[Prepared],
    vpl_sets: Sequence[vplace.VplSet],
    timer: StageTimer,
    *,
    write_back: bool = True,
) -> vplace.temporal.Keyed:
    """The frames' VPLs matched into slots (``vplace.temporal.track``) and, with
    ``write_back``, written as one set of keyed lights (``writeback.keyed``) with the world's
    sun and sky portals of each frame and the first frame's emitter lights; the frames' regions
    are drawn as one (``apply.write_region``, ``apply.union_of_regions``)."""
    scene = prepared[0].scene
    with timer.stage(f"match VPLs over {len(frames)} frames"):
        tracked = vplace.temporal.track(vpl_sets, scene.scale)
    if write_back:
        with timer.stage("write back keyed lights"):
            keyed.write_keyed(
                bl_scene,
                frames,
                tracked,
                scene_diagonal=scene.scale,
                region=scene.region,
                specular=prepared[0].vpl_specular,
                unlit=prepared[0].vpl_unlit,
                emitters=prepared[0].stand_ins.emitters,
                suns=[p.stand_ins.sun for p in prepared],
                portals=[p.stand_ins.portals for p in prepared],
                closed=all(p.stand_ins.closed for p in prepared),
            )
            marks = [apply.RegionMarks.of(p.coverage) for p in prepared]
            apply.write_region(bl_scene, apply.union_of_regions(marks))
    return tracked


def run_animated_job(
    bl_scene: bpy.types.Scene,
    out_dir: Path,
    frame_range: tuple[int, int, int],
    *,
    job: Job,
    truth_samples: int | None = None,
    score_between: bool = False,
    cycles_samples: Sequence[int] = (),
    eevee: bool = False,
    eevee_still: bool = False,
    volume_once: bool = False,
    volume_per_frame: bool = False,
    truth_noise: bool = False,
    write_back: bool = True,
    log: Callable[[str], None] = print,
) -> AnimationSummary:
    """Lays out, keys and scores an animation (see the module docs). ``frame_range`` is
    ``(START, END, STEP)``; the job's views must be the scene camera (``ViewSet()``)."""
    frames = check_animation(job, frame_range)
    if truth_samples is not None and truth_samples < 1:
        raise AddonError(f"truth samples must be at least 1, got {truth_samples}")
    if truth_noise and not truth_samples:
        raise AddonError("the truth's noise needs a truth: give truth samples")
    for n in cycles_samples:
        if n < 1:
            raise AddonError(f"Cycles sample counts must be at least 1, got {n}")
    if job.cache_dir is None:
        job.cache_dir = out_dir / "cache"
    output_folder(out_dir)
    timer = StageTimer(log)
    original = bl_scene.frame_current
    scored = list(range(frame_range[0], frame_range[1] + 1)) if score_between else frames
    try:
        runs: dict[int, _Frame] = {}
        costs = []
        eyes, looks = frame_eyes(bl_scene, frames)
        for f in frames:
            log(f"[vplace] frame {f}")
            runs[f], cost = _run_frame(bl_scene, f, job, truth_samples, timer, eyes, looks)
            costs.append(cost)
        first = runs[frames[0]]
        preps = [runs[f].prepared for f in frames]
        stage = f"lay out the keyed lights over {len(frames)} frames"
        with timer.stage(stage):
            keyed_sets = lay_out_frames(preps, job)
        tracked = key_lights(
            bl_scene,
            frames,
            preps,
            keyed_sets,
            timer,
            write_back=write_back,
        )
        log(f"[vplace] {tracked.position.shape[1]} keyed lights for {job.n_vpls} VPLs a frame")
        if write_back:
            bl_scene.frame_set(original)  # the copy opens at the user's frame
            blend = out_dir / "scene.blend"
            run_operator(
                "wm.save_as_mainfile",
                f"cannot save a copy of the file to {blend}",
                WriteBackError,
                filepath=str(blend),
                copy=True,
            )
        summary = AnimationSummary(
            scene=Path(bpy.data.filepath).stem or bl_scene.name,
            frames=frames,
            scored_frames=scored,
            resolution=[first.reference.gi.shape[1], first.reference.gi.shape[0]],
            n_vpls=job.n_vpls,
            slots=int(tracked.position.shape[1]),
            truth=first.reference.label,
            costs=costs,
            keyed_layout_seconds=timer.seconds[stage],
        )
        images: dict[str, list[np.ndarray]] = {}
        truths: list[np.ndarray] = []
        seconds: dict[str, list[float]] = {}
        # per scored frame, for attribute_flicker: EEVEE's direct light, Cycles' direct light,
        # the evaluator's light of the keyed VPLs
        parts: dict[str, list[np.ndarray]] = {"eevee_direct": [], "direct": [], "vpl": []}

        others: dict[int, Capture] = {}  # the truth's second render, per scored frame

        def add(
            frame: int,
            kind: str,
            image: np.ndarray,
            truth: np.ndarray,
            s: float,
            scores: dict[str, float] | None = None,
        ) -> None:
            """Scores one image (``scores``: already scored, as the evaluator's images are)."""
            images.setdefault(kind, []).append(image)
            seconds.setdefault(kind, []).append(s)
            if scores is None:
                again = others.get(frame)
                scores = vplace.job.score(image, truth, other=None if again is None else again.gi)
            row: dict[str, float | int | str | bool] = {
                "frame": frame,
                "captured": frame in runs,
                "image": kind,
                **scores,
                "seconds": s,
            }
            summary.rows.append(row)

        def add_over_direct(frame: int, kind: str, ref: vplace.job.Reference,
                            indirect: np.ndarray, s: float) -> None:  # fmt: skip
            """Scores the evaluator's image of ``indirect`` over the truth's direct light
            (``vplace.job.score_over_direct``: its noise-free RMSE with its twin)."""
            again = others.get(frame)
            other = None if again is None else (again.direct, again.gi)
            scores = vplace.job.score_over_direct(indirect, ref.direct, ref.gi, other=other)
            add(frame, kind, ref.direct + indirect, ref.gi, s, scores)

        scored_runs: dict[int, _Frame] = {}
        for f in scored:
            bl_scene.frame_set(f)  # the renders below are of this frame
            run = runs.get(f)
            if run is None:
                log(f"[vplace] frame {f} (between captured frames: scored only)")
                run, _ = _run_frame(bl_scene, f, job, truth_samples, timer)
            scored_runs[f] = run
            ref = run.reference
            truths.append(ref.gi)
            height, width = ref.gi.shape[:2]
            if truth_noise:
                with timer.stage(f"the truth again (seed {OTHER_REFERENCE_SEED}), frame {f}"):
                    again = capture(
                        bl_scene,
                        resolution=(width, height),
                        samples=truth_samples or 1,
                        seed=OTHER_REFERENCE_SEED,
                        cache_dir=job.cache_dir,
                    )
                add(f, TRUTH_AGAIN, again.gi, ref.gi, again.render_seconds)
                others[f] = again  # the images below: also against the noise-free truth
            start = time.perf_counter()
            lights = vplace.temporal.at_frame(tracked, frames, f)
            indirect, _ = vplace.evaluate(run.prepared.scene, ref.view, lights)
            add_over_direct(f, KEYED, ref, indirect, time.perf_counter() - start)
            parts["direct"].append(ref.direct)
            parts["vpl"].append(indirect)
            add_over_direct(f, STILL, ref, run.computed.indirect, run.computed.stats.seconds)
            add_over_direct(f, DIRECT, ref, np.zeros_like(ref.direct), 0.0)
            for n in cycles_samples:
                with timer.stage(f"Cycles + OIDN {n} spp, frame {f}"):
                    img = eevee_render.render(
                        bl_scene,
                        resolution=(width, height),
                        samples=n,
                        setup=eevee_render.SETUPS["cycles+oidn"],
                        seed=f,
                        cache_dir=job.cache_dir,
                    )
                add(f, cycles_kind(n), img.image, ref.gi, img.seconds)
            if eevee and write_back:
                size = (width, height)
                with eevee_setup.world_for_render(bl_scene):  # one bake for both
                    with timer.stage(f"EEVEE, frame {f}"):
                        img = _render_vpl_eevee(bl_scene, size, job.cache_dir, world_volume=False)
                    with timer.stage(f"EEVEE direct light, frame {f}"), override() as g:
                        apply.hide_vpl_lights(g, bl_scene)
                        direct = _render_vpl_eevee(
                            bl_scene, size, job.cache_dir, world_volume=False
                        )
                add(f, EEVEE, img.image, ref.gi, img.seconds)
                parts["eevee_direct"].append(direct.image)
        if eevee_still and eevee and write_back:
            for f in scored:
                _score_eevee_still(bl_scene, scored_runs[f], job, add, timer)
            # The keyed lights back (the same keys: the same frames and sets).
            key_lights(bl_scene, frames, preps, keyed_sets, timer)
        suns = [p.stand_ins.sun for p in preps]
        for per_frame, on in ((False, volume_once), (True, volume_per_frame)):
            if not on:
                continue
            with eevee_setup.users_sun(bl_scene, suns, frames):
                _score_volume(
                    bl_scene,
                    scored,
                    truths,
                    add,
                    timer,
                    per_frame=per_frame,
                    region=first.prepared.scene.region,
                )
    finally:
        bl_scene.frame_set(original)
    if len(truths) >= 2:
        for kind, imgs in images.items():
            steps = vplace.temporal.temporal_steps(imgs, truths)
            summary.temporal_steps[kind] = [float(x) for x in steps]
            summary.temporal_error[kind] = float(steps.mean())
    summary.seconds_per_frame = {k: float(np.mean(v)) for k, v in seconds.items()}
    if EEVEE in images and len(truths) >= 2:
        summary.flicker = attribute_flicker(
            images[EEVEE], parts["eevee_direct"], parts["direct"], parts["vpl"], truths
        )
        summary.eevee_direct_brightness = [
            vplace.job.attribute(e, ed, d, v, t).direct_brightness
            for e, ed, d, v, t in zip(
                images[EEVEE], parts["eevee_direct"], parts["direct"], parts["vpl"], truths,
                strict=True,
            )
        ]  # fmt: skip
    write_files(out_dir, summary)
    return summary


#: The parts of EEVEE's temporal error (:func:`attribute_flicker`), in the tables' order.
FLICKER_PARTS = {
    "eevee": "EEVEE + keyed VPLs, all of it",
    "direct": "(a) EEVEE's direct light (VPLs hidden) against Cycles' direct light",
    "vpl": "(b) EEVEE's light of the VPLs against the evaluator's",
    "evaluator": "(c) the evaluator's light of the VPLs against Cycles' indirect light",
}


def attribute_flicker(
    eevee: Sequence[np.ndarray],
    eevee_direct: Sequence[np.ndarray],
    direct: Sequence[np.ndarray],
    vpl: Sequence[np.ndarray],
    truths: Sequence[np.ndarray],
) -> dict[str, float]:
    """Where EEVEE's temporal error comes from, the still report's attribution (issue 21) taken
    across frames. With E = D_e + V_e (EEVEE's direct light, with the VPLs hidden, and the rest)
    and the truth T = D_c + I_c (Cycles' direct and indirect light), EEVEE's change error
    ``(E_t - E_t-1) - (T_t - T_t-1)`` is the sum of (a) ``dD_e - dD_c``, (b) ``dV_e - dV`` (V:
    the evaluator's light of the keyed VPLs) and (c) ``dV - dI_c``. Each part's temporal error
    (:func:`vplace.temporal.temporal_error`, over the truth's mean luminance, so the parts are
    in the same unit as the whole; they need not add up, as absolute values)."""
    lum = np.asarray(vplace.LUMINANCE, dtype=np.float64)
    over = max(float(np.mean([(t[..., :3] @ lum).mean() for t in truths])), 1e-12)

    def te(images: Sequence[np.ndarray], refs: Sequence[np.ndarray]) -> float:
        return vplace.temporal.temporal_error(images, refs, over=over)

    rest = [e - d for e, d in zip(eevee, eevee_direct, strict=True)]
    indirect = [t - d for t, d in zip(truths, direct, strict=True)]
    return {
        "eevee": te(eevee, truths),
        "direct": te(eevee_direct, direct),
        "vpl": te(rest, vpl),
        "evaluator": te(vpl, indirect),
    }


def _render_vpl_eevee(
    bl_scene: bpy.types.Scene,
    resolution: tuple[int, int],
    cache_dir: Path | None,
    *,
    world_volume: bool = True,
) -> eevee_render.EeveeImage:
    """EEVEE's render of the scene with the written VPLs at the current frame (the scored
    setup, with the world's volume when the world emits; ``world_volume=False``: the caller
    holds ``eevee_setup.world_for_render`` around it)."""
    if world_volume:
        with eevee_setup.world_for_render(bl_scene):
            return _render_vpl_eevee(bl_scene, resolution, cache_dir, world_volume=False)
    return eevee_render.render(
        bl_scene,
        resolution=resolution,
        samples=eevee_render.EEVEE_SAMPLES,
        setup=eevee_render.SETUPS["vpl"],
        cache_dir=cache_dir,
    )


def _score_eevee_still(
    bl_scene: bpy.types.Scene,
    run: _Frame,
    job: Job,
    add: Callable[[int, str, np.ndarray, np.ndarray, float], None],
    timer: StageTimer,
) -> None:
    """EEVEE with the still layout of ``run``'s frame written as the still write-back writes it
    (``apply.write_vpls``, with that frame's stand-ins), rendered at that frame: what the keyed
    lights are compared with. Replaces the VPL collection (the caller writes the keyed lights
    back)."""
    bl_scene.frame_set(run.frame)
    p = run.prepared
    apply.write_vpls(
        bl_scene,
        run.computed.vpls,
        scene_diagonal=p.scene.scale,
        region=p.scene.region,
        specular=p.vpl_specular,
        unlit=p.vpl_unlit,
        emitters=p.stand_ins.emitters,
        sun=p.stand_ins.sun,
        closed=p.stand_ins.closed,
        cut_lamps=p.cut_lamps,
    )
    height, width = run.reference.gi.shape[:2]
    with timer.stage(f"EEVEE + still VPLs, frame {run.frame}"):
        img = _render_vpl_eevee(bl_scene, (width, height), job.cache_dir)
    add(run.frame, EEVEE_STILL, img.image, run.reference.gi, img.seconds)


def _score_volume(
    bl_scene: bpy.types.Scene,
    scored: Sequence[int],
    truths: Sequence[np.ndarray],
    add: Callable[[int, str, np.ndarray, np.ndarray, float], None],
    timer: StageTimer,
    *,
    per_frame: bool,
    region: apply.Region | None = None,
) -> None:
    """EEVEE ray tracing with a light probe volume (vplace's lights hidden; the world's sun as
    the user's lamp, ``eevee_setup.users_sun``) rendered at every
    scored frame: baked once, at the first scored frame (what a user gets from one bake), or
    ``per_frame`` baked again at each (its seconds then the bake's and the render's). The
    probe is removed after; it spans ``region`` where the cameras see far less than the scene
    (``eevee_setup.scene_bounds``). Not cached: a render's key does not say when its volume was
    baked."""
    kind = VOLUME_PER_FRAME if per_frame else VOLUME_ONCE
    with override() as g, ExitStack() as once:
        hide_vpls(g)
        if not per_frame:
            bl_scene.frame_set(scored[0])
            seconds = once.enter_context(eevee_setup.temporary_volume(bl_scene, region=region))
            timer.log(f"[vplace] light probe volume baked once in {seconds:.1f} s")
        for f, truth in zip(scored, truths, strict=True):
            bl_scene.frame_set(f)
            height, width = truth.shape[:2]
            with ExitStack() as each:
                bake = 0.0
                if per_frame:
                    bake = each.enter_context(eevee_setup.temporary_volume(bl_scene, region=region))
                    timer.log(f"[vplace] light probe volume baked at frame {f} in {bake:.1f} s")
                with timer.stage(f"{kind}, frame {f}"):
                    img = eevee_render.render(
                        bl_scene,
                        resolution=(width, height),
                        samples=eevee_render.EEVEE_SAMPLES,
                        setup=eevee_render.SETUPS["rt+volume"],
                    )
            add(f, kind, img.image, truth, img.seconds + bake)


def write_files(out_dir: Path, summary: AnimationSummary) -> None:
    """``results.csv`` (one row per frame and image), ``animation.json`` and ``animation.md``."""
    columns = ["frame", "captured", "image", "ssim", "rmse", "relative_mse", "brightness"]
    if any("ssim_noise_free" in r for r in summary.rows):
        columns.append("ssim_noise_free")
    columns.append("seconds")
    with (out_dir / "results.csv").open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=columns, extrasaction="ignore")
        w.writeheader()
        for row in summary.rows:
            w.writerow(row)
    (out_dir / "animation.json").write_text(json.dumps(summary.to_dict(), indent=1))
    (out_dir / "animation.md").write_text(animation_report(summary))


def animation_report(summary: AnimationSummary) -> str:
    """The per-frame and temporal tables in Markdown."""
    kinds = list(dict.fromkeys(str(r["image"]) for r in summary.rows))
    lines = [
        f"# {summary.scene}: animated layout",
        "",
        f"Captured frames {summary.frames}, scored frames {summary.scored_frames}; "
        f"{summary.resolution[0]}x{summary.resolution[1]}, {summary.n_vpls} VPLs a frame, "
        f"{summary.slots} keyed lights (linear keys); truth: {summary.truth}.",
        "",
        "## SSIM per frame (brightness)",
        "",
    ]
    rows: list[list[str]] = []
    for f in summary.scored_frames:
        cells = [f"{f}" + ("" if f in summary.frames else " (between)")]
        for k in kinds:
            r = next((r for r in summary.rows if r["frame"] == f and r["image"] == k), None)
            cells.append("" if r is None else f"{r['ssim']:.3f} ({r['brightness']:.3f})")
        rows.append(cells)
    lines += vplace.markdown.table(["frame", *kinds], rows)
    lines += ["", "## Over the frames", ""]
    noise = TRUTH_AGAIN in kinds
    if noise:
        lines += [
            f"'{TRUTH_AGAIN}' is the truth rendered again with another seed: its SSIM and "
            "temporal error are the truth's own noise. Every image carries that noise in its "
            "scores; an image without error would score about 1 / sqrt(2) of that temporal "
            f"error ({summary.temporal_error.get(TRUTH_AGAIN, float('nan')) / 2**0.5:.4f}). The "
            "noise-free SSIM is against the noise-free truth, estimated from the two renders "
            "(`vplace.ssim_noise_free`).",
            "",
        ]
    rows = []
    for k in kinds:
        te = summary.temporal_error.get(k, float("nan"))
        free_ssim = summary.mean(k, "ssim_noise_free")  # none for the truth's second render
        free = [f"{free_ssim:.3f}" if np.isfinite(free_ssim) else "-"] if noise else []
        rows.append(
            [
                k,
                f"{summary.mean(k, 'ssim'):.3f}",
                *free,
                f"{summary.mean(k, 'rmse'):.4f}",
                f"{te:.4f}",
                f"{summary.seconds_per_frame.get(k, float('nan')):.2f}",
            ]
        )
    header = ["image", "mean SSIM", *(["mean SSIM, noise-free truth"] if noise else [])]
    lines += vplace.markdown.table([*header, "mean RMSE", "temporal error", "s per frame"], rows)
    if summary.flicker:
        lines += [
            "",
            "## Where EEVEE's temporal error comes from",
            "",
            "Each part's temporal error over the truth's mean luminance (`attribute_flicker`); "
            "EEVEE's direct light (VPLs hidden) over Cycles' per scored frame: "
            + ", ".join(f"{b:.3f}" for b in summary.eevee_direct_brightness)
            + ".",
            "",
        ]
        lines += vplace.markdown.table(
            ["part", "temporal error"],
            [[FLICKER_PARTS[k], f"{v:.4f}"] for k, v in summary.flicker.items()],
        )
    lines += ["", "## One-time cost per captured frame (s)", ""]
    rows = []
    for c in summary.costs:
        rows.append(
            [
                str(c.frame),
                f"{c.prepare_seconds:.2f}",
                f"{c.capture_render_seconds:.2f}",
                f"{c.layout_seconds:.2f}",
            ]
        )
    lines += vplace.markdown.table(
        ["frame", "export + capture (wall)", "captures' Cycles render", "fit + layout + refit"],
        rows,
    )
    n = max(len(summary.costs), 1)
    lines += [
        "",
        "The fit, layout and refit above are each frame's still layout (the scored "
        f"{STILL!r}); the keyed lights' own layout took {summary.keyed_layout_seconds:.2f} s "
        f"for the {len(summary.costs)} captured frames ({summary.keyed_layout_seconds / n:.2f} "
        "s a frame; `lay_out_frames`).",
    ]
    if summary.costs:
        lines += ["", captured_frame_cost(summary)]
    return "\n".join(lines) + "\n"


def captured_frame_cost(summary: AnimationSummary) -> str:
    """One sentence: what a captured frame of the keyed lights costs once (the captures' Cycles
    render as first rendered, and the frame's share of the keyed layout; as the still report
    counts a camera's captures, fit, layout and refit), against a Cycles + OIDN frame of
    ``job.COST_SAMPLES`` spp (the still report's yardstick too) where the run
    rendered one, and the export's wall time beside it."""
    n = max(len(summary.costs), 1)
    render = sum(c.capture_render_seconds for c in summary.costs) / n
    keyed = summary.keyed_layout_seconds / n
    once = render + keyed
    text = (
        f"A captured frame of the keyed lights costs {once:.2f} s once: the captures' Cycles "
        f"render ({render:.2f} s, as first rendered) and its share of the keyed layout "
        f"({keyed:.2f} s)"
    )
    cycles = summary.seconds_per_frame.get(cycles_kind(COST_SAMPLES), float("nan"))
    if np.isfinite(cycles) and cycles > 0:
        text += (
            f", {once / cycles:.2f}x a Cycles + OIDN {COST_SAMPLES} spp frame of this size "
            f"({cycles:.2f} s; at most 1x is the aim)"
        )
    export = sum(c.prepare_seconds for c in summary.costs) / n
    return text + (
        f". The export and capture's wall time comes beside it ({export:.2f} s a frame in this "
        "run; the captures' render is in it where they were not cached, and so is the bake of "
        "a world the add-on bakes)."
    )


def plot_animation(summary: AnimationSummary, path: Path) -> Path:
    """Two panels across the scored frames, one line per image: SSIM against the truth, and
    the temporal error's term at each step (:attr:`AnimationSummary.temporal_steps`). PNG;
    matplotlib is imported only here (the report's plots do the same)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    kinds = list(dict.fromkeys(str(r["image"]) for r in summary.rows))
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(8, 7), sharex=True)
    for kind in kinds:
        rows = [r for r in summary.rows if r["image"] == kind]
        top.plot([r["frame"] for r in rows], [r["ssim"] for r in rows], marker=".", label=kind)
        steps = summary.temporal_steps.get(kind)
        if steps:
            bottom.plot(summary.scored_frames[1:], steps, marker=".", label=kind)
    for f in summary.frames:
        for ax in (top, bottom):
            ax.axvline(f, color="0.85", lw=0.8, zorder=0)
    top.set_ylabel("SSIM against the truth")
    bottom.set_ylabel("temporal error at the step to this frame")
    bottom.set_xlabel("frame (grey: captured frames)")
    top.set_title(f"{summary.scene}: {summary.n_vpls} VPLs, {summary.slots} keyed lights")
    top.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
