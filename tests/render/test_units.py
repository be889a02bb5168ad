"""Units: Cycles renders of a point light and a small disk area light over a diffuse plane
match the formulas of DESIGN (Coordinates and units) within 2%."""

import math

import bpy
import numpy as np
from blender_util import add_lamp, empty_file

from addon.capture import passes as capture
from addon.compat import new_material, new_world

ALBEDO = 0.5


def plane_scene():
    empty_file()
    scene = bpy.context.scene
    mesh = bpy.data.meshes.new("plane")
    mesh.from_pydata([(-3, -3, 0), (3, -3, 0), (3, 3, 0), (-3, 3, 0)], [], [(0, 1, 2, 3)])
    mat = new_material("diffuse")
    nodes = mat.node_tree.nodes
    nodes.remove(nodes["Principled BSDF"])
    bsdf = nodes.new("ShaderNodeBsdfDiffuse")
    bsdf.inputs["Color"].default_value = (ALBEDO, ALBEDO, ALBEDO, 1)
    mat.node_tree.links.new(bsdf.outputs[0], nodes["Material Output"].inputs["Surface"])
    mesh.materials.append(mat)
    scene.collection.objects.link(bpy.data.objects.new("plane", mesh))
    cam_data = bpy.data.cameras.new("cam")
    cam_data.type = "ORTHO"
    cam_data.ortho_scale = 4.0
    cam = bpy.data.objects.new("cam", cam_data)
    cam.location = (0, 0, 5)
    scene.collection.objects.link(cam)
    scene.camera = cam
    scene.world = new_world("black")
    scene.world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
    return scene


POINTS = [(24, 24), (10, 30), (36, 12), (30, 40), (5, 5), (40, 22)]


def check(cap, expected_fn):
    ratios = []
    for row, col in POINTS:
        sl = np.s_[row - 1 : row + 2, col - 1 : col + 2]
        measured = cap.combined[sl].mean(axis=(0, 1))
        expected = expected_fn(cap.position[sl].reshape(-1, 3)).mean()
        ratios.append(measured / expected)
    ratios = np.array(ratios)
    print("Cycles / formula at the test points:", np.round(ratios, 4).tolist())
    assert np.abs(ratios - 1).max() < 0.02, ratios


def test_point_light_radiance():
    scene = plane_scene()
    y = np.array([0.3, -0.2, 1.0])
    add_lamp(scene, "POINT", tuple(y), 100.0, shadow_soft_size=0.0)
    cap = capture.capture(scene, resolution=(48, 48), samples=16)

    def expected(x):
        d = y - x
        r2 = (d**2).sum(-1)
        cos = d[:, 2] / np.sqrt(r2)
        return ALBEDO / math.pi * 100.0 / (4 * math.pi * r2) * cos

    check(cap, expected)


def test_disk_area_light_radiance():
    scene = plane_scene()
    y = np.array([0.0, 0.2, 1.5])
    add_lamp(scene, "AREA", tuple(y), 100.0, shape="DISK", size=0.05)
    cap = capture.capture(scene, resolution=(48, 48), samples=64)

    def expected(x):
        d = y - x
        r2 = (d**2).sum(-1)
        cos = d[:, 2] / np.sqrt(r2)  # cos at the receiver = cos at the emitter (facing down)
        return ALBEDO / math.pi * (100.0 / math.pi) * cos * cos / r2

    check(cap, expected)
