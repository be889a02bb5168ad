"""A closed room under Blender's default grey world: Cycles lets no world light in, EEVEE adds it
unoccluded unless it is set up for vplace. With "Set up EEVEE for vplace" (ray tracing with
ambient-occlusion-only fast GI, a probe volume that occludes the world without capturing
indirect light) EEVEE with the written VPLs must come within 5 % of the truth's brightness."""

import math

import bpy
import pytest
from blender_util import empty_file

from addon import apply, capture, eevee, eevee_setup, pipeline

SIZE = (48, 36)
#: The factory startup file's world: a Background of this grey at strength 1.
DEFAULT_WORLD_GREY = 0.0509


def _diffuse(name, color):
    mat = bpy.data.materials.new(name)
    tree = mat.node_tree
    tree.nodes.clear()
    bsdf = tree.nodes.new("ShaderNodeBsdfDiffuse")
    bsdf.inputs["Color"].default_value = (*color, 1.0)
    out = tree.nodes.new("ShaderNodeOutputMaterial")
    tree.links.new(bsdf.outputs["BSDF"], out.inputs["Surface"])
    return mat


def _box(name, size, location, mat, inward=False):
    sx, sy, sz = (s / 2.0 for s in size)
    verts = [(x * sx, y * sy, z * sz) for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]
    # Counter-clockwise seen from outside: normals point out.
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    if inward:
        faces = [f[::-1] for f in faces]
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(verts, [], faces)
    mesh.materials.append(mat)
    obj = bpy.data.objects.new(name, mesh)
    obj.location = location
    bpy.context.scene.collection.objects.link(obj)
    return obj


def world_room() -> bpy.types.Scene:
    """A closed 4 x 3 x 2.5 m room (white walls facing in), a red block, a 100 W point lamp,
    a camera inside, and the default grey world outside."""
    empty_file()
    scene = bpy.context.scene
    world = bpy.data.worlds.new("World")
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (
        *(DEFAULT_WORLD_GREY,) * 3,
        1.0,
    )
    scene.world = world
    _box("room", (4.0, 3.0, 2.5), (0.0, 0.0, 1.25), _diffuse("white", (0.8, 0.8, 0.8)), True)
    _box("block", (0.8, 0.8, 0.8), (0.8, 0.5, 0.4), _diffuse("red", (0.8, 0.1, 0.1)))
    lamp = bpy.data.lights.new("lamp", "POINT")
    lamp.energy = 100.0
    lamp.shadow_soft_size = 0.0
    lamp_obj = bpy.data.objects.new("lamp", lamp)
    lamp_obj.location = (-0.8, -0.4, 2.2)
    scene.collection.objects.link(lamp_obj)
    cam = bpy.data.objects.new("camera", bpy.data.cameras.new("camera"))
    cam.location = (-1.8, -1.3, 1.6)
    cam.rotation_euler = (math.radians(75), 0.0, math.radians(-55))
    scene.collection.objects.link(cam)
    scene.camera = cam
    scene.render.resolution_x, scene.render.resolution_y = SIZE
    bpy.context.view_layer.update()
    return scene


@pytest.mark.slow
def test_eevee_set_up_for_vplace_keeps_the_default_world_out_of_a_closed_room(tmp_path):
    scene = world_room()
    cache = tmp_path / "cache"
    report = pipeline.run_main_job(
        scene,
        tmp_path,
        n_vpls=256,
        resolution=SIZE,
        samples=64,
        truth_samples=256,
        eevee=False,
        baselines=(),
        log=print,
    )
    assert abs(report["metrics"]["brightness"] - 1.0) < 0.05  # the evaluator's own image
    truth = capture.capture(
        scene, resolution=SIZE, samples=256, seed=pipeline.REFERENCE_SEED, cache_dir=cache
    )
    # Without the set-up the world leaks in, and the panel says so.
    named = [p.setting for p in eevee_setup.problems(scene)]
    assert any("world" in s for s in named), named
    changed = eevee_setup.set_up(scene)
    assert eevee_setup.vplace_volume(scene) is not None, changed
    assert not [p for p in eevee_setup.problems(scene) if "world" in p.setting]
    shown = eevee.render(scene, resolution=SIZE, samples=4, setup=eevee.SETUPS["vpl+rt"])
    scored = pipeline.score(shown.image, truth.gi)
    print(f"evaluator {report['metrics']}\nEEVEE set up for vplace {scored}")
    assert abs(scored["brightness"] - 1.0) < 0.05
    assert scored["ssim"] > report["metrics"]["ssim_direct_only"]
    assert apply.find_collection() is not None
