"""Helpers for tests that drive Blender (the bpy module): scenes and RNA snapshots."""

from __future__ import annotations

import contextlib
import hashlib
import math
from collections.abc import Iterator
from typing import Any

import bpy
import numpy as np

import addon
from addon.compat import new_material
from addon.scene.export import VPL_MARKER
from addon.scenes.registry import build_cornell_box
from addon.writeback.par2d_bake import OUTPUT_MARKER

#: Custom properties that mark what vplace writes (and may replace).
MARKERS = (VPL_MARKER, OUTPUT_MARKER)


def _marked(idblock: Any) -> bool:
    return any(idblock.get(m, False) for m in MARKERS)


ROOT_OBJ = __import__("pathlib").Path(__file__).resolve().parent.parent / "blend_scenes"
CORNELL_OBJ = ROOT_OBJ / "cornell_box" / "CornellBox-Original.obj"

#: Properties that change without the user changing anything.
VOLATILE = {
    "is_dirty",
    "is_evaluated",
    "session_uid",
    "users",
    "tag",
    "original",
    "rna_type",
    "is_runtime_data",
    "preview",
    "name_full",
    "use_extra_user",
    "depsgraph",
    # The UV sculpt paint mode: reading it in a file that never entered it crashes Blender 4.2
    # (its brush's tool slots); vplace never touches tool settings.
    "uv_sculpt",
}


def add_lamp(
    scene: bpy.types.Scene,
    kind: str,
    location: tuple[float, float, float],
    energy: float,
    rotation: tuple[float, float, float] = (0.0, 0.0, 0.0),
    **props: Any,
) -> bpy.types.Object:
    """A lamp of Blender type ``kind`` (its data's ``props`` set) linked to ``scene``."""
    light = bpy.data.lights.new(kind, kind)
    light.energy = energy
    for k, v in props.items():
        setattr(light, k, v)
    obj = bpy.data.objects.new(kind, light)
    obj.location = location
    obj.rotation_euler = rotation
    scene.collection.objects.link(obj)
    return obj


def empty_file() -> None:
    bpy.ops.wm.read_factory_settings(use_empty=True)


def cornell() -> bpy.types.Scene:
    """A fresh file holding only the Cornell box."""
    empty_file()
    scene = build_cornell_box(CORNELL_OBJ)
    bpy.context.view_layer.update()  # evaluated matrices, as in a file opened from disk
    return scene


@contextlib.contextmanager
def addon_cornell(**settings: Any) -> Iterator[bpy.types.Scene]:
    """The add-on registered and a fresh Cornell box with tiny run settings (16 px capture,
    2 spp, 8 VPLs; ``settings`` override ``Scene.vplace`` fields) for the block."""
    addon.register()
    try:
        empty_file()
        scene = build_cornell_box(CORNELL_OBJ)
        s = scene.vplace
        s.capture_size, s.samples, s.vpl_budget = 16, 2, 8
        for name, value in settings.items():
            setattr(s, name, value)
        scene.render.image_settings.file_format = "PNG"  # as a saved file has it (test_capture)
        bpy.context.view_layer.update()
        yield scene
    finally:
        addon.unregister()


def _nan_safe(value: Any) -> Any:
    """NaN compares unequal to itself: stand it in by a string."""
    if isinstance(value, float) and math.isnan(value):
        return "nan"
    if isinstance(value, tuple):
        return tuple(_nan_safe(v) for v in value)
    return value


def _written_by_vplace(item: Any) -> bool:
    if isinstance(item, bpy.types.ID):
        return is_vplace(item)
    if isinstance(item, bpy.types.LayerCollection):
        return _marked(item.collection)
    return False


def _attribute_values(attr: bpy.types.Attribute) -> str:
    """A digest of a mesh attribute's values, element by element."""
    data = attr.data
    if len(data) == 0:
        return ""
    first = data[0]
    key = next(k for k in ("value", "vector", "color", "id") if hasattr(first, k))
    sample = getattr(first, key)
    if isinstance(sample, str):
        return hashlib.sha1("\0".join(getattr(d, key) for d in data).encode()).hexdigest()
    values = np.empty(len(data) * np.asarray(sample).size, dtype=np.float64)
    try:
        data.foreach_get(key, values)
    except TypeError:  # booleans and integers read one by one
        values = np.array([np.asarray(getattr(d, key), dtype=np.float64) for d in data])
    return hashlib.sha1(values.tobytes()).hexdigest()


def attribute_snapshot(attr: bpy.types.Attribute) -> dict[str, Any]:
    """A mesh attribute by what it holds: name, domain, type and its values. Not how Blender
    stores them: Blender 5.2 turns an attribute stored as one value for every element
    (``storage_type`` ``SINGLE``) into an array when some operator reads the mesh, the same values
    either way; a change vplace made would change the values."""
    return {
        "name": attr.name,
        "domain": attr.domain,
        "data_type": attr.data_type,
        "values": _attribute_values(attr),
    }


def rna_snapshot(struct: Any, depth: int = 3) -> Any:
    """Every plain property of an RNA struct, recursing into non-ID pointers and collections;
    a mesh attribute by its values (:func:`attribute_snapshot`)."""
    if struct is None:
        return None
    if isinstance(struct, bpy.types.Attribute):
        return attribute_snapshot(struct)
    if isinstance(struct, bpy.types.ID) and depth < 3:
        return ("ID", struct.name_full)
    out: dict[str, Any] = {}
    for prop in struct.bl_rna.properties:
        key = prop.identifier
        if key in VOLATILE:
            continue
        try:
            value = getattr(struct, key)
        except (AttributeError, RuntimeError):
            continue
        if prop.type in {"BOOLEAN", "INT", "FLOAT", "STRING", "ENUM"}:
            if hasattr(value, "__len__") and not isinstance(value, str | set):
                value = tuple(value)
                if value and hasattr(value[0], "__len__"):
                    value = tuple(tuple(v) for v in value)
            value = _nan_safe(value)
            out[key] = value
        elif prop.type == "POINTER" and depth > 0:
            out[key] = rna_snapshot(value, depth - 1)
        elif prop.type == "COLLECTION" and depth > 0:
            items = [i for i in list(value)[:64] if not _written_by_vplace(i)]
            out[key] = [rna_snapshot(item, depth - 1) for item in items]
    return out


DATA_COLLECTIONS = (
    "objects",
    "meshes",
    "materials",
    "lights",
    "cameras",
    "worlds",
    "collections",
    "scenes",
    "images",
    "node_groups",
    "textures",
)


def is_vplace(idblock: Any) -> bool:
    if _marked(idblock):
        return True
    if isinstance(idblock, bpy.types.Light | bpy.types.Mesh | bpy.types.LightProbe):
        return any(_marked(o) for o in bpy.data.objects if o.data == idblock)
    return False


def data_snapshot() -> dict[str, Any]:
    """A snapshot of every datablock except the ones vplace writes, and of each scene's
    collection tree without the VPL collection."""
    snap: dict[str, Any] = {}
    for coll_name in DATA_COLLECTIONS:
        for block in getattr(bpy.data, coll_name):
            if is_vplace(block) or block.name == "Render Result":  # Blender's render buffer
                continue
            s = rna_snapshot(block, depth=3)
            if isinstance(block, bpy.types.Scene):
                s.pop("collection", None)
                s.pop("vplace", None)  # the add-on's own settings and results
                s["children"] = sorted(c.name for c in block.collection.children if not _marked(c))
                s["objects"] = sorted(o.name for o in block.collection.objects if not _marked(o))
            if isinstance(block, bpy.types.Object):
                s["matrix_world"] = tuple(tuple(r) for r in block.matrix_world)
            snap[f"{coll_name}/{block.name_full}"] = s
    return snap


def diff(a: dict[str, Any], b: dict[str, Any], path: str = "") -> list[str]:
    """Paths where two snapshots differ."""
    out = []
    if isinstance(a, dict) and isinstance(b, dict):
        for k in sorted(set(a) | set(b)):
            if k not in a or k not in b:
                out.append(f"{path}/{k}: only in {'after' if k in b else 'before'}")
            else:
                out.extend(diff(a[k], b[k], f"{path}/{k}"))
    elif isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            out.extend(diff(x, y, f"{path}[{i}]"))
    elif a != b:
        out.append(f"{path}: {a!r} -> {b!r}")
    return out


def no_vpls() -> Any:
    """A VPL set of one powerless VPL: ``apply.write_vpls`` then writes only the stand-in lights
    (emitters, a world's sun) it is given."""

    from addon.native import vplace

    up = np.array([[0.0, 0.0, 1.0]], np.float32)
    return vplace.VplSet(np.zeros((1, 3), np.float32), up, np.zeros((1, 3), np.float32))


def add_mesh(
    scene: bpy.types.Scene, name: str, verts: list[Any], faces: list[Any]
) -> bpy.types.Object:
    """A new mesh object of ``verts`` and ``faces`` linked to ``scene``."""
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(verts, [], faces)
    obj = bpy.data.objects.new(name, mesh)
    scene.collection.objects.link(obj)
    bpy.context.view_layer.update()
    return obj


def add_glowing_panel(scene: bpy.types.Scene, strength: float) -> bpy.types.Object:
    """A 0.5 x 0.4 panel facing down just under the Cornell box's ceiling, of an Emission
    shader of ``strength``: an emissive mesh, which EEVEE lights with through vplace's
    stand-ins."""
    panel = add_mesh(
        scene,
        "panel",
        [(-0.25, -0.2, 1.95), (0.25, -0.2, 1.95), (0.25, 0.2, 1.95), (-0.25, 0.2, 1.95)],
        [(0, 3, 2, 1)],  # facing down
    )
    mat = new_material("glow")
    nodes = mat.node_tree.nodes
    nodes.remove(nodes["Principled BSDF"])
    emission = nodes.new("ShaderNodeEmission")
    emission.inputs["Strength"].default_value = strength
    mat.node_tree.links.new(emission.outputs[0], nodes["Material Output"].inputs["Surface"])
    panel.data.materials.append(mat)
    return panel


def principled(name: str, **inputs: Any) -> tuple[bpy.types.Material, bpy.types.Node]:
    """A new material with its default Principled BSDF's ``inputs`` set; the material and the
    node."""
    mat = new_material(name)
    node = mat.node_tree.nodes["Principled BSDF"]
    for key, value in inputs.items():
        node.inputs[key].default_value = value
    return mat, node
