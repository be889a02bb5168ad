"""ui/properties.py: the panel's settings default to the job's defaults and round-trip into a
job."""

from __future__ import annotations

import dataclasses
import json

import bpy
import pytest

import addon
from addon.capture.views import ViewSet
from addon.job import Job, method_name
from addon.native import vplace


@pytest.fixture
def settings():
    addon.register()
    try:
        bpy.ops.wm.read_factory_settings(use_empty=True)
        yield bpy.context.scene.vplace
    finally:
        addon.unregister()


def test_defaults_are_the_jobs(settings):
    job = Job.from_settings(settings)
    assert dataclasses.replace(job, views=ViewSet()) == Job()  # every other field
    assert method_name(settings.method, settings.refit) == Job().method
    views, default = settings.view_set(), ViewSet()
    # The view set is the job's but for the frame range, which only the "frames" mode reads:
    # the panel offers Blender's default animation range in steps of 50.
    assert dataclasses.replace(views, frame_end=1, frame_step=1) == default
    assert (views.frame_start, views.frame_end, views.frame_step) == (1, 250, 50)


def test_settings_round_trip_into_a_job(settings, tmp_path):
    settings.vpl_budget, settings.capture_size, settings.samples, settings.seed = 64, 96, 8, 3
    settings.profile, settings.cell_px, settings.alpha, settings.iterations = "omni", 8, 0.5, 1
    settings.method, settings.refit, settings.feature_mode = "vplace", False, "all"
    settings.view_mode = "orbit"
    settings.orbit_count = 5
    job = Job.from_settings(settings, cache_dir=tmp_path)
    expected = Job(
        n_vpls=64,
        size=96,
        samples=8,
        seed=3,
        profile="omni",
        cell_px=8,
        alpha=0.5,
        iterations=1,
        method="vplace",
        feature_mode="all",
        views=settings.view_set(),
        cache_dir=tmp_path,
    )
    assert job == expected
    assert job.views.mode == "orbit" and job.views.orbit_count == 5
    job.validate()
    # The layout's part of the job is the library's LayoutSettings, field for field.
    layout_fields = {f.name for f in dataclasses.fields(vplace.job.LayoutSettings)}
    assert layout_fields <= {f.name for f in dataclasses.fields(job)}


def test_the_stored_report_reads_back_by_attribute(settings):
    assert vplace.job.PanelReport.from_json(settings.last_report) is None
    settings.last_report = json.dumps(
        {"n_vpls": 8, "profile": "cosine", "metrics": {"rmse": 0.1}, "stage_seconds": {"a": 1.0}}
    )
    report = vplace.job.PanelReport.from_json(settings.last_report)
    assert report is not None and report.n_vpls == 8 and report.fit is None
    assert report.metrics["rmse"] == 0.1 and report.stage_seconds == {"a": 1.0}
