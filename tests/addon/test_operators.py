"""The add-on registered as Blender does it: the apply and clear operators, persistence."""

import json

import bpy
import pytest
from blender_util import CORNELL_OBJ, data_snapshot, diff, empty_file

import addon
from addon import apply
from addon.default_scene import build_cornell_box
from addon.native import vplace


@pytest.fixture
def registered():
    addon.register()
    yield
    addon.unregister()


def small_cornell():
    empty_file()
    scene = build_cornell_box(CORNELL_OBJ)
    s = scene.vplace
    s.resolution_x = s.resolution_y = 24
    s.samples = 4
    s.vpl_budget = 16
    bpy.context.view_layer.update()  # evaluated matrices, as in a file opened from disk
    return scene


def test_apply_clear_and_reload(registered, tmp_path):
    scene = small_cornell()
    assert bpy.ops.vplace.apply() == {"FINISHED"}
    coll = apply.find_collection()
    assert coll is not None and len(coll.objects) == 16
    report = json.loads(scene.vplace.last_report)
    assert report["n_vpls"] == 16 and report["metrics"]["rmse"] > 0
    assert report["fit"]["kept"]
    model = scene.vplace.model_json
    assert vplace.Fit.from_json(model).kept == report["fit"]["kept"]
    path = tmp_path / "saved.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    bpy.ops.wm.open_mainfile(filepath=str(path))
    scene = bpy.context.scene
    assert scene.vplace.vpl_budget == 16 and scene.vplace.resolution_x == 24
    assert json.loads(scene.vplace.last_report) == report
    assert scene.vplace.model_json == model  # the fitted model is kept in the .blend
    assert len(apply.find_collection().objects) == 16
    assert bpy.ops.vplace.clear_vpls() == {"FINISHED"}
    assert apply.find_collection() is None


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


@pytest.mark.parametrize("method", ["vplace", "rsm"])
def test_apply_with_each_layout_method(registered, method):
    scene = small_cornell()
    scene.vplace.method = method
    scene.vplace.cell_px = 8
    assert bpy.ops.vplace.apply() == {"FINISHED"}
    report = json.loads(scene.vplace.last_report)
    assert report["method"] == ("vplace+refit" if method == "vplace" else method)
    n = len(apply.find_collection().objects)
    assert (n == 16) if method == "vplace" else (0 < n <= 16)
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
