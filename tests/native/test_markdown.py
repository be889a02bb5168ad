"""vplace.markdown (the one table writer) and the main job's short report (vplace.job)."""

from __future__ import annotations

import json

from vplace import job as vjob
from vplace import markdown


def test_table_lines():
    assert markdown.table(["a", "b"], [[1, "x"], [2.5, None]]) == [
        "| a | b |",
        "|---|---|",
        "| 1 | x |",
        "| 2.5 | None |",
    ]
    assert markdown.table(["only"], []) == ["| only |", "|---|"]


def test_a_share_that_rounds_to_zero_has_no_minus_sign():
    assert markdown.percent(-0.003, signed=True) == "+0%"
    assert markdown.percent(-0.003) == "0%"
    assert markdown.percent(-0.04, signed=True) == "-4%"
    assert markdown.percent(0.456) == "46%"
    assert markdown.percent(0.456, signed=True) == "+46%"
    assert markdown.percent(0.0031, signed=True, digits=1) == "+0.3%"
    assert markdown.percent(-0.0004, signed=True, digits=1) == "+0.0%"
    assert markdown.percent(-0.0024, digits=1) == "-0.2%"
    assert markdown.percent(float("nan")) == "-"


def _report(**change) -> vjob.JobSummary:
    m = {"rmse": 0.1, "relative_mse": 0.2, "ssim": 0.9, "brightness": 1.0}
    metrics = {**m, **{f"{k}_direct_only": v / 2 for k, v in m.items()}}
    fields = dict(
        scene="box", triangles=12, lights=1, views=["c"], skipped_views={}, resolution=[32, 24],
        samples=4, capture_render_seconds=1.0, n_vpls=16, lights_written=16,
        emitter_lights_written=0, method="vplace+refit", alpha=1.0, iterations=3,
        profile="cosine", radius=0.01, seed=0, stage_seconds={"export scene": 0.5},
        evaluator=vjob.EvaluatorSummary(1000, 2000, 0.5, 2e6), metrics=metrics,
        reference=vjob.ReferenceInfo("a ground truth", 64, "c"),
    )  # fmt: skip
    return vjob.JobSummary(**{**fields, **change})


def test_job_report_rows():
    text = vjob.job_report(_report(baselines={"rsm": vjob.Baseline(_report().metrics, 1)}))
    assert text.startswith("# vplace report: box\n")
    assert "| export scene | 0.50 |" in text
    assert "Every image is scored against a ground truth." in text
    assert "| direct only | 0.05000 | 0.10000 | 0.4500 | 0.500 |" in text
    assert "| evaluator: direct + VPL indirect (vplace+refit) | 0.10000 |" in text
    assert "(rsm, same N)" in text and "EEVEE" not in text
    assert "Evaluator: 1000 shadow rays in 0.500 s = 2.00 M rays/s" in text
    assert "written as lights" not in text


def test_job_report_names_the_refits_view_weights():
    assert "weighed" not in vjob.job_report(_report())
    weighed = vjob.EvaluatorSummary(1000, 2000, 0.5, 2e6, refit_view_weights={"A": 1.0, "B": 1.0})
    assert "weighed" not in vjob.job_report(_report(evaluator=weighed))
    weighed.refit_view_weights = {"Main": 0.852, "Balcony": 2.388}
    assert (
        "The refit weighed each captured view's pixels by the inverse of its indirect light, "
        "so that a dim view's relative error counts as a bright one's: Main 0.85, Balcony "
        "2.39.\n" in vjob.job_report(_report(evaluator=weighed))
    )


def test_job_report_says_how_many_vpls_were_written():
    # The refit can leave VPLs with no power; they are not written, and the header says so.
    text = vjob.job_report(_report(lights_written=7))
    assert (
        "16 VPLs by vplace+refit (cosine, near-field radius 0.01 m); 7 written as lights, the "
        "other 9 carry no power (vplace+refit) and are not written\n" in text
    )


def test_job_report_says_when_the_vpls_size_follows_the_region_the_cameras_see():
    assert "region" not in vjob.job_report(_report(working_scale=8.7, bounds_diagonal=8.7))
    text = vjob.job_report(_report(working_scale=16.7, bounds_diagonal=1414.2))
    assert (
        "near-field radius 0.01 m); VPL sizes follow the region the cameras see (16.7 m), not "
        "the scene's bounds (1.41e+03 m across)\n" in text
    )


def test_job_report_and_panel_say_what_region_the_lights_were_laid_out_for():
    region = vjob.RegionSummary(4, [2.33, 4.02], 0.377, 0.498, 0.17)
    assert "coverage view" not in vjob.job_report(_report())
    text = vjob.job_report(_report(region=region))
    assert (
        "Region: 4 coverage views around 2 cameras (radius 2.33, 4.02 m); its surfaces seen: "
        "38% by the cameras, 50% with the coverage views (0.17 s to choose them; the "
        "collection 'vplace region' shows them).\n" in text
    )
    panel = vjob.PanelReport.from_json(json.dumps(_report(region=region).to_dict()))
    assert panel.region == region and panel.region.lines()[1].startswith("  its surfaces")
    one = vjob.RegionSummary(1, [0.9], 0.5, 0.6, 0.1).lines()[0]
    assert one == "Region: 1 coverage view around 1 camera (radius 0.9 m)"


def test_job_report_eevee_row():
    e = {"rmse": 0.1, "relative_mse": 0.2, "ssim": 0.9, "brightness": 1.0, "seconds": 2.0}
    text = vjob.job_report(_report(eevee={**e, "samples": 16, "world_volume_bake_seconds": 3}))
    assert "| EEVEE with the written lights (16 samples, 2.0 s; the world's probe volume " in text
    plain = vjob.job_report(_report(eevee={**e, "samples": 16}))
    assert "| EEVEE with the written lights (16 samples, 2.0 s) | 0.10000 |" in plain


def test_job_report_says_what_of_eevees_difference_is_blenders():
    e = {"rmse": 0.1, "relative_mse": 0.2, "ssim": 0.9, "brightness": 1.0, "seconds": 2.0}
    e["samples"] = 4
    close = vjob.job_report(_report(eevee={**e, "direct_brightness": 0.98}))
    assert "is 0.98x Cycles'." in close and "Blender's" not in close
    dark = {**e, "direct_brightness": 0.91}
    for part, (rmse, share) in {
        "direct": (0.02, 0.3),
        "vpl": (0.01, 0.1),
        "rest": (0.03, 0.6),
    }.items():
        dark[f"attribution_rmse_{part}"], dark[f"attribution_share_{part}"] = rmse, share
    text = vjob.job_report(_report(eevee=dark))
    assert "is 0.91x Cycles': this part of EEVEE's difference is Blender's, not vplace's." in text
    assert "EEVEE's VPL light against the evaluator's 0.0100 (+10%)" in text
    assert "the evaluator's own error 0.0300 (+60%)" in text
    # With stand-ins written, EEVEE's direct light is partly vplace's: the note says so.
    ours = vjob.job_report(_report(eevee=dark, portals_written=2, sun_written=True))
    assert "Blender's" not in ours
    assert (
        "this part of EEVEE's difference is not the VPLs' but how EEVEE lights the scene's lamps "
        "and vplace's 3 stand-in lights." in ours
    )
    assert "a SUN light for the world's sun; 2 sky portals" in ours


def test_job_report_says_how_much_of_eevees_error_is_at_emitters_the_camera_sees():
    e = {"rmse": 0.1, "relative_mse": 0.2, "ssim": 0.9, "brightness": 1.0, "seconds": 2.0}
    e["samples"] = 16
    for part in vjob.ATTRIBUTION_PARTS:
        e[f"attribution_rmse_{part}"], e[f"attribution_share_{part}"] = 0.01, 1 / 3
    before = vjob.job_report(_report(eevee=e))
    assert "(+33%)." in before and "see an emitter" not in before
    seen = {**e, "attribution_seen_pixels": 0.034, "attribution_seen_share": 0.8}
    text = vjob.job_report(_report(eevee=seen))
    assert (
        "; of EEVEE's squared error, 80% is its direct light in the 3.4% of pixels that see an "
        "emitter, the world or a lamp in a mirror (their edges and patterns, anti-aliased "
        "EEVEE's way: not light on surfaces)." in text
    )
    # A view that sees no emitter: nothing to say.
    none = vjob.job_report(_report(eevee={**seen, "attribution_seen_pixels": 0.0}))
    assert "see an emitter" not in none


def test_job_report_splits_eevees_direct_light_into_the_stand_ins_and_eevees_rendering():
    e = {"rmse": 0.1, "relative_mse": 0.2, "ssim": 0.9, "brightness": 1.0, "seconds": 2.0}
    e["samples"] = 16
    for part in vjob.ATTRIBUTION_PARTS:
        e[f"attribution_rmse_{part}"], e[f"attribution_share_{part}"] = 0.01, 0.25
    e["attribution_share_direct"] = 0.5
    before = vjob.job_report(_report(eevee=e))
    assert "stand-ins' own light" not in before
    text = vjob.job_report(_report(eevee={**e, "attribution_stand_in_share": 0.1}))
    assert (
        "; 10% is vplace's stand-ins' own light against Cycles' direct light (Cycles rendering "
        "them), 40% EEVEE's rendering of the lights." in text
    )


def test_job_report_says_where_the_vpl_powers_make_up_for_eevees_direct_light():
    assert "Match EEVEE's direct light" not in vjob.job_report(_report())
    text = vjob.job_report(_report(eevee_matched={"Camera": 0.034}))
    assert (
        "The VPL powers make up for EEVEE's direct light (Match EEVEE's direct light): its "
        "smooth shortfall against Cycles' direct light, in the captured views: Camera +3.4%."
    ) in text
    text = vjob.job_report(_report(eevee_matched={"Camera": 0.0031, "Left": -0.0004}))
    assert "in the captured views: Camera +0.3%, Left +0.0%." in text
