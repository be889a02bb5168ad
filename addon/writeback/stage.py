"""The write-back stage of a job: the VPLs (and the stand-in lights) written as Blender lights,
what EEVEE will not show right, and the main job's EEVEE render of the written lights."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from contextlib import AbstractContextManager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import bpy
import numpy as np

from ..capture import passes as capture
from ..capture.native_view import vpl_unlit
from ..errors import WriteBackError, run_operator
from ..native import vplace
from ..settings import override
from . import apply, cut_lights, eevee_setup
from .stand_ins import StandIns

if TYPE_CHECKING:
    from ..scene.export import ExportedScene


@dataclass
class WrittenBack:
    """What the write-back left: the stand-in lights it wrote, EEVEE's problems and what EEVEE
    shows of the user's own lamps differently (``eevee_setup.lamp_notes``), in words."""

    stand_ins: StandIns
    problems: list[str]
    lamp_notes: list[str]


def write_back(
    bl_scene: bpy.types.Scene,
    vpls: vplace.VplSet,
    *,
    specular: float,
    scene: vplace.Scene,
    exported: ExportedScene,
    lights: StandIns,
    cut_lamps: Sequence[str],
    blend_path: Path | None,
    stage: Callable[[str], AbstractContextManager[None]],
    log: Callable[[str], None],
    coverage: vplace.coverage.Coverage | None = None,
) -> WrittenBack:
    """Writes ``vpls`` (specular factor ``specular``: ``Prepared.vpl_specular``) and the
    stand-in ``lights`` of ``exported`` (``stand_ins.stand_ins``) into the VPL collection
    (``apply.write_vpls``, with ``cut_lamps``: ``Prepared.cut_lamps``), leaves unlit by the
    VPLs the objects ``native_view.vpl_unlit`` names (with a note), shows the region the
    lights were laid out for (``apply.write_region`` of the job's ``coverage``: its cameras'
    regions and its coverage views; without coverage views the last run's region goes),
    saves a copy of the file to
    ``blend_path`` when given, and logs what EEVEE will not show right and the lamp notes
    (``eevee_setup.lamp_notes``)."""
    unlit = vpl_unlit(exported, specular)
    if unlit:
        log(
            f"[vplace] note: the VPLs do not light {_names(unlit)} (Light Linking): sharp "
            "metal or glass, whose reflections are EEVEE's ray tracing's"
        )
    with stage("write back"):
        apply.write_vpls(
            bl_scene,
            vpls,
            scene_diagonal=scene.scale,
            region=scene.region,
            specular=specular,
            unlit=unlit,
            emitters=lights.emitters,
            sun=lights.sun,
            closed=lights.closed,
            cut_lamps=cut_lamps,
        )
        apply.write_region(bl_scene, apply.RegionMarks.of(coverage))
        if blend_path is not None:
            run_operator(
                "wm.save_as_mainfile",
                f"cannot save a copy of the file to {blend_path}",
                WriteBackError,
                filepath=str(blend_path),
                copy=True,
            )
    found = eevee_setup.problems(bl_scene)
    problems = [str(p) for p in found]
    for problem in found:
        log(f"[vplace] warning: EEVEE: {problem.advice()}")
    notes = eevee_setup.lamp_notes(bl_scene, cut_lamps)
    for note in notes:
        log(f"[vplace] note: {note}")
    return WrittenBack(lights, problems, notes)


def _names(names: Sequence[str], most: int = 3) -> str:
    """Up to ``most`` quoted names, and how many more."""
    shown = ", ".join(repr(n) for n in names[:most])
    return shown + (f" and {len(names) - most} more" if len(names) > most else "")


def score_eevee(
    bl_scene: bpy.types.Scene,
    reference: vplace.job.Reference,
    path: Path,
    cache_dir: Path | None,
    vpl_light: np.ndarray,
    emissive: Sequence[str] = (),
) -> dict[str, float]:
    """Renders the written lights with EEVEE from the scene camera (float, Standard view, the
    scored set-up), scores the image against the reference, and saves it as a PNG picture.

    As "Set up EEVEE for vplace" would (``eevee_setup.world_for_render``): with sky portals the
    world lights nothing but shows to the camera; else, when the world emits and the scene has
    no vplace probe volume, one is baked for the render (without indirect light, removed
    after), or EEVEE would light closed rooms with the world through their walls; its bake
    seconds are reported apart from the frame's.

    A second render hides the VPLs (the scene's lights and vplace's stand-ins stay): EEVEE's
    direct light, whose brightness against Cycles' (``direct_brightness``) is the part of the
    difference that is not the VPLs' (EEVEE's light of the scene's lamps and of the
    stand-ins). ``vpl_light``, the evaluator's image of the written VPLs, splits the error as
    ``vplace.job.attribute`` does (``attribution_*``). Cycles rendering the same lights
    (``eevee_setup.cycles_as_eevee_lights``; ``emissive``, the emissive materials' names, then
    light nothing) splits EEVEE's direct light into the stand-ins' own error and EEVEE's
    rendering of them (``attribution_stand_in_share``)."""
    from . import eevee_render as eevee

    height, width = reference.gi.shape[:2]

    def render(diffuse_color: bool = False) -> eevee.EeveeImage:
        return eevee.render(
            bl_scene,
            resolution=(width, height),
            samples=eevee.EEVEE_SAMPLES,
            setup=eevee.SETUPS["vpl"],
            cache_dir=cache_dir,
            diffuse_color=diffuse_color,
        )

    stand_ins = None
    with eevee_setup.world_for_render(bl_scene) as bake:
        img = render()
        with override() as g:
            apply.hide_vpl_lights(g, bl_scene)
            with_colour = (
                reference.diffuse_direct is not None and reference.diffuse_color is not None
            )
            direct = render(diffuse_color=with_colour)
            if eevee_setup.cycles_as_eevee_lights(g, bl_scene, emissive):
                stand_ins = capture.capture(
                    bl_scene,
                    resolution=(width, height),
                    samples=eevee_setup.STAND_IN_SAMPLES,
                    include_vpls=True,
                ).direct
    vplace.images.save_png(path, img.image)
    colour = None
    if direct.diffuse_color is not None:
        colour = vplace.job.colour_part(
            reference.diffuse_direct, direct.diffuse_color, reference.diffuse_color
        )
    a = vplace.job.attribute(
        img.image,
        direct.image,
        reference.direct,
        vpl_light,
        reference.gi,
        reference.seen,
        stand_ins,
        cut_lights.cut_pixels(bl_scene, reference.view, reference.seen),
        colour,
    )
    out = {
        **vplace.job.score(img.image, reference.gi),
        "seconds": img.seconds,
        "samples": eevee.EEVEE_SAMPLES,
        "world_volume_bake_seconds": bake,
        "direct_brightness": a.direct_brightness,
    }
    for part in vplace.job.ATTRIBUTION_PARTS:
        out[f"attribution_rmse_{part}"] = a.rmse[part]
        out[f"attribution_share_{part}"] = a.share[part]
    out["attribution_vpl_brightness"] = a.vpl_brightness
    out["attribution_vpl_hot_pixels"] = a.vpl_hot_pixels
    if reference.seen is not None:
        out["attribution_seen_pixels"] = a.seen_pixels
        out["attribution_seen_share"] = a.seen_share
    if stand_ins is not None:
        out["attribution_stand_in_share"] = a.stand_in_share
    out["attribution_cut_pixels"] = a.cut_pixels
    out["attribution_cut_share"] = a.cut_share
    out["attribution_cut_brightness"] = a.cut_brightness
    if colour is not None:
        out["attribution_colour_share"] = a.colour_share
    return out
