"""scene/convert.py: exported lights as core lights, the "nothing emits" refusal, and the scene
stage of a job (export, check, BVH)."""

from __future__ import annotations

import bpy
import numpy as np
import pytest
from blender_util import add_lamp, empty_file

from addon.capture.views import ViewSpec, eye_positions
from addon.errors import ExportError
from addon.job import StageTimer
from addon.native import vplace
from addon.scene.convert import check_lights, export_native, native_light
from addon.scene.export import LightInfo, export_scene
from addon.scenes import registry, rooms


def light(kind: str, **change) -> LightInfo:
    base = dict(
        name=kind.lower(), type=kind, position=(0.0, 0.0, 2.0), direction=(0.0, 0.0, -1.0),
        tangent=(1.0, 0.0, 0.0), power=(10.0, 10.0, 10.0), size_x=0.5, size_y=0.5,
        spot_half_angle=0.5,
    )  # fmt: skip
    return LightInfo(**{**base, **change})


@pytest.mark.parametrize("kind", ["POINT", "SPOT", "AREA", "SUN"])
def test_every_blender_light_type_has_a_core_light(kind):
    out = native_light(light(kind))
    assert out.kind == kind.lower()
    assert out.power == pytest.approx([10.0, 10.0, 10.0])


def test_an_unknown_light_type_names_the_light():
    with pytest.raises(vplace.InputError, match=r"'odd'.*'MESH'"):
        native_light(light("MESH", name="odd"))


def _floor_with(lamp_power: float | None) -> bpy.types.Scene:
    empty_file()
    scene = bpy.context.scene
    bpy.ops.mesh.primitive_plane_add(size=4.0)
    if lamp_power is not None:
        add_lamp(scene, "POINT", (0.0, 0.0, 2.0), energy=lamp_power)
    scene.world = None
    return scene


def test_the_scene_stage_times_export_and_bvh_and_refuses_darkness():
    scene = _floor_with(100.0)
    timer = StageTimer(log=lambda _line: None)
    exported, native = export_native(scene, timer.stage, timer.log)
    assert list(timer.seconds) == ["export scene", "build BVH"]
    assert native.triangle_count == len(exported.triangles) == 2
    assert native.light_count == 1
    with pytest.raises(ExportError, match="no lights that render"):
        check_lights(export_scene(_floor_with(None)))
    with pytest.raises(ExportError, match="every light has zero power"):
        export_native(_floor_with(0.0), timer.stage, timer.log)


def _sky_room(ground: float | None) -> tuple[bpy.types.Scene, np.ndarray]:
    """The built-in sky room (its world and sun light it through the windows), with a square
    ground plane of ``ground`` metres under its floor that no camera sees, and its cameras'
    positions."""
    bpy.ops.wm.open_mainfile(filepath=str(registry.builtin_scene("skyroom")))
    scene = bpy.context.scene
    if ground is not None:
        bpy.ops.mesh.primitive_plane_add(size=ground, location=(0.0, 0.0, -0.5))
    cams = [o for o in scene.objects if o.type == "CAMERA"]
    specs = [ViewSpec(c.name, c) for c in cams]
    return scene, eye_positions(scene, specs)


def _inside_share(native: vplace.Scene) -> float:
    """The share of 4,000 first-bounce VPLs in the sky room's air or on its inner surfaces."""
    p = np.asarray(vplace.uniform_vpls(native, 4000, seed=3).position)
    lo, hi = (np.asarray(c) for c in rooms.SKYROOM_INTERIOR)
    return float(np.all((p > lo - 0.01) & (p < hi + 0.01), axis=1).mean())


def _world_power(native: vplace.Scene) -> float:
    return sum(dict(native.emitted_powers())["world"])


def test_a_ground_no_camera_sees_takes_neither_the_vpls_size_nor_their_budget():
    """A kilometre of ground under a room made every VPL a disk of 14 m and sent the world's
    light to the ground (main before the working scale: the sky room's world sent 27,800 times
    the light, none of its VPLs in the room)."""
    timer = StageTimer(log=lambda _line: None)
    scene, eyes = _sky_room(None)
    _, room = export_native(scene, timer.stage, timer.log, eyes)
    # every built-in room keeps its bounds: its cameras see most of it
    assert room.scale == room.diagonal
    scene, eyes = _sky_room(1000.0)
    lines: list[str] = []
    _, native = export_native(scene, timer.stage, lines.append, eyes)
    assert native.diagonal > 1000.0
    assert room.scale < native.scale <= vplace.REGION_MARGIN * room.scale
    assert native.near_field_radius == pytest.approx(vplace.NEAR_FIELD_FRACTION * native.scale)
    assert any("region the cameras see" in line for line in lines), lines
    # the world sends its light through the working region's sphere, not the ground's
    ratio = _world_power(native) / _world_power(room)
    assert ratio == pytest.approx((native.scale / room.scale) ** 2, rel=1e-3)
    alone, kept = _inside_share(room), _inside_share(native)
    assert kept > 0.1 * alone, (kept, alone)
    # without the eyes: the bounds, and the ground takes the light and the VPLs
    _, blind = export_native(scene, timer.stage, timer.log)
    assert blind.scale == blind.diagonal
    assert _world_power(blind) / _world_power(room) > 10_000
    assert _inside_share(blind) < 0.1 * kept


def test_each_views_eye_is_its_camera_at_its_frame():
    empty_file()
    scene = bpy.context.scene
    bpy.ops.object.camera_add(location=(0.0, 0.0, 1.0))
    cam = bpy.context.object
    cam.keyframe_insert("location", frame=1)
    cam.location = (4.0, 0.0, 1.0)
    cam.keyframe_insert("location", frame=11)
    scene.frame_set(3)
    eyes = eye_positions(scene, [ViewSpec("a", cam, 1), ViewSpec("b", cam, 11), ViewSpec("c", cam)])
    assert eyes.dtype == np.float32 and eyes.shape == (3, 3)
    assert eyes[0].tolist() == [0.0, 0.0, 1.0] and eyes[1].tolist() == [4.0, 0.0, 1.0]
    assert 0.0 < eyes[2][0] < 4.0  # the scene's frame, put back
    assert scene.frame_current == 3
