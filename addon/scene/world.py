"""The world's light as the core needs it (DESIGN: Scene export): a uniform colour or an
equirectangular environment image with a rotation.

What is read exactly, from the active World Output's Surface:

- a Background (or Emission) node: its Color times its Strength, a uniform world;
- its Color from an Environment Texture (equirectangular) with an image: the image's float
  pixels in linear colour (8-bit sRGB images are linearized), times the Strength, with the
  rotation of a Mapping node on its Vector input when that node is a plain rotation (Point,
  Vector or Texture type, no location for Point, a uniform positive scale, fed by nothing or
  by the Generated texture coordinate), Blender's equirectangular convention otherwise
  unchanged (row 0 at +Z, ``u = 0.5 - atan2(y, x) / 2 pi``); images wider than
  :data:`MAX_IMAGE_WIDTH` are box-filtered down (the light they give is the same).

Anything else (a Sky Texture, gradients, mixes, a linked Strength, Light Path tricks, a
Mapping node with a location or a non-uniform scale, a mirror-ball projection) is **baked**:
Cycles renders the world alone through an equirectangular panoramic camera at
:data:`BAKE_SIZE` and :data:`BAKE_SAMPLES` samples, and that image is the world's light, with a
warning naming the node. That is an approximation in resolution only (a sun disc smaller than
a baked pixel keeps its power but spreads over the pixel), and it sees the world as a camera
ray does (a setup that differs by ray type is baked as the camera sees it).

**The sun's pixels are rendered again, finer.** A sun disc (a Sky Texture's is 0.55 degrees)
is smaller than a baked pixel (0.70 degrees), so a pixel's value is the fraction of its samples
that hit the disc: at 64 samples a pixel, the baked sky room's total light (mostly the sun) was
off by up to 5 % and by a different amount on every frame of a moving sun (against a bake at
8192 samples; ``tests/addon/test_world.py`` checks four sun positions), which the sun stand-in
and the VPLs then flicker with. So the bake finds its sun (the brightest pixel when it is
:data:`SUN_REFINE_CONTRAST` times the map's mean, and the sun of every Sky Texture node with a
disc) and renders the pixels around it again through the same camera restricted to their
latitudes and longitudes, :data:`SUN_REFINE_FACTOR` times finer in each direction, and
box-filters them back: 1024 samples a pixel where the sun is, 16 elsewhere, in about half the
time of the former 64 everywhere.
"""

from __future__ import annotations

import hashlib
import math
import os
import tempfile
from collections import OrderedDict
from dataclasses import dataclass, field
from typing import Any

import bpy
import numpy as np

from ..errors import ExportError, run_operator
from .materials import LUMINANCE

__all__ = [
    "BAKE_SAMPLES",
    "BAKE_SIZE",
    "MAX_IMAGE_WIDTH",
    "WorldInfo",
    "bake_world",
    "sky_sun_directions",
    "world_info",
]

#: Environment images wider than this are box-filtered down by an integer factor.
MAX_IMAGE_WIDTH = 2048
#: Resolution (W, H) of a baked world.
BAKE_SIZE = (512, 256)
#: Cycles samples per pixel of a baked world (the sun's pixels get more: module docs).
BAKE_SAMPLES = 16
#: A baked pixel this many times the map's mean radiance (solid-angle weighted) is a sun's.
SUN_REFINE_CONTRAST = 100.0
#: The sun's pixels are rendered again this many times finer in each direction ...
SUN_REFINE_FACTOR = 8
#: ... at these samples per fine pixel (SUN_REFINE_FACTOR^2 x this per baked pixel).
SUN_REFINE_SAMPLES = 16
#: At most this many baked pixels are rendered again (a bright region larger than this is not a
#: sun smaller than a pixel, and the bake's own samples serve it).
SUN_REFINE_MAX_PIXELS = 1024
#: Baked worlds kept in memory, by a signature of their node tree.
BAKE_CACHE_SIZE = 4
#: The camera rotation (Euler XYZ, radians) whose equirectangular panorama is the Environment
#: Texture's own mapping: pixel (row i from the top, column j) sees the direction the texture
#: maps to that pixel (measured: a baked test image comes back pixel for pixel).
BAKE_CAMERA_ROTATION = (math.pi / 2, 0.0, -math.pi / 2)


@dataclass
class WorldInfo:
    """The world's light: radiance ``color`` (W/(m^2 sr), colour x strength) times ``image``
    where there is one."""

    name: str
    color: tuple[float, float, float]
    #: (H, W, 3) float32, linear, row 0 at the top (+Z); None for a uniform colour.
    image: np.ndarray | None = None
    #: (3, 3) float64 taking world directions to image directions; None is the identity.
    rotation: np.ndarray | None = None
    #: How the world was read: "color", "image" or "baked".
    source: str = "color"
    warnings: list[str] = field(default_factory=list)
    #: The sun discs of a baked world's Sky Texture nodes, known exactly (``sky_sun_directions``:
    #: unit direction toward the sun, world space, and the disc's diameter in radians); the bake
    #: spreads each over the pixels it touches.
    suns: tuple[tuple[tuple[float, float, float], float], ...] = ()

    @property
    def emits(self) -> bool:
        """True when the world sends any light."""
        if max(self.color) <= 0.0:
            return False
        return self.image is None or bool(self.image.max() > 0.0)

    @property
    def mean_color(self) -> tuple[float, float, float]:
        """The radiance averaged over directions (solid-angle weighted), RGB."""
        if self.image is None:
            return self.color
        h = self.image.shape[0]
        theta = (np.arange(h) + 0.5) / h * math.pi
        w = np.sin(theta)[:, None, None]
        mean = (self.image * w).sum(axis=(0, 1)) / (w.sum() * self.image.shape[1])
        return (
            float(mean[0] * self.color[0]),
            float(mean[1] * self.color[1]),
            float(mean[2] * self.color[2]),
        )

    def fingerprint(self) -> bytes:
        """Bytes that change whenever the light changes (for capture caches)."""
        h = hashlib.sha256(repr((self.name, self.color, self.source)).encode())
        if self.image is not None:
            h.update(np.ascontiguousarray(self.image).tobytes())
        if self.rotation is not None:
            h.update(np.ascontiguousarray(self.rotation).tobytes())
        # (``suns`` come from the node tree the baked ``image`` already changes with.)
        return h.digest()


def _srgb_to_linear(c: np.ndarray) -> np.ndarray:
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4).astype(np.float32)


def _source(socket: Any) -> tuple[Any, Any] | None:
    """The node and output socket linked into ``socket`` (through reroutes), or None."""
    while socket.is_linked:
        link = socket.links[0]
        if link.is_muted:
            return None
        node = link.from_node
        if node.type == "REROUTE":
            socket = node.inputs[0]
            continue
        return node, link.from_socket
    return None


def _image_pixels(image: Any) -> tuple[np.ndarray | None, list[str]]:
    """An image's pixels as (H, W, 3) float32 linear, row 0 at the top, at most
    :data:`MAX_IMAGE_WIDTH` wide; None with a warning when it has none."""
    w, h = image.size
    if w == 0 or h == 0:
        return None, [
            f"environment image {image.name!r} has no pixels (missing file?): Cycles renders "
            "it magenta, and so does vplace"
        ]
    px = np.empty(w * h * image.channels, dtype=np.float32)
    image.pixels.foreach_get(px)
    px = px.reshape(h, w, image.channels)[::-1]
    rgb = np.repeat(px[..., :1], 3, axis=2) if image.channels < 3 else px[..., :3]
    warnings = []
    space = image.colorspace_settings.name
    if not image.is_float:
        if space == "sRGB":
            rgb = _srgb_to_linear(rgb)
        elif space not in {"Non-Color", "Linear Rec.709", "Linear"}:
            warnings.append(
                f"environment image {image.name!r} is in colour space {space!r}: read as linear"
            )
    factor = max(1, math.ceil(w / MAX_IMAGE_WIDTH))
    if factor > 1:
        hh, ww = h // factor, w // factor
        rgb = rgb[: hh * factor, : ww * factor].reshape(hh, factor, ww, factor, 3).mean(axis=(1, 3))
    return np.ascontiguousarray(rgb, dtype=np.float32), warnings


def _euler_matrix(rot: Any) -> np.ndarray:
    """The matrix of a Blender Euler rotation (XYZ order: ``Rz @ Ry @ Rx``)."""
    x, y, z = (float(a) for a in rot)
    cx, sx, cy, sy, cz, sz = (
        math.cos(x),
        math.sin(x),
        math.cos(y),
        math.sin(y),
        math.cos(z),
        math.sin(z),
    )
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz @ ry @ rx


def _is_identity_mapping(node: Any) -> bool:
    """True when a texture node's own (legacy) texture mapping does nothing."""
    m = getattr(node, "texture_mapping", None)
    if m is None:
        return True
    return (
        all(abs(v) < 1e-7 for v in m.translation)
        and all(abs(v) < 1e-7 for v in m.rotation)
        and all(abs(v - 1.0) < 1e-7 for v in m.scale)
        and not m.use_min
        and not m.use_max
    )


def _rotation(env: Any) -> tuple[np.ndarray | None, str | None]:
    """The rotation of an Environment Texture's Vector input, or (None, why not) when it is
    not a plain rotation of the direction."""
    if not _is_identity_mapping(env):
        return None, "the Environment Texture's own texture mapping"
    src = _source(env.inputs["Vector"])
    if src is None:
        return np.eye(3), None
    node, out = src
    if node.type == "TEX_COORD":
        return (np.eye(3), None) if out.name == "Generated" else (None, f"its {out.name} input")
    if node.type != "MAPPING":
        return None, f"the {node.bl_label} node on its Vector input"
    vin = _source(node.inputs["Vector"])
    if vin is not None and not (vin[0].type == "TEX_COORD" and vin[1].name == "Generated"):
        return None, f"the {vin[0].bl_label} node feeding its Mapping"
    if any(
        node.inputs[name].is_linked
        for name in ("Location", "Rotation", "Scale")
        if name in node.inputs
    ):
        return None, "a Mapping node with linked inputs"
    kind = node.vector_type
    scale = (
        np.array(node.inputs["Scale"].default_value[:]) if "Scale" in node.inputs else np.ones(3)
    )
    if kind not in {"POINT", "VECTOR", "TEXTURE"} or scale.min() <= 0 or np.ptp(scale) > 1e-6:
        return None, f"a Mapping node of type {kind} with scale {tuple(scale)}"
    if (
        kind in {"POINT", "TEXTURE"}
        and np.abs(np.array(node.inputs["Location"].default_value[:])).max() > 1e-7
    ):
        return None, "a Mapping node with a location"
    r = _euler_matrix(node.inputs["Rotation"].default_value)
    return (r.T if kind == "TEXTURE" else r), None


def _tree_signature(world: Any) -> str:
    """A hash of everything in a world's node tree that changes its light (for the bake
    cache): nodes with their settings and input values, links, images."""
    h = hashlib.sha256(world.name_full.encode())
    tree = world.node_tree
    for node in tree.nodes:
        h.update(f"{node.name}|{node.bl_idname}|{node.mute}".encode())
        for prop in node.bl_rna.properties:
            if prop.type in {
                "BOOLEAN",
                "INT",
                "FLOAT",
                "STRING",
                "ENUM",
            } and prop.identifier not in {
                "location",
                "width",
                "height",
                "select",
                "name",
                "label",
                "dimensions",
                "location_absolute",
            }:
                value = getattr(node, prop.identifier, None)
                h.update(
                    repr(
                        value[:]
                        if hasattr(value, "__len__") and not isinstance(value, str)
                        else value
                    ).encode()
                )
        for sock in node.inputs:
            value = getattr(sock, "default_value", None)
            if value is not None:
                h.update(repr(value[:] if hasattr(value, "__len__") else value).encode())
        image = getattr(node, "image", None)
        if image is not None:
            h.update(
                f"{image.name_full}|{image.filepath}|{tuple(image.size)}|{image.is_dirty}".encode()
            )
        mapping = getattr(node, "texture_mapping", None)
        if mapping is not None:
            h.update(repr((mapping.translation[:], mapping.rotation[:], mapping.scale[:])).encode())
    for link in tree.links:
        h.update(
            f"{link.from_node.name}.{link.from_socket.identifier}>{link.to_node.name}.{link.to_socket.identifier}|{link.is_muted}".encode()
        )
    return h.hexdigest()


_BAKED: OrderedDict[str, np.ndarray] = OrderedDict()


def _render_world(
    world: Any,
    size: tuple[int, int],
    samples: int,
    window: tuple[float, float, float, float] | None = None,
) -> np.ndarray:
    """Renders ``world`` alone with Cycles through an equirectangular panoramic camera:
    (H, W, 3) float32, linear, row 0 at the top, in the Environment Texture's convention.
    ``window`` = (latitude min, max, longitude min, max) in radians restricts the camera to
    those directions (the whole sphere is (-pi/2, pi/2, -pi, pi)).

    A temporary scene holds the camera; it and its data are removed however the render ends."""
    import OpenEXR

    tmp = bpy.data.scenes.new("vplace world bake")
    cam_data = bpy.data.cameras.new("vplace world bake")
    cam = bpy.data.objects.new("vplace world bake", cam_data)
    path = os.path.join(tempfile.mkdtemp(prefix="vplace_world_"), "world.exr")
    try:
        tmp.world = world
        cam_data.type = "PANO"
        cam_data.panorama_type = "EQUIRECTANGULAR"
        if window is not None:
            cam_data.latitude_min, cam_data.latitude_max = window[0], window[1]
            cam_data.longitude_min, cam_data.longitude_max = window[2], window[3]
        cam.rotation_euler = BAKE_CAMERA_ROTATION
        tmp.collection.objects.link(cam)
        tmp.camera = cam
        r, c = tmp.render, tmp.cycles
        r.engine = "CYCLES"
        r.resolution_x, r.resolution_y = size
        r.resolution_percentage = 100
        r.film_transparent = False
        c.device = "CPU"
        c.samples = samples
        c.use_adaptive_sampling = False
        c.use_denoising = False
        c.pixel_filter_type = "BOX"
        c.filter_width = 1.0
        tmp.view_settings.view_transform = "Standard"
        ims = r.image_settings
        ims.file_format = "OPEN_EXR"
        ims.color_mode = "RGB"
        ims.color_depth = "32"
        ims.exr_codec = "NONE"
        run_operator(
            "render.render", f"the bake of world {world.name!r} did not finish", ExportError,
            scene=tmp.name,
        )  # fmt: skip
        bpy.data.images["Render Result"].save_render(filepath=path, scene=tmp)
        with OpenEXR.File(path) as f:
            channels = f.parts[0].channels
            name = next(iter(channels))
            px = np.asarray(channels[name].pixels, dtype=np.float32)
        rgb = np.ascontiguousarray(px[..., :3], dtype=np.float32)
    finally:
        bpy.data.objects.remove(cam)
        bpy.data.cameras.remove(cam_data)
        bpy.data.scenes.remove(tmp)
        with_dir = os.path.dirname(path)
        if os.path.exists(path):
            os.remove(path)
        os.rmdir(with_dir)
    return np.nan_to_num(np.maximum(rgb, 0.0), nan=0.0, posinf=0.0)


def sky_sun_directions(world: Any) -> list[tuple[np.ndarray, float]]:
    """(unit direction toward the sun, disc diameter in radians) of every Sky Texture node of
    ``world`` that draws a sun disc and takes no Vector input (Blender's convention: the sun
    at ``sun_rotation`` about +Z from +Y toward +X, ``sun_elevation`` above the horizon;
    tested against the bake)."""
    tree = getattr(world, "node_tree", None)
    suns = []
    for node in tree.nodes if tree is not None else ():
        if node.type != "TEX_SKY" or node.mute or not getattr(node, "sun_disc", False):
            continue
        if node.sky_type not in {"SINGLE_SCATTERING", "MULTIPLE_SCATTERING", "NISHITA"}:
            continue
        # (iterated: Blender 5.0 finds no "Vector" by key in a Sky Texture read from a file)
        if any(i.is_linked for i in node.inputs) or not _is_identity_mapping(node):
            continue
        el, rot = float(node.sun_elevation), float(node.sun_rotation)
        d = np.array([math.cos(el) * math.sin(rot), math.cos(el) * math.cos(rot), math.sin(el)])
        suns.append((d, float(node.sun_size)))
    return suns


def _direction_pixel(d: np.ndarray, size: tuple[int, int]) -> tuple[int, int]:
    """The (row, column) of a baked map of ``size`` = (W, H) that direction ``d`` falls in."""
    w, h = size
    lat = math.asin(max(-1.0, min(1.0, float(d[2]))))
    u = 0.5 - math.atan2(float(d[1]), float(d[0])) / (2.0 * math.pi)
    row = min(h - 1, max(0, int((0.5 - lat / math.pi) * h)))
    return row, int(u * w) % w


def _sun_window(
    shape: tuple[int, int], seeds: list[tuple[int, int, float]]
) -> tuple[int, int, int, int] | None:
    """Rows [r0, r1) and columns [c0, c1) of a map of ``shape`` = (H, W) to render again
    (columns may run past either edge: they wrap): the pixels at ``seeds`` (row, column, disc
    diameter in radians, 0 when not known) with a margin that holds a disc's edge. None when
    that is more than :data:`SUN_REFINE_MAX_PIXELS` pixels."""
    h, w = shape
    pixel = math.pi / h  # radians a row spans; a column spans 2 pi / w = the same
    rows, cols = [], []
    for row, col, diameter in seeds:
        lat = math.pi / 2 - (row + 0.5) * pixel
        margin_r = math.ceil(0.5 * diameter / pixel) + 1
        margin_c = math.ceil((0.5 * diameter / pixel + 1) / max(math.cos(lat), 1e-3))
        rows += [row - margin_r, row + margin_r + 1]
        # columns relative to the first seed's, so a window across the seam stays contiguous
        c = col if not cols else cols[0] + ((col - cols[0] + w // 2) % w - w // 2)
        cols += [c - margin_c, c + margin_c + 1]
    r0, r1 = max(0, min(rows)), min(h, max(rows))
    c0, c1 = min(cols), max(cols)
    if c1 - c0 >= w:
        c0, c1 = 0, w
    if (r1 - r0) * (c1 - c0) > SUN_REFINE_MAX_PIXELS:
        return None
    return r0, r1, c0, c1


def _refine_sun(world: Any, image: np.ndarray) -> np.ndarray:
    """``image`` with its sun's pixels rendered again finer (module docs); unchanged when it
    has no sun."""
    h, w = image.shape[:2]
    lum = image @ LUMINANCE.astype(np.float32)
    mean = float(LUMINANCE @ WorldInfo("", (1.0, 1.0, 1.0), image).mean_color)
    seeds = [(*_direction_pixel(d, (w, h)), size) for d, size in sky_sun_directions(world)]
    top = np.unravel_index(int(np.argmax(lum)), lum.shape)
    if mean > 0.0 and lum[top] > SUN_REFINE_CONTRAST * mean:
        # the bright pixels of the brightest one's neighbourhood (one sun)
        rows = np.arange(max(0, top[0] - 8), min(h, top[0] + 9))
        cols = np.arange(top[1] - 8, top[1] + 9) % w
        near = lum[np.ix_(rows, cols)] > SUN_REFINE_CONTRAST * mean
        seeds += [(int(rows[i]), int(cols[j]), 0.0) for i, j in np.argwhere(near)]
    if not seeds:
        return image
    window = _sun_window((h, w), seeds)
    if window is None:
        return image
    r0, r1, c0, c1 = window
    k = SUN_REFINE_FACTOR
    lat = (math.pi / 2 - math.pi * r1 / h, math.pi / 2 - math.pi * r0 / h)
    lon = (-math.pi + 2 * math.pi * c0 / w, -math.pi + 2 * math.pi * c1 / w)
    fine = _render_world(world, ((c1 - c0) * k, (r1 - r0) * k), SUN_REFINE_SAMPLES, (*lat, *lon))
    coarse = fine.reshape(r1 - r0, k, c1 - c0, k, 3).mean(axis=(1, 3))
    out = image.copy()
    out[r0:r1, np.arange(c0, c1) % w] = coarse
    return out


def bake_world(
    world: Any, size: tuple[int, int] = BAKE_SIZE, samples: int = BAKE_SAMPLES
) -> np.ndarray:
    """``world``'s light as an equirectangular map (:func:`_render_world`), its sun's pixels
    rendered again finer (module docs).

    Results are cached in memory by the node tree's signature (the last
    :data:`BAKE_CACHE_SIZE`)."""
    key = f"{_tree_signature(world)}|{size}|{samples}"
    if key in _BAKED:
        _BAKED.move_to_end(key)
        return _BAKED[key]
    rgb = _refine_sun(world, _render_world(world, size, samples))
    _BAKED[key] = rgb
    while len(_BAKED) > BAKE_CACHE_SIZE:
        _BAKED.popitem(last=False)
    return rgb


def world_info(world: Any, *, bake: bool = True) -> WorldInfo | None:
    """The light of ``world`` (see the module docs); None without a world. ``bake=False``
    replaces a bake by the node's default colour (for callers that must not render)."""
    if world is None:
        return None
    tree = world.node_tree
    color = (float(world.color[0]), float(world.color[1]), float(world.color[2]))
    if tree is None:
        return WorldInfo(world.name, color)
    outputs = [n for n in tree.nodes if n.type == "OUTPUT_WORLD"]
    out = next((n for n in outputs if n.is_active_output), outputs[0] if outputs else None)
    if out is None:
        return WorldInfo(world.name, (0.0, 0.0, 0.0))
    src = _source(out.inputs["Surface"])
    if src is None:
        return WorldInfo(world.name, (0.0, 0.0, 0.0))
    node, _ = src
    why = None
    if node.type in {"BACKGROUND", "EMISSION"} and not node.mute:
        strength_in = node.inputs["Strength"]
        strength = float(strength_in.default_value)
        col = _source(node.inputs["Color"])
        if strength_in.is_linked:
            why = f"the {node.bl_label} node's linked Strength"
        elif col is None:
            c = node.inputs["Color"].default_value
            return WorldInfo(world.name, (c[0] * strength, c[1] * strength, c[2] * strength))
        elif col[0].type == "RGB":
            c = col[0].outputs[0].default_value
            return WorldInfo(world.name, (c[0] * strength, c[1] * strength, c[2] * strength))
        elif col[0].type == "TEX_ENVIRONMENT" and col[1].name == "Color":
            env = col[0]
            if env.image is None:
                # Cycles renders an Environment Texture without an image black.
                return WorldInfo(world.name, (0.0, 0.0, 0.0))
            if env.projection != "EQUIRECTANGULAR":
                why = f"an Environment Texture with {env.projection.lower()} projection"
            else:
                rotation, why = _rotation(env)
                if rotation is not None:
                    pixels, warnings = _image_pixels(env.image)
                    if pixels is None:
                        magenta = (strength, 0.0, strength)
                        return WorldInfo(world.name, magenta, warnings=warnings)
                    rot = None if np.allclose(rotation, np.eye(3)) else rotation
                    return WorldInfo(world.name, (strength,) * 3, pixels, rot, "image", warnings)
                why = f"an Environment Texture fed by {why}"
        else:
            why = f"the {col[0].bl_label} node"
    else:
        why = f"a {node.bl_label} shader"
    if not bake:
        return WorldInfo(
            world.name,
            color,
            warnings=[f"world {world.name!r}: {why} is not read; its viewport colour stands in"],
        )
    image = bake_world(world)
    w, h = image.shape[1], image.shape[0]
    return WorldInfo(
        world.name,
        (1.0, 1.0, 1.0),
        image,
        None,
        "baked",
        [
            f"world {world.name!r}: {why} is baked by Cycles to a {w}x{h} environment map "
            f"({BAKE_SAMPLES} samples per pixel, its sun's "
            f"{SUN_REFINE_FACTOR**2 * SUN_REFINE_SAMPLES}): an approximation"
        ],
        tuple(
            ((float(d[0]), float(d[1]), float(d[2])), size) for d, size in sky_sun_directions(world)
        ),
    )
