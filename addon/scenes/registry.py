"""The built-in scenes and their registry (:func:`builtin_scene`): the Cornell box (the default;
Williams College OBJ, public domain), Sponza (glTF, CC BY 3.0), and two rooms built from code
alone (:mod:`.builtin_rooms`: ``skyroom``, lit by a sky through windows, and ``panelroom``, lit
by emissive panels and a screen), and two animated ones (:mod:`.animated`: ``cornell_moving``,
``skyroom_afternoon``).

Geometry and materials come from ``CornellBox-Original.obj`` / ``.mtl`` (OBJ Y-up is turned into
Blender Z-up: ``(x, y, z) -> (x, -z, y)``; the OBJ unit is taken as the metre). The emissive
ceiling quad becomes an AREA light of the same rectangle and of power ``pi * A * Ke`` (a
Lambertian emitter of radiance ``Ke`` over area ``A``). The camera is the published Cornell
camera (position (278, 273, -800) mm, 35 mm lens, 25 mm film) mapped into the OBJ's frame.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import bpy
import numpy as np

from ..compat import eevee_engine, new_material, new_world
from ..errors import AddonError, run_operator
from . import animated, lroom
from . import rooms as builtin_rooms

REPO = Path(__file__).resolve().parents[2]
SCENES = REPO / "blend_scenes"
CORNELL_OBJ = SCENES / "cornell_box" / "CornellBox-Original.obj"
CORNELL_BLEND = SCENES / "cornell_box" / "cornell_box.blend"
SPONZA_GLTF = SCENES / "sponza" / "Sponza.gltf"
SPONZA_BLEND = SCENES / "sponza" / "sponza.blend"

#: The published Cornell camera in the OBJ's frame, converted to Blender axes.
CORNELL_CAMERA_LOCATION = (0.0, -3.894, 0.99)
CORNELL_LENS_MM = 35.0
CORNELL_SENSOR_MM = 25.0
#: A view the report holds out: inside the box, front right, looking at the back left corner
#: (Blender axes, metres).
CORNELL_HELD_OUT_CAMERA = "Cornell camera (held out)"
CORNELL_HELD_OUT_LOCATION = (0.55, -0.95, 1.45)
CORNELL_HELD_OUT_TARGET = (-0.55, 0.55, 0.45)
CORNELL_HELD_OUT_LENS_MM = 20.0
#: Further views inside the box, ``name -> (location, target, lens mm)``: two more the report
#: fits on, one more it holds out.
CORNELL_VIEWS = {
    "Cornell camera left": ((-0.6, -0.9, 1.0), (0.5, 0.6, 0.7), 20.0),
    "Cornell camera high": ((0.0, -1.6, 1.8), (0.0, 0.2, 0.3), 24.0),
    "Cornell camera (held out, low)": ((-0.3, -0.8, 0.35), (0.4, 0.6, 0.9), 18.0),
}


def parse_mtl(path: Path) -> dict[str, dict[str, tuple[float, ...]]]:
    """Material name -> {"Kd": (r, g, b), "Ke": ..., "Ks": ...} from a .mtl file."""
    mats: dict[str, dict[str, tuple[float, ...]]] = {}
    current: dict[str, tuple[float, ...]] | None = None
    for line in path.read_text().splitlines():
        parts = line.split("#", 1)[0].split()
        if not parts:
            continue
        if parts[0] == "newmtl":
            current = mats.setdefault(parts[1], {})
        elif current is not None and parts[0] in {"Kd", "Ke", "Ks"}:
            current[parts[0]] = tuple(float(v) for v in parts[1:4])
    return mats


def parse_obj(path: Path) -> list[tuple[str, str, np.ndarray, list[list[int]]]]:
    """Groups of an OBJ as (group name, material, vertices (n, 3) in OBJ axes, faces)."""
    verts: list[tuple[float, float, float]] = []
    groups: list[tuple[str, str, list[list[int]]]] = []
    material = ""
    for line in path.read_text().splitlines():
        parts = line.split("#", 1)[0].split()
        if not parts:
            continue
        if parts[0] == "v":
            verts.append((float(parts[1]), float(parts[2]), float(parts[3])))
        elif parts[0] == "usemtl":
            material = parts[1]
        elif parts[0] == "g":
            groups.append((parts[1], material, []))
        elif parts[0] == "f":
            n = len(verts)
            face = [int(p.split("/")[0]) for p in parts[1:]]
            groups[-1][2].append([i - 1 if i > 0 else n + i for i in face])
    all_v = np.array(verts, dtype=np.float64)
    out = []
    for name, mat, faces in groups:
        used = sorted({i for f in faces for i in f})
        remap = {old: new for new, old in enumerate(used)}
        out.append((name, mat, all_v[used], [[remap[i] for i in f] for f in faces]))
    return out


def obj_to_blender(v: np.ndarray) -> np.ndarray:
    """OBJ Y-up to Blender Z-up: ``(x, y, z) -> (x, -z, y)``."""
    return np.stack([v[:, 0], -v[:, 2], v[:, 1]], axis=1)


def _diffuse_material(name: str, color: tuple[float, ...]) -> bpy.types.Material:
    mat = new_material(name)
    bsdf = mat.node_tree.nodes.get("Principled BSDF")
    bsdf.inputs["Base Color"].default_value = (*color[:3], 1.0)
    bsdf.inputs["Roughness"].default_value = 1.0
    bsdf.inputs["Specular IOR Level"].default_value = 0.0
    mat.diffuse_color = (*color[:3], 1.0)
    return mat


def build_cornell_box(obj_path: Path, scene: bpy.types.Scene | None = None) -> bpy.types.Scene:
    """Adds the Cornell box (meshes, AREA light, camera, black world) to ``scene``."""
    scene = scene or bpy.context.scene
    mtl = parse_mtl(obj_path.with_suffix(".mtl"))
    materials: dict[str, bpy.types.Material] = {}
    for name, mat_name, v_obj, faces in parse_obj(obj_path):
        v = obj_to_blender(v_obj)
        if mtl.get(mat_name, {}).get("Ke", (0.0,))[0] > 0.0:
            ke = mtl[mat_name]["Ke"]
            lo, hi = v.min(axis=0), v.max(axis=0)
            sx, sy = float(hi[0] - lo[0]), float(hi[1] - lo[1])
            power = [math.pi * sx * sy * k for k in ke]
            light = bpy.data.lights.new(name, "AREA")
            light.shape = "RECTANGLE"
            light.size, light.size_y = sx, sy
            light.energy = max(power)
            light.color = [p / max(power) for p in power]
            obj = bpy.data.objects.new(name, light)
            # Centre of the quad, a hair below the ceiling; AREA lights emit along local -Z.
            obj.location = (*(0.5 * (lo + hi))[:2], float(lo[2]) - 1e-3)
            scene.collection.objects.link(obj)
            continue
        if mat_name not in materials:
            materials[mat_name] = _diffuse_material(mat_name, mtl[mat_name]["Kd"])
        mesh = bpy.data.meshes.new(name)
        mesh.from_pydata([tuple(p) for p in v], [], faces)
        mesh.update()
        mesh.materials.append(materials[mat_name])
        obj = bpy.data.objects.new(name, mesh)
        scene.collection.objects.link(obj)

    cam_data = bpy.data.cameras.new("Cornell camera")
    cam_data.lens = CORNELL_LENS_MM
    cam_data.sensor_width = CORNELL_SENSOR_MM
    cam_data.sensor_fit = "AUTO"
    cam = bpy.data.objects.new("Cornell camera", cam_data)
    cam.location = CORNELL_CAMERA_LOCATION
    cam.rotation_euler = (math.pi / 2, 0.0, 0.0)
    scene.collection.objects.link(cam)
    scene.camera = cam
    _look_at_camera(
        scene,
        CORNELL_HELD_OUT_CAMERA,
        CORNELL_HELD_OUT_LOCATION,
        CORNELL_HELD_OUT_TARGET,
        CORNELL_HELD_OUT_LENS_MM,
    )
    for name, (location, target, lens) in CORNELL_VIEWS.items():
        _look_at_camera(scene, name, location, target, lens)

    world = new_world("Black")
    bg = world.node_tree.nodes.get("Background")
    bg.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    bg.inputs["Strength"].default_value = 0.0
    world.color = (0.0, 0.0, 0.0)
    scene.world = world

    r = scene.render
    r.engine = "CYCLES"
    r.resolution_x = r.resolution_y = 160
    r.resolution_percentage = 100
    scene.cycles.samples = 64
    scene.cycles.device = "CPU"
    scene.eevee.taa_render_samples = 16
    return scene


def _look_at_camera(
    scene: bpy.types.Scene,
    name: str,
    location: tuple[float, float, float],
    target: tuple[float, float, float],
    lens_mm: float,
) -> bpy.types.Object:
    """A perspective camera at ``location`` aimed at ``target`` (not the scene's camera)."""
    from mathutils import Vector

    data = bpy.data.cameras.new(name)
    data.lens = lens_mm
    data.sensor_width = CORNELL_SENSOR_MM
    cam = bpy.data.objects.new(name, data)
    cam.location = location
    direction = Vector(target) - Vector(location)
    cam.rotation_euler = direction.to_track_quat("-Z", "Y").to_euler()
    scene.collection.objects.link(cam)
    return cam


def build_cornell_moving(scene: bpy.types.Scene | None = None) -> bpy.types.Scene:
    """The Cornell box with its lamp keyed to move and dim (``animated.key_cornell_lamp``)."""
    scene = build_cornell_box(CORNELL_OBJ, scene)
    animated.key_cornell_lamp(scene)
    return scene


def write_cornell_blend(obj_path: Path, blend_path: Path) -> Path:
    """Builds the Cornell box in a fresh file and saves it to ``blend_path``."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    build_cornell_box(obj_path)
    blend_path.parent.mkdir(parents=True, exist_ok=True)
    bpy.ops.wm.save_as_mainfile(filepath=str(blend_path), compress=True)
    return blend_path


#: Sponza: the sun through the open roof and the view down the atrium.
SPONZA_SUN_ROTATION = (math.radians(15.0), math.radians(-10.0), 0.0)
SPONZA_SUN_STRENGTH = 10.0  # W/m^2
SPONZA_CAMERA = "CameraMain"
SPONZA_HELD_OUT_CAMERA = "CameraAlternate"
#: A view added to the glTF's four: at the west end of the atrium, at head height, looking east.
SPONZA_WEST_CAMERA = "CameraWest"
SPONZA_WEST = ((-12.5, 0.3, 4.4), (8.0, 0.3, 6.6), 20.0)


def build_sponza(gltf_path: Path, scene: bpy.types.Scene | None = None) -> bpy.types.Scene:
    """Imports Sponza (glTF, CC BY 3.0) with a sun through the open roof and the glTF's main
    camera looking down the atrium; the other cameras of the file stay (held-out views)."""
    scene = scene or bpy.context.scene
    bpy.ops.import_scene.gltf(filepath=str(gltf_path))
    sun_data = bpy.data.lights.new("Sun", "SUN")
    sun_data.energy = SPONZA_SUN_STRENGTH
    sun_data.angle = math.radians(0.5)
    sun_data.color = (1.0, 0.95, 0.85)
    sun = bpy.data.objects.new("Sun", sun_data)
    sun.rotation_euler = SPONZA_SUN_ROTATION
    scene.collection.objects.link(sun)
    scene.camera = bpy.data.objects[SPONZA_CAMERA]
    location, target, lens = SPONZA_WEST
    _look_at_camera(scene, SPONZA_WEST_CAMERA, location, target, lens)
    world = new_world("Black")
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
    scene.world = world
    r = scene.render
    r.engine = "CYCLES"
    r.resolution_x, r.resolution_y = 192, 108
    r.resolution_percentage = 100
    scene.cycles.samples = 64
    scene.cycles.device = "CPU"
    scene.eevee.taa_render_samples = 16
    return scene


def write_sponza_blend(gltf_path: Path, blend_path: Path) -> Path:
    """Builds Sponza in a fresh file and saves it to ``blend_path``."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    build_sponza(gltf_path)
    blend_path.parent.mkdir(parents=True, exist_ok=True)
    bpy.ops.wm.save_as_mainfile(filepath=str(blend_path), compress=True)
    return blend_path


def _flat_object(
    name: str,
    outline: list[tuple[float, float]],
    collection: bpy.types.Collection,
    emission: tuple[float, float, float] | None = None,
) -> bpy.types.Object:
    """A flat polygon in the XY plane; emissive when ``emission`` is given."""
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([(x, y, 0.0) for x, y in outline], [], [list(range(len(outline)))])
    mesh.update()
    mat = new_material(name)
    bsdf = mat.node_tree.nodes.get("Principled BSDF")
    if emission is None:
        bsdf.inputs["Base Color"].default_value = (0.05, 0.05, 0.05, 1.0)
    else:
        strength = max(emission)
        bsdf.inputs["Emission Color"].default_value = (*(c / strength for c in emission), 1.0)
        bsdf.inputs["Emission Strength"].default_value = strength
    mesh.materials.append(mat)
    obj = bpy.data.objects.new(name, mesh)
    collection.objects.link(obj)
    return obj


def build_par2d_demo(scene: bpy.types.Scene | None = None) -> bpy.types.Collection:
    """A 2D scene for PAR: two lights and seven occluders (one non-convex) in the XY plane, in
    the collection ``PAR scene``, seen from above by an orthographic camera."""
    scene = scene or bpy.context.scene
    coll = bpy.data.collections.new("PAR scene")
    scene.collection.children.link(coll)
    circle = [
        (-2.0 + 0.35 * math.cos(a), 1.2 + 0.35 * math.sin(a))
        for a in np.linspace(0.0, 2.0 * math.pi, 16, endpoint=False)
    ]
    _flat_object("Warm light", circle, coll, emission=(4.0, 2.6, 1.2))
    _flat_object(
        "Cool light",
        [(1.6, -1.6), (2.4, -1.6), (2.4, -1.3), (1.6, -1.3)],
        coll,
        emission=(1.0, 2.0, 4.0),
    )
    boxes = [
        ("Pillar A", [(-0.9, 0.3), (-0.5, 0.3), (-0.5, 0.7), (-0.9, 0.7)]),
        ("Pillar B", [(0.4, -0.2), (0.8, -0.2), (0.8, 0.2), (0.4, 0.2)]),
        ("Wall", [(-1.6, -0.9), (-0.2, -0.6), (-0.25, -0.45), (-1.65, -0.75)]),
        ("Wedge", [(0.9, 1.0), (1.6, 0.7), (1.3, 1.5)]),
        ("L block", [(-0.2, 1.4), (0.6, 1.4), (0.6, 1.6), (0.0, 1.6), (0.0, 2.1), (-0.2, 2.1)]),
        ("Post", [(1.2, -0.8), (1.35, -0.8), (1.35, -0.65), (1.2, -0.65)]),
        ("Shard", [(-2.6, -1.5), (-2.2, -1.7), (-2.3, -1.2)]),
    ]
    for name, outline in boxes:
        _flat_object(name, outline, coll)
    cam_data = bpy.data.cameras.new("Top camera")
    cam_data.type = "ORTHO"
    cam_data.ortho_scale = 6.5
    cam = bpy.data.objects.new("Top camera", cam_data)
    cam.location = (0.0, 0.2, 10.0)
    scene.collection.objects.link(cam)
    scene.camera = cam
    world = new_world("Black")
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
    scene.world = world
    scene.render.engine = eevee_engine()
    scene.render.resolution_x = scene.render.resolution_y = 256
    scene.eevee.taa_render_samples = 4
    return coll


def _ensure_blend(blend: Path, sources: list[Path], build: Callable[[], Path]) -> Path:
    """``blend``, rebuilt by ``build`` when missing, older than any of ``sources``, or built by
    another Blender (an older one may not read a newer one's file; the stamp beside it says
    which built it)."""
    stamp = blend.with_name(blend.name + ".version")
    if (
        not blend.exists()
        or any(src.stat().st_mtime > blend.stat().st_mtime for src in sources)
        or not stamp.exists()
        or stamp.read_text() != bpy.app.version_string
    ):
        print(f"[vplace] building {blend.relative_to(REPO)} with Blender {bpy.app.version_string}")
        build()
        stamp.write_text(bpy.app.version_string)
    return blend


#: The built-in scenes: name -> (.blend, its sources, how to build it).
BUILTIN: dict[str, tuple[Path, list[Path], Callable[[], Path]]] = {
    "cornell": (
        CORNELL_BLEND,
        [CORNELL_OBJ, Path(__file__)],
        lambda: write_cornell_blend(CORNELL_OBJ, CORNELL_BLEND),
    ),
    "sponza": (
        SPONZA_BLEND,
        [SPONZA_GLTF, Path(__file__)],
        lambda: write_sponza_blend(SPONZA_GLTF, SPONZA_BLEND),
    ),
    "skyroom": (
        builtin_rooms.SKYROOM_BLEND,
        [Path(builtin_rooms.__file__)],
        lambda: builtin_rooms.write_skyroom_blend(builtin_rooms.SKYROOM_BLEND),
    ),
    "lroom": (
        lroom.LROOM_BLEND,
        [Path(lroom.__file__), Path(builtin_rooms.__file__)],
        lambda: lroom.write_lroom_blend(lroom.LROOM_BLEND),
    ),
    "panelroom": (
        builtin_rooms.PANELROOM_BLEND,
        [Path(builtin_rooms.__file__)],
        lambda: builtin_rooms.write_panelroom_blend(builtin_rooms.PANELROOM_BLEND),
    ),
    # Animated (issue 23, ``demo --animate``): the lamp moves and dims, the sun sweeps.
    "cornell_moving": (
        animated.CORNELL_MOVING_BLEND,
        [CORNELL_OBJ, Path(__file__), Path(animated.__file__)],
        lambda: builtin_rooms._write(build_cornell_moving, animated.CORNELL_MOVING_BLEND),
    ),
    "skyroom_afternoon": (
        animated.SKYROOM_AFTERNOON_BLEND,
        [Path(animated.__file__), Path(builtin_rooms.__file__)],
        lambda: animated.write_skyroom_afternoon_blend(animated.SKYROOM_AFTERNOON_BLEND),
    ),
}


def builtin_scene(name: str) -> Path:
    """The .blend of a built-in scene (see :data:`BUILTIN`), built on first use."""
    if name not in BUILTIN:
        raise AddonError(
            f"unknown built-in scene {name!r}: use {', '.join(sorted(BUILTIN))} or a .blend path"
        )
    blend, sources, build = BUILTIN[name]
    return _ensure_blend(blend, sources, build)


#: How a .blend file begins: Blender's header, or the gzip or Zstandard frame of a compressed one.
BLEND_MAGICS = (b"BLENDER", b"\x1f\x8b", b"\x28\xb5\x2f\xfd")


def check_blend(path: Path) -> Path:
    """``path`` if it is a .blend file, else an :class:`AddonError` naming it (missing, a
    folder, unreadable, or some other kind of file)."""
    if path.is_dir():
        raise AddonError(f"{path} is a folder, not a .blend file")
    if not path.is_file():
        raise AddonError(f"no such .blend file: {path}")
    try:
        with path.open("rb") as f:
            head = f.read(8)
    except OSError as exc:
        raise AddonError(f"cannot read the .blend file {path}: {exc.strerror or exc}") from exc
    if not head.startswith(BLEND_MAGICS):
        raise AddonError(f"not a .blend file: {path} (it does not begin as one)")
    return path


def open_blend(path: Path) -> None:
    """Opens ``path`` in place of the current file (never saved), or an :class:`AddonError`
    naming it."""
    check_blend(path)
    run_operator("wm.open_mainfile", f"cannot open the .blend file {path}", filepath=str(path))
