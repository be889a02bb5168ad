"""EEVEE as a measured output: float renders scored like the evaluator's image, the settings
vplace's measurements chose, and what a Blender user would pick instead.

:func:`render` renders the scene with EEVEE (or Cycles) from a camera into a 32-bit float EXR
(Standard view transform, so the pixels are scene-linear as in Cycles' passes) and returns it as
numpy, row 0 at the top, optionally cached on disk by everything that changes it. Every setting
it changes is restored afterwards, also when the render fails. An 8-bit PNG is a picture, not a
measurement: the report and the demo score these float images against the same Cycles ground
truth as the evaluator's.

The ways to render a view, each a :class:`Setup` (what a user would set up):

- ``vpl``: EEVEE with the written VPLs, ray tracing off (the VPLs carry the bounce light;
  EEVEE's screen-space GI would count it twice), shadows on and a pool that holds them
  (:mod:`eevee_setup`); for lights written with the near-field gather
  (``vplace.VplSet.near_field``), ray tracing on with the fast GI gathering global
  illumination within their near-field distance (``eevee_setup.fast_gi_for``), the light
  between nearby surfaces that the evaluator adds and no VPL carries;
- ``vpl+rt``: the same plus EEVEE's ray tracing for glossy reflections, its fast GI set to
  ambient occlusion only (the global-illumination one would add the bounce again): what
  :func:`eevee_setup.set_up` applies;
- ``plain``: EEVEE without help (no VPLs, no ray tracing): EEVEE's own direct light;
- ``rt``: EEVEE's own ray tracing with its fast GI approximation (no VPLs);
- ``rt+volume``: that plus a light probe volume fitted to the scene's bounds and baked with
  its default capture (:func:`eevee_setup.temporary_volume`; the bake time is a one-time
  cost);
- ``cycles+oidn``: Cycles at a few samples denoised with OpenImageDenoise.

A set-up without VPLs hides vplace's lights for its render. Where the world has a sun, the
report and the animation score ``plain``, ``rt`` and ``rt+volume`` with the sun lamp a user
would add (:func:`eevee_setup.users_sun`): EEVEE extracts next to nothing from such a sky.
Every set-up filters its pixels as the truth does (:data:`FILM_FILTER_SIZE`; Cycles' set-up
with the truth's one-pixel box), so the scores compare light, not anti-aliasing.
"""

from __future__ import annotations

import functools
import hashlib
import os
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import bpy
import numpy as np
import OpenEXR

from ..capture import render_key
from ..capture.passes import IMAGE_SETTINGS, PIXEL_FILTER, hide_vpls, read_exr, vpl_objects
from ..compat import eevee_engine
from ..errors import AddonError, run_operator
from ..scene.export import render_view_layer
from ..settings import SettingsGuard, measured_frame, override, standard_view
from . import apply, eevee_setup

#: EEVEE's render samples in the scored renders (Blender renders 64 by default). 4 were as close
#: to Cycles' image of the VPLs as 16 (SSIM 0.946 against 0.949 on Sponza), but not EEVEE's soft
#: shadows of the scene's own lamps: on the Cornell box EEVEE's direct light scored SSIM 0.910
#: and 0.886 against Cycles' at 4 samples, 0.978 and 0.941 at 16 (the held-out low and the high
#: camera), which was all of EEVEE's SSIM gap to the evaluator there; 16 cost 1.8x the time.
EEVEE_SAMPLES = 16
#: EEVEE's film filter in the scored renders, pixels. The captures and the truth are Cycles with
#: a one-pixel box filter (``capture.passes``); EEVEE's filter is a Gaussian of standard deviation
#: 0.284 x ``render.filter_size`` (its source reads the size as a radius, where Cycles reads its
#: ``filter_width`` as a width), so 1.0 gives 0.284 px against the box's 0.289. At Blender's
#: default 1.5 EEVEE was twice as blurred: the edges of the panel room's visible emissive panels
#: held 51 % of its direct light's squared error (RMSE 0.047 against Cycles', 0.031 at 1.0). The
#: sharper filter averages fewer samples: without the stand-ins' jitter SSIM fell 0.945 -> 0.938,
#: with it (what vplace writes) it rose 0.963 -> 0.965 and RMSE fell 0.045 -> 0.027.
FILM_FILTER_SIZE = 1.0
#: Bump when a cached render's meaning changes.
RENDER_VERSION = 8


@dataclass(frozen=True)
class Setup:
    """One way to render a view (see the module docs)."""

    name: str
    engine: str = field(default_factory=eevee_engine)
    vpls: bool = False
    raytracing: bool = False
    fast_gi: bool = True
    volume: bool = False
    denoise: bool = False
    #: The VPL collection whose kept region and near-field distance set the lamps' reach and
    #: the fast GI (``eevee_setup.threshold_for``, ``fast_gi_for``): the written lights', or
    #: another that a render writes for itself (``match_eevee.COLLECTION``), so that a run
    #: renders the same whether or not an earlier run's lights are in the scene.
    collection: str = apply.COLLECTION_NAME

    def configure(self, g: SettingsGuard, scene: bpy.types.Scene) -> None:
        """Applies this set-up's settings through ``g`` (restored by its guard)."""
        if self.engine == "CYCLES":
            c = scene.cycles
            g.set(c, "device", "CPU")
            g.set(c, "use_adaptive_sampling", False)
            g.set(c, "use_denoising", self.denoise)
            if self.denoise:
                g.set(c, "denoiser", "OPENIMAGEDENOISE")
            g.set(c, "use_animated_seed", False)
            # The truth's filter, not the user's: scored like the others.
            for attr, value in PIXEL_FILTER.items():
                g.set(c, attr, value)
            return
        e = scene.eevee
        g.set(scene.render, "filter_size", FILM_FILTER_SIZE)
        # Every EEVEE set-up lets the user's lamps reach across the scene (Cycles never fades
        # them): the comparison is about bounce light, not a threshold a user would fix anyway.
        threshold = eevee_setup.threshold_for(scene, self.collection)
        if threshold != e.light_threshold:
            g.set(e, "light_threshold", threshold)
        # Every EEVEE set-up traces the soft shadows with the rays vplace's set-up gives them
        # (eevee_setup.shadow_rays_for): the scene's lamps' noise is EEVEE's, not the lights'.
        rays = eevee_setup.shadow_rays_for(scene)
        if rays is not None:
            g.set(e, "shadow_ray_count", rays)
        # Lights written with the near-field gather leave it to the fast GI, which EEVEE
        # applies only with ray tracing on.
        method, near = eevee_setup.fast_gi_for(scene, self.collection) if self.vpls else ("", 0.0)
        raytracing = self.raytracing or near > 0.0
        g.set(e, "use_raytracing", raytracing)
        if hasattr(e, "use_fast_gi"):  # Blender 4.5 on; 4.2's fast GI is on with ray tracing
            g.set(e, "use_fast_gi", self.fast_gi)
        if raytracing:
            g.set(e, "ray_tracing_method", "SCREEN")
        if self.vpls:
            # What eevee_setup.set_up applies: shadows on, a pool that holds them, and ray
            # tracing (when on) with the fast GI of the written lights: ambient occlusion only
            # (no second bounce), or global illumination within their near-field distance.
            g.set(e, "use_shadows", True)
            mb = eevee_setup.pool_for(eevee_setup.shadow_pages(scene))
            if int(e.shadow_pool_size) < mb:
                g.set(e, "shadow_pool_size", str(mb))
            if raytracing:
                g.set(e, "fast_gi_method", method)
                if near > 0.0:
                    g.set(e, "fast_gi_distance", near)
            # vplace wrote the world's sun as a lamp: EEVEE must not extract it a second time.
            world = scene.world
            if world is not None and world.sun_threshold > 0.0 and apply.world_sun_light(scene):
                g.set(world, "sun_threshold", 0.0)


SETUPS = {
    s.name: s
    for s in (
        Setup("vpl", vpls=True),
        Setup("vpl+rt", vpls=True, raytracing=True),
        Setup("plain"),
        Setup("rt", raytracing=True),
        Setup("rt+volume", raytracing=True, volume=True),
        Setup("cycles+oidn", engine="CYCLES", denoise=True),
    )
}


@dataclass
class EeveeImage:
    """An EEVEE render: scene-linear RGB (H, W, 3) float32, row 0 at the top, and its time."""

    image: np.ndarray
    seconds: float
    #: EEVEE's Diffuse Color pass (H, W, 3), where the render was asked for it: the surfaces'
    #: colour as EEVEE filters it (its textures' mipmaps and its film filter), which the
    #: attribution holds against Cycles' (``vplace.job.attribute``'s ``colour``).
    diffuse_color: np.ndarray | None = None


def read_exr_rgb(path: Path) -> np.ndarray:
    """The RGB channels of a single-layer EXR as (H, W, 3) float32, row 0 at the top."""
    with OpenEXR.File(str(path)) as f:
        channels = f.parts[0].channels
        if "RGB" in channels or "RGBA" in channels:
            px = np.asarray(channels.get("RGB", channels.get("RGBA")).pixels, dtype=np.float32)
            return np.ascontiguousarray(px[..., :3])
        return np.stack(
            [np.asarray(channels[c].pixels, dtype=np.float32) for c in ("R", "G", "B")], axis=-1
        )


def _diffuse_color_output(g: SettingsGuard, scene: bpy.types.Scene) -> str:
    """Turns the output into a multilayer EXR with the Diffuse Color pass of the view layer that
    renders (``export.render_view_layer``); returns that layer's name."""
    layer = render_view_layer(scene)
    g.set(layer, "use_pass_combined", True)
    g.set(layer, "use_pass_diffuse_color", True)
    g.image_format(scene.render.image_settings, "OPEN_EXR", multilayer=True)
    return layer.name


def _configure_output(g: SettingsGuard, scene: bpy.types.Scene, path: Path) -> None:
    r = scene.render
    g.set(r, "filepath", str(path))
    g.set(r, "use_compositing", False)
    g.set(r, "use_sequencer", False)
    g.set(r, "use_border", False)
    standard_view(g, scene)
    ims = r.image_settings
    g.remember(ims, IMAGE_SETTINGS)
    g.image_format(ims, "OPEN_EXR")
    g.set(ims, "color_mode", "RGB")
    g.set(ims, "color_depth", "32")
    g.set(ims, "exr_codec", "NONE")


def _platform() -> str | None:
    import gpu

    try:
        p = gpu.platform
        return f"{p.backend_type_get()} {p.vendor_get()} {p.renderer_get()} {p.version_get()}"
    except (SystemError, RuntimeError, AttributeError):  # no GPU context (yet)
        return None


@functools.cache
def _start_gpu() -> None:
    """Makes Blender start its GPU context: a one-pixel Workbench render of a temporary empty
    scene (0.4 s on llvmpipe), removed afterwards with its camera. Once a process: where it
    started no context, there is no GPU to start, and EEVEE says so when it renders."""
    scene = bpy.data.scenes.new("vplace GPU probe")
    cam_data = bpy.data.cameras.new("vplace GPU probe")
    cam = bpy.data.objects.new("vplace GPU probe", cam_data)
    try:
        scene.collection.objects.link(cam)
        scene.camera = cam
        scene.render.engine = "BLENDER_WORKBENCH"
        scene.render.resolution_x = scene.render.resolution_y = 1
        bpy.ops.render.render(scene=scene.name)
    except RuntimeError:
        pass  # no GPU to start: EEVEE will say so when it renders
    finally:
        bpy.data.objects.remove(cam)
        bpy.data.cameras.remove(cam_data)
        bpy.data.scenes.remove(scene)


def gpu_renderer() -> str | None:
    """The GPU and driver that EEVEE renders on (the backend, vendor, renderer and version
    strings Blender reports), or None where Blender has no GPU. In background mode Blender
    starts its GPU context only when something renders, so this starts it (:func:`_start_gpu`).

    Why it keys EEVEE's renders: two GPUs render the same scene differently (EEVEE's shadows
    and direct light in the sky room differed by up to .08 RMSE between an NVIDIA H100 and
    Mesa's llvmpipe), so a cache that holds renders from two machines must not hand one
    machine's image to the other."""
    found = _platform()
    if found is None and bpy.app.background:
        _start_gpu()
        found = _platform()
    return found


def _key(
    scene: bpy.types.Scene,
    camera: bpy.types.Object,
    resolution: tuple[int, int],
    samples: int | None,
    engine: str,
    setup: Setup | None,
    seed: int,
    renderer: str | None,
    diffuse_color: bool = False,
) -> str:
    """What a render depends on: what the engine reads to render the scene (:mod:`render_key`),
    vplace's lights included unless the set-up hides them, the camera, the size, the samples,
    the set-up and, for EEVEE, the GPU that renders it (:func:`gpu_renderer`)."""
    h = hashlib.sha256()
    with_vpls = setup is None or setup.vpls
    skip = () if with_vpls else vpl_objects(scene)
    h.update(render_key.scene_signature(scene, engine, skip=skip).encode())
    if setup is None:  # the scene's own EEVEE settings, those a set-up sets included
        h.update(repr(render_key.plain_values(scene.eevee)).encode())
    h.update(repr([list(r) for r in camera.matrix_world]).encode())
    h.update(repr(render_key.plain_values(camera.data)).encode())
    name = setup.name if setup is not None else "scene"
    if setup is not None and setup.collection != apply.COLLECTION_NAME:
        name += f" ({setup.collection})"
    if setup is not None and engine != "CYCLES":  # the lamps' reach follows the kept region
        h.update(repr(apply.stored_region(setup.collection, scene)).encode())
    h.update(repr((resolution, samples, engine, name, seed, RENDER_VERSION, renderer)).encode())
    if diffuse_color:
        h.update(b"diffuse color")
    if setup is not None and setup.vpls and engine != "CYCLES":
        method, near = eevee_setup.fast_gi_for(scene, setup.collection)
        if near > 0.0:  # the fast GI the set-up applies follows the written lights
            h.update(repr((method, near)).encode())
    return h.hexdigest()[:24]


def render(
    scene: bpy.types.Scene,
    *,
    resolution: tuple[int, int],
    camera: bpy.types.Object | None = None,
    samples: int | None = None,
    setup: Setup | None = None,
    seed: int = 0,
    cache_dir: Path | None = None,
    diffuse_color: bool = False,
) -> EeveeImage:
    """Renders ``scene`` from ``camera`` (default: the scene camera) with ``setup`` (default: the
    scene's own EEVEE settings) to a float image. ``samples``: EEVEE's render samples or Cycles'
    (default: the scene's). With ``cache_dir``, an identical earlier render on the same GPU is
    loaded instead. With ``diffuse_color`` the image comes with the render's Diffuse Color
    pass (:attr:`EeveeImage.diffuse_color`)."""
    camera = camera if camera is not None else scene.camera
    if camera is None or camera.type != "CAMERA":
        raise AddonError("the render needs a camera object")
    engine = setup.engine if setup is not None else eevee_engine()
    on_gpu = engine != "CYCLES"
    renderer = gpu_renderer() if on_gpu else None
    cached = None
    if cache_dir is not None:
        key = _key(scene, camera, resolution, samples, engine, setup, seed, renderer, diffuse_color)
        cached = Path(cache_dir) / f"render-{key}.npz"
        if on_gpu and renderer is None:
            # No GPU context to ask: render, then file the image under the GPU that rendered it.
            cached = None
        elif cached.exists():
            with np.load(cached) as data:
                colour = data["diffuse_color"] if "diffuse_color" in data else None
                found = EeveeImage(data["image"], float(data["seconds"]), colour)
            render_key.touch(cached)
            return found
    with tempfile.TemporaryDirectory(prefix="vplace-render-") as tmp:
        path = Path(tmp) / "render.exr"
        with override() as g:
            r = scene.render
            g.set(scene, "camera", camera)
            g.set(r, "engine", engine)
            g.set(r, "resolution_x", resolution[0])
            g.set(r, "resolution_y", resolution[1])
            g.set(r, "resolution_percentage", 100)
            if engine == "CYCLES":
                g.set(scene.cycles, "seed", seed)
                if samples is not None:
                    g.set(scene.cycles, "samples", samples)
            elif samples is not None:
                g.set(scene.eevee, "taa_render_samples", samples)
            _configure_output(g, scene, path)
            measured_frame(g, scene, camera)
            layer = _diffuse_color_output(g, scene) if diffuse_color else None
            if setup is not None:
                setup.configure(g, scene)
                if not setup.vpls:
                    hide_vpls(g)
            start = time.perf_counter()
            what = f"the {engine} render of scene {scene.name!r} did not finish"
            run_operator("render.render", what, write_still=True, scene=scene.name)
            seconds = time.perf_counter() - start
        if not path.exists():
            raise AddonError(f"{what}: Blender wrote no image")
        if layer is None:
            out = EeveeImage(read_exr_rgb(path), seconds)
        else:
            passes = read_exr(path, layer)
            if "Combined" not in passes or "Diffuse Color" not in passes:
                raise AddonError(f"{what}: the image has no Combined and Diffuse Color passes")
            out = EeveeImage(
                np.ascontiguousarray(passes["Combined"][..., :3]),
                seconds,
                np.ascontiguousarray(passes["Diffuse Color"][..., :3]),
            )
    if cache_dir is not None and cached is None and (renderer := gpu_renderer()) is not None:
        key = _key(scene, camera, resolution, samples, engine, setup, seed, renderer, diffuse_color)
        cached = Path(cache_dir) / f"render-{key}.npz"
    if cached is not None:
        cached.parent.mkdir(parents=True, exist_ok=True)
        tmp_path = cached.with_suffix(".tmp.npz")
        extra = {} if out.diffuse_color is None else {"diffuse_color": out.diffuse_color}
        np.savez(tmp_path, image=out.image, seconds=out.seconds, **extra)
        os.replace(tmp_path, cached)
        render_key.prune(cached.parent, keep=cached)
    return out
