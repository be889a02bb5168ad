"""The PAR bake operator on the demo scene: light map values, re-run replaces, undo-safe data."""

import bpy
import numpy as np
import pytest
from blender_util import data_snapshot, diff, empty_file

import addon
from addon.native import vplace
from addon.scenes import registry as default_scene
from addon.writeback import par2d_bake


@pytest.fixture
def registered():
    addon.register()
    yield
    addon.unregister()


def test_bake_operator_values_and_rerun(registered):
    empty_file()
    default_scene.build_par2d_demo()
    bpy.context.view_layer.update()
    before = data_snapshot()
    assert bpy.ops.vplace.bake_par2d(collection="PAR scene", width=24, height=20) == {"FINISHED"}
    assert bpy.ops.vplace.bake_par2d(collection="PAR scene", width=24, height=20) == {"FINISHED"}
    outputs = [c for c in bpy.data.collections if c.get(par2d_bake.OUTPUT_MARKER)]
    assert len(outputs) == 1 and len(outputs[0].objects) == 1
    image = bpy.data.images["vplace PAR light map"]
    assert tuple(image.size) == (24, 20)
    px = np.array(image.pixels[:], dtype=np.float32).reshape(20, 24, 4)[::-1, :, :3]
    # The baked pixels are the library's light map of the same polygons.
    flat = par2d_bake.collect_polygons(
        bpy.data.collections["PAR scene"], bpy.context.evaluated_depsgraph_get()
    )
    expected, _ = par2d_bake.bake_collection(flat, 24, 20, "exact")
    np.testing.assert_allclose(px, expected, rtol=1e-5, atol=1e-6)
    assert px.max() > 1.0 and (px == 0).any()  # inside a light; inside an occluder
    # Nothing of the user's changed but the output collection (and its image, material).
    after = {k: v for k, v in data_snapshot().items() if "PAR light map" not in k}
    assert diff(before, after) == []


def test_bake_operator_errors(registered):
    empty_file()
    with pytest.raises(RuntimeError, match="no collection named 'nope'"):
        bpy.ops.vplace.bake_par2d(collection="nope")
    bpy.context.scene.collection.children.link(bpy.data.collections.new("empty"))
    with pytest.raises(RuntimeError, match="holds no mesh triangles"):
        bpy.ops.vplace.bake_par2d(collection="empty")
    assert issubclass(vplace.InputError, vplace.VplaceError)


def test_a_bake_in_one_scene_keeps_another_scenes_light_map():
    empty_file()
    default_scene.build_par2d_demo()
    bpy.context.view_layer.update()
    source = bpy.data.collections["PAR scene"]
    a = bpy.context.scene
    b = bpy.data.scenes.new("B")
    par2d_bake.bake_to_scene(a, source, 8, 6)
    theirs = par2d_bake.bake_to_scene(b, source, 8, 6).name
    par2d_bake.bake_to_scene(a, source, 8, 6)  # replaces A's light map only
    assert theirs in bpy.data.objects and theirs in b.objects
    outputs = [c for c in bpy.data.collections if c.get(par2d_bake.OUTPUT_MARKER)]
    assert len(outputs) == 2
    assert sum(len(c.objects) for c in outputs) == 2
