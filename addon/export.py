"""Scene export: the evaluated depsgraph as numpy arrays (DESIGN: Scene export).

Triangles in world space with a material id each; materials reduced to what the core shades
(diffuse albedo = base colour x (1 - metallic), the mean texture colour where the base colour is
textured; roughness; metallic; emission: an Emission shader's or the Principled BSDF's colour x
strength, radiance from both sides); lights with their effective RGB power and every parameter
Cycles renders them with (point and spot radius and soft falloff, spot size and blend, area
shape, sizes and spread, sun angle); the world's light (``world.py``: a colour, an environment
image with its rotation, or a baked node setup); the camera. The VPLs that vplace wrote itself
(objects marked ``vplace_vpl``) are never exported.
"""

from __future__ import annotations

import contextlib
import hashlib
import math
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import bpy
import numpy as np

from .errors import ExportError
from .world import WorldInfo, world_info

__all__ = [
    "ExportError",
    "ExportedScene",
    "WorldInfo",
    "export_scene",
    "light_info",
    "material_info",
]

#: Custom property that marks the objects and the collection vplace writes.
VPL_MARKER = "vplace_vpl"
#: Albedo of a slot without a material (Blender's default grey).
DEFAULT_ALBEDO = (0.8, 0.8, 0.8)


@dataclass
class MaterialInfo:
    """What the core needs of a material."""

    name: str
    albedo: tuple[float, float, float]
    roughness: float = 0.5
    metallic: float = 0.0
    emission: tuple[float, float, float] = (0.0, 0.0, 0.0)
    textured: bool = False


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
    #: What the export approximated, in words (a baked world, an unreadable image, ...).
    warnings: list[str] = field(default_factory=list)

    @property
    def albedo(self) -> np.ndarray:
        """(M, 3) float32 diffuse albedo per material."""
        return np.array([m.albedo for m in self.materials], dtype=np.float32).reshape(-1, 3)

    @property
    def emission(self) -> np.ndarray:
        """(M, 3) float32 emitted radiance per material (W/(m^2 sr), both sides)."""
        e = np.array([m.emission for m in self.materials], dtype=np.float32).reshape(-1, 3)
        return np.ascontiguousarray(np.maximum(e, 0.0))

    def emitters(self) -> list[str]:
        """What sends light, in words: lights with power, the world, emissive materials."""
        out = [f"light {light.name!r}" for light in self.lights if max(light.power) > 0.0]
        if self.world is not None and self.world.emits:
            out.append(f"world {self.world.name!r}")
        out += [f"material {m.name!r}" for m in self.materials if max(m.emission) > 0.0]
        return out

    def fingerprint(self) -> str:
        """A hash of everything that changes a render of this scene (for capture caches)."""
        h = hashlib.sha256()
        for arr in (self.vertices, self.triangles, self.material_ids):
            h.update(np.ascontiguousarray(arr).tobytes())
        h.update(repr([vars(m) for m in self.materials]).encode())
        h.update(repr([vars(light) for light in self.lights]).encode())
        h.update(repr(self.world_color).encode())
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


def material_info(mat: bpy.types.Material | None) -> MaterialInfo:
    """Reduces a material to albedo, roughness, metallic and emission."""
    if mat is None:
        return MaterialInfo("<none>", DEFAULT_ALBEDO)
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
        color, textured = _input_color(shader, "Base Color")
        metallic = _input_float(shader, "Metallic", 0.0)
        strength = _input_float(shader, "Emission Strength", 0.0)
        emit, _ = _input_color(shader, "Emission Color")
        info = MaterialInfo(
            mat.name,
            tuple(c * (1.0 - metallic) for c in color),  # type: ignore[arg-type]
            _input_float(shader, "Roughness", 0.5),
            metallic,
            (emit[0] * strength, emit[1] * strength, emit[2] * strength),
            textured,
        )
    elif shader.type == "BSDF_DIFFUSE":
        color, textured = _input_color(shader, "Color")
        info = MaterialInfo(mat.name, color, 1.0, 0.0, textured=textured)
    elif shader.type == "EMISSION":
        emit, _ = _input_color(shader, "Color")
        s = _input_float(shader, "Strength", 1.0)
        info = MaterialInfo(
            mat.name, (0.0, 0.0, 0.0), emission=(emit[0] * s, emit[1] * s, emit[2] * s)
        )
    a = np.clip(np.array(info.albedo, dtype=np.float64), 0.0, 1.0)
    info.albedo = (float(a[0]), float(a[1]), float(a[2]))
    return info


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
        if not light.normalize:
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


def _is_vpl(obj: bpy.types.Object) -> bool:
    original = obj.original if obj.original is not None else obj
    return bool(original.get(VPL_MARKER, False))


GEOMETRY_TYPES = {"MESH", "CURVE", "SURFACE", "META", "FONT", "CURVES"}


def export_scene(
    scene: bpy.types.Scene,
    depsgraph: bpy.types.Depsgraph | None = None,
    *,
    include_vpls: bool = False,
) -> ExportedScene:
    """Exports the render-visible geometry, materials, lights and camera of ``scene``.

    The lights vplace wrote are left out unless ``include_vpls`` (a capture's cache key needs
    them: they change the render).
    """
    if depsgraph is None:
        depsgraph = bpy.context.evaluated_depsgraph_get()
    verts: list[np.ndarray] = []
    tris: list[np.ndarray] = []
    mids: list[np.ndarray] = []
    materials: list[MaterialInfo] = []
    mat_index: dict[str, int] = {}
    lights: list[LightInfo] = []
    names: list[str] = []
    offset = 0

    def mat_id(mat: bpy.types.Material | None) -> int:
        key = mat.name_full if mat is not None else ""
        if key not in mat_index:
            mat_index[key] = len(materials)
            materials.append(material_info(mat))
        return mat_index[key]

    for inst in depsgraph.object_instances:
        obj = inst.object
        original = obj.original if obj.original is not None else obj
        if original.hide_render or (_is_vpl(obj) and not include_vpls):
            continue
        if obj.type == "LIGHT":
            lights.append(light_info(original.name, obj.data, inst.matrix_world))
            continue
        if obj.type not in GEOMETRY_TYPES:
            continue
        with evaluated_mesh(obj) as mesh:
            if mesh is None or len(mesh.polygons) == 0:
                continue
            mesh.calc_loop_triangles()
            nv, nt = len(mesh.vertices), len(mesh.loop_triangles)
            co = np.empty(nv * 3, dtype=np.float32)
            mesh.vertices.foreach_get("co", co)
            idx = np.empty(nt * 3, dtype=np.int64)
            mesh.loop_triangles.foreach_get("vertices", idx)
            mi = np.empty(nt, dtype=np.int64)
            mesh.loop_triangles.foreach_get("material_index", mi)
            slots = [s.material for s in obj.material_slots] or [None]
        co = co.reshape(-1, 3).astype(np.float64)
        if not np.isfinite(co).all():
            raise ExportError(
                f"object {original.name!r} has vertices with NaN or infinite coordinates; "
                "fix or hide the mesh"
            )
        m = np.array(inst.matrix_world, dtype=np.float64)
        world = co @ m[:3, :3].T + m[:3, 3]
        slot_ids = np.array([mat_id(s) for s in slots], dtype=np.int64)
        verts.append(world.astype(np.float32))
        tris.append(idx.reshape(-1, 3) + offset)
        mids.append(slot_ids[np.clip(mi, 0, len(slot_ids) - 1)])
        offset += nv
        names.append(original.name)

    if not tris:
        raise ExportError("the scene has no visible mesh geometry to export")
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
    world_color = world.mean_color if world is not None else (0.0, 0.0, 0.0)
    return ExportedScene(
        np.concatenate(verts).astype(np.float32),
        np.concatenate(tris).astype(np.uint32),
        np.concatenate(mids).astype(np.uint32),
        materials,
        lights,
        camera,
        world_color,
        names,
        world,
        list(world.warnings) if world is not None else [],
    )
