"""The add-on registered as Blender does it: the apply and clear operators, persistence."""

import json

import bpy
import numpy as np
import pytest
from blender_util import CORNELL_OBJ, data_snapshot, diff, empty_file

import addon
from addon.native import vplace
from addon.scenes.registry import build_cornell_box
from addon.writeback import apply


@pytest.fixture
def registered():
    addon.register()
    yield
    addon.unregister()


def small_cornell():
    empty_file()
    scene = build_cornell_box(CORNELL_OBJ)
    s = scene.vplace
    s.capture_size = 24
    s.samples = 4
    s.vpl_budget = 16
    bpy.context.view_layer.update()  # evaluated matrices, as in a file opened from disk
    return scene


def report_of(scene):
    return json.loads(scene.vplace.last_report)


def test_apply_clear_and_reload(registered, tmp_path):
    scene = small_cornell()
    assert bpy.ops.vplace.apply() == {"FINISHED"}
    coll = apply.find_collection()
    # Every VPL with power is a light (the refit may switch a few off: not written).
    assert coll is not None and len(coll.objects) == report_of(scene)["lights_written"] > 8
    report = json.loads(scene.vplace.last_report)
    assert report["n_vpls"] == 16 and report["metrics"]["rmse"] > 0
    assert report["fit"]["kept"]
    model = scene.vplace.model_json
    assert vplace.Fit.from_json(model).kept == report["fit"]["kept"]
    path = tmp_path / "saved.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    bpy.ops.wm.open_mainfile(filepath=str(path))
    scene = bpy.context.scene
    assert scene.vplace.vpl_budget == 16 and scene.vplace.capture_size == 24
    assert json.loads(scene.vplace.last_report) == report
    assert scene.vplace.model_json == model  # the fitted model is kept in the .blend
    assert len(apply.find_collection().objects) == report["lights_written"]
    assert bpy.ops.vplace.clear_vpls() == {"FINISHED"}
    assert apply.find_collection() is None


def test_apply_shows_the_region_and_its_coverage_views_and_clear_removes_them(registered):
    """Issue 20: the region the lights are laid out for is visible in the viewport and in the
    panel's report: a sphere empty around the camera of the region's radius, an arrow empty
    per coverage view from its eye along its view, nothing rendered; a run without coverage
    views and "Clear VPLs" take the last run's region away."""
    scene = small_cornell()
    scene.vplace.coverage = 3
    assert bpy.ops.vplace.apply() == {"FINISHED"}
    region = report_of(scene)["region"]
    assert region["views"] >= 1 and len(region["radius_m"]) == 1
    assert 0 < region["covered_before"] < region["covered_after"] <= 1
    coll = apply.find_collection(apply.REGION_NAME)
    assert coll is not None and coll is not apply.find_collection()
    spheres = sorted(o.name for o in coll.objects if o.empty_display_type == "SPHERE")
    arrows = [o for o in coll.objects if o.empty_display_type == "SINGLE_ARROW"]
    assert spheres == ["vplace region 1"] and len(arrows) == region["views"]
    sphere = coll.objects["vplace region 1"]
    assert sphere.empty_display_size == pytest.approx(region["radius_m"][0], rel=1e-5)
    assert (sphere.location - scene.camera.matrix_world.translation).length < 1e-4
    assert all(o.type == "EMPTY" and o.hide_render for o in coll.objects)
    lines = vplace.job.PanelReport.from_json(scene.vplace.last_report).region.lines()
    assert lines[0].startswith(f"Region: {region['views']} coverage view")
    scene.vplace.coverage = 0
    assert bpy.ops.vplace.apply() == {"FINISHED"}
    assert apply.find_collection(apply.REGION_NAME) is None
    assert "region" not in report_of(scene) or report_of(scene)["region"] is None
    scene.vplace.coverage = 3
    assert bpy.ops.vplace.apply() == {"FINISHED"}
    assert apply.find_collection(apply.REGION_NAME) is not None
    assert bpy.ops.vplace.clear_vpls() == {"FINISHED"}
    assert apply.find_collection(apply.REGION_NAME) is None
    assert not [o for o in bpy.data.objects if o.name.startswith("vplace region")]


def test_failed_apply_reports_and_changes_nothing(registered):
    scene = small_cornell()
    bpy.data.objects["light"].hide_render = True  # no light: the VPLs cannot be placed
    before = data_snapshot()
    with pytest.raises(RuntimeError, match="the scene has no lights that render"):
        bpy.ops.vplace.apply()  # an operator that reports ERROR makes bpy.ops raise
    assert apply.find_collection() is None
    assert diff(before, data_snapshot()) == []
    scene.camera = None
    assert not bpy.ops.vplace.apply.poll()


def test_a_report_that_fails_after_the_write_keeps_the_lights_as_one_undo_step(
    registered, monkeypatch
):
    scene = small_cornell()
    scene.vplace.last_report = '{"n_vpls": 99}'  # an older run's

    def fails(*_args, **_kwargs):
        raise vplace.InputError("the summary broke")

    monkeypatch.setattr(addon.job, "summary", fails)
    # FINISHED, not CANCELLED: Blender pushes an undo step for the lights just written.
    assert bpy.ops.vplace.apply() == {"FINISHED"}
    assert len(apply.find_collection().objects) > 8
    assert scene.vplace.last_report == ""  # not the older run's report of other lights


def test_apply_is_greyed_out_while_a_run_works(registered, monkeypatch):
    import threading

    from addon.ui import modal

    small_cornell()
    gate = threading.Event()
    worker = threading.Thread(target=gate.wait, args=(10,), daemon=True)
    worker.start()
    monkeypatch.setattr(modal, "_current", ("Lay out and apply", worker))
    try:
        assert not bpy.ops.vplace.apply.poll()
    finally:
        gate.set()
        worker.join()
    assert bpy.ops.vplace.apply.poll()


@pytest.mark.parametrize("method", ["vplace", "rsm"])
def test_apply_with_each_layout_method(registered, method):
    scene = small_cornell()
    scene.vplace.method = method
    scene.vplace.cell_px = 8
    assert bpy.ops.vplace.apply() == {"FINISHED"}
    report = json.loads(scene.vplace.last_report)
    assert report["method"] == ("vplace+refit" if method == "vplace" else method)
    n = len(apply.find_collection().objects)
    assert 0 < n <= 16 and n == report["lights_written"]
    if method == "vplace":
        errors = report["evaluator"]["iteration_errors"]
        assert errors and report["evaluator"]["best_iteration"] == errors.index(min(errors))
        before, after = report["evaluator"]["refit_error"]  # the refit is on by default
        assert after <= before


def test_capture_fit_and_report_operators_leave_the_scene_as_it_was(registered, tmp_path):
    scene = small_cornell()
    scene.render.image_settings.file_format = "PNG"  # see test_capture: a saved file has it set
    before = data_snapshot()
    assert bpy.ops.vplace.capture() == {"FINISHED"}
    assert bpy.ops.vplace.fit() == {"FINISHED"}
    fit = scene.vplace.report()["fit"]
    assert fit["kept"] and abs(sum(fit["weights"].values()) - 1) < 1e-9
    assert vplace.Fit.from_json(scene.vplace.model_json).kept == fit["kept"]
    assert bpy.ops.vplace.report(directory=str(tmp_path)) == {"FINISHED"}
    report = json.loads((tmp_path / "report.json").read_text())
    assert report["method"] == "vplace+refit"
    assert set(report["baselines"]) == {"uniform", "rsm", "vplace"}
    assert not (tmp_path / "scene.blend").exists()  # a report does not write back
    assert apply.find_collection() is None
    assert diff(before, data_snapshot()) == []


def written_lights():
    """(index, location, power RGB, size) of every light in the VPL collection, sorted."""
    out = []
    for o in apply.find_collection().objects:
        d = o.data
        power = tuple(round(c * d.energy, 6) for c in d.color)
        out.append((o["vplace_index"], tuple(round(v, 6) for v in o.location), power, d.size))
    return sorted(out)


def drawn_region():
    """The region's empties (``apply.write_region``): name, shape, size and world matrix."""
    coll = apply.find_collection(apply.REGION_NAME)
    assert coll is not None and len(coll.objects) > 1
    return sorted(
        (o.name, o.empty_display_type, o.empty_display_size, tuple(map(tuple, o.matrix_world)))
        for o in coll.objects
    )


@pytest.mark.slow
def test_apply_twice_writes_the_same_lights_and_image(registered, tmp_path):
    from addon.capture import passes as capture

    scene = small_cornell()
    assert bpy.ops.vplace.apply() == {"FINISHED"}
    first, region = written_lights(), drawn_region()
    image = capture.capture(scene, resolution=(24, 24), samples=8, include_vpls=True)
    # The second run captures with the first run's lights in the scene: the capture hides them,
    # so it sees what the first saw and writes the same lights, for the same region.
    assert bpy.ops.vplace.apply() == {"FINISHED"}
    assert written_lights() == first and drawn_region() == region
    again = capture.capture(scene, resolution=(24, 24), samples=8, include_vpls=True)
    np.testing.assert_array_equal(again.combined, image.combined)
    # One collection of lights and one of their region, each replaced, not doubled.
    marked = sorted(c.name for c in bpy.data.collections if c.get("vplace_vpl"))
    assert marked == sorted([apply.COLLECTION_NAME, apply.REGION_NAME])
