"""The procedural built-in rooms (``addon/builtin_rooms.py``): each builds, opens and exports as
vplace reads it (the sky room lit by its world alone and the sun shining in through the windows,
the panel room by emissive triangles alone and closed), textured floors, alpha cut-outs that
rays pass, every report camera inside its room, and the main job on each bringing the image
closer to Cycles than direct light alone."""

import json
import math
import subprocess
import sys
from pathlib import Path

import bpy
import numpy as np
import pytest
from mathutils import Vector

from addon.native import vplace
from addon.report import config as report
from addon.report import runs
from addon.scene import export
from addon.scene.convert import build_scene, check_lights
from addon.scenes import registry as default_scene
from addon.scenes import rooms as builtin_rooms

ROOT = Path(__file__).resolve().parents[2]
INTERIOR = {
    "skyroom": builtin_rooms.SKYROOM_INTERIOR,
    "panelroom": builtin_rooms.PANELROOM_INTERIOR,
}
ROOMS = list(INTERIOR)


def open_room(name):
    """Opens the built-in room's .blend (built when missing or older than its code)."""
    blend = default_scene.builtin_scene(name)
    bpy.ops.wm.open_mainfile(filepath=str(blend))
    return bpy.context.scene


def material_of(ex, triangles):
    """The exported material name of each triangle index (None for a miss)."""
    return [ex.materials[ex.material_ids[t]].name if t >= 0 else None for t in triangles]


def inside_points(name, n, seed=0, margin=0.3):
    """``n`` random points in the room's air, ``margin`` m off its walls, floor and ceiling."""
    lo, hi = (np.array(c) for c in INTERIOR[name])
    rng = np.random.default_rng(seed)
    return rng.uniform(lo + margin, hi - margin, (n, 3)).astype(np.float32)


def sphere_directions(n, seed=1):
    d = np.random.default_rng(seed).normal(size=(n, 3))
    return (d / np.linalg.norm(d, axis=1, keepdims=True)).astype(np.float32)


@pytest.mark.parametrize("name", ROOMS)
def test_rooms_are_registered_and_rebuilt_when_their_code_changes(name):
    blend, sources, _ = default_scene.BUILTIN[name]
    assert default_scene.builtin_scene(name) == blend
    assert blend == ROOT / "blend_scenes" / name / f"{name}.blend"
    assert Path(builtin_rooms.__file__) in sources
    assert (ROOT / "blend_scenes" / name / "README.md").is_file()
    assert blend.is_file() and blend.stat().st_mtime >= Path(builtin_rooms.__file__).stat().st_mtime


def test_skyroom_is_lit_by_the_sky_alone_and_the_sun_falls_in_patches():
    scene = open_room("skyroom")
    assert not [o.name for o in bpy.data.objects if o.type == "LIGHT"]
    ex = export.export_scene(scene)
    check_lights(ex)  # no refusal: the world lights the room
    assert ex.lights == [] and ex.emitters() == ["world 'Sky'"]
    assert ex.world.source == "baked" and any("Sky Texture" in w for w in ex.warnings)
    # The sun: the baked map's brightest texel, above the horizon in the south-west (-x, -y).
    img = ex.world.image
    row, col = np.unravel_index(np.argmax(img.sum(axis=2)), img.shape[:2])
    theta = (row + 0.5) / img.shape[0] * math.pi
    phi = (0.5 - (col + 0.5) / img.shape[1]) * 2.0 * math.pi
    sun = np.array([math.sin(theta) * math.cos(phi), math.sin(theta) * math.sin(phi)])
    sun = np.append(sun, math.cos(theta)).astype(np.float32)
    assert sun[0] < -0.3 and sun[1] < -0.3 and 0.4 < sun[2] < 0.7
    # From a grid over the floor, rays towards the sun escape through the windows from some
    # points only: sun patches, not a lit floor and not a dark one.
    native = build_scene(ex)
    x, y = np.meshgrid(np.linspace(-2.9, 2.9, 59), np.linspace(-1.9, 1.9, 39))
    floor = np.c_[x.ravel(), y.ravel(), np.full(x.size, 0.02)].astype(np.float32)
    _, tri, _ = native.intersect(floor, np.tile(sun, (len(floor), 1)))
    sunny = (tri < 0).mean()
    assert 0.03 < sunny < 0.3, sunny


def test_skyroom_lets_light_in_only_through_its_windows():
    ex = export.export_scene(open_room("skyroom"))
    native = build_scene(ex)
    origins = np.repeat(inside_points("skyroom", 8), 500, axis=0)
    t, tri, _ = native.intersect(origins, sphere_directions(len(origins)))
    escaped = tri < 0
    # Three windows of 4.6 m^2 in 84 m^2 of room surface: a few per cent of the rays leave.
    assert 0.005 < escaped.mean() < 0.1, escaped.mean()
    assert t[~escaped].max() < math.dist(*INTERIOR["skyroom"])


def test_panelroom_is_closed_and_lit_by_emissive_triangles_alone():
    scene = open_room("panelroom")
    assert not [o.name for o in bpy.data.objects if o.type == "LIGHT"]
    ex = export.export_scene(scene)
    check_lights(ex)  # no refusal: the panels and the screen emit
    assert ex.lights == [] and not ex.world.emits and ex.warnings == []
    assert sorted(ex.emitters()) == ["material 'Panel light'", "material 'TV screen'"]
    native = build_scene(ex)
    # The lower face of three panels and the screen: two triangles each.
    assert native.emissive_triangle_count == 8 and native.light_count == 0
    origins = np.repeat(inside_points("panelroom", 8), 500, axis=0)
    t, tri, _ = native.intersect(origins, sphere_directions(len(origins)))
    assert (tri >= 0).all() and t.max() < math.dist(*INTERIOR["panelroom"])


@pytest.mark.parametrize(
    ("name", "floor", "cut_outs"),
    [("skyroom", "Wooden floor", ["Leaves"]), ("panelroom", "Tiled floor", ["Leaves", "Lattice"])],
)
def test_floors_are_textured_and_leaves_and_lattices_are_cut_out(name, floor, cut_outs):
    ex = export.export_scene(open_room(name))
    by_name = {m.name: m for m in ex.materials}
    m = by_name[floor]
    assert m.textured and m.texture is not None and ex.uvs is not None
    assert ex.textures[m.texture.index].shape == (512, 512, 4)
    # The floor's UVs repeat the texture (metres / tile), so the texture's texels vary on it.
    floor_uvs = ex.uvs[ex.material_ids == list(by_name).index(floor)]
    assert floor_uvs.max() - floor_uvs.min() > 2.0
    native = build_scene(ex)
    assert native.has_alpha_tests
    for cut in cut_outs:
        alpha = by_name[cut].alpha
        assert alpha is not None and alpha.texture is not None, cut
        texels = ex.textures[alpha.texture.index][..., 3]
        assert 0.1 < (texels > 0.5).mean() < 0.7, cut  # partly cut away
        assert not any(cut in w for w in ex.warnings)


def test_panel_light_passes_the_lattice_through_its_holes():
    ex = export.export_scene(open_room("panelroom"))
    native = build_scene(ex)
    x, y = np.meshgrid(np.linspace(1.25, 2.35, 23), np.linspace(-0.25, 0.25, 11))
    below = np.c_[x.ravel(), y.ravel(), np.full(x.size, 1.0)].astype(np.float32)
    up = np.tile(np.array([[0.0, 0.0, 1.0]], np.float32), (len(below), 1))
    _, tri, _ = native.intersect(below, up)
    hit = material_of(ex, tri)
    through = hit.count("Panel light") / len(hit)
    assert set(hit) == {"Panel light", "Lattice"} and 0.2 < through < 0.9, through


@pytest.mark.parametrize("name", ROOMS)
def test_report_cameras_stand_inside_the_room_and_look_at_it(name):
    scene = open_room(name)
    preset = report.PRESETS[name]
    assert len(preset.fit_views) == 3 and len(preset.held_out_views) == 2
    assert preset.resolution == (256, 144) and preset.capture_samples == 16
    assert scene.camera.name == preset.fit_views[0]
    r = scene.render
    assert r.resolution_x * 9 == r.resolution_y * 16
    lo, hi = (Vector(c) for c in INTERIOR[name])
    depsgraph = bpy.context.evaluated_depsgraph_get()
    boxes = []
    for obj in scene.objects:
        if obj.type == "MESH":
            corners = [obj.matrix_world @ Vector(c) for c in obj.bound_box]
            boxes.append((obj.name, *(Vector(f(c[i] for c in corners) for i in range(3))
                                      for f in (min, max))))  # fmt: skip
    for cam_name in (*preset.fit_views, *preset.held_out_views):
        cam = bpy.data.objects[cam_name]
        assert cam.type == "CAMERA"
        p = cam.matrix_world.translation
        assert all(lo[i] + 0.1 < p[i] < hi[i] - 0.1 for i in range(3)), (cam_name, p)
        inside = [n for n, b0, b1 in boxes if all(b0[i] < p[i] < b1[i] for i in range(3))]
        assert inside == [], (cam_name, inside)
        # The view's centre ray meets the room, inside it.
        forward = cam.matrix_world.to_quaternion() @ Vector((0.0, 0.0, -1.0))
        hit, where, *_ = scene.ray_cast(depsgraph, p, forward)
        assert hit and all(lo[i] - 0.01 <= where[i] <= hi[i] + 0.01 for i in range(3)), cam_name


def demo(name, out):
    """The command line's main job on the room: tiny captures of the report's fit views."""
    cmd = [
        sys.executable, "-m", "addon.cli", "demo", "--scene", name, "--out", str(out),
        "--cameras", *report.PRESETS[name].fit_views,
        "--size", "64", "--samples", "16", "--vpls", "64", "--truth-samples", "512",
        "--no-eevee",
    ]  # fmt: skip
    return subprocess.run(cmd, capture_output=True, text=True, timeout=600, cwd=ROOT)


@pytest.mark.slow
@pytest.mark.parametrize("name", ROOMS)
def test_main_job_on_the_room_beats_direct_light_alone(name, tmp_path):
    r = demo(name, tmp_path)
    assert r.returncode == 0 and "error" not in r.stderr, r.stdout[-2000:] + r.stderr[-2000:]
    result = json.loads((tmp_path / "report.json").read_text())
    assert result["views"] == list(report.PRESETS[name].fit_views)
    assert result["skipped_views"] == {}
    m = result["metrics"]
    print(name, m)
    assert m["rmse"] < 0.8 * m["rmse_direct_only"]
    assert m["relative_mse"] < 0.6 * m["relative_mse_direct_only"]
    assert m["ssim"] > m["ssim_direct_only"]
    assert abs(m["brightness"] - 1.0) < 0.15


def test_the_report_and_the_command_line_run_the_rooms_by_default():
    from addon import cli

    assert set(ROOMS) <= set(report.ReportConfig().scenes) <= set(report.PRESETS)
    assert cli.parse_args(["report"]).scenes == list(report.ReportConfig().scenes)
    for name in ROOMS:
        assert report.PRESETS[name].truth_samples == 1024 and report.PRESETS[name].blend is None


def test_lroom_hides_its_wing_from_the_scene_camera_and_shows_it_to_the_held_out_ones():
    """The L-shaped room (``scenes/lroom.py``): the fit camera sees nothing of the sunlit wing,
    the held-out wing camera sees the wing in a fifth of its pixels and more."""
    from addon.capture.passes import camera_matrices
    from addon.scenes import lroom

    blend, sources, _ = default_scene.BUILTIN["lroom"]
    assert default_scene.builtin_scene("lroom") == blend and Path(lroom.__file__) in sources
    assert (ROOT / "blend_scenes" / "lroom" / "README.md").is_file()
    scene = open_room("lroom")
    ex = export.export_scene(scene)
    native = build_scene(ex)

    def wing_share(camera_name):
        cam = scene.objects[camera_name]
        eye, world_to_clip = camera_matrices(scene, cam, (64, 36))
        s = (np.arange(64) + 0.5) / 64 * 2 - 1
        t = (np.arange(36) + 0.5) / 36 * 2 - 1
        x, y = np.meshgrid(s, -t)
        ndc = np.stack([x, y, np.ones_like(x), np.ones_like(x)], axis=-1).reshape(-1, 4)
        far = ndc @ np.linalg.inv(world_to_clip).T
        d = far[:, :3] / far[:, 3:] - eye
        d = (d / np.linalg.norm(d, axis=1, keepdims=True)).astype(np.float32)
        o = np.repeat(eye[None].astype(np.float32), len(d), axis=0)
        dist, tri, _ = native.intersect(o, d)
        hit = tri >= 0  # the rest leave through a window
        assert hit.mean() > 0.9
        p = o[hit] + d[hit] * dist[hit, None]
        return float(((p[:, 0] > 0.05) & (p[:, 1] > 0.05)).mean())

    (fit,) = lroom.LROOM_FIT
    assert wing_share(fit) == 0.0
    assert wing_share("Lroom camera (held out, wing)") > 0.2  # a fifth of what it sees


def coinciding_faces(ex):
    """Pairs of triangles in one plane, facing the same way, whose insides overlap: a surface
    shown twice (faces that meet back to back, as a box on a floor, are not counted)."""
    v = ex.vertices.astype(np.float64)
    a, b, c = (v[ex.triangles[:, k]] for k in range(3))
    n = np.cross(b - a, c - a)
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    planes: dict[tuple, list[int]] = {}
    for i, key in enumerate(np.round(np.column_stack([n, (n * a).sum(1)]), 4)):
        planes.setdefault(tuple(key), []).append(i)
    inner = np.array([[1 / 3, 1 / 3, 1 / 3], [0.6, 0.2, 0.2], [0.2, 0.6, 0.2], [0.2, 0.2, 0.6]])
    found = []
    for ids in planes.values():
        for i in ids:
            points = inner @ np.stack([a[i], b[i], c[i]])
            for j in ids:
                e0, e1, q = b[j] - a[j], c[j] - a[j], points - a[j]
                m = np.array([[e0 @ e0, e0 @ e1], [e0 @ e1, e1 @ e1]])
                if j == i or abs(np.linalg.det(m)) < 1e-18:
                    continue
                s, t = np.linalg.solve(m, np.stack([q @ e0, q @ e1])).reshape(2, -1)
                if ((s > 1e-4) & (t > 1e-4) & (1 - s - t > 1e-4)).any():
                    found.append((i, j))
    return found


@pytest.mark.parametrize("name", [*ROOMS, "lroom"])
def test_no_surface_of_a_room_is_shown_twice(name):
    # Two boxes that overlap show two faces in one plane; Cycles renders them black (a ray
    # leaving one face meets the other at once) where vplace and EEVEE light them: the sofa's
    # arms and backrest made every hot-spot pixel of the L room's wing view.
    ex = export.export_scene(open_room(name))
    assert coinciding_faces(ex) == []


@pytest.mark.slow
def test_lights_laid_out_for_the_lroom_camera_hold_on_the_walls_only_its_region_shows(tmp_path):
    """Issue 20: the L room's camera does not see the wing; its held-out cameras do. The lights
    laid out for that camera alone, with the coverage views of its region (the default), score
    at least `uniform` with as many VPLs on both held-out views, on every seed (mean margins of
    .016 and .04 at this size). Without the coverage views (as every job ran when the issue was
    filed) the same layout falls below `uniform` on the wing: the scene tests what they add."""

    def held_out_ssim(coverage: int) -> dict[tuple[str, str], list[float]]:
        config = report.ReportConfig(
            scenes=("lroom",),
            budgets=(64,),
            resolution=(96, 54),
            truth_samples=128,
            truth_noise=False,
            methods=("uniform", "vplace+refit"),
            seeds=(0, 1, 2),
            generated_views=0,
            with_eevee=False,
            par2d=False,
            coverage=coverage,
            cache_dir=tmp_path / "cache",
        )
        result = runs.run_report(config, tmp_path / f"coverage{coverage}", log=lambda _: None)
        out: dict[tuple[str, str], list[float]] = {}
        for r in result["rows"]:
            if r["renderer"] == "evaluator" and r["role"] == "held-out":
                out.setdefault((r["view"], r["method"]), []).append(r["ssim"])
        return out

    covered = held_out_ssim(vplace.coverage.DEFAULT_COUNT)
    views = sorted({view for view, _ in covered})
    assert len(views) == 2
    for view in views:
        vplace_runs, uniform_runs = covered[(view, "vplace+refit")], covered[(view, "uniform")]
        assert len(vplace_runs) == 3
        assert all(v >= u for v, u in zip(vplace_runs, uniform_runs, strict=True)), view
    bare = held_out_ssim(0)
    wing = next(view for view in views if "wing" in view)
    assert np.mean(bare[(wing, "vplace+refit")]) < np.mean(bare[(wing, "uniform")])
