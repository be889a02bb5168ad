"""Capture: one Cycles render per view gives the G-buffer and the lighting passes (DESIGN: Capture).

Render settings are changed through :func:`settings.override` and restored however the render
ends. The lights vplace wrote (the ``vplace VPLs`` collection) are hidden from the render, so a
capture never sees bounce light it would then count twice. Results are cached on disk as
``.npz`` keyed by everything that changes the render (:func:`capture_key`: :mod:`render_key`'s
signature of what Cycles reads, without vplace's lights, the camera, the resolution, the
samples and the seed); the cache keeps under
:data:`render_key.CACHE_LIMIT_BYTES`, least recently used entries removed first.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import tempfile
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, fields
from pathlib import Path

import bpy
import numpy as np
import OpenEXR

from ..compat import PASS_NAMES
from ..errors import CaptureError, run_operator
from ..native import vplace
from ..scene.export import VPL_MARKER, is_vplace, render_view_layer
from ..scene.materials import LUMINANCE
from ..settings import SettingsGuard, at_frame, measured_frame, override, standard_view
from . import render_key

#: Bump when the capture's content or layout changes, to invalidate caches.
CAPTURE_VERSION = 4
#: Planar depth of pixels that see no geometry (Cycles writes 1e10).
BACKGROUND_DEPTH = 1e9

#: EXR pass name -> view-layer flag that enables it.
PASS_FLAGS = {
    "Combined": "use_pass_combined",
    "Depth": "use_pass_z",
    "Normal": "use_pass_normal",
    "Position": "use_pass_position",
    "Diffuse Direct": "use_pass_diffuse_direct",
    "Diffuse Indirect": "use_pass_diffuse_indirect",
    "Diffuse Color": "use_pass_diffuse_color",
    "Glossy Direct": "use_pass_glossy_direct",
    "Glossy Indirect": "use_pass_glossy_indirect",
    "Glossy Color": "use_pass_glossy_color",
    "Emission": "use_pass_emit",
    "Environment": "use_pass_environment",
}


#: Cycles' pixel filter of every capture and ground truth: a one-pixel box, so each pass is the
#: mean over its pixel (``eevee_render`` scores every other render with the same spread).
PIXEL_FILTER: dict[str, object] = {"pixel_filter_type": "BOX", "filter_width": 1.0}
#: Image settings in the order they must be restored (each may reset the ones after it).
IMAGE_SETTINGS = ("media_type", "file_format", "color_mode", "color_depth", "exr_codec")


__all__ = ["Capture", "CaptureError", "camera_matrices", "capture", "capture_key"]


#: A pixel shows a lamp's mirror image (:attr:`Capture.seen_light`) where its glossy direct
#: light is above this many times the view's mean direct light: a surface a lamp lights is a
#: few times the mean at most, an emitter's own radiance hundreds of times.
MIRRORED_LAMP = 20.0

#: Where the diffuse layer holds at least this share of a pixel's modelled reflectance
#: (luminance), its diffuse passes measure the light the surface receives
#: (:meth:`Capture.reflected_irradiance`); below it the glossy passes stand in, in proportion.
DIFFUSE_SHARE = 0.1


@dataclass
class Capture:
    """The passes of one view, H x W (x 3) float32, row 0 at the top, scene-linear."""

    combined: np.ndarray
    depth: np.ndarray
    normal: np.ndarray
    position: np.ndarray
    diffuse_direct: np.ndarray
    diffuse_indirect: np.ndarray
    diffuse_color: np.ndarray
    glossy_direct: np.ndarray
    glossy_indirect: np.ndarray
    glossy_color: np.ndarray
    emission: np.ndarray
    environment: np.ndarray
    samples: int
    render_seconds: float
    key: str
    #: The view's name (the camera's, or the camera's and the frame's), the camera object's
    #: name, its world position (3,) and world-to-clip matrix (4, 4).
    view: str
    camera: str
    camera_position: np.ndarray
    world_to_clip: np.ndarray

    @property
    def height(self) -> int:
        return int(self.depth.shape[0])

    @property
    def width(self) -> int:
        return int(self.depth.shape[1])

    @property
    def covered(self) -> np.ndarray:
        """True where the pixel sees geometry."""
        return self.depth < BACKGROUND_DEPTH

    @property
    def albedo(self) -> np.ndarray:
        """Diffuse albedo (the DiffCol pass)."""
        return self.diffuse_color

    @property
    def direct(self) -> np.ndarray:
        """``D = DiffDir*DiffCol + GlossDir*GlossCol + Emit + Env``."""
        return (
            self.diffuse_direct * self.diffuse_color
            + self.glossy_direct * self.glossy_color
            + self.emission
            + self.environment
        ).astype(np.float32)

    @property
    def seen_light(self) -> np.ndarray:
        """(H, W, 3) the light of an emitter the camera sees (``vplace.job.seen_directly``'s
        ``seen_light``): Cycles' ``Emit + Env``, plus the glossy direct light ``GlossDir *
        GlossCol`` of the pixels where a lamp's mirror image shows, those whose glossy direct
        light is above :data:`MIRRORED_LAMP` times the view's mean direct light (luminance,
        over covered pixels). A lamp seen in chrome is a few pixels hundreds of times brighter
        than the room, which EEVEE and Cycles anti-alias each their own way: on a kitchen's
        chrome lamp shade, five such pixels held nearly all of EEVEE's squared error."""
        lum = np.asarray(vplace.LUMINANCE, dtype=np.float32)
        glossy = (self.glossy_direct * self.glossy_color)[..., :3]
        covered = self.covered
        mean = float((self.direct[..., :3] @ lum)[covered].mean()) if covered.any() else 0.0
        mirrored = (glossy @ lum > MIRRORED_LAMP * mean) & covered
        seen = self.emission[..., :3] + self.environment[..., :3]
        return (seen + np.where(mirrored[..., None], glossy, 0.0)).astype(np.float32)

    @property
    def gi(self) -> np.ndarray:
        """``G = Combined`` (RGB)."""
        return self.combined

    @property
    def indirect(self) -> np.ndarray:
        """The diffuse indirect light ``DiffInd * DiffCol``: what diffuse VPLs can reproduce, and
        the target of the fit, the layout iteration and the refit. (``G - D`` would also hold
        glossy and transmitted indirect light, which no diffuse VPL produces.)"""
        return (self.diffuse_indirect * self.diffuse_color).astype(np.float32)

    def reflectance(self, gloss: np.ndarray | None = None) -> np.ndarray:
        """What a receiver reflects of the light the VPLs give it: the diffuse albedo, plus the
        Glossy Color pass where ``gloss`` (an (H, W) weight, ``native_view.gloss_mask``) says its
        glossy layer is modelled."""
        if gloss is None:
            return self.albedo
        return (self.albedo + gloss[..., None] * self.glossy_color).astype(np.float32)

    def glossy_stand_in(self, gloss: np.ndarray | None = None) -> np.ndarray:
        """(H, W) in [0, 1]: how far the diffuse passes fail to measure the light a pixel's
        surface receives, ``1 - t``, ``t = share / DIFFUSE_SHARE`` clamped, ``share`` the
        diffuse layer's part of the reflectance (luminance) where ``gloss`` adds the glossy
        layer; 0 everywhere without ``gloss`` (see :meth:`reflected_irradiance`)."""
        if gloss is None:
            return np.zeros(self.covered.shape, np.float32)
        diffuse = self.diffuse_color @ LUMINANCE
        total = diffuse + gloss * (self.glossy_color @ LUMINANCE)
        share = np.where(total > 0.0, diffuse / np.where(total > 0.0, total, 1.0), 1.0)
        return (1.0 - np.clip(share / DIFFUSE_SHARE, 0.0, 1.0)).astype(np.float32)

    def reflected_irradiance(
        self, gloss: np.ndarray | None = None, direct: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """The direct and the indirect irradiance over pi that, times :meth:`reflectance`, give
        the light a pixel's surface sends on: what the layout's pixel emitters and the
        near-field gather reflect.

        Irradiance does not depend on the surface's layers, and ``DiffDir`` and ``DiffInd``
        measure it on any surface with a diffuse layer, the same from every view. But Cycles
        writes a diffuse pass only where there is a diffuse layer: a rough metal (Sponza's
        curtains, metallic 1) has a black ``DiffDir`` however brightly the sun lights it, and
        with it alone the sunniest surface a view saw sent nothing on. Where the diffuse layer
        holds less than :data:`DIFFUSE_SHARE` of the reflectance, something else stands in, in
        proportion (:meth:`glossy_stand_in`, ``s``): for the direct light ``direct`` ((H, W, 3),
        vplace's own estimate, ``native_view.metal_irradiance``), else ``GlossDir``; for the
        indirect light ``GlossInd``, the only measure of it there. ``GlossDir`` depends on the
        view (a highlight reads high)."""
        if gloss is None:
            return self.diffuse_direct, self.diffuse_indirect
        s = self.glossy_stand_in(gloss)[..., None]
        stand_in = self.glossy_direct if direct is None else direct

        def mix(diffuse_pass: np.ndarray, other: np.ndarray) -> np.ndarray:
            return ((1.0 - s) * diffuse_pass + s * other).astype(np.float32)

        return (
            mix(self.diffuse_direct, stand_in),
            mix(self.diffuse_indirect, self.glossy_indirect),
        )

    def modelled_indirect(self, gloss: np.ndarray | None = None) -> np.ndarray:
        """The indirect light vplace models: :attr:`indirect`, plus the glossy indirect light
        ``GlossInd * GlossCol`` where ``gloss`` says so (see :meth:`reflectance`)."""
        if gloss is None:
            return self.indirect
        extra = gloss[..., None] * self.glossy_indirect * self.glossy_color
        return (self.indirect + extra).astype(np.float32)

    def save(self, path: Path) -> None:
        """Writes the capture as an uncompressed ``.npz``."""
        arrays = {f.name: getattr(self, f.name) for f in fields(self)}
        tmp = path.with_suffix(".tmp.npz")
        np.savez(tmp, **arrays)
        os.replace(tmp, path)

    @classmethod
    def load(cls, path: Path) -> Capture:
        """Reads a capture written by :meth:`save`."""
        with np.load(path) as data:
            kw = {f.name: data[f.name] for f in fields(cls)}
        kw["samples"] = int(kw["samples"])
        kw["render_seconds"] = float(kw["render_seconds"])
        kw["key"] = str(kw["key"])
        kw["camera"] = str(kw["camera"])
        kw["view"] = str(kw["view"])
        return cls(**kw)


@contextlib.contextmanager
def cycles_session(scene: bpy.types.Scene) -> Iterator[None]:
    """Cycles keeps its scene between the captures made in the block: the render engine is
    Cycles for the whole block, with ``render.use_persistent_data``, both put back after
    (which frees what Cycles kept). Each capture then syncs what changed since the last (the
    camera, the size), where on its own it syncs the whole scene: a capture sets the engine
    and restores it, and a new engine, or the same one assigned again, makes Cycles start
    over. The passes are the same, bit for bit (``tests/addon/test_passes.py``)."""
    with override() as g:
        g.set(scene.render, "engine", "CYCLES")
        g.set(scene.render, "use_persistent_data", True)
        yield


def _render(scene: bpy.types.Scene, view_layer: bpy.types.ViewLayer) -> None:
    """Renders one still (a seam that tests replace to inject failures)."""
    run_operator(
        "render.render",
        f"Cycles did not finish the capture of scene {scene.name!r}",
        CaptureError,
        write_still=False,
        scene=scene.name,
        layer=view_layer.name,
    )


def _configure(
    g: SettingsGuard,
    scene: bpy.types.Scene,
    view_layer: bpy.types.ViewLayer,
    resolution: tuple[int, int],
    samples: int,
    seed: int,
) -> None:
    r, c = scene.render, scene.cycles
    g.set(r, "engine", "CYCLES")
    g.set(c, "device", "CPU")
    g.set(c, "samples", samples)
    g.set(c, "use_adaptive_sampling", False)
    g.set(c, "use_denoising", False)
    g.set(c, "seed", seed)
    g.set(c, "use_animated_seed", False)
    for attr, value in PIXEL_FILTER.items():
        g.set(c, attr, value)
    g.set(r, "resolution_x", resolution[0])
    g.set(r, "resolution_y", resolution[1])
    g.set(r, "resolution_percentage", 100)
    g.set(r, "use_border", False)
    g.set(r, "use_single_layer", True)
    g.set(r, "use_compositing", False)
    g.set(r, "use_sequencer", False)
    standard_view(g, scene)
    for flag in PASS_FLAGS.values():
        g.set(view_layer, flag, True)
    ims = r.image_settings
    g.remember(ims, IMAGE_SETTINGS)
    g.image_format(ims, "OPEN_EXR", multilayer=True)
    g.set(ims, "color_depth", "32")
    g.set(ims, "exr_codec", "NONE")


def read_exr(path: Path, layer: str) -> dict[str, np.ndarray]:
    """Passes of a multilayer EXR as arrays, keyed by pass name."""
    out: dict[str, np.ndarray] = {}
    xyz: dict[str, dict[str, np.ndarray]] = {}
    with OpenEXR.File(str(path)) as f:
        for part in f.parts:
            for name, ch in part.channels.items():
                key = name.removeprefix(layer + ".")
                first, dot, rest = key.partition(".")
                key = PASS_NAMES.get(first, first) + dot + rest  # Blender before 5.0
                pixels = np.asarray(ch.pixels, dtype=np.float32)
                base, _, comp = key.rpartition(".")
                if base in PASS_FLAGS and comp in {"X", "Y", "Z"}:
                    xyz.setdefault(base, {})[comp] = pixels
                else:
                    out[key] = pixels
    for base, comps in xyz.items():
        if base == "Depth":
            out[base] = comps["Z"]
        else:
            out[base] = np.stack([comps["X"], comps["Y"], comps["Z"]], axis=-1)
    return out


def camera_matrices(
    scene: bpy.types.Scene, camera: bpy.types.Object, resolution: tuple[int, int]
) -> tuple[np.ndarray, np.ndarray]:
    """The camera's world position (3,) and world-to-clip matrix (4, 4, OpenGL conventions) for
    an image of ``resolution`` with square pixels (what vplace renders:
    ``settings.measured_frame``). The view is the camera's matrix without its scale, as Blender
    renders it: a camera scaled (2, 1, 1) frames what it frames unscaled."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    w, h = resolution
    projection = camera.calc_matrix_camera(depsgraph, x=w, y=h, scale_x=1.0, scale_y=1.0)
    view = camera.matrix_world.normalized().inverted()
    world_to_clip = np.array(projection @ view, dtype=np.float64)
    return np.array(camera.matrix_world.translation, dtype=np.float64), world_to_clip


def vpl_objects(scene: bpy.types.Scene) -> list[bpy.types.Object]:
    """The light objects vplace wrote (marked, or in a collection vplace marked)."""
    return [o for o in scene.objects if is_vplace(o)]


def capture_key(
    scene: bpy.types.Scene,
    camera: bpy.types.Object,
    resolution: tuple[int, int],
    samples: int,
    seed: int,
    view_layer: bpy.types.ViewLayer | None = None,
    include_vpls: bool = False,
) -> str:
    """The cache key: what Cycles reads to render the scene (:func:`render_key.scene_signature`,
    without vplace's own lights: a capture hides them), the camera, resolution, samples and seed.
    It does not depend on vplace's export, so a new vplace that exports more keeps the cache."""
    h = hashlib.sha256()
    h.update(
        render_key.scene_signature(
            scene,
            "CYCLES",
            skip=() if include_vpls else vpl_objects(scene),
            view_layer=view_layer,
        ).encode()
    )
    h.update(repr([list(row) for row in camera.matrix_world]).encode())
    data = camera.data
    h.update(repr(render_key.plain_values(data)).encode())
    h.update(repr((resolution, samples, seed, CAPTURE_VERSION)).encode())
    return h.hexdigest()[:24]


def hide_vpls(g: SettingsGuard) -> None:
    """Hides every collection vplace wrote from the render (restored by the guard)."""
    for coll in bpy.data.collections:
        if coll.get(VPL_MARKER, False):
            g.set(coll, "hide_render", True)


def capture(
    scene: bpy.types.Scene,
    *,
    camera: bpy.types.Object | None = None,
    frame: int | None = None,
    name: str | None = None,
    resolution: tuple[int, int] | None = None,
    samples: int = 64,
    seed: int = 0,
    cache_dir: Path | None = None,
    on_progress: Callable[[str], None] | None = None,
    include_vpls: bool = False,
) -> Capture:
    """Renders ``scene`` from ``camera`` (default: the scene camera) at ``frame`` (default: the
    current one) with Cycles CPU and returns every pass as numpy; ``name`` names the view
    (default: the camera's).

    The lights vplace wrote are hidden from the render unless
    ``include_vpls`` (to render what the written lights give, as a test or a comparison does).
    ``resolution`` defaults to the scene's output size. With ``cache_dir``, an identical earlier
    capture is loaded instead of rendering. ``on_progress`` receives Cycles' status lines.
    """
    camera = camera if camera is not None else scene.camera
    if camera is None:
        raise CaptureError("the scene has no camera: add one and make it the scene camera")
    if camera.type != "CAMERA":
        raise CaptureError(f"{camera.name!r} is not a camera object")
    if samples < 1:
        raise CaptureError(f"samples must be at least 1, got {samples}")
    if resolution is None:
        pct = scene.render.resolution_percentage / 100.0
        resolution = (
            max(1, int(scene.render.resolution_x * pct)),
            max(1, int(scene.render.resolution_y * pct)),
        )
    if min(resolution) < 1:
        raise CaptureError(f"resolution must be at least 1 x 1, got {resolution}")
    with at_frame(scene, frame):
        return _capture_now(
            scene,
            camera,
            name or camera.name,
            resolution,
            samples,
            seed,
            Path(cache_dir) if cache_dir is not None else None,
            on_progress,
            include_vpls,
        )


def _capture_now(
    scene: bpy.types.Scene,
    camera: bpy.types.Object,
    name: str,
    resolution: tuple[int, int],
    samples: int,
    seed: int,
    cache_dir: Path | None,
    on_progress: Callable[[str], None] | None,
    include_vpls: bool,
) -> Capture:
    """:func:`capture` at the current frame."""
    view_layer = render_view_layer(scene)
    key = capture_key(scene, camera, resolution, samples, seed, view_layer, include_vpls)
    cached = cache_dir / f"capture-{key}.npz" if cache_dir is not None else None
    if cached is not None and cached.exists():
        try:
            loaded = Capture.load(cached)
            render_key.touch(cached)
            return loaded
        except (KeyError, ValueError, OSError, EOFError):
            pass  # unreadable or of another layout: render it again and replace it

    def handler(stats: str, *_: object) -> None:
        if on_progress is not None:
            on_progress(str(stats))

    with tempfile.TemporaryDirectory(prefix="vplace-capture-") as tmp:
        exr = Path(tmp) / "passes.exr"
        bpy.app.handlers.render_stats.append(handler)
        try:
            with override() as g:
                g.set(scene, "camera", camera)
                if not include_vpls:
                    hide_vpls(g)
                _configure(g, scene, view_layer, resolution, samples, seed)
                measured_frame(g, scene, camera)
                start = time.perf_counter()
                _render(scene, view_layer)
                seconds = time.perf_counter() - start
                bpy.data.images["Render Result"].save_render(filepath=str(exr), scene=scene)
        finally:
            bpy.app.handlers.render_stats.remove(handler)
        passes = read_exr(exr, view_layer.name)
    missing = [p for p in PASS_FLAGS if p not in passes]
    if missing:
        raise CaptureError(f"the render is missing the passes {missing}")
    rgb = {k: v[..., :3].astype(np.float32) for k, v in passes.items() if v.ndim == 3}
    camera_position, world_to_clip = camera_matrices(scene, camera, resolution)
    result = Capture(
        combined=rgb["Combined"],
        depth=passes["Depth"].astype(np.float32),
        normal=rgb["Normal"],
        position=rgb["Position"],
        diffuse_direct=rgb["Diffuse Direct"],
        diffuse_indirect=rgb["Diffuse Indirect"],
        diffuse_color=rgb["Diffuse Color"],
        glossy_direct=rgb["Glossy Direct"],
        glossy_indirect=rgb["Glossy Indirect"],
        glossy_color=rgb["Glossy Color"],
        emission=rgb["Emission"],
        environment=rgb["Environment"],
        samples=samples,
        render_seconds=seconds,
        key=key,
        view=name,
        camera=camera.name,
        camera_position=camera_position,
        world_to_clip=world_to_clip,
    )
    if cached is not None:
        cached.parent.mkdir(parents=True, exist_ok=True)
        result.save(cached)
        render_key.prune(cached.parent, keep=cached)
    return result
