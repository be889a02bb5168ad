"""The capture stage of a job: every view's Cycles capture (cached), the views that are left out
and why, and each capture as a ``vplace.View``; with the main job's reference render.

It is handed the exported scene and its ``vplace.Scene`` and hands back a :class:`Captured`; the
stages before it never see a capture.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from contextlib import AbstractContextManager
from dataclasses import dataclass, field
from pathlib import Path

import bpy
import numpy as np

from ..errors import CaptureError
from ..native import vplace
from ..scene.export import ExportedScene
from . import render_key
from .native_view import gloss_mask, spared_materials, view_of, vpl_specular
from .passes import Capture, capture, cycles_session
from .views import ViewSpec, pose_camera


@dataclass
class Captured:
    """The captured views, in order, with their ``vplace.View`` and glossy masks."""

    captures: list[Capture]
    views: list[vplace.View]
    #: Per capture, where its rough glossy layers are modelled (``native_view.gloss_mask``).
    gloss: list[np.ndarray | None]
    #: Views left out, with the reason (a camera that sees nothing, a duplicate view).
    skipped: dict[str, str] = field(default_factory=dict)
    #: The coverage views of the region around the captures (``vplace.coverage``), if asked.
    coverage: vplace.coverage.Coverage | None = None

    @property
    def specular(self) -> float:
        """The written VPLs' specular factor (``native_view.vpl_specular``): 1 exactly when
        glossy layers are modelled (``capture_views`` gives masks only then), else 0."""
        return 1.0 if any(g is not None for g in self.gloss) else 0.0


@dataclass(frozen=True)
class ReferenceRender:
    """How the main job's reference is made: the scene camera at ``samples`` and ``seed``;
    ``ground_truth`` when the samples were asked for; ``own_capture_ok`` when the first view's
    capture may stand in (no truth asked and the first view is the scene camera now)."""

    samples: int
    seed: int
    ground_truth: bool
    own_capture_ok: bool


@render_key.meshes_unchanged()
def capture_views(
    bl_scene: bpy.types.Scene,
    scene: vplace.Scene,
    exported: ExportedScene,
    specs: Sequence[ViewSpec],
    *,
    resolution: tuple[int, int],
    samples: int,
    seed: int,
    cache_dir: Path | None,
    stage: Callable[[str], AbstractContextManager[None]],
    log: Callable[[str], None],
    region: vplace.coverage.Region | None = None,
    profile: str = "cosine",
    radius: float | None = None,
    render_coverage: bool = False,
) -> Captured:
    """Captures each view of ``specs``, then, with a ``region`` of one or more views, adds the
    coverage views of that region around them: with ``render_coverage`` (the job's default)
    rendered by Cycles (:func:`rendered_coverage`), following the captures as captures; without,
    ray traced (``vplace.coverage``, no render; ``profile`` and ``radius`` those of the job's
    VPLs). A view that sees no geometry, or that
    renders exactly what an earlier view renders (the same capture key), is left out and said
    so; only when no view is left is it an error. ``stage`` is the job timer's ``stage``. Each
    mesh is hashed for the cache keys once for all the views (``render_key.meshes_unchanged``),
    and Cycles keeps its scene from one capture to the next (``passes.cycles_session``)."""
    with cycles_session(bl_scene):
        last = [0.0]

        def on_progress(line: str) -> None:
            now = time.perf_counter()
            if now - last[0] > 2.0:
                last[0] = now
                log(f"[vplace]   {line}")

        captures: list[Capture] = []
        skipped: dict[str, str] = {}
        for spec in specs:
            with stage(f"capture {spec.name} (Cycles)"):
                cap = capture(
                    bl_scene,
                    camera=spec.camera,
                    frame=spec.frame,
                    name=spec.name,
                    resolution=resolution,
                    samples=samples,
                    seed=seed,
                    cache_dir=cache_dir,
                    on_progress=on_progress,
                )
            same = next((c.view for c in captures if c.key == cap.key), None)
            if same is not None:
                skipped[spec.name] = f"the same view as {same!r}"
            elif not cap.covered.any():
                skipped[spec.name] = "the camera sees no geometry (only background)"
            else:
                captures.append(cap)
                continue
            log(f"[vplace] view {spec.name!r} left out: {skipped[spec.name]}")
        if not captures:
            names = ", ".join(repr(n) for n in skipped)
            raise CaptureError(
                f"no view is left to lay out VPLs for ({names}: "
                + "; ".join(skipped.values())
                + "): aim the camera at the scene"
            )
        if all(not (c.combined[c.covered] > 0.0).any() for c in captures):
            log(
                "[vplace] warning: every capture is black: no light reaches what the cameras see, "
                "so the VPLs have nothing to carry there (is a lamp outside a closed room?)"
            )
        masks = [gloss_mask(scene, exported, c) for c in captures]
        specular = vpl_specular(scene, exported, captures, masks)
        if not specular and exported.rough_gloss.any():
            lit = exported.sharp_gloss & ~spared_materials(exported)
            sharp = [m.name for m, s in zip(exported.materials, lit, strict=True) if s]
            log(
                "[vplace] note: the written VPLs have no specular: the sharp glossy layers (e.g. "
                f"{sharp[0]!r}) show more glossy light in the captures than the rough ones, and "
                "EEVEE would mirror each VPL in them as a spot (their reflections are EEVEE's ray "
                "tracing's)"
            )
        gloss = masks if specular else [None] * len(captures)
        views = [view_of(c, gloss=g, scene=scene) for c, g in zip(captures, gloss, strict=True)]
        cover = None
        if region is not None and region.count > 0 and render_coverage:
            cover, rendered = rendered_coverage(
                bl_scene,
                scene,
                exported,
                views,
                region,
                frame=specs[0].frame,
                samples=samples,
                seed=seed,
                cache_dir=cache_dir,
                stage=stage,
                on_progress=on_progress,
            )
            rendered_gloss = [
                gloss_mask(scene, exported, c) if specular else None for c in rendered
            ]
            captures += rendered
            gloss = gloss + rendered_gloss
            views += [
                view_of(c, gloss=g, scene=scene)
                for c, g in zip(rendered, rendered_gloss, strict=True)
            ]
            log(f"[vplace] {cover.describe(exported.unit_scale)}, rendered by Cycles")
        elif region is not None and region.count > 0:
            with stage("coverage views (ray traced)"):
                cover = vplace.coverage.cover(
                    scene,
                    exported.vertices[exported.triangles],
                    views,
                    region,
                    seed=seed,
                    profile=profile,
                    radius=radius,
                )
            log(f"[vplace] {cover.describe(exported.unit_scale)}")
        return Captured(captures, views, gloss, skipped, cover)


def rendered_coverage(
    bl_scene: bpy.types.Scene,
    scene: vplace.Scene,
    exported: ExportedScene,
    views: Sequence[vplace.View],
    region: vplace.coverage.Region,
    *,
    frame: int | None,
    samples: int,
    seed: int,
    cache_dir: Path | None,
    stage: Callable[[str], AbstractContextManager[None]],
    on_progress: Callable[[str], None] | None = None,
) -> tuple[vplace.coverage.Coverage, list[Capture]]:
    """The coverage views of ``region`` around the captured ``views`` rendered by Cycles: the
    poses ``vplace.coverage.pick`` chooses (traced probes), each captured from a temporary
    camera (:func:`views.pose_camera`, removed after) at ``region.size`` pixels square with the
    captures' ``samples`` and ``seed`` at ``frame``, named ``vplace.coverage.RENDERED_PREFIX``
    ``k`` (not ``vplace.coverage.PREFIX``). Their indirect light is then Cycles', not light-path
    VPLs' estimate, and they are fitted as captures (the refit bounding the scales where it fits
    them, ``vplace.job.REGION_MAX_SCALE``). A pose that sees no geometry is left out. The
    ``Coverage`` holds the poses (its ``views`` empty) and the seconds of the pick; the renders'
    own are the captures'."""
    start = time.perf_counter()
    poses, before, after, radii, eyes = vplace.coverage.pick(
        scene, exported.vertices[exported.triangles], views, region
    )
    picked = time.perf_counter() - start
    rendered = []
    for k, pose in enumerate(poses, start=1):
        name = f"{vplace.coverage.RENDERED_PREFIX}{k}"
        with stage(f"capture {name} (Cycles)"), pose_camera(bl_scene, pose, name) as camera:
            cap = capture(
                bl_scene,
                camera=camera,
                frame=frame,
                name=name,
                resolution=(region.size, region.size),
                samples=samples,
                seed=seed,
                cache_dir=cache_dir,
                on_progress=on_progress,
            )
        if cap.covered.any():
            rendered.append(cap)
    return vplace.coverage.Coverage([], poses, before, after, radii, picked, eyes), rendered


def reference_of(
    cap: Capture, view: vplace.View, gloss: np.ndarray | None, label: str
) -> vplace.job.Reference:
    """The arrays of a capture that a run is scored against."""
    return vplace.job.Reference(
        view,
        cap.direct,
        cap.gi,
        cap.modelled_indirect(gloss),
        label,
        camera=cap.view,
        samples=cap.samples,
        seen=vplace.job.seen_directly(cap.seen_light, cap.direct),
        diffuse_direct=cap.diffuse_direct,
        diffuse_color=cap.diffuse_color,
    )


def own_reference(captured: Captured, samples: int) -> vplace.job.Reference:
    """The first view's own capture as the reference (no extra render)."""
    return reference_of(
        captured.captures[0],
        captured.views[0],
        captured.gloss[0] if captured.gloss else None,
        f"its own capture ({samples} spp; the capture's noise lowers every score)",
    )


def render_reference(
    bl_scene: bpy.types.Scene,
    scene: vplace.Scene,
    exported: ExportedScene,
    captured: Captured,
    render: ReferenceRender,
    *,
    capture_samples: int,
    cache_dir: Path | None,
    stage: Callable[[str], AbstractContextManager[None]],
) -> vplace.job.Reference:
    """What the main job scores against: the scene camera at the current frame, rendered by
    Cycles (cached) as ``render`` says; the first view's own capture when that may stand in and
    is the scene camera."""
    cam = bl_scene.camera
    first = captured.captures[0]
    if render.own_capture_ok and first.camera == cam.name:
        return own_reference(captured, capture_samples)
    with stage(f"reference render {cam.name} ({render.samples} spp, cached)"):
        ref = capture(
            bl_scene,
            camera=cam,
            resolution=(first.width, first.height),
            samples=render.samples,
            seed=render.seed,
            cache_dir=cache_dir,
        )
    kind = (
        "a ground truth"
        if render.ground_truth
        else "as noisy as the capture: give truth samples for a ground truth"
    )
    gloss = gloss_mask(scene, exported, ref) if captured.specular else None
    return reference_of(
        ref,
        view_of(ref, held_out=True, gloss=gloss, scene=scene),
        gloss,
        f"Cycles at {render.samples} spp of {cam.name} ({kind})",
    )
