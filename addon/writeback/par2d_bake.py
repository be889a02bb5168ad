"""Bakes a 2D PAR light map of a collection of flat objects onto an image-textured plane.

Plain functions, no class registration. Each mesh object of the collection is triangulated and
its triangles are projected onto the XY plane (world space); every triangle is a convex polygon
of the 2D scene, so non-convex outlines are handled. A triangle whose material emits (Principled
"Emission Color" x "Emission Strength", or an Emission shader) is a light with that RGB
emission; any other triangle is an occluder. Triangles that are degenerate once projected (seen
edge-on from above) are skipped. The light map is written as a float image and shown, unlit, on a
plane through an Emission shader, so EEVEE and Cycles both display it.
"""

from __future__ import annotations

from dataclasses import dataclass

import bpy
import numpy as np

from ..compat import new_material
from ..native import vplace
from ..scene.export import material_info, world_triangles
from . import apply

__all__ = [
    "Flat2DScene",
    "bake_collection",
    "collect_polygons",
    "light_map_image",
    "make_display_plane",
]

#: Projected triangles with twice their area below this times the squared bounds are skipped.
DEGENERATE_RTOL = 1e-12


@dataclass
class Flat2DScene:
    """The 2D scene of a collection: triangles projected onto XY with their emission."""

    triangles: np.ndarray  # (T, 3, 2) float64, world XY
    emission: np.ndarray  # (T, 3) float64, zero for occluders
    skipped: int  # degenerate projected triangles left out

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """``(xmin, ymin, xmax, ymax)`` of all triangles."""
        pts = self.triangles.reshape(-1, 2)
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        return float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1])


def collect_polygons(
    collection: bpy.types.Collection, depsgraph: bpy.types.Depsgraph
) -> Flat2DScene:
    """Triangulates every mesh object of ``collection`` (and its children) and projects it.

    Raises:
        vplace.InputError: the collection holds no usable triangle.
    """
    tris: list[np.ndarray] = []
    emits: list[np.ndarray] = []
    for obj in collection.all_objects:
        if obj.type != "MESH":
            continue
        ev = obj.evaluated_get(depsgraph)
        mats = [material_info(s.material).emission for s in ev.material_slots]
        found = world_triangles(ev, ev.matrix_world)
        if found is None:
            continue
        world, mat_idx = found
        tris.append(world[:, :, :2])
        table = np.array(mats if mats else [(0.0, 0.0, 0.0)], dtype=np.float64).reshape(-1, 3)
        emits.append(table[np.clip(mat_idx, 0, len(table) - 1)])
    if not tris:
        raise vplace.InputError(f"collection {collection.name!r} holds no mesh triangles")
    t = np.concatenate(tris, axis=0)
    e = np.clip(np.concatenate(emits, axis=0), 0.0, None)
    span = float(np.ptp(t.reshape(-1, 2), axis=0).max()) or 1.0
    a, b = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]
    area2 = np.abs(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])
    keep = area2 > DEGENERATE_RTOL * span * span
    if not keep.any():
        raise vplace.InputError(
            f"collection {collection.name!r}: every triangle is edge-on when seen from above"
        )
    return Flat2DScene(t[keep], e[keep], int((~keep).sum()))


def bake_collection(
    flat: Flat2DScene,
    width: int,
    height: int,
    method: str = "exact",
    margin: float = 0.1,
    rays: int = 1024,
) -> tuple[np.ndarray, tuple[float, float, float, float]]:
    """The ``(height, width, 3)`` light map of ``flat`` over its bounds grown by ``margin``
    (a fraction of the larger side), and those bounds ``(xmin, ymin, xmax, ymax)``."""
    x0, y0, x1, y1 = flat.bounds
    pad = margin * max(x1 - x0, y1 - y0, 1e-9)
    bounds = (x0 - pad, y0 - pad, x1 + pad, y1 + pad)
    scene = vplace.par2d.Scene2D(list(flat.triangles), flat.emission)
    img = scene.light_map(bounds, width, height, method, rays=rays)  # type: ignore[arg-type]
    return img, bounds


def light_map_image(name: str, pixels: np.ndarray) -> bpy.types.Image:
    """A float image holding ``pixels`` ``(H, W, 3)`` (row 0 at the top), replacing any old one."""
    h, w, _ = pixels.shape
    old = bpy.data.images.get(name)
    if old is not None:
        bpy.data.images.remove(old)
    image = bpy.data.images.new(name, width=w, height=h, alpha=False, float_buffer=True)
    # Set the colour space first: changing it afterwards reloads the image and loses the pixels.
    image.colorspace_settings.name = "Linear Rec.709"
    rgba = np.ones((h, w, 4), dtype=np.float32)
    rgba[..., :3] = pixels[::-1]  # Blender stores the bottom row first
    image.pixels.foreach_set(rgba.ravel())
    image.update()
    image.pack()
    return image


def make_display_plane(
    image: bpy.types.Image,
    bounds: tuple[float, float, float, float],
    collection: bpy.types.Collection,
    z: float = 0.0,
    name: str = "PAR light map",
) -> bpy.types.Object:
    """A plane covering ``bounds`` at height ``z`` showing ``image`` unlit (Emission shader)."""
    x0, y0, x1, y1 = bounds
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([(x0, y0, z), (x1, y0, z), (x1, y1, z), (x0, y1, z)], [], [(0, 1, 2, 3)])
    uv = mesh.uv_layers.new(name="UVMap")
    uv.data.foreach_set("uv", [0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 0.0, 1.0])
    mesh.update()
    mat = new_material(name)
    tree = mat.node_tree
    tree.nodes.clear()
    tex = tree.nodes.new("ShaderNodeTexImage")
    tex.image = image
    tex.interpolation = "Closest"
    emit = tree.nodes.new("ShaderNodeEmission")
    out = tree.nodes.new("ShaderNodeOutputMaterial")
    tree.links.new(tex.outputs["Color"], emit.inputs["Color"])
    tree.links.new(emit.outputs["Emission"], out.inputs["Surface"])
    mesh.materials.append(mat)
    obj = bpy.data.objects.new(name, mesh)
    collection.objects.link(obj)
    return obj


#: The collection the bake writes (replaced on every bake) and the mark on what it owns.
OUTPUT_COLLECTION = "vplace PAR light map"
OUTPUT_MARKER = "vplace_par2d"


def bake_to_scene(
    scene: bpy.types.Scene,
    source: bpy.types.Collection,
    width: int = 256,
    height: int = 256,
    method: str = "exact",
    z: float = -0.01,
) -> bpy.types.Object:
    """Bakes ``source`` and shows the light map on a plane in the ``vplace PAR light map``
    collection, replacing the previous bake (its plane, material, mesh and image) only."""
    flat = collect_polygons(source, bpy.context.evaluated_depsgraph_get())
    pixels, bounds = bake_collection(flat, width, height, method)
    user = bpy.data.collections.get(OUTPUT_COLLECTION)
    if user is not None and not user.get(OUTPUT_MARKER, False):
        raise vplace.InputError(
            f"a collection named {OUTPUT_COLLECTION!r} exists but was not made by vplace"
        )
    old = apply.scene_collection(scene, OUTPUT_COLLECTION, OUTPUT_MARKER)
    if old is not None:
        for obj in list(old.objects):
            if obj.get(OUTPUT_MARKER, False):
                mesh = obj.data
                mats = [m for m in mesh.materials if m is not None]
                bpy.data.objects.remove(obj)
                bpy.data.meshes.remove(mesh)
                for mat in mats:
                    if mat.users == 0:
                        bpy.data.materials.remove(mat)
        bpy.data.collections.remove(old)
    coll = bpy.data.collections.new(OUTPUT_COLLECTION)
    coll[OUTPUT_MARKER] = True
    coll[apply.ROLE_KEY] = OUTPUT_COLLECTION
    scene.collection.children.link(coll)
    image = light_map_image("vplace PAR light map", pixels)
    obj = make_display_plane(image, bounds, coll, z=z)
    obj[OUTPUT_MARKER] = True
    obj["vplace_method"] = method
    return obj
