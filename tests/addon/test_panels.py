"""The panel's draw() and the cancellation path of the modal operator, checked headlessly.

The bpy module has no window, so the panel cannot be shown; draw() runs here against a layout
that records what it is asked to draw."""

import json

import bpy
import numpy as np
import pytest
from blender_util import addon_cornell

from addon import job as pipeline
from addon.native import vplace
from addon.ui import panels as ui
from addon.writeback import apply


class Recorder:
    def __init__(self, log):
        self.log = log
        self.use_property_split = False

    def prop(self, data, name, **_kw):
        self.log.append(("prop", name))

    def operator(self, idname, **_kw):
        self.log.append(("operator", idname))

    def label(self, text="", **_kw):
        self.log.append(("label", text))

    def _child(self, *_a, **_kw):
        return Recorder(self.log)

    def template_list(self, *args, **_kw):
        self.log.append(("list", args[0]))

    row = column = box = grid_flow = _child


@pytest.fixture
def scene():
    with addon_cornell() as sc:
        sc.eevee.light_threshold = 1e-4  # EEVEE lets the box's lamp reach the whole box
        yield sc


def draw(scene, panel_class=ui.VPLACE_PT_main):
    log = []
    panel = type("Panel", (), {"layout": Recorder(log)})()
    panel_class.draw(panel, type("Ctx", (), {"scene": scene})())
    return log


def test_views_panel_shows_what_each_mode_needs(scene):
    wanted = {
        "active": set(),
        "cameras": {("list", "VPLACE_UL_cameras"), ("operator", "vplace.camera_add")},
        "frames": {("prop", "frame_start"), ("prop", "frame_end"), ("prop", "frame_step")},
        "orbit": {("prop", "orbit_count"), ("prop", "orbit_radius"), ("prop", "orbit_angle")},
    }
    for mode, items in wanted.items():
        scene.vplace.view_mode = mode
        log = draw(scene, ui.VPLACE_PT_views)
        assert ("prop", "view_mode") in log
        assert items <= set(log), (mode, log)


def test_panel_shows_settings_buttons_and_last_results(scene):
    log = draw(scene)
    props = {name for kind, name in log if kind == "prop"}
    assert {
        "vpl_budget",
        "cell_px",
        "alpha",
        "refit",
        "iterations",
        "capture_size",
        "samples",
        "profile",
        "feature_mode",
        "near_field",
    } <= props
    ops = [name for kind, name in log if kind == "operator"]
    assert ops == [
        "vplace.capture",
        "vplace.fit",
        "vplace.apply",
        "vplace.clear_vpls",
        "vplace.setup_eevee",
        "vplace.report",
        "vplace.bake_par2d",
    ]
    assert not [t for kind, t in log if kind == "label"]  # no results yet
    # Whether the captures give the lights the near-field gather differs between Blenders'
    # renders; lights with it ask for EEVEE's fast GI (test_eevee_setup). Here: without.
    scene.vplace.near_field = False
    assert bpy.ops.vplace.apply() == {"FINISHED"}
    labels = [t for kind, t in draw(scene) if kind == "label"]
    assert any(t.startswith("RMSE vs Cycles GI") for t in labels)
    assert any(t.startswith("R² ") for t in labels)
    assert any(t.startswith("capture Cornell camera (Cycles):") for t in labels)
    # The region the lights were laid out for (issue 20; also drawn in 'vplace region').
    assert any(t.startswith("Region: ") and "around 1 camera (radius" in t for t in labels)
    assert any(t.startswith("  its surfaces seen: ") for t in labels)
    assert "EEVEE will not show these lights right:" not in labels
    # The box's lamp casts soft shadows without jitter: the panel says it is EEVEE's, not ours.
    assert "EEVEE's own light, not vplace's:" in labels
    assert any(
        t.startswith("1 lamp(s) with soft shadows, no jitter (e.g. 'light')") for t in labels
    )
    # The blocks' faces' planes pass through the lamp: EEVEE darkens them, the panel says so.
    assert any(
        t.startswith("1 lamp(s) a surface's plane passes through (e.g. 'light')") for t in labels
    )
    # It names the remedy vplace has (the VPL powers made up for EEVEE's direct light) where
    # that is turned off; left to decide ("auto", the default), the remedy was offered already.
    remedy = "  'Match EEVEE's direct light' makes up for it"
    assert scene.vplace.match_eevee == "auto" and remedy not in labels
    scene.vplace.match_eevee = "off"
    assert remedy in [t for kind, t in draw(scene) if kind == "label"]
    scene.vplace.match_eevee = "on"
    assert remedy not in [t for kind, t in draw(scene) if kind == "label"]
    scene.objects["light"].data.use_shadow_jitter = True
    labels = [t for kind, t in draw(scene) if kind == "label"]
    assert not any(t.startswith("1 lamp(s) with soft shadows") for t in labels)
    assert "EEVEE's own light, not vplace's:" in labels  # the plane through the lamp stays
    scene.objects["light"].data.use_shadow = False  # a lamp without shadow is not darkened
    assert "EEVEE's own light, not vplace's:" not in [t for _, t in draw(scene)]
    scene.objects["light"].data.use_shadow = True
    apply.find_collection()[apply.CUT_LAMPS_KEY] = []
    assert "EEVEE's own light, not vplace's:" not in [t for _, t in draw(scene)]
    # A setting that would drop the VPLs' shadows is named in the panel.
    scene.eevee.use_shadows = False
    labels = [t for kind, t in draw(scene) if kind == "label"]
    assert "EEVEE will not show these lights right:" in labels
    assert "scene.eevee.use_shadows" in labels


def test_cancelled_compute_writes_nothing(scene):
    bpy.context.view_layer.update()
    job = pipeline.Job.from_settings(scene.vplace)
    timer = pipeline.StageTimer(log=lambda _line: None)
    prepared = pipeline.prepare(scene, job, timer)
    progress = vplace.Progress()
    progress.cancel()  # what Esc does in the modal operator
    with pytest.raises(vplace.CancelledError):
        pipeline.compute(prepared, job, timer, progress)
    assert apply.find_collection() is None


@pytest.mark.slow
def test_match_and_check_in_eevee_show_eevees_direct_light_and_whose_part_its_difference_is():
    with addon_cornell(
        capture_size=48, samples=64, vpl_budget=64, check_eevee=True, match_eevee="on"
    ) as scene:
        scene.eevee.light_threshold = 1e-4
        before = (scene.render.engine, scene.render.resolution_x, scene.render.film_transparent)
        assert bpy.ops.vplace.apply() == {"FINISHED"}
        assert (scene.render.engine, scene.render.resolution_x, scene.render.film_transparent) == (
            before
        )
        e = json.loads(scene.vplace.last_report)["eevee"]
        assert 0.5 < e["ssim"] <= 1.0
        shares = [e[f"attribution_share_{p}"] for p in vplace.job.ATTRIBUTION_PARTS]
        assert sum(shares) == pytest.approx(1.0, abs=1e-6)
        # The box's lamp is the user's: vplace wrote no stand-in light, so the stand-ins' own
        # light is Cycles' direct light again, and holds next to nothing of EEVEE's error.
        assert abs(e["attribution_stand_in_share"]) < 0.05
        labels = [t for kind, t in draw(scene) if kind == "label"]
        assert any(t.startswith("EEVEE: SSIM ") for t in labels)
        # "Match EEVEE's direct light" rendered it first, judged whether it helps, and says
        # which: by how much it differs where it was kept, the figures where it was left out.
        choice = json.loads(scene.vplace.last_report)["eevee_match"]
        matched = any(t.startswith("Matched EEVEE's direct light: Cornell camera ") for t in labels)
        left_out = "Match EEVEE's direct light left out: it would not help here" in labels
        assert (matched, left_out) == (choice["kept"], not choice["kept"])
        assert any(t.endswith("EEVEE's rendering (not vplace's)") for t in labels)


def test_panel_names_the_objects_the_vpls_do_not_light(scene):
    assert bpy.ops.vplace.apply() == {"FINISHED"}
    assert "Not lit by the VPLs (Light Linking):" not in [t for _, t in draw(scene)]
    vpls = vplace.VplSet(
        np.zeros((1, 3), np.float32), np.array([[0, 0, 1]], np.float32), np.ones((1, 3), np.float32)
    )
    apply.write_vpls(scene, vpls, scene_diagonal=3.0, specular=1.0, unlit=["tallBox", "shortBox"])
    labels = [t for kind, t in draw(scene) if kind == "label"]
    assert "Not lit by the VPLs (Light Linking):" in labels
    assert "  'shortBox' and 1 more: sharp metal or glass," in labels


@pytest.mark.parametrize(
    "stored",
    [
        {"n_vpls": 4, "profile": "cosine", "fit": {"r2": 0.5, "kept": []}},  # an older fit
        {"n_vpls": 4, "fit": {"r2": 0.5, "cv_rmse": 1.0}},  # a newer one
        {"n_vpls": 4, "metrics": {"rmse": 0.1}},  # a metric missing
        {"n_vpls": 4, "eevee_match": {"kept": False}},
        {"n_vpls": 4, "stage_seconds": {"capture": None}},
        [1, 2],
    ],
)
def test_a_report_of_another_vplace_is_said_not_raised_at_each_redraw(scene, stored):
    scene.vplace.last_report = json.dumps(stored)
    labels = [text for kind, text in draw(scene) if kind == "label"]
    assert "The last run's report is of another vplace: run again" in labels
    scene.vplace.last_report = "not json"
    labels = [text for kind, text in draw(scene) if kind == "label"]
    assert "The last run's report is of another vplace: run again" in labels


def test_a_run_writes_nothing_when_the_scene_changed_while_it_worked(scene):
    """The lights go to the scene that was captured, or nowhere (a script switched scenes)."""
    from addon.ui import modal

    class Job(modal.BackgroundOperator):
        def __init__(self):
            self.said, self.written = [], None

        def report(self, _kind, message):
            self.said.append(message)

        def start(self, context):
            pass

        def work(self, _progress):
            return 1

        def finish(self, context, _result):
            self.written = context.scene
            return {"FINISHED"}

    other = bpy.data.scenes.new("Other")
    job = Job()
    job._start(type("Ctx", (), {"scene": scene})())
    assert job._finish(type("Ctx", (), {"scene": other})(), 1) == {"CANCELLED"}
    assert job.written is None and "the scene changed from" in job.said[0]
    assert job._finish(type("Ctx", (), {"scene": scene})(), 1) == {"FINISHED"}
    assert job.written == scene
