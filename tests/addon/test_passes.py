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
    # A factory-empty file leaves image_settings.linear_colorspace_settings unset ('', which
    # Blender warns "matches no enum"); Blender fills it in on first use and it cannot be set
    # back to ''. Any saved user file has it set; touch the settings once to get there.
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
