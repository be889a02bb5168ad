"""Views: one set of lights for several cameras, frames of an animated camera, or an orbit; the
views that cannot be used are left out with a message, and the file is left as it was."""

import math

import bpy
import numpy as np
import pytest
from blender_util import add_lamp, addon_cornell, data_snapshot, diff, empty_file

from addon import job as pipeline
from addon.capture import views
from addon.errors import AddonError, CaptureError
from addon.native import vplace
from addon.scenes.registry import CORNELL_HELD_OUT_CAMERA
from addon.writeback import apply


@pytest.fixture
def scene():
    with addon_cornell(cell_px=8) as sc:
        yield sc


def prepared(scene, **view_options):
    job = pipeline.Job.from_settings(scene.vplace)
    job.views = views.ViewSet(**view_options)
    return pipeline.prepare(scene, job, pipeline.quiet_timer())


def users(p):
    """The captures of the user's views in ``p``: the rendered coverage views left out."""
    return [c for c in p.captures if not c.view.startswith(vplace.coverage.RENDERED_PREFIX)]


def test_two_chosen_cameras_give_one_set_of_lights(scene, tmp_path):
    s = scene.vplace
    s.view_mode = "cameras"
    for name in ("Cornell camera", CORNELL_HELD_OUT_CAMERA):
        bpy.context.view_layer.objects.active = bpy.data.objects[name]
        assert bpy.ops.vplace.camera_add() == {"FINISHED"}
    assert [c.camera.name for c in s.cameras] == ["Cornell camera", CORNELL_HELD_OUT_CAMERA]
    assert bpy.ops.vplace.apply() == {"FINISHED"}
    report = s.report()
    assert report["views"] == ["Cornell camera", CORNELL_HELD_OUT_CAMERA]
    # The region's coverage views, rendered and fitted beside them (the default).
    assert report["region_views"] == [f"region view {k}" for k in range(1, 5)]
    assert set(report["fit"]["view_r2"]) == set(report["views"] + report["region_views"])
    assert len(apply.find_collection().objects) <= 8
    assert bpy.ops.vplace.camera_remove() == {"FINISHED"} and len(s.cameras) == 1
    s.camera_index = 5  # no such row: said, nothing removed
    with pytest.raises(RuntimeError, match="select a camera row"):
        bpy.ops.vplace.camera_remove()
    assert len(s.cameras) == 1


def test_frames_of_an_animated_camera(scene):
    cam = scene.camera
    cam.location.x = -0.3
    cam.keyframe_insert("location", frame=1)
    cam.location.x = 0.3
    cam.keyframe_insert("location", frame=11)
    scene.frame_set(5)
    p = prepared(scene, mode="frames", frame_start=1, frame_end=11, frame_step=10)
    assert [c.view for c in users(p)] == ["Cornell camera frame 1", "Cornell camera frame 11"]
    xs = [c.camera_position[0] for c in users(p)]
    assert xs == pytest.approx([-0.3, 0.3], abs=1e-5)
    assert scene.frame_current == 5  # the user's frame comes back


def test_orbit_views_leave_the_file_as_it_was(scene):
    before = data_snapshot()
    p = prepared(scene, mode="orbit", orbit_count=3, orbit_angle=20.0)
    assert len(users(p)) == 3 and p.captures[0].view == "Cornell camera"
    positions = [tuple(c.camera_position) for c in users(p)]
    assert len(set(positions)) == 3
    assert diff(before, data_snapshot()) == []
    assert not [o for o in bpy.data.objects if o.get(views.ORBIT_MARKER)]


def test_bad_views_are_left_out_with_a_message_and_the_others_work(scene):
    away = bpy.data.objects.new("Away", bpy.data.cameras.new("Away"))
    away.location = (0.0, -6.0, 1.0)
    away.rotation_euler = (-1.5, 0.0, 0.0)  # looking down and away from the box
    scene.collection.objects.link(away)
    bpy.context.view_layer.update()
    lines = []
    job = pipeline.Job.from_settings(scene.vplace)
    job.views = views.ViewSet(mode="cameras", cameras=("Cornell camera", "Away", "Cornell camera"))
    p = pipeline.prepare(scene, job, pipeline.StageTimer(lines.append))
    assert [c.view for c in users(p)] == ["Cornell camera"]
    assert p.skipped == {"Away": "the camera sees no geometry (only background)"}
    assert any("view 'Away' left out" in line for line in lines)
    # The same camera twice is one view (its name is listed once).
    job.views = views.ViewSet(mode="cameras", cameras=("Away",))
    with pytest.raises(CaptureError, match="no view is left"):
        pipeline.prepare(scene, job, pipeline.quiet_timer())
    with pytest.raises(AddonError, match="no camera object named 'Nope'"):
        prepared(scene, mode="cameras", cameras=("Nope",))
    with pytest.raises(AddonError, match="choose at least one camera"):
        prepared(scene, mode="cameras")
    with pytest.raises(AddonError, match="step must be at least 1"):
        prepared(scene, mode="frames", frame_start=5, frame_end=1)


def test_two_views_rendering_the_same_image_count_once(scene):
    twin = scene.camera.copy()
    twin.name = "Twin camera"
    scene.collection.objects.link(twin)
    bpy.context.view_layer.update()
    p = prepared(scene, mode="cameras", cameras=("Cornell camera", "Twin camera"))
    assert [c.view for c in users(p)] == ["Cornell camera"]
    assert p.skipped == {"Twin camera": "the same view as 'Cornell camera'"}


def test_more_views_than_memory_allows_are_refused_before_rendering(scene, monkeypatch):
    monkeypatch.setattr(pipeline, "MAX_CAPTURE_BYTES", 1000)
    with pytest.raises(CaptureError, match="GB of captures"):
        prepared(scene, mode="orbit", orbit_count=2)


def test_capture_size_follows_the_render_aspect(scene):
    scene.render.resolution_x, scene.render.resolution_y = 1920, 1080
    assert views.capture_resolution(scene, 160) == (160, 90)
    scene.render.resolution_x, scene.render.resolution_y = 600, 800
    assert views.capture_resolution(scene, 160) == (120, 160)


def _house_seen_through_its_wall() -> tuple[bpy.types.Scene, bpy.types.Object]:
    """A closed room 12 x 9 x 3 m (walls 0.25 m thick, a lamp inside) and a camera 0.4 m outside
    its south wall, looking in: its clip start (1 m) passes the wall, as architects set it."""
    empty_file()
    scene = bpy.context.scene
    w, d, h, t = 12.0, 9.0, 3.0, 0.25
    slabs = {
        "floor": ((0, 0, -t / 2), (w + 2 * t, d + 2 * t, t)),
        "ceiling": ((0, 0, h + t / 2), (w + 2 * t, d + 2 * t, t)),
        "south": ((0, -d / 2 - t / 2, h / 2), (w + 2 * t, t, h)),
        "north": ((0, d / 2 + t / 2, h / 2), (w + 2 * t, t, h)),
        "west": ((-w / 2 - t / 2, 0, h / 2), (t, d, h)),
        "east": ((w / 2 + t / 2, 0, h / 2), (t, d, h)),
    }
    for name, (loc, size) in slabs.items():
        bpy.ops.mesh.primitive_cube_add(location=loc, scale=[s / 2 for s in size])
        bpy.context.object.name = name
    add_lamp(scene, "POINT", (0.0, 0.0, 2.5), 100.0)
    data = bpy.data.cameras.new("outside")
    data.clip_start = 1.0
    cam = bpy.data.objects.new("outside", data)
    cam.location = (0.0, -d / 2 - t - 0.4, 1.6)
    cam.rotation_euler = (math.radians(90.0), 0.0, 0.0)  # looking north, along +y
    scene.collection.objects.link(cam)
    scene.camera = cam
    scene.render.resolution_x, scene.render.resolution_y = 64, 36
    bpy.context.view_layer.update()
    return scene, cam


def test_a_camera_that_sees_through_a_wall_stands_in_the_room_behind_it():
    # An architect's camera outside the wall, its clip start past it, sees the room. Its eye was
    # its position outside: the region it saw was a 6 x 3 m patch of the wall's outer face (the
    # working scale 13.8 m where the room's is 16.1 m), and the coverage views stood outside,
    # looking at the facade and the roof. Now it stands where its view begins: 0.35 m into the
    # room.
    scene, cam = _house_seen_through_its_wall()
    eye = views.eye_positions(scene, [views.ViewSpec("outside", cam)])[0]
    assert eye.tolist() == pytest.approx([0.0, -4.5 + 0.35, 1.6], abs=1e-4)
    job = pipeline.Job(size=32, samples=2)
    prepared = pipeline.prepare(scene, job, pipeline.quiet_timer())
    assert prepared.scene.scale == pytest.approx(prepared.scene.diagonal)
    assert prepared.scene.region is None
    poses = prepared.coverage.poses
    assert poses
    for p in poses:  # inside the room's walls, not in front of its facade
        assert -6.0 < p.eye[0] < 6.0 and -4.5 < p.eye[1] < 4.5 and 0.0 < p.eye[2] < 3.0, p.eye


def test_rendered_coverage_views_are_cycles_captures_of_the_traced_poses(scene):
    # "Render coverage views": the poses the traced coverage picks, each rendered by Cycles from
    # a temporary camera, fitted as captures (their indirect light is Cycles', not light-path
    # VPLs'). A camera turned the wrong way would render another view: the rendered G-buffer
    # must be the traced one's, pixel for pixel, and the file must be left as it was.
    traced = prepared(scene, coverage=2, render_coverage=False)
    assert len(traced.coverage.poses) == 2 and len(traced.captures) == 1
    before = data_snapshot()
    rendered = prepared(scene, coverage=2)  # the default
    assert diff(before, data_snapshot()) == []
    assert not [o for o in bpy.data.objects if o.get(views.COVERAGE_MARKER)]
    assert [p.eye.tolist() for p in rendered.coverage.poses] == [
        p.eye.tolist() for p in traced.coverage.poses
    ]
    names = [c.view for c in rendered.captures]
    assert names == ["Cornell camera", "region view 1", "region view 2"]
    assert len(rendered.views) == 3  # no traced coverage view beside them
    fitted = vplace.coverage.captures_of(rendered.views)
    assert [v.name for v in fitted] == names
    for cap, view in zip(rendered.captures[1:], traced.views[1:], strict=True):
        assert (cap.width, cap.height) == (view.width, view.height) == (48, 48)
        both = cap.covered & view.covered
        assert both.sum() > 0.9 * view.covered.sum()
        dist = np.linalg.norm(cap.position[both] - view.position[both], axis=1)
        assert np.median(dist) < 0.01 * rendered.scene.scale, np.median(dist)
        assert cap.indirect.sum() > 0.0


def test_each_eye_comes_with_where_its_camera_looks():
    """``eye_views``: a camera's view axis (unit, without its scale), none for a panoramic one."""
    empty_file()
    scene = bpy.context.scene
    cam = bpy.data.objects.new("cam", bpy.data.cameras.new("cam"))
    scene.collection.objects.link(cam)
    cam.rotation_euler = (math.pi / 2, 0.0, 0.0)  # looking along +Y
    cam.scale = (2.0, 1.0, 3.0)
    pano = bpy.data.objects.new("pano", bpy.data.cameras.new("pano"))
    pano.data.type = "PANO"
    scene.collection.objects.link(pano)
    bpy.context.view_layer.update()
    eyes, looks = views.eye_views(scene, [views.ViewSpec("cam", cam), views.ViewSpec("pano", pano)])
    assert eyes.shape == looks.shape == (2, 3)
    np.testing.assert_allclose(looks[0], [0.0, 1.0, 0.0], atol=1e-6)
    np.testing.assert_array_equal(looks[1], [0.0, 0.0, 0.0])
