"""scene/convert.py: exported lights as core lights, the "nothing emits" refusal, and the scene
stage of a job (export, check, BVH)."""

from __future__ import annotations

import bpy
import pytest
from blender_util import add_lamp, empty_file

from addon.errors import ExportError
from addon.job import StageTimer
from addon.native import vplace
from addon.scene.convert import check_lights, export_native, native_light
from addon.scene.export import LightInfo, export_scene


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
