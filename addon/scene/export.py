"""Scene export: the scene as Cycles renders it, as numpy arrays (DESIGN: Scene export).

Triangles in world space with a material id each, and per triangle corner the UVs its
material's textures read; materials reduced to what the core shades by the material rule of
:mod:`.materials` (the diffuse albedo, a base-colour texture, an alpha cut-out; roughness;
metallic; emission: an Emission shader's or the Principled BSDF's colour x strength, radiance
from both sides); the images the materials read, each read once; lights with their effective
RGB power and every parameter Cycles renders them with (point and spot radius and soft
falloff, spot size and blend, area shape, sizes and spread, sun angle); the world's light
(``world.py``: a colour, an environment image with its rotation, or a baked node setup); the
camera. The VPLs that vplace wrote itself (objects marked ``vplace_vpl``) are
never exported.

**Which objects take part: the render-visibility rule.** Export and capture use one rule, the
one Cycles renders by: the depsgraph evaluated *for rendering* the view layer that
:func:`render_view_layer` names (collections excluded from the view layer or disabled in renders
and objects disabled in renders are out; objects hidden only in the viewport are in; modifiers
at their render levels, geometry nodes' render branch, particle and collection instances). It
comes from a render with a minimal internal engine (:func:`with_render_depsgraph`: a few
milliseconds, nothing drawn, every setting restored). Per object, Cycles' ray visibility
decides the rest: an object invisible to both diffuse and shadow rays takes no part in the
light transport vplace models and is left out; one invisible to diffuse rays reflects nothing
(albedo 0) but still casts shadows; one invisible to shadow rays only still blocks them in
vplace (a warning says so).

**Unsupported things** are left out with one warning naming the object, and the rest is
exported: volume objects and volume-only materials, hair curves, point clouds and hair
particles. A material with true displacement keeps its undisplaced surface (with a warning),
which is nearer to what Cycles renders than leaving the object out. Light and shadow linking
(an object's Light Linking collections) is exported as if absent, with a warning: the captures
follow it, the light paths do not. Warnings are collected in ``ExportedScene.warnings``.

**A surface shown twice** (faces that lie one over the other, facing the same way: an object
duplicated in place, a mirror about the object's own centre) is exported as it is, with a
warning naming the objects (:func:`shown_twice`): Cycles renders it black, a ray leaving one
face meeting the other at once, where EEVEE and vplace light it, so the captures call it dark.
"""

from __future__ import annotations

import contextlib
import hashlib
import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any, TypeVar

import bpy
import numpy as np

from ..errors import ExportError
from ..settings import override
from . import materials as mat_rule
from .world import WorldInfo, world_info

__all__ = [
    "ExportError",
    "ExportedScene",
    "WorldInfo",
    "export_scene",
    "light_info",
    "material_info",
    "render_view_layer",
    "with_render_depsgraph",
]

T = TypeVar("T")

#: Custom property that marks the objects and the collection vplace writes.
VPL_MARKER = "vplace_vpl"
#: Albedo of a slot without a material (Blender's default grey).
DEFAULT_ALBEDO = (0.8, 0.8, 0.8)
#: Corners closer than this fraction of the scene's diagonal are one point to :func:`shown_twice`.
COINCIDE_TOLERANCE = 1e-6
#: :func:`shown_twice`'s warning names at most this many pairs of objects.
SHOWN_TWICE_NAMED = 3


_MIX = np.uint64(0x9E3779B97F4A7C15)
_TURN = np.uint64(0xC2B2AE3D27D4EB4F)


def _mixed(keys: np.ndarray) -> np.ndarray:
    """One 64-bit hash per row of ``keys`` (N x K, uint64), wrapping."""
    out = np.zeros(len(keys), dtype=np.uint64)
    for k in range(keys.shape[1]):
        out = (out ^ keys[:, k]) * _MIX + np.uint64(2 * k + 1)
    return out


def _edge(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """A hash of the directed edges ``a -> b`` (uint64 corner keys): ``a -> b`` and ``b -> a``
    differ."""
    return ((a * _MIX) ^ b) * _TURN


def shown_twice(
    vertices: np.ndarray, triangles: np.ndarray, owners: np.ndarray, names: list[str]
) -> list[tuple[str, str, int]]:
    """Surfaces shown twice: triangles whose corners coincide (to :data:`COINCIDE_TOLERANCE`
    of the scene's diagonal) in the same cyclic order, so facing the same way, with another's.
    ``owners[t]`` indexes ``names`` for triangle ``t``. Per pair of object names (sorted; one
    name twice for an object's own faces), the triangles that lie on another; most first.
    Faces that meet back to back (two boxes side by side, a box on a floor) face opposite ways
    and are not counted. One sort of a hash per triangle where none coincide (Sponza's 262k
    triangles: about 20 ms)."""
    if len(triangles) < 2:
        return []
    lo = vertices.min(axis=0)
    cell = max(float(np.linalg.norm(vertices.max(axis=0) - lo)), 1e-12) * COINCIDE_TOLERANCE
    q = np.rint((vertices - lo) / np.float32(cell)).astype(np.int64).view(np.uint64)
    a, b, c = _mixed(q)[triangles.astype(np.int64)].T  # one key per corner
    whole = (a != b) & (b != c) & (a != c)
    # The sum of the three directed edges: the same from whichever corner a triangle starts,
    # another for the triangle turned over.
    key = (_edge(a, b) + _edge(b, c) + _edge(c, a))[whole]
    ordered = np.sort(key)
    if not (ordered[1:] == ordered[:-1]).any():  # the usual case
        return []
    _, inverse, counts = np.unique(key, return_inverse=True, return_counts=True)
    ids = np.flatnonzero(whole)[counts[inverse.ravel()] > 1]
    # Exactly, on the few left: the same three corners in the same turn.
    corner = np.column_stack([a[ids], b[ids], c[ids]])
    first = np.argmin(corner, axis=1)
    cycle = corner[np.arange(len(ids))[:, None], (first[:, None] + np.arange(3)) % 3]
    groups, group_of = np.unique(cycle, axis=0, return_inverse=True)
    group_of = group_of.ravel()
    pairs: dict[tuple[str, str], int] = {}
    for g in range(len(groups)):
        members = ids[group_of == g]
        if len(members) < 2:
            continue
        who = sorted(names[o] for o in owners[members])
        pairs[(who[0], who[1])] = pairs.get((who[0], who[1]), 0) + len(members) - 1
    return sorted(((a, b, n) for (a, b), n in pairs.items()), key=lambda p: (-p[2], p[0], p[1]))


def shown_twice_warning(found: list[tuple[str, str, int]]) -> str | None:
    """The export's warning for :func:`shown_twice`'s pairs (None without)."""
    if not found:
        return None
    said = [
        f"{n} face(s) of {a!r} on its own" if a == b else f"{n} face(s) of {a!r} on {b!r}"
        for a, b, n in found[:SHOWN_TWICE_NAMED]
    ]
    more = len(found) - SHOWN_TWICE_NAMED
    if more > 0:
        said.append(f"{more} more pair(s) of objects")
    return (
        f"a surface shown twice ({'; '.join(said)}; faces that lie one over the other, facing "
        "the same way): Cycles renders it black (a ray leaving one face meets the other at "
        "once) where EEVEE lights it, so the captures call it dark; delete the copy (or Merge "
        "by Distance)"
    )


@dataclass
class TextureInfo:
    """How a material reads one of the exported textures."""

    index: int  # into ExportedScene.textures
    uv_map: str  # "" = the active render UV map
    uv_scale: tuple[float, float] = (1.0, 1.0)
    uv_offset: tuple[float, float] = (0.0, 0.0)
    wrap: str = "repeat"


@dataclass
class AlphaInfo:
    """An alpha cut-out: rays pass where ``offset + scale * value < cutoff`` (``value`` the
    texture's alpha channel or luminance, see ``source``)."""

    offset: float
    scale: float = 0.0
    texture: TextureInfo | None = None
    source: str = "alpha"
    cutoff: float = 0.5


@dataclass
class MaterialInfo:
    """What the core needs of a material."""

    name: str
    albedo: tuple[float, float, float]  # the diffuse albedo's mean (the texture's mean colour)
    roughness: float = 0.5
    metallic: float = 0.0
    emission: tuple[float, float, float] = (0.0, 0.0, 0.0)
    textured: bool = False
    #: The albedo at a hit is ``albedo_offset + texture_tint * rgb(texture)``.
    texture: TextureInfo | None = None
    albedo_offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    texture_tint: tuple[float, float, float] = (1.0, 1.0, 1.0)
    alpha: AlphaInfo | None = None
    #: The roughness of its glossy layer (None: none; :mod:`.materials`).
    gloss_roughness: float | None = None
    #: The glossy layers' reflectance, which the light paths reflect off besides the albedo
    #: (:mod:`.materials`), its mean; None: no layer. With ``texture``, at a hit
    #: ``gloss_offset + gloss_tint * rgb(texture)``.
    gloss: tuple[float, float, float] | None = None
    gloss_offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    gloss_tint: tuple[float, float, float] = (0.0, 0.0, 0.0)
    #: Only a volume (left out); true displacement (exported undisplaced).
    volume_only: bool = False
    displaced: bool = False
    #: Light passes through it (glass; :mod:`.materials`): it blocks vplace's rays all the
    #: same, but a room seen through it is not closed (``stand_ins.StandIns.closed``).
    transmits: bool = False
    warnings: list[str] = field(default_factory=list)


#: A glossy layer at least this rough is modelled by vplace as a broad lobe: the light it gets
#: from the VPLs is counted like diffuse light, with the Glossy Color pass as its reflectance
#: (the normalized Blinn-Phong lobe ``(s + 8) / (8 pi) (n . h)^s`` at the exponent
#: ``s = 2 / a^2 - 2`` of a roughness-1 layer, ``a = 1``: ``s = 0``, a constant ``1 / pi``),
#: and the written VPLs light it through their specular factor. 0.5 is EEVEE's default
#: ray-tracing maximum roughness: sharper layers are the ones EEVEE's ray tracing reflects,
#: and vplace leaves their glossy light to it.
ROUGH_GLOSS = 0.5


@dataclass
class LightInfo:
    """A light in world space, with power already multiplied by colour, exposure and temperature."""

    name: str
    type: str  # POINT, SPOT, AREA, SUN
    position: tuple[float, float, float]
    direction: tuple[float, float, float]  # emission axis: the light's local -Z
    tangent: tuple[float, float, float]  # the light's local +X
    power: tuple[float, float, float]  # W per channel (W/m^2 for SUN)
    radius: float = 0.0  # POINT, SPOT: Blender's shadow_soft_size
    spot_half_angle: float = math.pi
    area_disk: bool = False  # AREA: DISK or ELLIPSE (sizes size_x x size_y)
    size_x: float = 0.0
    size_y: float = 0.0
    soft_falloff: bool = True  # POINT, SPOT: Blender's use_soft_falloff
    spot_blend: float = 0.0
    spread: float = math.pi  # AREA
    angle: float = 0.0  # SUN: the full angle of its disk


@dataclass
class CameraInfo:
    """The scene camera."""

    name: str
    matrix_world: np.ndarray  # 4 x 4
    lens: float
    sensor_width: float
    resolution: tuple[int, int]


@dataclass
class ExportedScene:
    """The scene as arrays, ready for ``vplace.Scene``."""

    vertices: np.ndarray  # (V, 3) float32
    triangles: np.ndarray  # (T, 3) uint32
    material_ids: np.ndarray  # (T,) uint32
    materials: list[MaterialInfo]
    lights: list[LightInfo]
    camera: CameraInfo | None
    world_color: tuple[float, float, float] = (0.0, 0.0, 0.0)
    objects: list[str] = field(default_factory=list)
    #: The world's light (None without a world).
    world: WorldInfo | None = None
    #: (T, 3, 2) float32 UV of each triangle corner, as its material's textures read them;
    #: None when no material reads a texture.
    uvs: np.ndarray | None = None
    #: (H, W, 4) float32 linear RGBA images, row 0 at the top; ``texture_names`` their images.
    textures: list[np.ndarray] = field(default_factory=list)
    texture_names: list[str] = field(default_factory=list)
    #: What was left out or approximated, one line each (naming the object or material).
    warnings: list[str] = field(default_factory=list)
    #: The reflections Cycles follows, ``(diffuse, glossy, total)`` (:func:`light_bounces`);
    #: None: no limits known.
    light_bounces: tuple[int, int, int] | None = None
    #: Metres per Blender unit (:func:`unit_scale`): every length here is in Blender units.
    unit_scale: float = 1.0
    #: The indices into ``materials`` that each object's exported faces show, by object name;
    #: only objects exported as themselves (one drawn also as an instance is left out) ...
    object_materials: dict[str, tuple[int, ...]] = field(default_factory=dict)
    #: ... and those the instances' faces show.
    instanced_materials: tuple[int, ...] = ()

    @property
    def albedo(self) -> np.ndarray:
        """(M, 3) float32 diffuse albedo per material (a textured material's mean)."""
        return np.array([m.albedo for m in self.materials], dtype=np.float32).reshape(-1, 3)

    @property
    def emission(self) -> np.ndarray:
        """(M, 3) float32 emitted radiance per material (W/(m^2 sr), both sides)."""
        e = np.array([m.emission for m in self.materials], dtype=np.float32).reshape(-1, 3)
        return np.ascontiguousarray(np.maximum(e, 0.0))

    @property
    def rough_gloss(self) -> np.ndarray:
        """(M,) bool: the materials whose glossy layer vplace models (:data:`ROUGH_GLOSS`)."""
        r = [m.gloss_roughness for m in self.materials]
        return np.array([g is not None and g >= ROUGH_GLOSS for g in r], dtype=bool)

    @property
    def sharp_gloss(self) -> np.ndarray:
        """(M,) bool: the materials whose glossy layer is left to EEVEE's ray tracing."""
        r = [m.gloss_roughness for m in self.materials]
        return np.array([g is not None and g < ROUGH_GLOSS for g in r], dtype=bool)

    @property
    def emissive_materials(self) -> list[str]:
        """The names of the materials that emit light."""
        return [m.name for m in self.materials if max(m.emission) > 0.0]

    def emitters(self) -> list[str]:
        """What sends light, in words: lights with power, the world, emissive materials."""
        out = [f"light {light.name!r}" for light in self.lights if max(light.power) > 0.0]
        if self.world is not None and self.world.emits:
            out.append(f"world {self.world.name!r}")
        out += [f"material {name!r}" for name in self.emissive_materials]
        return out

    def fingerprint(self) -> str:
        """A hash of everything that changes a render of this scene (for capture caches)."""
        h = hashlib.sha256()
        for arr in (self.vertices, self.triangles, self.material_ids):
            h.update(np.ascontiguousarray(arr).tobytes())
        if self.uvs is not None:
            h.update(np.ascontiguousarray(self.uvs).tobytes())
        for tex in self.textures:
            h.update(repr(tex.shape).encode())
            h.update(np.ascontiguousarray(tex).tobytes())
        h.update(repr([vars(m) for m in self.materials]).encode())
        h.update(repr([vars(light) for light in self.lights]).encode())
        h.update(repr((self.world_color, self.light_bounces)).encode())
        if self.world is not None:
            h.update(self.world.fingerprint())
        return h.hexdigest()


def _srgb_to_linear(c: np.ndarray) -> np.ndarray:
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def _mean_image_color(image: bpy.types.Image) -> tuple[float, float, float] | None:
    """Mean linear RGB of an image (subsampled), or None when it has no pixels."""
    w, h = image.size
    if w == 0 or h == 0:
        return None
    px = np.empty(w * h * image.channels, dtype=np.float32)
    image.pixels.foreach_get(px)
    px = px.reshape(-1, image.channels)[::7, :3]
    if not image.is_float and image.colorspace_settings.name == "sRGB":
        px = _srgb_to_linear(px)
    mean = px.mean(axis=0)
    return (float(mean[0]), float(mean[1]), float(mean[2]))


def _input_color(node: bpy.types.Node, name: str) -> tuple[tuple[float, float, float], bool]:
    """The colour of a node input: its default value, or the mean colour of a linked image."""
    sock = node.inputs.get(name)
    if sock is None:
        return DEFAULT_ALBEDO, False
    if sock.is_linked:
        src = sock.links[0].from_node
        if src.type == "TEX_IMAGE" and src.image is not None:
            mean = _mean_image_color(src.image)
            if mean is not None:
                return mean, True
        if src.type == "RGB":
            v = src.outputs[0].default_value
            return (v[0], v[1], v[2]), False
    v = sock.default_value
    return (float(v[0]), float(v[1]), float(v[2])), False


def _input_float(node: bpy.types.Node, name: str, default: float) -> float:
    sock = node.inputs.get(name)
    return float(sock.default_value) if sock is not None else default


def material_info(
    mat: bpy.types.Material | None,
    images: mat_rule.ImageCache | None = None,
    texture_index: Callable[[str], int] | None = None,
) -> MaterialInfo:
    """Reduces a material to its diffuse surface (the material rule of :mod:`.materials`),
    roughness, metallic and emission.

    ``images`` shares image reads between materials; ``texture_index`` gives the index of an
    image (``Image.name_full``) among the exported textures. Without it a texture's mean colour
    stands in for it (``textured`` says so).
    """
    images = images if images is not None else mat_rule.ImageCache()
    if mat is None:
        info = MaterialInfo("<none>", DEFAULT_ALBEDO)
    else:
        info = _shading_info(mat)
    _apply_surface(info, mat_rule.surface_of(mat, images), images, texture_index)
    return info


def _shading_info(mat: bpy.types.Material) -> MaterialInfo:
    """Roughness, metallic and emission of a material (its albedo is :func:`_apply_surface`'s)."""
    base = tuple(mat.diffuse_color[:3])
    info = MaterialInfo(mat.name, (base[0], base[1], base[2]), mat.roughness, mat.metallic)
    tree = mat.node_tree
    if tree is None:
        return info
    out = next((n for n in tree.nodes if n.type == "OUTPUT_MATERIAL" and n.is_active_output), None)
    if out is None or not out.inputs["Surface"].is_linked:
        return info
    shader = out.inputs["Surface"].links[0].from_node
    if shader.type == "BSDF_PRINCIPLED":
        metallic = _input_float(shader, "Metallic", 0.0)
        strength = _input_float(shader, "Emission Strength", 0.0)
        emit, _ = _input_color(shader, "Emission Color")
        info = MaterialInfo(
            mat.name,
            info.albedo,
            _input_float(shader, "Roughness", 0.5),
            metallic,
            (emit[0] * strength, emit[1] * strength, emit[2] * strength),
        )
    elif shader.type == "BSDF_DIFFUSE":
        info = MaterialInfo(mat.name, info.albedo, 1.0, 0.0)
    elif shader.type == "EMISSION":
        emit, _ = _input_color(shader, "Color")
        s = _input_float(shader, "Strength", 1.0)
        info = MaterialInfo(
            mat.name, (0.0, 0.0, 0.0), emission=(emit[0] * s, emit[1] * s, emit[2] * s)
        )
    return info


def _rgb(v: np.ndarray) -> tuple[float, float, float]:
    return (float(v[0]), float(v[1]), float(v[2]))


def _apply_surface(
    info: MaterialInfo,
    surface: mat_rule.Surface,
    images: mat_rule.ImageCache,
    texture_index: Callable[[str], int] | None,
) -> None:
    """Sets ``info``'s albedo, texture and alpha from the material rule's ``surface``."""
    info.albedo = _rgb(np.clip(surface.albedo.mean(images), 0.0, 1.0))
    info.textured = surface.albedo.tex is not None
    info.volume_only, info.displaced = surface.volume_only, surface.displaced
    info.transmits = surface.transmits
    info.gloss_roughness = surface.gloss_roughness
    info.warnings = list(surface.warnings)

    def texture(use: mat_rule.TextureUse) -> TextureInfo | None:
        if texture_index is None:
            return None
        return TextureInfo(
            texture_index(use.image), use.uv_map, use.uv_scale, use.uv_offset, use.wrap
        )

    alb, layer = surface.albedo, surface.gloss
    if layer is not None:
        info.gloss = _rgb(np.clip(layer.mean(images), 0.0, 1.0))
    # The one texture a material reads: its albedo's, else (a metal) its glossy layer's.
    use = next(
        (v.tex for v in (alb, layer) if v is not None and v.tex is not None and v.coef.any()),
        None,
    )
    if use is not None:
        info.texture = texture(use)
    if info.texture is not None:
        if alb.tex == use:
            info.albedo_offset = _rgb(np.clip(alb.const, 0.0, 1.0))
            info.texture_tint = _rgb(np.maximum(alb.coef, 0.0))
        else:
            info.albedo_offset, info.texture_tint = info.albedo, (0.0, 0.0, 0.0)
        if layer is not None and layer.tex == use:
            info.gloss_offset = _rgb(np.clip(layer.const, 0.0, 1.0))
            info.gloss_tint = _rgb(np.maximum(layer.coef, 0.0))
        elif info.gloss is not None:
            info.gloss_offset = info.gloss
    if surface.alpha_tested:
        a = surface.alpha
        tex = texture(a.tex) if a.tex is not None and a.coef.any() else None
        if tex is None:
            info.alpha = AlphaInfo(float(a.mean(images)[0]), cutoff=surface.cutoff)
        else:
            assert a.tex is not None
            source = "alpha" if a.tex.channel == "alpha" else "luminance"
            info.alpha = AlphaInfo(float(a.const[0]), float(a.coef[0]), tex, source, surface.cutoff)
        if info.alpha.texture is None and info.alpha.offset >= info.alpha.cutoff:
            info.alpha = None  # a constant alpha that never cuts


def light_info(name: str, light: bpy.types.Light, matrix: Any) -> LightInfo:
    """A light's world-space description with its effective RGB power."""
    color = np.array(light.color[:3], dtype=np.float64)
    if getattr(light, "use_temperature", False):
        color = color * np.array(light.temperature_color[:3])
    power = color * light.energy * 2.0 ** getattr(light, "exposure", 0.0)
    m = np.array(matrix, dtype=np.float64)
    pos = m[:3, 3]
    axis_x, axis_z = m[:3, 0], m[:3, 2]
    scale_x = float(np.linalg.norm(axis_x))
    scale_y = float(np.linalg.norm(m[:3, 1]))
    direction = -axis_z / max(np.linalg.norm(axis_z), 1e-30)
    tangent = axis_x / max(scale_x, 1e-30)
    info = LightInfo(
        name,
        light.type,
        tuple(pos),  # type: ignore[arg-type]
        tuple(direction),  # type: ignore[arg-type]
        tuple(tangent),  # type: ignore[arg-type]
        tuple(power),  # type: ignore[arg-type]
        radius=float(getattr(light, "shadow_soft_size", 0.0)),
    )
    if light.type in {"POINT", "SPOT"}:
        info.soft_falloff = bool(getattr(light, "use_soft_falloff", True))
    if light.type == "SPOT":
        info.spot_half_angle = float(light.spot_size) / 2.0
        info.spot_blend = float(light.spot_blend)
    elif light.type == "AREA":
        info.area_disk = light.shape in {"DISK", "ELLIPSE"}
        sx = light.size * scale_x
        sy = (light.size_y if light.shape in {"RECTANGLE", "ELLIPSE"} else light.size) * scale_y
        info.size_x, info.size_y = sx, sy
        info.spread = float(getattr(light, "spread", math.pi))
        # ``normalize`` came with Blender 4.5; before it an area light's power was normalized.
        if not getattr(light, "normalize", True):
            area = math.pi * sx * sy / 4.0 if info.area_disk else sx * sy
            info.power = tuple(p * area for p in info.power)  # type: ignore[assignment]
    elif light.type == "SUN":
        info.angle = float(getattr(light, "angle", 0.0))
    return info


@contextlib.contextmanager
def evaluated_mesh(obj: bpy.types.Object) -> Iterator[bpy.types.Mesh | None]:
    """The evaluated mesh of ``obj``, always released with ``to_mesh_clear()``."""
    try:
        mesh = obj.to_mesh()
    except RuntimeError:
        mesh = None
    try:
        yield mesh
    finally:
        obj.to_mesh_clear()


def world_triangles(obj: bpy.types.Object, matrix: Any) -> tuple[np.ndarray, np.ndarray] | None:
    """The evaluated mesh of ``obj`` as triangles in world space, (T, 3, 3) float64 (``matrix``
    its world matrix, 4x4), with each triangle's material slot index (T,) int64; None where it
    has none."""
    m = np.asarray(matrix, dtype=np.float64)
    with evaluated_mesh(obj) as mesh:
        if mesh is None or len(mesh.vertices) == 0:
            return None
        mesh.calc_loop_triangles()
        nt = len(mesh.loop_triangles)
        if nt == 0:
            return None
        co = np.empty(len(mesh.vertices) * 3, dtype=np.float64)
        mesh.vertices.foreach_get("co", co)
        idx = np.empty(nt * 3, dtype=np.int64)
        mesh.loop_triangles.foreach_get("vertices", idx)
        slot = np.empty(nt, dtype=np.int64)
        mesh.loop_triangles.foreach_get("material_index", slot)
    co = co.reshape(-1, 3) @ m[:3, :3].T + m[:3, 3]
    return co[idx.reshape(-1, 3)], slot


def _is_vpl(obj: bpy.types.Object) -> bool:
    original = obj.original if obj.original is not None else obj
    return bool(original.get(VPL_MARKER, False))


def is_vplace(obj: bpy.types.Object) -> bool:
    """Whether vplace wrote ``obj`` (marked, or in a collection vplace marked)."""
    return bool(obj.get(VPL_MARKER, False)) or any(
        c.get(VPL_MARKER, False) for c in obj.users_collection
    )


def base_name(name: str) -> str:
    """``name`` without the ``.001`` Blender adds to a name already taken."""
    base, dot, tail = name.rpartition(".")
    return base if dot and len(tail) == 3 and tail.isdigit() and base else name


#: Object types Cycles renders that vplace cannot turn into triangles.
UNSUPPORTED_TYPES = {"VOLUME": "a volume", "CURVES": "hair curves", "POINTCLOUD": "a point cloud"}


def render_view_layer(scene: bpy.types.Scene) -> bpy.types.ViewLayer:
    """The view layer a capture renders and an export reads: the context's view layer when
    ``scene`` is the context's scene and that layer renders ("Use for Rendering"), else the
    scene's first view layer that renders. Raises :class:`ExportError` where none does (F12
    refuses that scene too)."""
    context = bpy.context.view_layer if bpy.context.scene == scene else None
    if context is not None and context.use:
        return context
    layer = next((v for v in scene.view_layers if v.use), None)
    if layer is None:
        raise ExportError(
            f"no view layer of scene {scene.name!r} renders: turn on 'Use for Rendering' for "
            "one (View Layer properties)"
        )
    return layer


class _RenderDepsgraphEngine(bpy.types.RenderEngine):
    """A render engine that draws nothing: its ``render`` hands the render depsgraph to the
    call of :func:`with_render_depsgraph` in progress. Registered only during that call."""

    bl_idname = "VPLACE_RENDER_DEPSGRAPH"
    bl_label = "vplace (export)"
    bl_use_postprocess = False

    #: The call in progress: (view layer name, function, [result], [error]).
    call: tuple[str, Callable[[bpy.types.Depsgraph], Any], list[Any], list[BaseException]] | None
    call = None

    def render(self, depsgraph: bpy.types.Depsgraph) -> None:
        call = type(self).call
        if call is None or depsgraph.view_layer_eval.name != call[0] or call[2] or call[3]:
            return
        try:
            call[2].append(call[1](depsgraph))
        except BaseException as exc:  # handed to the caller, raised there
            call[3].append(exc)


def with_render_depsgraph(
    scene: bpy.types.Scene,
    view_layer: bpy.types.ViewLayer,
    fn: Callable[[bpy.types.Depsgraph], T],
) -> T:
    """Calls ``fn`` with the depsgraph Cycles would render ``view_layer`` of ``scene`` with
    (mode ``RENDER``: render visibility, render modifier levels and instancing) and returns its
    result; ``fn``'s exceptions propagate. The depsgraph lives only during the call.

    It comes from a render with an internal engine that draws nothing (registered for the call
    only); the scene's engine, compositing and sequencer settings are restored after.
    """
    engine = _RenderDepsgraphEngine
    if engine.call is not None:
        raise ExportError("a render-depsgraph export is already running")
    result: list[Any] = []
    errors: list[BaseException] = []
    registered = False
    try:
        bpy.utils.register_class(engine)
        registered = True
        engine.call = (view_layer.name, fn, result, errors)
        with override() as g:
            r = scene.render
            g.set(r, "engine", engine.bl_idname)
            g.set(r, "use_compositing", False)
            g.set(r, "use_sequencer", False)
            g.set(r, "use_single_layer", True)
            g.set(view_layer, "use", True)
            bpy.ops.render.render(write_still=False, scene=scene.name, layer=view_layer.name)
    finally:
        engine.call = None
        if registered:
            bpy.utils.unregister_class(engine)
    if errors:
        raise errors[0]
    if not result:
        raise ExportError(
            f"Blender did not evaluate view layer {view_layer.name!r} of scene {scene.name!r} "
            "for rendering"
        )
    return result[0]


@dataclass
class _Part:
    """One exported object instance: world-space vertices, triangles, material ids, UVs."""

    vertices: np.ndarray  # (V, 3) float32
    triangles: np.ndarray  # (T, 3) int64, local indices
    material_ids: np.ndarray  # (T,) int64
    uvs: np.ndarray | None  # (T, 3, 2) float32


class _Exporter:
    """Walks a render depsgraph's instances by the render-visibility rule (module docs)."""

    def __init__(self, include_vpls: bool) -> None:
        self.include_vpls = include_vpls
        self.images = mat_rule.ImageCache()
        self.materials: list[MaterialInfo] = []
        self.mat_index: dict[tuple[str, bool], int] = {}
        self.texture_keys: dict[str, int] = {}
        self.parts: list[_Part] = []
        self.lights: list[LightInfo] = []
        self.names: list[str] = []
        self.object_materials: dict[str, set[int]] = {}
        self.instanced: set[str] = set()
        self.warnings: list[str] = []
        self._warned: set[str] = set()

    def warn(self, text: str) -> None:
        if text not in self._warned:
            self._warned.add(text)
            self.warnings.append(text)

    def texture_index(self, image: str) -> int:
        if image not in self.texture_keys:
            self.texture_keys[image] = len(self.texture_keys)
        return self.texture_keys[image]

    def mat_id(self, mat: bpy.types.Material | None, reflects: bool) -> int:
        mat = mat.original if mat is not None and mat.original is not None else mat
        key = (mat.name_full if mat is not None else "", reflects)
        if key not in self.mat_index:
            info = material_info(mat, self.images, self.texture_index)
            for w in info.warnings:
                self.warn(w)
            if not reflects:  # invisible to diffuse rays: it only blocks light
                info.name += " (not diffuse-visible)"
                info.albedo = (0.0, 0.0, 0.0)
                info.texture, info.albedo_offset = None, (0.0, 0.0, 0.0)
                info.gloss = None
            self.mat_index[key] = len(self.materials)
            self.materials.append(info)
        return self.mat_index[key]

    def _light(self, name: str, light: bpy.types.Light, matrix: Any) -> None:
        """Adds a lamp: not a Cycles light portal (it guides Cycles' sampling of the world and
        emits nothing), never one of negative power."""
        if getattr(getattr(light, "cycles", None), "is_portal", False):
            self.warn(
                f"lamp {name!r} is a Cycles light portal: it emits nothing in Cycles and is "
                "left out (EEVEE renders it as an ordinary area lamp)"
            )
            return
        info = light_info(name, light, matrix)
        if min(info.power) < 0.0:
            raise ExportError(
                f"lamp {name!r} has a negative power ({light.energy:g} W): vplace lays out "
                "light, not its removal; make it 0 or more, or hide it from renders"
            )
        self.lights.append(info)

    def visit(self, inst: bpy.types.DepsgraphObjectInstance) -> None:
        obj = inst.object
        original = obj.original if obj.original is not None else obj
        if _is_vpl(obj) and not self.include_vpls:
            return
        if not inst.is_instance and not inst.show_self:
            return  # an emitter whose particle settings hide it
        self._check_linking(original)
        if obj.type == "LIGHT":
            self._light(original.name, obj.data, inst.matrix_world)
            return
        if obj.type in UNSUPPORTED_TYPES:
            self.warn(
                f"object {original.name!r} is {UNSUPPORTED_TYPES[obj.type]}, which vplace "
                "cannot export: it is left out"
            )
            return
        if obj.type != "MESH":
            # A text, curve, surface or metaball: Cycles renders the mesh its evaluation makes,
            # which the depsgraph hands on as an instance of the object's own (below); the
            # object itself renders nothing (Cycles' geometry is mesh data). Both exported,
            # each of its faces lay on another (stop 80). Other types render nothing.
            return
        # That mesh is the object itself, not an instance of something else.
        own = inst.is_instance and inst.parent is not None and inst.parent.original == original
        if not inst.is_instance:
            self._check_particles(obj, original.name)
        if not (obj.visible_diffuse or obj.visible_shadow):
            return  # only the camera (or glossy rays) see it: no part in diffuse transport
        if not obj.visible_shadow:
            self.warn(
                f"object {original.name!r} casts no shadows in Cycles (ray visibility) but "
                "blocks vplace's shadow rays"
            )
        if getattr(original, "is_shadow_catcher", False):
            self.warn(
                f"object {original.name!r} is a shadow catcher: Cycles shows only the shadows "
                "on it, vplace lights and scores it as an ordinary surface"
            )
        part = self._mesh(obj, original.name, inst.matrix_world, obj.visible_diffuse)
        if part is not None:
            self.parts.append(part)
            self.names.append(original.name)
            used = np.unique(part.material_ids).tolist()
            self.object_materials.setdefault(original.name, set()).update(used)
            if inst.is_instance and not own:
                self.instanced.add(original.name)

    def _check_linking(self, obj: bpy.types.Object) -> None:
        """A warning for light or shadow linking (Blender 4.0 on): Cycles' captures follow it;
        vplace's light paths light and shadow every object."""
        linking = getattr(obj, "light_linking", None)
        if linking is None:
            return
        for attr, what in (("receiver_collection", "light"), ("blocker_collection", "shadow")):
            coll = getattr(linking, attr, None)
            if coll is not None:
                self.warn(
                    f"object {obj.name!r} links its {what} to collection {coll.name!r} "
                    f"({what.capitalize()} Linking): the captures follow it, vplace's light "
                    "paths do not (they reach every object), so where no capture looks its "
                    "bounce may differ from Cycles'"
                )

    def _check_particles(self, obj: bpy.types.Object, name: str) -> None:
        for ps in getattr(obj, "particle_systems", ()):
            settings = ps.settings
            if settings.type == "HAIR" and settings.render_type == "PATH":
                self.warn(
                    f"object {name!r} has hair particles ({ps.name!r}), which vplace cannot "
                    "export: they are left out"
                )

    def _mesh(self, obj: bpy.types.Object, name: str, matrix: Any, reflects: bool) -> _Part | None:
        with evaluated_mesh(obj) as mesh:
            if mesh is None or len(mesh.polygons) == 0:
                return None
            mesh.calc_loop_triangles()
            nv, nt = len(mesh.vertices), len(mesh.loop_triangles)
            co = np.empty(nv * 3, dtype=np.float32)
            mesh.vertices.foreach_get("co", co)
            idx = np.empty(nt * 3, dtype=np.int32)
            mesh.loop_triangles.foreach_get("vertices", idx)
            mi = np.empty(nt, dtype=np.int32)
            mesh.loop_triangles.foreach_get("material_index", mi)
            slots = [s.material for s in obj.material_slots] or [None]
            slot_ids = np.array([self.mat_id(m, reflects) for m in slots], dtype=np.int64)
            mids = slot_ids[np.clip(mi, 0, len(slot_ids) - 1)]
            uvs = self._uvs(mesh, name, mids)
        co64 = co.reshape(-1, 3).astype(np.float64)
        if not np.isfinite(co64).all():
            raise ExportError(
                f"object {name!r} has vertices with NaN or infinite coordinates; "
                "fix or hide the mesh"
            )
        tris = idx.reshape(-1, 3).astype(np.int64)
        keep = self._surfaces(name, mids)
        if keep is not None:
            tris, mids = tris[keep], mids[keep]
            uvs = uvs[keep] if uvs is not None else None
            if len(tris) == 0:
                return None
        m = np.array(matrix, dtype=np.float64)
        world = co64 @ m[:3, :3].T + m[:3, 3]
        if np.linalg.det(m[:3, :3]) < 0.0:
            # Mirrored (a negative scale): its faces keep facing out, as Blender shows them and
            # Cycles renders them, with their corners in the other turn.
            tris = tris[:, ::-1]
            uvs = uvs[:, ::-1] if uvs is not None else None
        return _Part(world.astype(np.float32), tris, mids, uvs)

    def _surfaces(self, name: str, mids: np.ndarray) -> np.ndarray | None:
        """Warnings for volume-only and displaced materials; the triangles to keep (None: all)."""
        used = np.unique(mids)
        drop = [int(m) for m in used if self.materials[m].volume_only]
        for m in used:
            info = self.materials[int(m)]
            if info.volume_only:
                self.warn(
                    f"object {name!r}: material {info.name!r} is a volume, which vplace cannot "
                    "export: its faces are left out"
                )
            if info.displaced:
                self.warn(
                    f"object {name!r}: material {info.name!r} displaces the surface, which "
                    "vplace cannot reproduce: the undisplaced surface is exported"
                )
        return ~np.isin(mids, drop) if drop else None

    def _uvs(self, mesh: bpy.types.Mesh, name: str, mids: np.ndarray) -> np.ndarray | None:
        """(T, 3, 2) UVs of each triangle corner from the map its material's textures read;
        None when no material of the object reads a texture."""
        wanted: dict[int, str] = {}
        for m in np.unique(mids):
            info = self.materials[int(m)]
            maps = [t.uv_map for t in (info.texture, info.alpha and info.alpha.texture) if t]
            if maps:
                if len(set(maps)) > 1:
                    self.warn(
                        f"material {info.name!r} reads two UV maps ({maps[0]!r}, {maps[1]!r}): "
                        f"vplace reads both textures through {maps[0]!r}"
                    )
                wanted[int(m)] = maps[0]
        if not wanted:
            return None
        nt = len(mesh.loop_triangles)
        loops = np.empty(nt * 3, dtype=np.int32)
        mesh.loop_triangles.foreach_get("loops", loops)
        layers = mesh.uv_layers
        active = next((la for la in layers if la.active_render), None)
        out = np.zeros((nt, 3, 2), dtype=np.float32)
        cache: dict[str, np.ndarray] = {}
        for layer_name in sorted(set(wanted.values())):
            layer = active if layer_name == "" else layers.get(layer_name)
            if layer is None:
                what = "no UV map" if layer_name == "" else f"no UV map {layer_name!r}"
                self.warn(
                    f"object {name!r} has {what}: its textures are read at UV (0, 0), as "
                    "Cycles does"
                )
                continue
            if layer.name not in cache:
                uv = np.empty(len(mesh.loops) * 2, dtype=np.float32)
                layer.uv.foreach_get("vector", uv)
                cache[layer.name] = uv.reshape(-1, 2)[loops].reshape(nt, 3, 2)
            rows = np.isin(mids, [m for m, n in wanted.items() if n == layer_name])
            out[rows] = cache[layer.name][rows]
        return out

    def result(self, scene: bpy.types.Scene) -> ExportedScene:
        if not self.parts:
            raise ExportError("the scene has no visible mesh geometry to export")
        offsets = np.cumsum([0] + [len(p.vertices) for p in self.parts[:-1]])
        tris = np.concatenate([p.triangles + o for p, o in zip(self.parts, offsets, strict=True)])
        any_uvs = any(p.uvs is not None for p in self.parts)
        uvs = None
        if any_uvs:
            uvs = np.concatenate(
                [
                    p.uvs if p.uvs is not None else np.zeros((len(p.triangles), 3, 2), np.float32)
                    for p in self.parts
                ]
            )
        textures, names = [], []
        for key in self.texture_keys:  # in index order
            data = self.images.get(key)
            if data is None:  # missing image: one magenta texel, as Cycles renders it
                px = np.array([[[*mat_rule.MISSING_IMAGE, 1.0]]], dtype=np.float32)
            else:
                px = data.pixels
            textures.append(px)
            names.append(key)
        for w in self.images.warnings:
            self.warn(w)
        cam = scene.camera
        camera = None
        if cam is not None and cam.type == "CAMERA":
            r = scene.render
            scale = r.resolution_percentage / 100.0
            camera = CameraInfo(
                cam.name,
                np.array(cam.matrix_world, dtype=np.float64),
                cam.data.lens,
                cam.data.sensor_width,
                (int(r.resolution_x * scale), int(r.resolution_y * scale)),
            )
        world = world_info(scene.world)
        if world is not None:
            for w in world.warnings:
                self.warn(w)
        vertices = np.concatenate([p.vertices for p in self.parts]).astype(np.float32, copy=False)
        owners = np.repeat(np.arange(len(self.parts)), [len(p.triangles) for p in self.parts])
        twice = shown_twice_warning(shown_twice(vertices, tris, owners, self.names))
        if twice is not None:
            self.warn(twice)
        return ExportedScene(
            vertices,
            tris.astype(np.uint32),
            np.concatenate([p.material_ids for p in self.parts]).astype(np.uint32),
            self.materials,
            self.lights,
            camera,
            world.mean_color if world is not None else (0.0, 0.0, 0.0),
            self.names,
            world=world,
            uvs=uvs,
            textures=textures,
            texture_names=names,
            warnings=self.warnings,
            light_bounces=self.bounces(scene),
            unit_scale=unit_scale(scene),
            object_materials={
                name: tuple(sorted(mats))
                for name, mats in self.object_materials.items()
                if name not in self.instanced
            },
            instanced_materials=tuple(
                sorted(set().union(*(self.object_materials[n] for n in self.instanced)))
            ),
        )

    def bounces(self, scene: bpy.types.Scene) -> tuple[int, int, int]:
        """:func:`light_bounces`, with a warning where Cycles follows no diffuse bounce."""
        diffuse, glossy, total = light_bounces(scene)
        if min(diffuse, total) == 0:
            self.warn(
                "Cycles follows no diffuse bounce here (Light Paths > Max Bounces > Diffuse or "
                "Total is 0), so its renders show no bounce light; vplace's lights add the "
                "first bounce"
            )
        return diffuse, glossy, total


def unit_scale(scene: bpy.types.Scene) -> float:
    """Metres per Blender unit: the scene's Units > Unit Scale (1 without a unit system).
    Cycles and EEVEE render in Blender units whatever the scale, and so does vplace; the lengths
    it reads from the user (``--radius``, ``--region-radius``, an orbit's radius) and writes
    into its reports are in metres, converted with this."""
    u = scene.unit_settings
    if u.system == "NONE" or not u.scale_length > 0.0:
        return 1.0
    return float(u.scale_length)


def light_bounces(scene: bpy.types.Scene) -> tuple[int, int, int]:
    """The reflections ``scene``'s Cycles renders follow before the surface a path ends on, which
    a light lights directly: Light Paths > Max Bounces ``(Diffuse, Glossy, Total)`` (Blender's
    defaults 4, 4, 12). A capture renders with them, so the light vplace adds to a view stops
    there too: light that only many reflections bring (a room lit through a doorway) is darker
    in Cycles than every bounce would make it."""
    c = scene.cycles
    total = max(0, int(c.max_bounces))
    return min(int(c.diffuse_bounces), total), min(int(c.glossy_bounces), total), total


def export_scene(
    scene: bpy.types.Scene,
    depsgraph: bpy.types.Depsgraph | None = None,
    *,
    include_vpls: bool = False,
) -> ExportedScene:
    """Exports the geometry, materials, textures, lights and camera of ``scene`` that Cycles
    renders (the render-visibility rule of the module docs).

    ``depsgraph`` defaults to the render depsgraph of :func:`render_view_layer` (through
    :func:`with_render_depsgraph`); a given one is used as it is. The lights vplace wrote are
    left out unless ``include_vpls`` (a capture's cache key needs them: they change the render).
    Unsupported objects are left out and named in ``ExportedScene.warnings``.
    """
    exporter = _Exporter(include_vpls)

    def walk(dg: bpy.types.Depsgraph) -> None:
        for inst in dg.object_instances:
            exporter.visit(inst)

    if depsgraph is not None:
        walk(depsgraph)
    else:
        with_render_depsgraph(scene, render_view_layer(scene), walk)
    return exporter.result(scene)
