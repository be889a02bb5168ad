"""Scene export: triangles, materials, lights and camera of the evaluated depsgraph."""

import math

import bpy
import numpy as np
import pytest
from blender_util import CORNELL_OBJ, add_glowing_panel, cornell, empty_file

from addon.native import vplace
from addon.scene import export
from addon.scene.convert import build_scene
from addon.scenes.registry import parse_mtl, parse_obj


def test_cornell_export_matches_the_obj():
    scene = cornell()
    ex = export.export_scene(scene)
    groups = [g for g in parse_obj(CORNELL_OBJ) if g[0] != "light"]
    n_tris = sum(len(f) - 2 for g in groups for f in g[3])
    assert ex.triangles.shape == (n_tris, 3) and ex.material_ids.shape == (n_tris,)
    assert ex.vertices.dtype == np.float32 and ex.triangles.dtype == np.uint32
    mtl = parse_mtl(CORNELL_OBJ.with_suffix(".mtl"))
    albedo = {m.name: m.albedo for m in ex.materials}
    for name in ("leftWall", "rightWall", "floor"):
        np.testing.assert_allclose(albedo[name], mtl[name]["Kd"], rtol=1e-6)
    (light,) = ex.lights
    assert light.type == "AREA" and not light.area_disk
    np.testing.assert_allclose(light.direction, (0, 0, -1), atol=1e-6)
    area = light.size_x * light.size_y
    np.testing.assert_allclose(area, 0.47 * 0.38, rtol=1e-3)
    np.testing.assert_allclose(light.power, np.pi * area * np.array(mtl["light"]["Ke"]), rtol=1e-3)
    assert ex.camera is not None and ex.camera.lens == 35.0
    # The box spans about 2 m; the native scene builds with the same numbers.
    native = build_scene(ex)
    assert native.triangle_count == n_tris and native.light_count == 1
    assert 3.0 < native.diagonal < 3.6


def test_hidden_objects_and_fingerprint():
    scene = cornell()
    a = export.export_scene(scene)
    bpy.data.objects["tallBox"].hide_render = True
    b = export.export_scene(scene)
    assert b.triangles.shape[0] < a.triangles.shape[0]
    assert a.fingerprint() != b.fingerprint()
    bpy.data.objects["tallBox"].hide_render = False
    assert export.export_scene(scene).fingerprint() == a.fingerprint()
    bpy.data.lights["light"].energy *= 2
    assert export.export_scene(scene).fingerprint() != a.fingerprint()


def test_light_and_shadow_linking_are_named():
    # Cycles' captures follow an object's Light Linking collections; vplace's light paths reach
    # every object, so the export says so, once per object and kind.
    scene = cornell()
    assert not any("Linking" in w for w in export.export_scene(scene).warnings)
    lamp = bpy.data.objects["light"]
    receivers = bpy.data.collections.new("lit by the lamp")
    receivers.objects.link(bpy.data.objects["tallBox"])
    lamp.light_linking.receiver_collection = receivers
    lamp.light_linking.blocker_collection = receivers
    try:
        warned = [w for w in export.export_scene(scene).warnings if "Linking" in w]
        assert len(warned) == 2 and all("'light'" in w and "lit by the lamp" in w for w in warned)
        assert "(Light Linking)" in warned[0] and "(Shadow Linking)" in warned[1]
    finally:
        lamp.light_linking.receiver_collection = None
        lamp.light_linking.blocker_collection = None
        bpy.data.collections.remove(receivers)


def test_light_paths_stop_where_cycles_does():
    # Cycles follows Light Paths > Max Bounces (Diffuse, Glossy, each at most Total); light that
    # needs more reflections (a room lit through a doorway) is not in its renders, so the light
    # paths of the native scene stay within them too.
    scene = cornell()
    c = scene.cycles
    saved = c.diffuse_bounces, c.glossy_bounces, c.max_bounces
    try:
        c.diffuse_bounces, c.glossy_bounces, c.max_bounces = 4, 4, 12  # Blender's defaults
        four = export.export_scene(scene)
        assert four.light_bounces == (4, 4, 12)
        assert build_scene(four).light_bounces == (4, 4, 12)
        c.diffuse_bounces, c.glossy_bounces = 2, 0
        two = export.export_scene(scene)
        assert build_scene(two).light_bounces == (2, 0, 12)
        assert two.fingerprint() != four.fingerprint()
        c.diffuse_bounces, c.glossy_bounces, c.max_bounces = 8, 8, 1
        assert build_scene(export.export_scene(scene)).light_bounces == (1, 1, 1)
        c.diffuse_bounces, c.max_bounces = 0, 12
        none = export.export_scene(scene)
        assert any("no diffuse bounce" in w for w in none.warnings)
        assert build_scene(none).light_bounces == (1, 8, 12)  # vplace adds the first bounce
        c.diffuse_bounces, c.glossy_bounces, c.max_bounces = 1024, 1024, 1024
        most = vplace.MAX_BOUNCES
        assert build_scene(export.export_scene(scene)).light_bounces == (most, most, most)
    finally:
        c.diffuse_bounces, c.glossy_bounces, c.max_bounces = saved


def test_light_power_includes_exposure_and_normalize():
    empty_file()
    scene = bpy.context.scene
    light = bpy.data.lights.new("a", "AREA")
    light.energy, light.size = 10.0, 0.5
    want = 10.0  # Blender 4.2: no exposure, the power always normalized
    if hasattr(light, "exposure"):  # Blender 4.5 on
        light.exposure, light.normalize = 1.0, False
        want = 10 * 2 * 0.25
    obj = bpy.data.objects.new("a", light)
    scene.collection.objects.link(obj)
    mesh = bpy.data.meshes.new("m")
    mesh.from_pydata([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [], [(0, 1, 2)])
    scene.collection.objects.link(bpy.data.objects.new("m", mesh))
    (info,) = export.export_scene(scene).lights
    np.testing.assert_allclose(info.power, [want] * 3, rtol=1e-6)


def test_portals_negative_lamps_and_shadow_catchers():
    """A Cycles light portal emits nothing in Cycles: left out, said so. A lamp of negative
    power is a one-line error naming it. A shadow catcher is said to be lit as a surface."""
    scene = cornell()
    portal = bpy.data.lights.new("portal", "AREA")
    portal.energy = 1000.0
    portal.cycles.is_portal = True
    scene.collection.objects.link(bpy.data.objects.new("portal", portal))
    box = bpy.data.objects["tallBox"]
    box.is_shadow_catcher = True
    out = export.export_scene(scene)
    assert [light.name for light in out.lights] == ["light"]
    assert any("'portal' is a Cycles light portal" in w for w in out.warnings)
    assert any("'tallBox' is a shadow catcher" in w for w in out.warnings)
    bpy.data.objects["light"].data.energy = -5.0
    with pytest.raises(export.ExportError, match="lamp 'light' has a negative power"):
        export.export_scene(scene)


def test_bad_scenes_give_clear_errors():
    empty_file()
    with pytest.raises(export.ExportError, match="no visible mesh geometry"):
        export.export_scene(bpy.context.scene)
    mesh = bpy.data.meshes.new("broken")
    mesh.from_pydata([(0, 0, 0), (1, 0, 0), (0, math.nan, 0)], [], [(0, 1, 2)])
    bpy.context.scene.collection.objects.link(bpy.data.objects.new("broken", mesh))
    with pytest.raises(export.ExportError, match="'broken' has vertices with NaN"):
        export.export_scene(bpy.context.scene)


def test_emissive_materials_and_what_emits():
    from addon.errors import ExportError
    from addon.scene.convert import check_lights

    scene = cornell()
    bpy.data.objects["light"].hide_render = True
    ex = export.export_scene(scene)
    assert ex.lights == [] and ex.emitters() == []
    with pytest.raises(ExportError, match="no lights that render"):
        check_lights(ex)
    # A Principled BSDF's emission colour x strength, for both an Emission shader and it.
    mat = bpy.data.materials["floor"]
    p = mat.node_tree.nodes["Principled BSDF"]
    p.inputs["Emission Color"].default_value = (1.0, 0.5, 0.25, 1.0)
    p.inputs["Emission Strength"].default_value = 4.0
    ex = export.export_scene(scene)
    (floor,) = [m for m in ex.materials if m.name == "floor"]
    np.testing.assert_allclose(floor.emission, (4.0, 2.0, 1.0))
    assert ex.emission.shape == (len(ex.materials), 3) and ex.emitters() == ["material 'floor'"]
    check_lights(ex)
    native = build_scene(ex)
    assert native.light_count == 0 and native.emissive_triangle_count > 0


def test_lengths_in_metres_are_turned_into_scene_units():
    # Blender renders in its units whatever the Unit Scale; vplace reads the command line's
    # metres into them and writes metres back.
    from addon.capture.views import ViewSet
    from addon.job import Job

    scene = cornell()
    assert export.unit_scale(scene) == 1.0
    scene.unit_settings.scale_length = 0.01  # a scene modelled in centimetres
    try:
        assert export.unit_scale(scene) == pytest.approx(0.01)
        assert export.export_scene(scene).unit_scale == pytest.approx(0.01)
        job = Job(radius=0.05, views=ViewSet(mode="orbit", orbit_radius=2.0, region_radius=1.5))
        cm = job.in_scene_units(export.unit_scale(scene))
        assert cm.radius == pytest.approx(5.0)
        assert (cm.views.orbit_radius, cm.views.region_radius) == pytest.approx((200.0, 150.0))
        assert Job().in_scene_units(0.01).radius is None
        assert job.in_scene_units(1.0) is job
        scene.unit_settings.system = "NONE"  # no units: a scene unit is a metre
        assert export.unit_scale(scene) == 1.0
    finally:
        scene.unit_settings.system = "METRIC"
        scene.unit_settings.scale_length = 1.0


def _rendered_triangles(scene, names):
    """The triangles Cycles renders for the objects ``names``: those of the meshes the render
    depsgraph hands on (an object's own mesh, or the mesh a text, curve, surface or metaball
    becomes at its render resolution)."""

    def count(dg):
        total = 0
        for inst in dg.object_instances:
            data = inst.object.data
            if inst.object.original.name in names and isinstance(data, bpy.types.Mesh):
                data.calc_loop_triangles()
                total += len(data.loop_triangles)
        return total

    return export.with_render_depsgraph(scene, scene.view_layers[0], count)


def test_texts_curves_surfaces_and_metaballs_are_exported_once():
    """The depsgraph hands on a text (a curve, a surface, a metaball) as itself and as the mesh
    its evaluation makes; Cycles renders the mesh alone. Both were exported, every face twice
    (my studio's text and metaball: 7,200 triangles where Cycles renders 4,032)."""
    empty_file()
    scene = bpy.context.scene
    bpy.ops.object.text_add(location=(0, 0, 0))
    bpy.context.object.data.extrude = 0.05
    bpy.ops.object.metaball_add(location=(3, 0, 0))
    bpy.ops.curve.primitive_bezier_curve_add(location=(6, 0, 0))
    bpy.context.object.data.bevel_depth = 0.1
    curve = bpy.context.object.name
    bpy.ops.surface.primitive_nurbs_surface_sphere_add(location=(0, 4, 0))
    bpy.ops.curve.primitive_bezier_curve_add(location=(6, 4, 0))  # no bevel: nothing renders
    bare = bpy.context.object.name
    bpy.ops.object.light_add(type="POINT", location=(0, 0, 3))
    names = ["Text", "Mball", curve, "SurfSphere"]
    ex = export.export_scene(scene)
    assert sorted(ex.objects) == sorted(names) and bare not in ex.objects
    assert len(ex.triangles) == _rendered_triangles(scene, names) > 0
    assert not [w for w in ex.warnings if "shown twice" in w]


def test_a_surface_shown_twice_is_named():
    """Cycles renders faces that lie one over the other, facing the same way, black (a ray
    leaving one meets the other at once) where EEVEE and vplace light them: a cube copied in
    place, a cube arrayed onto itself. (A cube mirrored about its own centre is a surface
    shown twice too, but its copy's quads split along the other diagonal, and triangles that
    do not match corner for corner go unnamed.) Faces that meet back to back (two cubes side
    by side, a cube on a floor) are the usual way of things and go unnamed."""
    empty_file()
    scene = bpy.context.scene
    bpy.ops.object.light_add(type="POINT", location=(0, 0, 5))
    bpy.ops.mesh.primitive_plane_add(size=10)
    bpy.ops.mesh.primitive_cube_add(location=(0, 0, 1))  # on the floor
    bpy.ops.mesh.primitive_cube_add(location=(2, 0, 1))  # side by side with the next
    bpy.ops.mesh.primitive_cube_add(location=(4, 0, 1))
    assert not [w for w in export.export_scene(scene).warnings if "shown twice" in w]
    bpy.ops.mesh.primitive_cube_add(location=(8, 0, 1))
    bpy.context.object.name = "original"
    bpy.ops.object.duplicate()  # copied in place
    bpy.context.object.name = "copy"
    bpy.ops.mesh.primitive_cube_add(location=(0, 4, 1))
    bpy.context.object.name = "arrayed"
    array = bpy.context.object.modifiers.new("array", "ARRAY")
    array.relative_offset_displace = (0, 0, 0)  # the second copy on the first
    (warning,) = [w for w in export.export_scene(scene).warnings if "shown twice" in w]
    assert "12 face(s) of 'copy' on 'original'" in warning
    assert "12 face(s) of 'arrayed' on its own" in warning


def test_shown_twice_counts_the_same_corners_in_the_same_turn():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32)
    one = np.array([[0, 1, 2]])
    turned = np.array([[4, 5, 3]])  # the same face from another corner
    flipped = np.array([[3, 5, 4]])  # back to back
    owners = np.array([0, 1])
    assert export.shown_twice(v, np.vstack([one, turned]), owners, ["a", "b"]) == [("a", "b", 1)]
    assert export.shown_twice(v, np.vstack([one, flipped]), owners, ["a", "b"]) == []
    moved = v + np.array([[0, 0, 0]] * 3 + [[0, 0, 1e-3]] * 3, np.float32)
    assert export.shown_twice(moved, np.vstack([one, turned]), owners, ["a", "b"]) == []


def test_a_mirrored_object_faces_out_as_blender_shows_it():
    """A negative scale turns an object's corners round; Blender still shows its faces facing
    out, and Cycles renders them so. The export turns them back: a closed emitter's inside
    (``EmissionRay::trapped``) and the same-facing test of a surface shown twice read it."""
    scene = cornell()
    panel = add_glowing_panel(scene, 5.0)  # facing down
    for sx in (1.0, -1.0):
        panel.scale.x = sx
        bpy.context.view_layer.update()
        ex = export.export_scene(scene)
        glow = [i for i, m in enumerate(ex.materials) if m.name == "glow"]
        v = ex.vertices.astype(np.float64)[ex.triangles[np.isin(ex.material_ids, glow)]]
        n = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
        assert len(n) == 2 and (n[:, 2] < 0).all(), sx
