"""A built-in L-shaped room built from code alone (no asset files, so no licence): ``lroom``,
where one camera cannot see what the next one sees.

The interior (6 x 4 x 2.8 m, walls :data:`.rooms.WALL` thick as in the other rooms) has its
south-east quarter filled by a solid block, so the floor plan is an L: a *west arm*
(``x < 0``, full depth) and a *north-east wing* (``x > 0``, ``y > 0``). The scene camera
(:data:`LROOM_FIT`) stands in the west arm looking at its north-west corner and sees nothing of
the wing. The wing holds what lights the room: a sun through a window in its east wall throws a
patch on the wing's floor and its sofa, whose bounce reaches the west arm around the corner; a
lamp in the west arm lights the rest. The held-out cameras (:data:`LROOM_HELD_OUT`) look into
the wing and back at the block's west face: walls, objects and a sun patch that the scene
camera never sees. A layout fitted to the scene camera alone must light them too.

The world is Blender's default grey (0.05); the sun is a SUN lamp (no sky texture), the lamp a
POINT lamp, so the scene is what a user gets from a new file with a room imported into it.
"""

from __future__ import annotations

import math
from pathlib import Path

import bpy

from ..compat import new_world
from .rooms import (
    REPO,
    Vec3,
    _boxes,
    _cameras,
    _leaves,
    _principled,
    _render_settings,
    _write,
    plant,
    plastered_shell,
    sofa,
    table,
)

LROOM_BLEND = REPO / "blend_scenes" / "lroom" / "lroom.blend"
#: The interior box, ``(min corner, max corner)`` in metres; :data:`LROOM_BLOCK` fills part of it.
LROOM_INTERIOR = ((-3.0, -2.0, 0.0), (3.0, 2.0, 2.8))
#: The solid block that makes the L (its faces at ``x = 0`` and ``y = 0`` are walls).
LROOM_BLOCK: tuple[Vec3, Vec3] = ((0.0, -2.0, 0.0), (3.0, 0.0, 2.8))
#: The sun: irradiance (W/m^2), elevation and the heading it shines toward (radians from +x,
#: counter-clockwise): from the east, low enough to reach the wing's floor through its window.
SUN_STRENGTH = 6.0
SUN_ELEVATION = math.radians(35.0)
SUN_HEADING = math.radians(185.0)
#: The west arm's lamp: a point light (W) under the ceiling.
LAMP_POWER = 120.0
LAMP_LOCATION = (-1.9, -0.6, 2.4)

#: Cameras, ``name -> (location, target, lens mm)`` on a 36 mm sensor.
LROOM_FIT = {
    "Lroom camera": ((-0.3, -1.7, 1.6), (-2.8, 0.8, 0.7), 18.0),
}
LROOM_HELD_OUT = {
    "Lroom camera (held out, wing)": ((-2.5, 1.4, 1.6), (2.8, 0.6, 0.7), 18.0),
    "Lroom camera (held out, back)": ((-2.6, 1.6, 1.8), (0.0, -1.8, 0.6), 18.0),
}

__all__ = [
    "LROOM_BLEND",
    "LROOM_BLOCK",
    "LROOM_FIT",
    "LROOM_HELD_OUT",
    "LROOM_INTERIOR",
    "build_lroom",
    "write_lroom_blend",
]


def _sun(scene: bpy.types.Scene) -> bpy.types.Object:
    """The SUN lamp shining toward :data:`SUN_HEADING` and down at :data:`SUN_ELEVATION`."""
    from mathutils import Vector

    data = bpy.data.lights.new("Sun", "SUN")
    data.energy = SUN_STRENGTH
    data.angle = math.radians(0.5)
    sun = bpy.data.objects.new("Sun", data)
    ce = math.cos(SUN_ELEVATION)
    travel = Vector(
        (ce * math.cos(SUN_HEADING), ce * math.sin(SUN_HEADING), -math.sin(SUN_ELEVATION))
    )
    sun.rotation_euler = travel.to_track_quat("-Z", "Y").to_euler()
    sun.location = (6.0, 1.0, 5.0)
    scene.collection.objects.link(sun)
    return sun


def _lamp(scene: bpy.types.Scene) -> bpy.types.Object:
    data = bpy.data.lights.new("Lamp", "POINT")
    data.energy = LAMP_POWER
    data.color = (1.0, 0.9, 0.78)
    data.shadow_soft_size = 0.1
    lamp = bpy.data.objects.new("Lamp", data)
    lamp.location = LAMP_LOCATION
    scene.collection.objects.link(lamp)
    return lamp


def build_lroom(scene: bpy.types.Scene | None = None) -> bpy.types.Scene:
    """Adds the L-shaped room (see the module docs) to ``scene``."""
    scene = scene or bpy.context.scene
    coll = scene.collection
    windows = {"east": [(1.0, 1.2, 0.8, 1.4)], "west": [(-0.8, 0.8, 1.0, 1.0)]}
    plastered_shell(coll, LROOM_INTERIOR, windows)
    _boxes("Corner block", [LROOM_BLOCK], _principled("Block yellow", (0.75, 0.6, 0.25)), coll)
    wood = _principled("Dark wood", (0.12, 0.06, 0.03), 0.5)
    table("Table", (-1.8, 0.6), (1.2, 0.8, 0.75), wood, coll)
    sofa("Sofa", (0.9, 1.1), (2.5, 1.95), "+y", _principled("Sofa fabric", (0.5, 0.1, 0.12)), coll)
    _boxes(
        "Cabinet",
        [((2.45, 0.1, 0.0), (2.95, 0.8, 0.9))],
        _principled("Cabinet white", (0.6, 0.6, 0.58), 0.4),
        coll,
    )
    plant("Plant", (-2.6, 1.6), 1.4, _principled("Clay pot", (0.45, 0.15, 0.06)), _leaves(), coll)

    world = new_world("World")
    world.color = (0.05, 0.05, 0.05)
    bg = world.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (0.05, 0.05, 0.05, 1.0)
    bg.inputs["Strength"].default_value = 1.0
    scene.world = world
    _sun(scene)
    _lamp(scene)
    _cameras(scene, LROOM_FIT, LROOM_HELD_OUT)
    _render_settings(scene)
    return scene


def write_lroom_blend(blend_path: Path | None = None) -> Path:
    """Builds the L-shaped room in a fresh file and saves it to ``blend_path``."""
    return _write(build_lroom, blend_path or LROOM_BLEND)
