"""Lights that stand in for emissive meshes in EEVEE (``emitter_lights``): a rectangle per quad,
a disk per other triangle, of power ``pi A L`` per open side, at most ``MAX_EMITTER_LIGHTS``,
written into the VPL collection facing the way the surface emits."""

import math

import bpy
import numpy as np
import pytest
from blender_util import empty_file, no_vpls
from mathutils import Vector

from addon.compat import new_material, new_world
from addon.scene import export
from addon.scene.convert import build_scene
from addon.writeback import apply
from addon.writeback import stand_ins as emitter_lights

RADIANCE = (2.0, 1.0, 0.5)


@pytest.fixture
def scene():
    empty_file()
    return bpy.context.scene


def emissive(name, strength=1.0):
    mat = new_material(name)
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    nodes.remove(nodes["Principled BSDF"])
    em = nodes.new("ShaderNodeEmission")
    em.inputs["Color"].default_value = (*RADIANCE, 1.0)
    em.inputs["Strength"].default_value = strength
    links.new(em.outputs[0], nodes["Material Output"].inputs["Surface"])
    return mat


def mesh(scene, name, verts, faces, mat):
    me = bpy.data.meshes.new(name)
    me.from_pydata(verts, [], faces)
    me.materials.append(mat)
    obj = bpy.data.objects.new(name, me)
    scene.collection.objects.link(obj)
    bpy.context.view_layer.update()
    return obj


def lights_of(scene):
    exported = export.export_scene(scene)
    return emitter_lights.emitter_lights(exported, build_scene(exported)), exported


def test_a_quad_is_one_rectangle_per_side_of_power_pi_a_l(scene):
    # 2 x 0.5 m, tilted about X by 30 degrees, alone in space: both sides open.
    c, s = math.cos(math.radians(30)), math.sin(math.radians(30))
    verts = [(x, y * c, y * s) for x, y in ((0, 0), (2, 0), (2, 0.5), (0, 0.5))]
    mesh(scene, "panel", verts, [(0, 1, 2, 3)], emissive("panel"))
    lights, _ = lights_of(scene)
    assert [e.shape for e in lights] == ["RECTANGLE", "RECTANGLE"]
    normal = np.array([0.0, -s, c])
    for e, sign in zip(lights, (1.0, -1.0), strict=True):
        assert sorted([e.size, e.size_y]) == pytest.approx([0.5, 2.0])
        np.testing.assert_allclose(e.normal, sign * normal, atol=1e-6)
        np.testing.assert_allclose(e.power, np.pi * 1.0 * np.array(RADIANCE), rtol=1e-5)
        centre = np.array([1.0, 0.25 * c, 0.25 * s])
        assert np.linalg.norm(np.array(e.position) - centre) < 0.01


def test_a_triangle_is_a_disk_of_its_area_and_a_closed_back_is_left_out(scene):
    mesh(scene, "tri", [(0, 0, 1), (1, 0, 1), (0, 1, 1)], [(0, 1, 2)], emissive("tri"))
    # A floor 1 cm under the triangle: its downward side cannot send light out.
    floor = new_material("floor")
    mesh(
        scene,
        "floor",
        [(-5, -5, 0.99), (5, -5, 0.99), (5, 5, 0.99), (-5, 5, 0.99)],
        [(0, 1, 2, 3)],
        floor,
    )
    lights, _ = lights_of(scene)
    assert len(lights) == 1
    (e,) = lights
    assert e.shape == "DISK"
    assert math.pi * (e.size / 2) ** 2 == pytest.approx(0.5)
    np.testing.assert_allclose(e.normal, (0, 0, 1), atol=1e-6)
    np.testing.assert_allclose(e.power, np.pi * 0.5 * np.array(RADIANCE), rtol=1e-5)


def test_many_emitters_are_drawn_by_power_and_keep_the_total(scene):
    faces, verts = [], []
    for k in range(100):  # 100 small triangles, far apart, all open on both sides
        x = 3.0 * k
        verts += [(x, 0, 0), (x + 0.1, 0, 0), (x, 0.1, 0)]
        faces.append((3 * k, 3 * k + 1, 3 * k + 2))
    mesh(scene, "sparks", verts, faces, emissive("sparks"))
    lights, _ = lights_of(scene)
    assert len(lights) <= emitter_lights.MAX_EMITTER_LIGHTS
    total = sum(np.array(e.power) for e in lights)
    np.testing.assert_allclose(total, 200 * np.pi * 0.005 * np.array(RADIANCE), rtol=1e-4)


def test_no_emission_no_lights(scene):
    mesh(scene, "grey", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [(0, 1, 2)], new_material("g"))
    assert lights_of(scene)[0] == []


def test_written_emitter_lights_face_the_way_the_surface_emits(scene):
    verts = [(0, 0, 2), (1, 0, 2), (1, 0.5, 2), (0, 0.5, 2)]
    mesh(scene, "panel", verts, [(0, 1, 2, 3)], emissive("panel", strength=3.0))
    lights, _ = lights_of(scene)
    none = no_vpls()
    coll = apply.write_vpls(scene, none, scene_diagonal=3.0, emitters=lights)
    bpy.context.view_layer.update()
    objs = sorted(coll.objects, key=lambda o: o.name)
    assert len(objs) == 2 and all(
        o.data.type == "AREA" and o.data.shape == "RECTANGLE" for o in objs
    )
    for obj, e in zip(objs, lights, strict=True):
        emits = obj.matrix_world.to_3x3() @ Vector((0, 0, -1))
        np.testing.assert_allclose(tuple(emits), e.normal, atol=1e-6)
        side = obj.matrix_world.to_3x3() @ Vector((1, 0, 0))
        assert abs(side.dot(Vector(e.tangent))) == pytest.approx(1.0, abs=1e-6)
        assert (obj.data.size, obj.data.size_y) == pytest.approx((e.size, e.size_y))
        assert obj.data.energy * max(obj.data.color) == pytest.approx(max(e.power), rel=1e-5)
        assert obj.get(export.VPL_MARKER)
        # The stand-ins' soft shadows are jittered (the VPLs' are not: apply's module docs).
        assert obj.data.use_shadow and obj.data.use_shadow_jitter
    # vplace's own lights are never exported as part of the scene.
    again = export.export_scene(scene)
    assert not again.lights
    assert apply.clear_vpls() == 2


def world_image(h=64, w=128, sky=0.2, sun=None):
    """A WorldInfo with an equirectangular image: a uniform sky and one sun pixel ``sun``
    (row, column, radiance)."""
    from addon.scene.world import WorldInfo

    img = np.full((h, w, 3), sky, np.float32)
    if sun is not None:
        i, j, value = sun
        img[i, j] = value
    return WorldInfo("w", (1.0, 1.0, 1.0), image=img, source="image")


def test_a_world_sun_is_its_compact_bright_lobe_with_its_irradiance():
    h, w = 64, 128
    i, j = 20, 40
    sun = emitter_lights.world_sun(world_image(h, w, sun=(i, j, 5000.0)))
    assert sun is not None
    theta = (i + 0.5) / h * np.pi
    phi = (0.5 - (j + 0.5) / w) * 2 * np.pi
    expected = (np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta))
    np.testing.assert_allclose(sun.direction, expected, atol=1e-9)
    d_omega = (2 * np.pi / w) * (np.pi / h) * np.sin(theta)
    np.testing.assert_allclose(sun.irradiance, [5000.0 * d_omega] * 3, rtol=1e-9)
    assert 0.0 < sun.angle < np.radians(5.0)


def test_a_sky_textures_sun_keeps_its_own_disc_where_the_bake_spread_it():
    """A baked Sky Texture's disc (0.545 degrees) spreads over the map's pixels it touches: the
    stand-in takes the disc's direction and diameter (``WorldInfo.suns``), not the pixels'
    (their spread made the sky room's sun 1.92 degrees wide, and EEVEE blurred its patches by as
    much); a disc that is not among the sun's pixels is someone else's and is left out."""
    h, w = 64, 128
    info = world_image(h, w, sun=(20, 40, 5000.0))
    info.image[20:22, 40:42] = 5000.0
    spread = emitter_lights.world_sun(info)
    assert spread is not None and spread.angle > np.radians(5.0)
    theta = (21.0 / h) * np.pi
    phi = (0.5 - 41.0 / w) * 2 * np.pi
    disc = (np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta))
    far = (0.0, 0.0, 1.0)
    size = np.radians(0.545)
    info.suns = ((far, 0.01), (tuple(float(c) for c in disc), size))
    sun = emitter_lights.world_sun(info)
    np.testing.assert_allclose(sun.direction, disc, atol=1e-9)
    assert sun.angle == size
    np.testing.assert_allclose(sun.irradiance, spread.irradiance)
    info.suns = ((far, 0.01),)
    assert emitter_lights.world_sun(info).angle == spread.angle


def test_a_sky_without_an_outstanding_sun_has_none():
    assert emitter_lights.world_sun(world_image()) is None
    assert emitter_lights.world_sun(world_image(sun=(20, 40, 2.0))) is None  # 10x, not 20x
    from addon.scene.world import WorldInfo

    assert emitter_lights.world_sun(WorldInfo("c", (1.0, 1.0, 1.0))) is None


def test_the_written_sun_shines_from_the_suns_direction_and_eevee_must_not_extract_it(scene):
    from addon.writeback import eevee_setup

    sun = emitter_lights.world_sun(world_image(sun=(20, 40, 5000.0)))
    world = new_world("sky")
    scene.world = world
    world.sun_threshold = 10.0
    floor = new_material("floor")
    mesh(scene, "floor", [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], [(0, 1, 2, 3)], floor)
    none = no_vpls()
    coll = apply.write_vpls(scene, none, scene_diagonal=3.0, sun=sun)
    bpy.context.view_layer.update()
    (obj,) = coll.objects
    # Shadowed, not jittered (its half-degree penumbra gains nothing: apply's docs).
    assert obj.data.type == "SUN" and obj.data.use_shadow and not obj.data.use_shadow_jitter
    assert obj.data.energy * max(obj.data.color) == pytest.approx(max(sun.irradiance), rel=1e-5)
    travels = obj.matrix_world.to_3x3() @ Vector((0, 0, -1))
    np.testing.assert_allclose(tuple(travels), -np.array(sun.direction), atol=1e-6)
    assert apply.world_sun_light(scene) == obj
    assert any(p.setting == "world.sun_threshold" for p in eevee_setup.problems(scene))
    eevee_setup.set_up(scene, bake_volume=False)
    assert world.sun_threshold == 0.0


def test_the_sun_counts_only_where_it_reaches_what_a_view_sees(scene):
    mesh(
        scene,
        "floor",
        [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)],
        [(0, 1, 2, 3)],
        new_material("f"),
    )
    exported = export.export_scene(scene)
    sun = emitter_lights.SunLight((0.0, 0.0, 1.0), (5.0, 5.0, 5.0), 0.01)
    ys, xs = np.mgrid[0:8, 0:8]
    position = np.stack([(xs - 3.5) / 5, (ys - 3.5) / 5, 0 * xs], axis=-1).astype(np.float32)
    normal = np.zeros_like(position)
    normal[..., 2] = 1.0
    covered = np.ones((8, 8), bool)
    lit = emitter_lights.sun_lit_fraction(build_scene(exported), position, normal, covered, sun)
    assert lit == 1.0
    # A roof over the floor: the sun reaches nothing the view sees.
    roof = [
        (-2.3, -1.9, 1),
        (2.1, -1.9, 1),
        (2.1, 2.2, 1),
        (-2.3, 2.2, 1),
    ]  # not on a pixel diagonal
    mesh(scene, "roof", roof, [(0, 1, 2, 3)], new_material("r"))
    exported = export.export_scene(scene)
    lit = emitter_lights.sun_lit_fraction(build_scene(exported), position, normal, covered, sun)
    assert lit == 0.0
    below = emitter_lights.SunLight((0.0, 0.0, -1.0), (5.0, 5.0, 5.0), 0.01)
    assert (
        emitter_lights.sun_lit_fraction(build_scene(exported), position, normal, covered, below)
        == 0.0
    )
