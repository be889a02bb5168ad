"""Capture: passes into numpy, every changed render setting restored (also on error), cache."""

import bpy
import numpy as np
import pytest
from blender_util import cornell, diff, rna_snapshot

from addon.capture import passes as capture


def scene_state(scene):
    return rna_snapshot(scene, depth=3)


def test_capture_restores_settings_and_gives_consistent_passes(tmp_path):
    scene = cornell()
    scene.render.image_settings.file_format = "JPEG"  # the user's own choices must survive
    scene.render.image_settings.quality = 77
    scene.cycles.samples = 333
    before = scene_state(scene)
    cap = capture.capture(scene, resolution=(24, 20), samples=8, cache_dir=tmp_path)
    assert diff(before, scene_state(scene)) == []
    assert cap.combined.shape == (20, 24, 3) and cap.depth.shape == (20, 24)
    for arr in (cap.position, cap.normal, cap.albedo, cap.direct, cap.gi):
        assert arr.dtype == np.float32 and np.isfinite(arr).all()
    cov = cap.covered
    assert cov.all()  # the box fills the Cornell camera's view
    # Unit normals, except at pixels that straddle two surfaces (the box filter averages them).
    length = np.linalg.norm(cap.normal[cov], axis=-1)
    assert (length <= 1.0 + 1e-3).all() and np.mean(np.abs(length - 1.0) < 1e-3) > 0.6
    # Combined = (DiffDir + DiffInd) * DiffCol + gloss + emission (BLENDER_FACTS).
    recon = (
        (cap.diffuse_direct + cap.diffuse_indirect) * cap.diffuse_color
        + (cap.glossy_direct + cap.glossy_indirect) * cap.glossy_color
        + cap.emission
        + cap.environment
    )
    np.testing.assert_allclose(recon, cap.combined, atol=1e-4)
    # The indirect image is positive on average: the box bounces light.
    assert cap.indirect.mean() > 0.01


def test_capture_restores_settings_when_the_render_fails(monkeypatch):
    scene = cornell()
    # A file whose output format was never changed (a factory file, Blender's startup file, a
    # file saved from either) leaves image_settings.linear_colorspace_settings unset ('', which
    # Blender warns "matches no enum"); Blender fills it in ('sRGB') the first time the format
    # changes, a capture's included, and it cannot be set back to ''. Touch it once first.
    scene.render.image_settings.file_format = "PNG"
    before = scene_state(scene)

    def boom(*_args):
        raise RuntimeError("injected render failure")

    monkeypatch.setattr(capture, "_render", boom)
    with pytest.raises(RuntimeError, match="injected render failure"):
        capture.capture(scene, resolution=(8, 8), samples=1)
    assert diff(before, scene_state(scene)) == []
    assert not any(h.__name__ == "handler" for h in bpy.app.handlers.render_stats)


def test_capture_cache_hits_and_misses(tmp_path, monkeypatch):
    scene = cornell()
    first = capture.capture(scene, resolution=(8, 8), samples=2, cache_dir=tmp_path)
    calls = []
    real = capture._render
    monkeypatch.setattr(capture, "_render", lambda *a: (calls.append(1), real(*a)))
    again = capture.capture(scene, resolution=(8, 8), samples=2, cache_dir=tmp_path)
    assert calls == [] and np.array_equal(first.combined, again.combined)
    bpy.data.objects["tallBox"].location.x += 0.1  # content changed: a new render
    capture.capture(scene, resolution=(8, 8), samples=2, cache_dir=tmp_path)
    assert calls == [1]


def test_captures_in_one_cycles_session_are_the_same_and_the_session_leaves_no_trace():
    """Cycles keeps its scene between the captures of a session (``cycles_session``): the passes
    are the same bit for bit as captures made one by one, from two cameras and two sizes, and
    the engine and ``use_persistent_data`` come back as the user had them, also when a capture
    fails."""
    scene = cornell()
    scene.render.engine = "BLENDER_WORKBENCH"  # not Cycles (EEVEE's name differs by version)
    high = bpy.data.objects.new("high", scene.camera.data)
    high.matrix_world = scene.camera.matrix_world
    high.location.z += 0.3
    scene.collection.objects.link(high)
    shots = [(scene.camera, (16, 12)), (high, (16, 12)), (scene.camera, (8, 8))]
    alone = [capture.capture(scene, camera=c, resolution=r, samples=4) for c, r in shots]
    before = scene_state(scene)
    with capture.cycles_session(scene):
        assert scene.render.engine == "CYCLES" and scene.render.use_persistent_data
        together = [capture.capture(scene, camera=c, resolution=r, samples=4) for c, r in shots]
    assert diff(before, scene_state(scene)) == []
    for a, b in zip(alone, together, strict=True):
        for name in ("combined", "depth", "position", "normal", "diffuse_direct"):
            assert np.array_equal(getattr(a, name), getattr(b, name)), name
        assert np.array_equal(a.diffuse_indirect, b.diffuse_indirect)
    with pytest.raises(RuntimeError, match="boom"), capture.cycles_session(scene):
        raise RuntimeError("boom")
    assert scene.render.engine == "BLENDER_WORKBENCH" and not scene.render.use_persistent_data


def test_capture_errors():
    scene = cornell()
    with pytest.raises(capture.CaptureError, match="samples"):
        capture.capture(scene, samples=0)
    scene.camera = None
    with pytest.raises(capture.CaptureError, match="no camera"):
        capture.capture(scene, samples=1)


def test_capture_hides_the_lights_vplace_wrote(tmp_path):
    from addon.native import vplace
    from addon.writeback import apply

    scene = cornell()
    first = capture.capture(scene, resolution=(16, 16), samples=4)
    up = np.tile(np.float32([0, 0, 1]), (4, 1))
    pos = np.float32([[0.2, 0.1, 0.3], [-0.3, 0.2, 0.5], [0.0, -0.2, 1.0], [0.1, 0.3, 0.2]])
    vpls = vplace.VplSet(pos, up, np.full((4, 3), 5.0, np.float32))
    coll = apply.write_vpls(scene, vpls, scene_diagonal=3.4)
    again = capture.capture(scene, resolution=(16, 16), samples=4)
    # The bright VPLs change nothing: the capture neither renders them nor keys on them, so a
    # second "Lay out and apply" sees what the first saw.
    assert again.key == first.key
    np.testing.assert_array_equal(again.combined, first.combined)
    assert not coll.hide_render  # shown again after the capture
    lit = capture.capture(scene, resolution=(16, 16), samples=4, include_vpls=True)
    assert lit.key != first.key and lit.combined.mean() > 1.05 * first.combined.mean()


def test_an_unreadable_cache_file_is_rendered_again(tmp_path):
    scene = cornell()
    first = capture.capture(scene, resolution=(8, 8), samples=2, cache_dir=tmp_path)
    (path,) = tmp_path.glob("capture-*.npz")
    path.write_bytes(b"not an npz")
    again = capture.capture(scene, resolution=(8, 8), samples=2, cache_dir=tmp_path)
    np.testing.assert_array_equal(again.combined, first.combined)
    assert capture.Capture.load(path).key == first.key  # replaced by a good one


def _uv(world_to_clip, point):
    h = world_to_clip @ np.array([*point, 1.0])
    return (h[:2] / h[3] + 1.0) / 2.0


def test_a_capture_frames_what_the_camera_frames_whatever_its_pixels_views_scale_or_focus():
    """Non-square pixels (Blender cannot write them as a multilayer EXR), a stereo pair, a
    camera scaled (2, 1, 1) and depth of field: the capture renders square pixels of one view at
    the render's shape, sharp, and projects as Blender's own camera does; every setting of the
    user's comes back."""
    from bpy_extras.object_utils import world_to_camera_view
    from mathutils import Vector

    from addon.capture.views import capture_resolution

    scene = cornell()
    plain = capture.capture(scene, resolution=(24, 20), samples=2)
    cam = scene.camera
    r = scene.render
    r.pixel_aspect_x = 2.0
    r.use_multiview = True
    cam.data.dof.use_dof = True
    cam.data.dof.focus_distance = 0.2
    cam.data.dof.aperture_fstop = 0.1
    cam.scale = (2.0, 1.0, 1.0)
    bpy.context.view_layer.update()
    before = scene_state(scene)
    dof_before = rna_snapshot(cam.data.dof, depth=1)
    size = capture_resolution(scene, 24)
    aspect = r.resolution_x * 2.0 / r.resolution_y
    assert abs(size[0] / size[1] - aspect) < 0.05 * aspect
    cap = capture.capture(scene, resolution=size, samples=2)
    assert diff(before, scene_state(scene)) == []
    assert diff(dof_before, rna_snapshot(cam.data.dof, depth=1)) == []
    assert cap.combined.shape == (size[1], size[0], 3)
    for point in [(0.1, 0.2, 0.3), (-0.2, 0.25, 0.1), (0.25, -0.1, 0.45)]:
        want = np.array(world_to_camera_view(scene, cam, Vector(point))[:2])
        np.testing.assert_allclose(_uv(cap.world_to_clip, point), want, atol=2e-3)
    # the camera's scale and focus change nothing a capture renders
    r.pixel_aspect_x = 1.0
    again = capture.capture(scene, resolution=(24, 20), samples=2)
    np.testing.assert_array_equal(again.position, plain.position)
    np.testing.assert_array_equal(again.combined, plain.combined)


def test_a_capture_of_a_moving_camera_is_sharp_whatever_the_motion_blur():
    """The render's motion blur would blur the G-buffer of a moving camera as depth of field
    does (positions and normals averaged over the shutter): the capture renders the frame
    sharp, and the user's setting comes back."""
    scene = cornell()
    cam = scene.camera
    for frame, dx in ((1, 0.0), (3, 0.6)):
        cam.location.x += dx
        cam.keyframe_insert("location", frame=frame)
    scene.frame_set(2)
    sharp = capture.capture(scene, resolution=(24, 20), samples=2)
    scene.render.use_motion_blur = True
    blurred = capture.capture(scene, resolution=(24, 20), samples=2)
    assert scene.render.use_motion_blur
    np.testing.assert_array_equal(blurred.normal, sharp.normal)
    np.testing.assert_array_equal(blurred.combined, sharp.combined)


def test_a_capture_renders_the_view_layer_that_renders():
    """The window's view layer turned off for rendering: the capture renders the one that is on
    (as F12 does); none on is a one-line error."""
    from addon.errors import ExportError

    scene = cornell()
    bpy.context.view_layer.use = False
    on = scene.view_layers.new("on")
    cap = capture.capture(scene, resolution=(12, 10), samples=1)
    assert cap.covered.all()
    on.use = False
    with pytest.raises(ExportError, match=r"no view layer of scene .* renders"):
        capture.capture(scene, resolution=(12, 10), samples=1)
