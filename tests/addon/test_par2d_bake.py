"""addon.par2d_bake: flat objects of a collection -> 2D scene -> light map on a plane."""

import bpy
import numpy as np
import pytest
from blender_util import empty_file

from addon.compat import new_material
from addon.native import vplace
from addon.writeback import par2d_bake


def _square(name, x0, y0, x1, y1, collection, emission=None, z=0.0):
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([(x0, y0, z), (x1, y0, z), (x1, y1, z), (x0, y1, z)], [], [(0, 1, 2, 3)])
    obj = bpy.data.objects.new(name, mesh)
    collection.objects.link(obj)
    if emission is not None:
        mat = new_material(name)
        bsdf = mat.node_tree.nodes["Principled BSDF"]
        bsdf.inputs["Emission Color"].default_value = (*emission, 1.0)
        bsdf.inputs["Emission Strength"].default_value = 2.0
        mesh.materials.append(mat)
    return obj


def _flat_collection():
    empty_file()
    scene = bpy.data.scenes.new("par2d")
    bpy.context.window_manager.windows[0].scene = (
        scene if bpy.context.window_manager.windows else None
    )
    coll = bpy.data.collections.new("flat")
    scene.collection.children.link(coll)
    _square("light", 2.0, -0.5, 3.0, 0.5, coll, emission=(1.0, 0.5, 0.25))
    _square("wall", 1.0, -0.2, 1.3, 0.1, coll, z=0.3)  # the height is ignored
    return coll


def test_collect_bake_and_display():
    coll = _flat_collection()
    depsgraph = bpy.context.evaluated_depsgraph_get()
    flat = par2d_bake.collect_polygons(coll, depsgraph)
    assert flat.triangles.shape == (4, 3, 2) and flat.skipped == 0
    emitting = flat.emission.any(axis=1)
    assert emitting.sum() == 2
    np.testing.assert_allclose(flat.emission[emitting], [[2.0, 1.0, 0.5]] * 2)
    img, bounds = par2d_bake.bake_collection(flat, 24, 16, "exact", margin=0.25)
    assert img.shape == (16, 24, 3)

    # The same map straight from the library with the squares as convex polygons (at the
    # float32 precision of Blender's vertex coordinates).
    def f32(poly):
        return np.asarray(poly, dtype=np.float32).astype(np.float64)

    ref = vplace.par2d.Scene2D.from_lights(
        [f32([[2, -0.5], [3, -0.5], [3, 0.5], [2, 0.5]])],
        [[2.0, 1.0, 0.5]],
        [f32([[1, -0.2], [1.3, -0.2], [1.3, 0.1], [1, 0.1]])],
    ).light_map(bounds, 24, 16, "exact")
    np.testing.assert_allclose(img, ref, rtol=1e-9, atol=1e-12)
    image = par2d_bake.light_map_image("par2d_test", img)
    pixels = np.empty(24 * 16 * 4, dtype=np.float32)
    image.pixels.foreach_get(pixels)
    np.testing.assert_allclose(pixels.reshape(16, 24, 4)[::-1, :, :3], img, rtol=1e-6)
    plane = par2d_bake.make_display_plane(image, bounds, coll, z=-0.01)
    assert plane.data.materials[0].node_tree.nodes["Image Texture"].image == image
    assert len(plane.data.vertices) == 4


def test_empty_collection_is_an_input_error():
    empty_file()
    coll = bpy.data.collections.new("nothing")
    with pytest.raises(vplace.InputError):
        par2d_bake.collect_polygons(coll, bpy.context.evaluated_depsgraph_get())
