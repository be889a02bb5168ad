"""Sky portals (``writeback.portals``): the openings through which the sky reaches a room, found
by rays from the cameras, and the light each lets in; as stand-in lights and in EEVEE's set-up."""

import math

import bpy
import numpy as np
import pytest
from blender_util import empty_file

from addon.compat import new_material, new_world
from addon.native import vplace
from addon.scene.world import WorldInfo
from addon.writeback import apply, eevee_setup, portals
from addon.writeback.stand_ins import EmitterLight, StandIns

#: The room's interior (4 x 3 x 2.5 m), its walls' thickness, and the window in its south wall
#: (y = -1.5): centre x, width, sill and height.
INTERIOR = ((-2.0, -1.5, 0.0), (2.0, 1.5, 2.5))
WALL = 0.2
WINDOW = (0.5, 1.0, 0.8, 1.2)
EYE = (-0.5, 0.6, 1.4)


def _box_triangles(lo, hi):
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    v = np.array([(x, y, z) for x in (x0, x1) for y in (y0, y1) for z in (z0, z1)], np.float32)
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    tris = [t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))]
    return v, np.array(tris, np.uint32)


def room_scene(
    window: bool = True,
    *,
    roof: bool = True,
    hole: tuple[float, float, float, float] = WINDOW,
    furniture: tuple[tuple[tuple[float, float, float], tuple[float, float, float]], ...] = (),
) -> vplace.Scene:
    """The room as boxes (floor, ceiling, four walls; the south wall around the window,
    ``hole``: centre x, width, sill and height), and ``furniture`` boxes (low, high corner)."""
    (x0, y0, z0), (x1, y1, z1) = INTERIOR
    t = WALL
    boxes = [((x0 - t, y0 - t, z0 - t), (x1 + t, y1 + t, z0))]
    if roof:
        boxes.append(((x0 - t, y0 - t, z1), (x1 + t, y1 + t, z1 + t)))
    boxes += [
        ((x0 - t, y1, z0), (x1 + t, y1 + t, z1)),
        ((x0 - t, y0, z0), (x0, y1, z1)),
        ((x1, y0, z0), (x1 + t, y1, z1)),
    ]
    south = ((x0 - t, y0 - t, z0), (x1 + t, y0, z1))
    if window:
        cx, w, sill, h = hole
        (a0, b0, c0), (a1, b1, c1) = south
        boxes += [
            ((a0, b0, c0), (cx - w / 2, b1, c1)),
            ((cx + w / 2, b0, c0), (a1, b1, c1)),
            ((cx - w / 2, b0, c0), (cx + w / 2, b1, sill)),
            ((cx - w / 2, b0, sill + h), (cx + w / 2, b1, c1)),
        ]
    else:
        boxes.append(south)
    boxes += list(furniture)
    verts, tris = [], []
    for lo, hi in boxes:
        v, tr = _box_triangles(lo, hi)
        tris.append(tr + sum(len(x) for x in verts))
        verts.append(v)
    v, tr = np.concatenate(verts), np.concatenate(tris)
    lamp = vplace.Light.point((0.0, 0.0, 2.0), (10.0, 10.0, 10.0))
    return vplace.Scene(
        v, tr, np.zeros(len(tr), np.uint32), np.array([[0.6, 0.6, 0.6]], np.float32), [lamp]
    )


def test_the_window_is_found_where_it_is():
    found, share = portals.openings(room_scene(), [EYE])
    assert len(found) == 1, found
    assert 0.0 < share < portals.MAX_OPEN
    o = found[0]
    cx, w, sill, h = WINDOW
    np.testing.assert_allclose(o.outward, [0.0, -1.0, 0.0], atol=0.05)
    # In the wall (between its faces, y = -1.7 .. -1.5), centred on the window.
    assert -1.7 - 0.05 <= o.centre[1] <= -1.5 + 0.05, o.centre
    np.testing.assert_allclose(o.centre[[0, 2]], [cx, sill + h / 2], atol=0.12)
    # Level and upright: the first side along x, as wide and as tall as the window within 20 %.
    assert abs(o.tangent[0]) > 0.99 and abs(o.bitangent[2]) > 0.99
    assert o.size == pytest.approx(w, rel=0.2) and o.size_y == pytest.approx(h, rel=0.2)
    # Its reveals reach through the wall: the outer plane is the wall's outer face.
    assert o.centre[1] - o.reveal == pytest.approx(-1.5 - WALL, abs=0.02)
    np.testing.assert_allclose(o.outer_centre, o.centre + o.reveal * o.outward)


@pytest.mark.parametrize("eye", [(-1.9, 1.4, 1.6), (-1.9, 1.4, 2.3), (-1.9, 1.4, 1.2)])
def test_a_window_seen_from_a_far_corner_lies_in_its_wall(eye):
    """From a far corner the rim is mostly the wall's face but also a reveal and the sill: the
    plane through every rim hit tilted 5-8 degrees here (30 in a room of 5 x 4 m, facing the
    portal's light up into the room); the wall's face is the plane."""
    (o,), _ = portals.openings(room_scene(hole=(1.0, 0.8, 0.5, 0.7)), [eye])
    np.testing.assert_allclose(o.outward, [0.0, -1.0, 0.0], atol=0.02)
    # On the wall's face (its extent, from one eye this oblique, is what that eye sees of it).
    assert o.centre[1] == pytest.approx(-1.5, abs=0.02)


#: A table in front of the window, its top at 1.1 m, 0.6 m deep (low, high corner).
TABLE = ((-0.2, -1.45, 1.05), (1.2, -0.85, 1.1))


@pytest.mark.parametrize(
    "eye", [(1.5, 1.0, 0.5), (-1.0, 0.0, 0.8), (0.5, 0.0, 0.8), (1.5, 0.0, 0.8)]
)
def test_a_table_before_the_window_is_not_an_opening(eye):
    """Seen past a table, most of a window's rim is the table's top, and its plane put the
    rays' crossings anywhere: 46 x 5 m and 78 x 15 m "openings" facing up at the table's height
    (the sky room's low held-out camera found a 5.6 x 3.9 m one half a metre over the floor,
    which the portal's light then came from). An opening lies within its rim, or is none."""
    found, _ = portals.openings(room_scene(furniture=(TABLE,)), [eye])
    _, w, _, h = WINDOW
    for o in found:
        np.testing.assert_allclose(o.outward, [0.0, -1.0, 0.0], atol=0.05)
        assert o.size < 1.25 * w and o.size_y < 1.25 * h, o
        assert -1.7 - 0.05 <= o.centre[1] <= -1.5 + 0.05, o


def test_more_eyes_find_the_same_window_once():
    found, _ = portals.openings(room_scene(), [EYE, (1.2, 0.9, 1.0), (-1.5, -0.8, 2.0)])
    assert len(found) == 1, found


def test_a_roof_open_to_the_sky_is_one_opening():
    """A courtyard (the room without its roof, as Sponza's atrium): the opening is the roof."""
    found, share = portals.openings(room_scene(roof=False), [EYE])
    assert share < portals.MAX_OPEN
    top = found[0]
    np.testing.assert_allclose(top.outward, [0.0, 0.0, 1.0], atol=0.05)
    assert 2.4 <= top.centre[2] <= 2.75
    # Its outer plane is where the walls end (the rim's hits lie a little below).
    assert top.outer_centre[2] == pytest.approx(2.5, abs=0.03)
    (x0, y0, _), (x1, y1, _) = INTERIOR
    sides = sorted([top.size, top.size_y])
    np.testing.assert_allclose(sides, [y1 - y0, x1 - x0], rtol=0.15)


def test_a_closed_room_and_an_open_scene_get_no_portal():
    found, share = portals.openings(room_scene(window=False), [EYE])
    assert found == [] and share == 0.0
    # Outdoors (a floor alone): most rays leave, the world lights the scene directly.
    v, t = _box_triangles((-5.0, -5.0, -0.1), (5.0, 5.0, 0.0))
    floor = vplace.Scene(
        v,
        t,
        np.zeros(len(t), np.uint32),
        np.array([[0.5, 0.5, 0.5]], np.float32),
        [vplace.Light.point((0.0, 0.0, 2.0), (1.0, 1.0, 1.0))],
    )
    found, share = portals.openings(floor, [(0.0, 0.0, 1.6)])
    assert found == [] and share > portals.MAX_OPEN


def test_the_sky_a_window_lets_in():
    """A uniform sky of radiance L: the window receives pi L less what its reveals hide, and the
    light enters facing in; a sky with a sun (one bright pixel) that is left out gives the same."""
    scene = room_scene()
    (o,), _ = portals.openings(scene, [EYE])
    radiance = 0.2
    info = WorldInfo("sky", (radiance,) * 3)
    rng = np.random.default_rng(1)
    power, heading = portals.sky_power(scene, portals.sky_radiance(info), o, rng)
    full = math.pi * radiance * o.area
    assert 0.5 * full < power[0] < full, (power, full)
    assert heading[1] > 0.9  # into the room (+y)
    # A sun low in the south (the window's side: azimuth -65 degrees, elevation 31).
    image = np.full((32, 64, 3), radiance, np.float32)
    image[10, 43] = 1e4
    sun = np.zeros((32, 64), bool)
    sun[10, 43] = True
    with_sun = WorldInfo("sky", (1.0, 1.0, 1.0), image=image, source="image")

    def measured(without):
        rng = np.random.default_rng(1)
        return portals.sky_power(scene, portals.sky_radiance(with_sun, without), o, rng)[0]

    np.testing.assert_allclose(measured(sun), power, rtol=0.01)
    assert measured(None)[0] > 2.0 * power[0]


def test_stand_ins_carry_the_portals():
    portal = EmitterLight(
        (0, 0, 1), (0, 1, 0), (1, 0, 0), "RECTANGLE", 1.0, 1.2, (1, 1, 1), "p", True
    )
    lamp = EmitterLight((0, 0, 2), (0, 0, -1), (1, 0, 0), "DISK", 0.2, 0.2, (5, 5, 5), "lamp")
    assert StandIns([lamp, portal], None).portals == [portal]


@pytest.fixture
def sky_scene():
    empty_file()
    scene = bpy.context.scene
    world = new_world("Sky")
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.3, 0.4, 0.6, 1.0)
    scene.world = world
    mesh = bpy.data.meshes.new("floor")
    mesh.from_pydata([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], [], [(0, 1, 2, 3)])
    scene.collection.objects.link(bpy.data.objects.new("floor", mesh))
    return scene


def _write_portal(scene):
    vpls = vplace.VplSet(
        np.zeros((1, 3), np.float32),
        np.array([[0, 0, 1]], np.float32),
        np.ones((1, 3), np.float32),
        radius=0.01,
    )
    portal = EmitterLight(
        (0, -1, 1),
        (0, 1, 0),
        (1, 0, 0),
        "RECTANGLE",
        1.0,
        1.2,
        (2.0, 2.5, 3.0),
        "sky portal 1",
        True,
    )
    apply.write_vpls(scene, vpls, emitters=[portal])


def test_a_written_portal_keeps_the_world_from_lighting_eevee(sky_scene):
    scene, world = sky_scene, sky_scene.world
    _write_portal(scene)
    written = eevee_setup.portal_lights(scene)
    assert len(written) == 1 and written[0].data.type == "AREA"
    assert written[0].data.energy == pytest.approx(3.0)
    assert any(p.setting == "world" for p in eevee_setup.problems(scene))
    nodes_before = len(world.node_tree.nodes)
    assert eevee_setup.camera_only_blocker(world) is None
    # For a render: the camera-only world for the block, taken out after.
    with eevee_setup.world_for_render(scene) as bake:
        assert bake == 0.0 and eevee_setup.is_camera_only(world)
        assert not any(o.type == "LIGHT_PROBE" for o in scene.objects)  # no volume
    assert not eevee_setup.is_camera_only(world) and len(world.node_tree.nodes) == nodes_before
    # "Set up EEVEE for vplace": an EEVEE-only output; Cycles' output is the world's own.
    changed = eevee_setup.set_up(scene, bake_volume=False)
    assert any("sky portals" in c for c in changed)
    outputs = [n for n in world.node_tree.nodes if n.bl_idname == "ShaderNodeOutputWorld"]
    assert sorted(n.target for n in outputs) == ["ALL", "EEVEE"]
    eevee_out = next(n for n in outputs if n.target == "EEVEE")
    mix = eevee_out.inputs["Surface"].links[0].from_node
    assert mix.bl_idname == "ShaderNodeMixShader"
    assert mix.inputs[0].links[0].from_socket.name == "Is Camera Ray"
    assert mix.inputs[2].links[0].from_node == world.node_tree.nodes["Background"]
    assert not any(p.setting == "world" for p in eevee_setup.problems(scene))
    assert eevee_setup.set_up(scene, bake_volume=False) == []  # nothing left to change
    # Without portals the world lights EEVEE again.
    apply.clear_vpls()
    _write_portal(scene)
    for obj in eevee_setup.portal_lights(scene):
        bpy.data.objects.remove(obj)
    assert any("no longer there" in p.message for p in eevee_setup.problems(scene))
    changed = eevee_setup.set_up(scene, bake_volume=False)
    assert any("lights EEVEE again" in c for c in changed)
    assert not eevee_setup.is_camera_only(world)


def test_a_world_of_its_own_eevee_output_is_left_alone(sky_scene):
    """A world whose EEVEE output is the user's is not changed: the portals are left out (for a
    render, hidden for the block; by the set-up, hidden) and the world's volume occludes it."""
    scene, world = sky_scene, sky_scene.world
    out = world.node_tree.nodes.new("ShaderNodeOutputWorld")
    out.target = "EEVEE"
    assert "EEVEE World Output of its own" in eevee_setup.camera_only(world)
    assert "of its own" in eevee_setup.camera_only_blocker(world)
    assert not eevee_setup.is_camera_only(world)
    _write_portal(scene)
    (portal,) = eevee_setup.portal_lights(scene)
    with eevee_setup.world_for_render(scene, probes=2) as bake:
        assert portal.hide_render and bake > 0.0  # a volume, as without portals
    assert not portal.hide_render and not eevee_setup.is_camera_only(world)
    changed = eevee_setup.set_up(scene, bake_volume=False)
    assert any("hid the sky portals" in c for c in changed) and portal.hide_render
    assert eevee_setup.vplace_volume(scene) is not None


def _box_room(scene, *, open_top: bool = False):
    """A 4 x 3 x 2.5 m box of single faces around :data:`EYE` (a default cube scaled, as users
    model a room), its top face left out with ``open_top``."""
    mesh = bpy.data.meshes.new("room")
    v = [(x, y, z) for x in (-2, 2) for y in (-1.5, 1.5) for z in (0, 2.5)]
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4)]
    quads += [] if open_top else [(1, 5, 7, 3)]
    mesh.from_pydata(v, [], quads)
    scene.collection.objects.link(bpy.data.objects.new("room", mesh))


def test_a_closed_room_shuts_the_world_out_of_eevee(sky_scene):
    """No ray from the eyes leaves a closed room: the world lights nothing inside in Cycles, so
    EEVEE's world lights nothing either (as with sky portals), never through the walls."""
    from addon.scene import export
    from addon.scene.convert import build_scene
    from addon.writeback import stand_ins as stand_ins_module
    from addon.writeback.stand_ins import stand_ins

    scene, world = sky_scene, sky_scene.world
    _box_room(scene)
    exported = export.export_scene(scene)
    lights = stand_ins(exported, build_scene(exported), [], [EYE])
    assert lights.closed and not lights.portals and lights.open_share == 0.0
    # A glass ball in the room leaves it closed; a glass pane over an open top does not: the
    # sky lights the room through it in Cycles.
    glass = new_material("glass")
    glass.node_tree.nodes["Principled BSDF"].inputs["Transmission Weight"].default_value = 1.0
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.3, location=(0.5, 0.0, 1.0))
    bpy.context.object.data.materials.append(glass)
    exported = export.export_scene(scene)
    assert [m.name for m in exported.materials if m.transmits] == ["glass"]
    assert stand_ins(exported, build_scene(exported), [], [EYE]).closed
    bpy.data.objects.remove(bpy.data.objects["room"])
    _box_room(scene, open_top=True)
    exported = export.export_scene(scene)
    assert not stand_ins(exported, build_scene(exported), [], [EYE]).closed
    # No eye needed: a floor that sees the sky through the open top keeps the room open (a
    # window round a corner, which a wall the camera sees sees), as the eye does.
    native = build_scene(exported)
    floor = np.zeros((4, 4, 3), np.float32) + np.array([0.0, 0.0, 0.01], np.float32)
    up = np.zeros((4, 4, 3), np.float32) + np.array([0.0, 0.0, 1.0], np.float32)
    seen = np.ones((4, 4), bool)
    assert stand_ins_module.sky_seen(native, exported, [(floor, up, seen)], [])
    bpy.ops.mesh.primitive_plane_add(size=6.0, location=(0.0, 0.0, 2.5))
    bpy.context.object.data.materials.append(glass)
    exported = export.export_scene(scene)
    assert not stand_ins(exported, build_scene(exported), [], [EYE]).closed
    assert stand_ins_module.sky_seen(build_scene(exported), exported, [(floor, up, seen)], [])
    glass.node_tree.nodes["Principled BSDF"].inputs["Transmission Weight"].default_value = 0.0
    exported = export.export_scene(scene)  # the pane is opaque now: the room is closed
    assert not stand_ins_module.sky_seen(build_scene(exported), exported, [(floor, up, seen)], [])
    assert stand_ins(exported, build_scene(exported), [(floor, up, seen)], [EYE]).closed
    # Written with the lights, the closed room keeps the world from lighting EEVEE.
    vpls = vplace.VplSet(
        np.zeros((1, 3), np.float32),
        np.array([[0, 0, 1]], np.float32),
        np.ones((1, 3), np.float32),
        radius=0.01,
    )
    apply.write_vpls(scene, vpls, closed=True)
    assert apply.stored_closed() and eevee_setup.world_shut_out(scene)
    assert any("closed room" in p.message for p in eevee_setup.problems(scene))
    with eevee_setup.world_for_render(scene) as bake:
        assert bake == 0.0 and eevee_setup.is_camera_only(world)
        assert not any(o.type == "LIGHT_PROBE" for o in scene.objects)  # no volume
    assert not eevee_setup.is_camera_only(world)
    changed = eevee_setup.set_up(scene, bake_volume=False)
    assert any("closed room" in c for c in changed) and eevee_setup.is_camera_only(world)
    assert eevee_setup.vplace_volume(scene) is None
    assert not any(p.setting == "world" for p in eevee_setup.problems(scene))
    # Lights written for an open scene: the world lights EEVEE again, through a volume.
    apply.write_vpls(scene, vpls)
    assert not apply.stored_closed() and not eevee_setup.world_shut_out(scene)
    changed = eevee_setup.set_up(scene, bake_volume=False)
    assert any("lights EEVEE again" in c for c in changed)
    assert eevee_setup.vplace_volume(scene) is not None


def test_each_direction_finds_the_same_neighbours_as_a_search_of_every_direction():
    for n in (portals.DIRECTIONS, 1000, 20):
        dirs = vplace.coverage.fibonacci_sphere(n)
        cos = dirs @ dirs.T
        np.fill_diagonal(cos, -2.0)
        near = portals._neighbours(dirs)
        assert near.shape == (n, portals.NEIGHBOURS)
        # The k-th nearest cosine of every direction, whichever of a tie each search names.
        want = -np.sort(-cos, axis=1)[:, : portals.NEIGHBOURS]
        got = -np.sort(-np.take_along_axis(cos, near, axis=1), axis=1)
        assert np.array_equal(got, want), n
