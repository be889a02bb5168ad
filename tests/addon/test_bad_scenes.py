"""Scenes that must give a clear message (or just work), never a traceback or a crash."""

import math

import bpy
import numpy as np
import pytest
from blender_util import add_glowing_panel, add_mesh, addon_cornell, data_snapshot, diff

from addon.compat import new_world
from addon.scene import bench_export
from addon.writeback import apply


@pytest.fixture
def scene():
    with addon_cornell() as sc:
        yield sc


def fails_cleanly(message):
    before = data_snapshot()
    with pytest.raises(RuntimeError, match=message):
        bpy.ops.vplace.apply()
    assert apply.find_collection() is None
    assert diff(before, data_snapshot()) == []


def test_no_camera(scene):
    scene.camera = None
    assert not bpy.ops.vplace.apply.poll()
    with pytest.raises(RuntimeError, match="poll"):
        bpy.ops.vplace.apply()


def test_everything_black(scene):
    bpy.data.lights["light"].energy = 0.0
    fails_cleanly("every light has zero power")


def test_only_background_in_view(scene):
    scene.camera.rotation_euler = (-math.pi / 2, 0.0, 0.0)  # looking away from the box
    scene.camera.location = (0.0, -5.0, 1.0)
    bpy.context.view_layer.update()
    fails_cleanly("'Cornell camera': the camera sees no geometry")


def test_mesh_with_nan_vertices(scene):
    add_mesh(scene, "broken", [(0, 0, 0), (1, 0, 0), (0, math.nan, 0)], [(0, 1, 2)])
    fails_cleanly("'broken' has vertices with NaN")


def light_by_world_only(scene):
    bpy.data.objects["light"].hide_render = True
    world = new_world("sky")
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.5, 0.6, 0.9, 1.0)
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 2.0
    scene.world = world


def light_by_emissive_mesh_only(scene):
    bpy.data.objects["light"].hide_render = True
    add_glowing_panel(scene, 20.0)


@pytest.mark.parametrize("light_by", [light_by_world_only, light_by_emissive_mesh_only])
def test_lit_without_light_objects(scene, light_by):
    light_by(scene)
    bpy.context.view_layer.update()
    assert bpy.ops.vplace.apply() == {"FINISHED"}
    report = scene.vplace.report()
    written = report["lights_written"] + report["emitter_lights_written"]
    assert len(apply.find_collection().objects) == written > 0
    assert report["metrics"]["rmse"] > 0
    # An emissive mesh gets lights that stand in for it in EEVEE; the world gets none.
    assert (report["emitter_lights_written"] > 0) == (light_by is light_by_emissive_mesh_only)


def test_zero_area_faces_are_harmless(scene):
    add_mesh(scene, "flat", [(0, 0, 1), (0.1, 0, 1), (0.2, 0, 1)], [(0, 1, 2)])
    assert bpy.ops.vplace.apply() == {"FINISHED"}
    assert len(apply.find_collection().objects) == scene.vplace.report()["lights_written"] > 0


def test_linked_library_object(scene, tmp_path):
    # A library file holding one box, linked (read-only) into the Cornell scene.
    lib_scene = bpy.data.scenes.new("lib")
    mesh = bpy.data.meshes.new("libbox")
    mesh.from_pydata(
        [(-0.2, -0.2, 0.0), (0.2, -0.2, 0.0), (0.0, 0.2, 0.0), (0.0, 0.0, 0.4)],
        [],
        [(0, 1, 2), (0, 1, 3), (1, 2, 3), (2, 0, 3)],
    )
    lib_obj = bpy.data.objects.new("libbox", mesh)
    lib_scene.collection.objects.link(lib_obj)
    lib = tmp_path / "lib.blend"
    bpy.data.libraries.write(str(lib), {lib_obj})
    bpy.data.objects.remove(lib_obj)
    bpy.data.meshes.remove(mesh)
    bpy.data.scenes.remove(lib_scene)
    with bpy.data.libraries.load(str(lib), link=True) as (_src, dst):
        dst.objects = ["libbox"]
    linked = dst.objects[0]
    assert linked.library is not None
    scene.collection.objects.link(linked)
    bpy.context.view_layer.update()
    before = data_snapshot()
    assert bpy.ops.vplace.apply() == {"FINISHED"}
    assert diff(before, data_snapshot()) == []


@pytest.mark.slow
def test_a_million_triangles_works(scene):
    n = 709  # (n - 1)^2 * 2 = 1,002,528 triangles
    mesh, _, _ = bench_export.grid_mesh(
        "terrain", np.linspace(-0.9, 0.9, n), lambda x, _y: 0.3 + 0.02 * np.sin(9 * x)
    )
    scene.collection.objects.link(bpy.data.objects.new("terrain", mesh))
    bpy.context.view_layer.update()
    assert bpy.ops.vplace.apply() == {"FINISHED"}
    report = scene.vplace.report()
    assert report["triangles"] > 1_000_000
    assert len(apply.find_collection().objects) == scene.vplace.report()["lights_written"] > 0


def test_a_lamp_outside_the_room_is_said_to_light_nothing_the_cameras_see():
    """The lamp behind the Cornell box's back wall: every capture is black, and the job says
    so (it still runs: the lamp is the user's)."""
    from blender_util import cornell

    from addon import job as pipeline
    from addon.capture.views import ViewSet

    scene = cornell()
    bpy.data.objects["light"].location = (0.0, 5.0, 1.0)
    bpy.context.view_layer.update()
    lines = []
    job = pipeline.Job(resolution=(16, 12), samples=2, views=ViewSet(coverage=0), n_vpls=8)
    pipeline.prepare(scene, job, pipeline.StageTimer(lines.append))
    assert any("every capture is black" in line for line in lines)
    bpy.data.objects["light"].location = (0.0, 0.0, 1.9)
    bpy.context.view_layer.update()
    lines.clear()
    pipeline.prepare(scene, job, pipeline.StageTimer(lines.append))
    assert not any("black" in line for line in lines)
