"""The speed-against-error report: one tiny run of the Cornell .blend through every stage (fit
views, a held-out view, the evaluator, EEVEE and the alternatives), the target and break-even
arithmetic, and configuration errors."""

import csv
import json
import math
from dataclasses import replace

import bpy
import mathutils
import numpy as np
import pytest

from addon.errors import ReportError
from addon.native import vplace
from addon.report import runs as report
from addon.report import summary
from addon.report.config import CAPTURE_CURVE, RELAYOUT, WITH_RT, ReportConfig, Row, RowDetails
from addon.scenes import registry as default_scene
from addon.writeback import apply

FIT = ["Cornell camera", "Cornell camera left"]
HELD_OUT = [default_scene.CORNELL_HELD_OUT_CAMERA]
EVAL_METHODS = {"uniform", "rsm", "vplace", "vplace+refit"}


def tiny(**change):
    """A report on the Cornell .blend that every stage runs through in a couple of minutes."""
    config = {
        "blend": default_scene.builtin_scene("cornell"),
        "fit_cameras": FIT,
        "held_out_cameras": HELD_OUT,
        "budgets": [8, 16],
        "resolution": (32, 32),
        "capture_samples": 8,
        "truth_samples": 32,
        "cycles_samples": [1, 4],
        "seeds": [0, 1],
        "eevee_methods": ["uniform", "vplace+refit"],
        "volume_resolution": 2,
        "eevee_samples": 4,
        "capture_curve": [4, 8],
        "par2d": False,
    }
    return ReportConfig(**{**config, **change})


@pytest.fixture(scope="module")
def tiny_report(tmp_path_factory):
    out = tmp_path_factory.mktemp("report")
    blend = default_scene.builtin_scene("cornell")
    mtime = blend.stat().st_mtime_ns
    lines: list[str] = []
    result = report.run_report(tiny(), out, log=lines.append)
    return out, result, lines, blend, mtime


def _rows(result, **match):
    return [r for r in result["rows"] if all(r[k] == v for k, v in match.items())]


@pytest.mark.slow
def test_one_set_of_lights_is_scored_on_fit_and_held_out_views(tiny_report):
    _, result, lines, _, _ = tiny_report
    views = {(r["view"], r["role"]) for r in result["rows"]}
    assert views == {(v, "fit") for v in FIT} | {(v, "held-out") for v in HELD_OUT}
    for view, role in views:
        evaluated = _rows(result, view=view, renderer="evaluator")
        methods = {(r["method"], r["n_vpls"]) for r in evaluated}
        expected = {(m, n) for m in EVAL_METHODS for n in (8, 16)}
        if role == "held-out":  # the same lights, and the per-view re-layout as its own row
            expected |= {(RELAYOUT, 8), (RELAYOUT, 16)}
        expected.add((CAPTURE_CURVE, 16))  # the grid budget from captures at 4 and 8 spp
        assert methods == expected
        curve = [r for r in evaluated if r["method"] == CAPTURE_CURVE]
        assert sorted((r["samples"], r["seed"]) for r in curve) == [(4, 0), (4, 1), (8, 0), (8, 1)]
        assert all(r["one_time_seconds"] >= r["extra"]["capture_seconds"] > 0 for r in curve)
        for r in evaluated:
            assert np.isfinite([r["rmse"], r["relative_mse"], r["ssim"], r["brightness"]]).all()
            assert r["shadow_rays"] > 0 and r["frame_seconds"] > 0.0
        # The VPLs add light the direct image lacks: every method beats direct only in RMSE, on
        # the mean over seeds (one seed of 16 VPLs may put one close to a wall: a bright spot).
        direct = _rows(result, view=view, method="direct")[0]
        means = [m for m in result["means"] if m["view"] == view and m["renderer"] == "evaluator"]
        assert all(m["rmse"] < direct["rmse"] for m in means if m["n_vpls"] == 16)
    # One layout for all views: a method's one-time cost and its lights do not depend on the view.
    for method in ("uniform", "vplace+refit"):
        costs = {r["one_time_seconds"] for r in _rows(result, method=method, n_vpls=16, seed=0)}
        assert len(costs) == 1
    refit = _rows(result, method="vplace+refit", renderer="evaluator")
    assert all(r["extra"]["refit_error_after"] <= r["extra"]["refit_error_before"] for r in refit)
    assert any("report written" in line for line in lines)
    # Two seeds for the stochastic layouts, one run of the deterministic RSM; means per group.
    fit_rows = _rows(result, view=FIT[0], renderer="evaluator", n_vpls=8)
    assert sorted(r["seed"] for r in fit_rows if r["method"] == "uniform") == [0, 1]
    assert [r["seed"] for r in fit_rows if r["method"] == "rsm"] == [None]
    means = {(m["view"], m["method"], m["renderer"], m["n_vpls"]): m for m in result["means"]}
    mean = means[(FIT[0], "uniform", "evaluator", 8)]
    runs = [r["ssim"] for r in fit_rows if r["method"] == "uniform"]
    assert mean["ssim"] == pytest.approx(np.mean(runs)) and mean["extra"]["seeds"] == 2
    assert mean["extra"]["ssim_std"] == pytest.approx(np.std(runs))
    assert mean["extra"]["by_seed"]["1"]["ssim"] == pytest.approx(runs[1])


@pytest.mark.slow
def test_eevee_and_the_alternatives_are_scored_on_every_view(tiny_report):
    _, result, _, _, _ = tiny_report
    for view in FIT + HELD_OUT:
        shown = {
            (r["method"], r["samples"]): r
            for r in result["rows"]
            if r["view"] == view and r["renderer"] in ("eevee", "cycles")
        }
        assert set(shown) == {
            ("uniform", 4),
            ("vplace+refit", 4),
            ("vplace+refit" + WITH_RT, 4),
            ("eevee", 4),
            ("eevee rt", 4),
            ("eevee rt + volume", 4),
            ("cycles+oidn", 1),
            ("cycles+oidn", 4),
        }
        for (method, _), r in shown.items():
            assert np.isfinite([r["rmse"], r["ssim"], r["brightness"]]).all()
            assert r["frame_seconds"] > 0.0
            # The EEVEE rows of VPL methods render the first seed's grid-budget lights.
            with_vpls = method.startswith(("uniform", "vplace"))
            assert (r["n_vpls"], r["seed"]) == ((16, 0) if with_vpls else (None, None))
        # The VPLs add the bounce light plain EEVEE lacks.
        assert shown[("vplace+refit", 4)]["brightness"] > shown[("eevee", 4)]["brightness"]
        # The bake is a one-time cost of the volume's row, never of a frame.
        volume = shown[("eevee rt + volume", 4)]
        assert volume["one_time_seconds"] == volume["extra"]["bake_seconds"] > 0.0
        assert shown[("cycles+oidn", 1)]["one_time_seconds"] == 0.0
        # Every EEVEE image of written lights is attributed, and only those.
        for (method, _), r in shown.items():
            a = r["extra"].get("attribution")
            assert (a is not None) == (method in ("uniform", "vplace+refit")), method
            if a is not None:
                assert sum(a["share"].values()) == pytest.approx(1.0)
                assert all(v >= 0.0 for v in a["rmse"].values())
                assert 0.3 < a["direct_brightness"] < 3.0 and a["vpl_brightness"] > 0.0
    checks = {c["check"] for c in result["targets"]}
    assert any("EEVEE with the VPLs within 0.02 SSIM of the evaluator" in c for c in checks)
    assert any("held out" in c and "relative MSE below direct" in c for c in checks)
    assert {b["view"] for b in result["break_even"]} == set(FIT + HELD_OUT)
    for b in result["break_even"]:
        assert b["note"] and b["eevee_frame_seconds"] > 0.0


@pytest.mark.slow
def test_tiny_report_writes_csv_json_plots_and_markdown(tiny_report):
    out, result, _, _, _ = tiny_report
    with (out / "results.csv").open() as f:
        table = list(csv.DictReader(f))
    assert len(table) == len(result["rows"])
    assert {r["renderer"] for r in table} == {"evaluator", "eevee", "cycles", "reference"}
    assert json.loads((out / "results.json").read_text())["rows"] == result["rows"]
    pngs = sorted(p.name for p in out.glob("*.png"))
    assert "error_vs_vpls.png" in pngs
    prefixes = ("error_vs_time_cornell_", "grid_cornell_", "eevee_cornell_", "vpl_difference_")
    for prefix in prefixes:
        assert sum(n.startswith(prefix) for n in pngs) == 3, prefix
    for name in pngs:
        assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    md = (out / "report.md").read_text()
    # The two fit cameras and the region's coverage views, rendered and fitted beside them.
    (scene,) = result["scenes"].values()
    fitted = list(scene["fit"]["view_r2"])
    assert fitted[:2] == FIT and len(fitted) > 2
    assert all(v.startswith(vplace.coverage.RENDERED_PREFIX) for v in fitted[2:]), fitted
    assert f"Fit over {len(fitted)} views" in md and "ground truth 32 spp" in md
    assert f"| {RELAYOUT} |" in md and "## Break-even" in md and "## Targets" in md
    assert "evaluator, same lights" in md and "Capture samples against layout quality" in md
    assert "(b) VPL light" in md and "vpl_difference_cornell_" in md
    assert "The written VPLs' specular factor: 0." in md  # the Cornell box has no glossy layer
    # Every view's truth was rendered twice: each image is also scored against the noise-free
    # truth, and each view states the ceiling its truth's noise puts on SSIM.
    assert all(np.isfinite(float(r["ssim_noise_free"])) for r in table)
    assert all(float(r["rmse_noise_free"]) >= 0.0 for r in table)
    for view, info in scene["views"].items():
        noise = info["truth_noise"]
        assert 0.0 < noise["truths_ssim"] < noise["ceiling"] <= 1.0, view
    assert md.count("The truth's own noise") == 3 and "SSIM, noise-free truth" in md
    # A view whose two renders agree below NOISY_TRUTH says that the estimate reads low there.
    noisy = [
        v
        for v, i in scene["views"].items()
        if i["truth_noise"]["truths_ssim"] < summary.NOISY_TRUTH
    ]
    assert md.count("here the noise-free estimate itself reads low") == len(noisy)
    assert any("(noise-free truth)" in c["check"] for c in result["targets"])


@pytest.mark.slow
def test_report_leaves_the_blend_untouched_and_reuses_cached_renders(tiny_report, tmp_path):
    out, result, _, blend, mtime = tiny_report
    assert blend.stat().st_mtime_ns == mtime
    assert bpy.context.scene.camera.name == "Cornell camera"  # the other views were temporary
    assert apply.find_collection() is None
    assert not [o for o in bpy.data.objects if o.type == "LIGHT_PROBE"]
    cached = sorted(p.name for p in (out / "cache").iterdir())
    # What the cost check times is rendered on every run: the cache holds the truths (32 spp),
    # never a capture of the layout (8 spp, or the curve's 4) nor a Cycles + OIDN frame.
    spp = {int(np.load(out / "cache" / n)["samples"]) for n in cached if n.startswith("capture-")}
    assert spp == {32}
    kept = {float(np.load(out / "cache" / n)["seconds"]) for n in cached if n.startswith("render-")}
    eevee_frames = {r["frame_seconds"] for r in result["rows"] if r["renderer"] == "eevee"}
    cycles_frames = {r["frame_seconds"] for r in result["rows"] if r["renderer"] == "cycles"}
    assert eevee_frames & kept and cycles_frames and not cycles_frames & kept
    second = report.run_report(
        tiny(
            methods=["uniform"],
            budgets=[8],
            capture_curve=[],
            with_eevee=False,
            cache_dir=out / "cache",
        ),
        tmp_path,
        log=lambda _line: None,
    )
    assert sorted(p.name for p in (out / "cache").iterdir()) == cached
    assert second["seconds"] < result["seconds"]
    first = [r for r in result["rows"] if r["renderer"] in ("evaluator", "reference")]
    first = [r for r in first if r["method"] in ("uniform", "direct") and r["n_vpls"] in (None, 8)]
    assert [(r["view"], r["method"], r["seed"], r["rmse"], r["ssim"]) for r in first] == [
        (r["view"], r["method"], r["seed"], r["rmse"], r["ssim"]) for r in second["rows"]
    ]


def _row(view, method, n, ssim, rmse=0.1, renderer="evaluator", role="fit", samples=None, **kw):
    fields = {
        "relative_mse": 0.0,
        "brightness": 1.0,
        "one_time_seconds": 0.0,
        "frame_seconds": 0.0,
        **kw,
    }
    return Row("s", view, role, method, renderer, n, samples, rmse=rmse, ssim=ssim, **fields)


def test_targets_are_checked_against_the_noise_free_truth_as_well():
    # The held-out view's truth is noisier: against it, the view misses the spread; against
    # the noise-free truth (both views' images scored without the truths' noise) it holds.
    rows = [
        _row("A", "uniform", 256, 0.70, ssim_noise_free=0.85),
        _row("A", "vplace+refit", 256, 0.78, ssim_noise_free=0.95),
        _row("H", "uniform", 256, 0.50, role="held-out", ssim_noise_free=0.78),
        _row("H", "vplace+refit", 256, 0.58, role="held-out", ssim_noise_free=0.93),
    ]
    checks = {c["check"]: c for c in summary.targets(rows)}
    plain = checks["s H (held out) N=256: within 0.03 SSIM of the fit views' mean"]
    assert not plain["met"] and plain["value"] == pytest.approx(0.20)
    free = checks[
        "s H (held out) N=256: within 0.03 SSIM of the fit views' mean (noise-free truth)"
    ]
    assert free["met"] and free["value"] == pytest.approx(0.02)
    fit = checks["s N=256: the fit views reach SSIM 0.9 (noise-free truth)"]
    assert fit["met"] and fit["value"] == pytest.approx(0.95)
    assert checks["s H (held-out) N=256: not below uniform (noise-free truth)"]["met"]
    # Rows without a second truth render get no such check.
    bare = summary.targets([replace(r, ssim_noise_free=math.nan) for r in rows])
    assert not any("noise-free" in c["check"] for c in bare)


def test_held_out_checks_say_whether_the_view_stands_inside_the_region():
    # Issue 20's bound is for the views a camera in the region can take: the report's checks
    # name each held-out view's place, so a miss outside the region reads as one.
    rows = [
        _row("A", "vplace+refit", 256, 0.95),
        _row("H", "vplace+refit", 256, 0.93, role="held-out"),
        _row("O", "vplace+refit", 256, 0.90, role="held-out"),
    ]
    checks = {c["check"]: c for c in summary.targets(rows, {"s": {"H": True, "O": False}})}
    spread = "N=256: within 0.03 SSIM of the fit views' mean"
    inside = checks[f"s H (held out, inside the region) {spread}"]
    outside = checks[f"s O (held out, outside the region) {spread}"]
    assert inside["met"] and not outside["met"]
    assert not any(c.startswith("s H (held out) ") for c in checks)
    # Without the regions (rows alone) the names stay as they were.
    assert f"s O (held out) {spread}" in {c["check"] for c in summary.targets(rows)}


def test_the_report_passes_each_held_out_views_place_to_its_checks():
    info = {
        "s": {
            "views": {
                "A": {"role": "fit"},
                "H": {"role": "held-out", "region": {"inside": True}},
                "O": {"role": "held-out", "region": {"inside": False}},
            }
        },
        "t": {"views": {}},
    }
    assert report._inside(info) == {"s": {"H": True, "O": False}, "t": {}}


def test_a_view_with_a_noisy_truth_says_its_noise_free_estimate_reads_low():
    # The noise-free estimate reads low where the two truth renders agree below NOISY_TRUTH
    # (ARCHITECTURE); the view's section says so there, and only there.
    rows = [_row("A", "vplace+refit", 256, 0.78, ssim_noise_free=0.95)]
    caution = "here the noise-free estimate itself reads low"
    for agree, said in ((0.46, True), (summary.NOISY_TRUTH - 0.01, True), (0.9, False)):
        lines = summary._noise_lines(rows, {"truths_ssim": agree, "ceiling": 0.95}, [256])
        assert (caution in " ".join(lines)) is said, agree
    assert summary._noise_lines(rows, {}, [256]) == []


def test_break_even_compares_against_the_noise_free_truth_where_it_can():
    # Against the noisy truth 4 spp seems to reach EEVEE's SSIM; against the noise-free truth
    # it takes 16 spp, a dearer frame.
    def cycles(spp, ssim, free, seconds):
        return _row("A", "cycles+oidn", None, ssim, renderer="cycles", samples=spp,
                    ssim_noise_free=free, frame_seconds=seconds)  # fmt: skip

    eevee = _row("A", "vplace+refit", 16, 0.75, renderer="eevee", ssim_noise_free=0.95,
                 one_time_seconds=10.0, frame_seconds=1.0)  # fmt: skip
    rows = [eevee, cycles(4, 0.76, 0.93, 2.0), cycles(16, 0.77, 0.96, 3.0)]
    (found,) = summary.break_even(rows)
    assert found["noise_free"] and found["cycles_samples"] == 16
    assert found["eevee_ssim"] == 0.95 and found["frames"] == 5
    # Without the second truth render: against the truth, as before.
    bare = [replace(r, ssim_noise_free=math.nan) for r in rows]
    (found,) = summary.break_even(bare)
    assert not found["noise_free"] and found["cycles_samples"] == 4 and found["frames"] == 10


def test_targets_compare_held_out_views_with_the_fit_mean_and_eevee_with_the_same_lights():
    rows = [
        _row("A", "uniform", 256, 0.80),
        _row("A", "rsm", 256, 0.84),
        _row("A", "vplace+refit", 256, 0.92, details=RowDetails(by_seed={"0": {"ssim": 0.95}})),
        _row("B", "vplace+refit", 256, 0.90),
        _row("H", "uniform", 256, 0.70, role="held-out", relative_mse=0.2),
        _row("H", "vplace+refit", 256, 0.86, role="held-out", relative_mse=0.1),
        _row("H", "direct", None, 0.5, renderer="reference", role="held-out", relative_mse=0.3),
        _row(
            "A",
            "vplace+refit",
            256,
            0.94,
            renderer="eevee",
            seed=0,
            brightness=1.05,
            hot_pixels=0.0,
        ),
    ]
    checks = {c["check"]: c for c in summary.targets(rows)}
    fit = checks["s N=256: the fit views reach SSIM 0.9"]
    assert fit["met"] and fit["value"] == pytest.approx(0.91)
    spread = checks["s H (held out) N=256: within 0.03 SSIM of the fit views' mean"]
    assert not spread["met"] and spread["value"] == pytest.approx(0.05)
    assert checks["s A (fit) N=256: vplace+refit SSIM >= uniform + 0.05"]["met"]
    vs_rsm = checks["s A (fit) N=256: vplace+refit SSIM >= rsm + 0.05"]
    assert vs_rsm["met"] and vs_rsm["value"] == pytest.approx(0.08)
    assert checks["s H (held-out) N=256: not below uniform"]["met"]
    assert checks["s H (held out) N=256: relative MSE below direct light's"]["met"]
    # EEVEE rendered seed 0's lights: compared with that seed's evaluator image, not the mean.
    same = checks[
        "s A (fit): EEVEE with the VPLs within 0.02 SSIM of the evaluator (the same lights)"
    ]
    assert same["met"] and same["value"] == pytest.approx(0.01)
    bright = checks["s A (fit): EEVEE with the VPLs within 3% of the truth's brightness"]
    assert not bright["met"] and bright["value"] == pytest.approx(0.05)
    # EEVEE's RMSE (0.1) against seed 0's evaluator RMSE (the row's, 0.1 by default here).
    assert checks["s A (fit): EEVEE's RMSE at most 1.25x the evaluator's (the same lights)"]["met"]
    hot = checks["s A (fit): EEVEE's hot-spot pixels at most 0.1%"]
    assert hot["met"] and hot["value"] == 0.0
    # Against EEVEE's own GI: the scored set-up as it is, and like for like, the set-up vplace
    # applies (ray tracing on) where the report rendered it.
    own_gi = _row("A", "eevee rt + volume", None, 0.86, renderer="eevee")
    traced = _row("A", "vplace+refit" + WITH_RT, 256, 0.92, renderer="eevee", seed=0)
    plain = "s A (fit): EEVEE with the VPLs >= EEVEE ray tracing + volume + 0.05"
    like = (
        "s A (fit): EEVEE with the VPLs and ray tracing (the set-up vplace applies) >= EEVEE "
        "ray tracing + volume + 0.05"
    )
    assert like not in checks_of([*rows, own_gi], None)
    both = checks_of([*rows, own_gi, traced], None)
    assert both[plain]["met"] and both[plain]["value"] == pytest.approx(0.08)
    assert both[like]["met"] and both[like]["value"] == pytest.approx(0.06)
    traced.ssim = 0.90
    assert not checks_of([*rows, own_gi, traced], like)["met"]
    # An attributed EEVEE row: each miss says whose part of the error it is.
    a = {
        "rmse": {"direct": 0.2, "vpl": 0.01, "rest": 0.1},
        "share": {"direct": 0.8, "vpl": 0.05, "rest": 0.15},
        "ssim_cycles_direct": 0.93,
        "ssim_evaluator_vpl": 0.80,
    }
    rows[-1] = _row("A", "vplace+refit", 256, 0.80, rmse=0.3, renderer="eevee", seed=0,
                    hot_pixels=0.0, details=RowDetails(attribution=a))  # fmt: skip
    checks = {c["check"]: c for c in summary.targets(rows)}
    rmse = checks["s A (fit): EEVEE's RMSE at most 1.25x the evaluator's (the same lights)"]
    assert not rmse["met"]
    assert (
        "80% is EEVEE's direct light against Cycles' (the scene's lamps and vplace's stand-ins, "
        "not the VPLs)" in rmse["detail"]
    )
    gap = checks[
        "s A (fit): EEVEE with the VPLs within 0.02 SSIM of the evaluator (the same lights)"
    ]
    assert (
        not gap["met"]
        and "with Cycles' direct light under EEVEE's VPL light 0.9300" in gap["detail"]
    )
    # Brightness: EEVEE's direct light is the one vplace renders (its stand-ins, VPLs hidden),
    # not EEVEE without vplace (which lights a sky-lit room with the whole world, 1.8x).
    rows += [
        _row("A", "eevee", None, 0.4, renderer="eevee", brightness=1.8 * 0.5),
        _row("A", "direct", None, 0.6, renderer="reference", brightness=0.5),
    ]
    bright = checks_of(rows, "s A (fit): EEVEE with the VPLs within 3% of the truth's brightness")
    assert "without vplace is 1.800x Cycles' direct light" in bright["detail"]
    rows[-3].details.attribution["direct_brightness"] = 0.95
    bright = checks_of(rows, "s A (fit): EEVEE with the VPLs within 3% of the truth's brightness")
    assert bright["detail"].endswith("EEVEE's direct light (VPLs hidden) is 0.950x Cycles'")
    # With Cycles' rendering of the same lights, (a) is split: vplace's stand-ins against EEVEE.
    a["stand_in_share"] = 0.3
    rmse = checks_of(
        rows, "s A (fit): EEVEE's RMSE at most 1.25x the evaluator's (the same lights)"
    )
    assert (
        "(of it, 30% the stand-ins' own light as Cycles renders it, 50% EEVEE's rendering of "
        "the lights)" in rmse["detail"]
    )
    assert summary._stand_in_cell(a) == "+30% / +50%"
    assert summary._stand_in_cell({**a, "stand_in_share": float("nan")}) == "-"
    # The hot-spot check says which swap takes its hot pixels away (none before the swaps).
    name = "s A (fit): EEVEE's hot-spot pixels at most 0.1%"
    assert "Cycles' direct light under" not in checks_of(rows, name)["detail"]
    a.update(hot_cycles_direct=0.0001, hot_evaluator_vpl=0.002)
    assert checks_of(rows, name)["detail"].endswith(
        "; with Cycles' direct light under EEVEE's VPL light 0.010%, with the evaluator's VPL "
        "light over EEVEE's direct light 0.200%"
    )


def checks_of(rows, name):
    """The check ``name`` of ``rows``' targets; with ``name`` None, every check by name."""
    checks = {c["check"]: c for c in summary.targets(rows)}
    return checks if name is None else checks[name]


def test_break_even_counts_frames_until_the_one_time_cost_is_paid():
    eevee = {"renderer": "eevee", "one_time_seconds": 100.0}
    ours = _row("A", "vplace+refit", 256, 0.90, frame_seconds=1.0, **eevee)
    cycles = [
        _row("A", "cycles+oidn", None, s, renderer="cycles", samples=spp, frame_seconds=t)
        for spp, s, t in ((4, 0.85, 2.0), (16, 0.91, 6.0), (64, 0.95, 20.0))
    ]
    (entry,) = summary.break_even([ours, *cycles])
    # 16 spp is the fewest that reach 0.90; each frame saves 5 s, so 100 s pay off after 20.
    assert entry["cycles_samples"] == 16 and entry["frames"] == 20
    slow = _row("A", "vplace+refit", 256, 0.90, frame_seconds=7.0, **eevee)
    assert summary.break_even([slow, *cycles])[0]["frames"] is None
    better = _row("A", "vplace+refit", 256, 0.99, frame_seconds=1.0, **eevee)
    (entry,) = summary.break_even([better, *cycles])
    assert entry["cycles_samples"] is None and "fewer than 6 frames" in entry["note"]


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"methods": ["magic"]}, "unknown methods"),
        ({"budgets": [0, 8]}, "positive"),
        ({"budgets": []}, "positive"),
        ({"blend": None, "scenes": ["attic"]}, "unknown scenes"),
        ({"cycles_samples": [0]}, "at least 1"),
        ({"budgets": [100000]}, "not supported"),
        ({"alternatives": ["magic"]}, "unknown alternatives"),
        ({"eevee_methods": ["magic"]}, "unknown EEVEE methods"),
        ({"blend": "/nonexistent/scene.blend"}, "no such .blend"),
        ({"fit_cameras": []}, "needs --fit-cameras"),
        ({"volume_resolution": 0}, "at least 1 probe"),
        ({"capture_curve": [0]}, "at least 1"),
        ({"feature_mode": "magic"}, "feature mode"),
    ],
)
def test_bad_configuration_is_a_clear_error(change, message, tmp_path):
    with pytest.raises(ReportError, match=message):
        report.run_report(tiny(**change), tmp_path)
    assert not (tmp_path / "results.csv").exists()


def test_eevee_views_keeps_the_named_views_and_refuses_names_of_no_view(tmp_path):
    from types import SimpleNamespace

    data = SimpleNamespace(views=[SimpleNamespace(name=n) for n in ("Main", "West", "made 1")])
    every = report.eevee_views(data, tiny())
    assert [v.name for v in every] == ["Main", "West", "made 1"]
    # In the scene's order; a name of another scene's view is no error while one matches.
    chosen = report.eevee_views(data, tiny(eevee_views=["made 1", "Main", "Balcony"]))
    assert [v.name for v in chosen] == ["Main", "made 1"]
    with pytest.raises(ReportError, match=r"none of the EEVEE views .* 'Main', 'West', 'made 1'"):
        report.eevee_views(data, tiny(eevee_views=["Balcony"]))
    # A report fails on such a name once the scene's views are known, before any layout.
    lines: list[str] = []
    with pytest.raises(ReportError, match="none of the EEVEE views"):
        report.run_report(tiny(eevee_views=["No such view"]), tmp_path, log=lines.append)
    assert not any("fitted on" in line for line in lines)
    assert not (tmp_path / "results.csv").exists()
    assert summary._eevee_views_note({"config": {"eevee_views": []}}) == ""
    assert "'Main'" in summary._eevee_views_note({"config": {"eevee_views": ["Main"]}})


def test_camera_view_restores_the_camera_and_refuses_unknown_names():
    from blender_util import cornell

    scene = cornell()
    before = scene.camera
    other = bpy.data.objects.new("Other camera", bpy.data.cameras.new("Other camera"))
    scene.collection.objects.link(other)
    with pytest.raises(RuntimeError), report.camera_view(scene, "Other camera"):
        assert scene.camera == other
        raise RuntimeError("render failed")
    assert scene.camera == before
    with pytest.raises(ReportError, match="no camera object"), report.camera_view(scene, "Nope"):
        pass


def test_every_built_in_scene_is_captured_at_the_main_jobs_samples():
    """The report scores the lights a user gets and the one-time cost a user pays: each
    built-in scene's fit views are captured at ``Job.samples`` (Sponza was at 128 and the
    Cornell box at 256, eight and sixteen times a user's capture)."""
    from addon.job import Job
    from addon.report.config import PRESETS

    presets = ReportConfig(scenes=tuple(PRESETS)).presets()
    assert {p.name for p in presets} == set(PRESETS)
    assert all(p.capture_samples == Job.samples for p in presets), [
        (p.name, p.capture_samples) for p in presets
    ]


def test_a_blend_is_named_after_its_file_and_captured_at_the_main_jobs_samples(tmp_path):
    """``report --blend`` captures at the spp the demo and the panel capture at (one default,
    ``Job.samples``), and calls the scene by its file's name."""
    import addon
    from addon.cli import parse_args
    from addon.job import Job

    blend = tmp_path / "my_room.blend"
    (preset,) = ReportConfig(blend=blend, fit_cameras=["Camera"]).presets()
    assert preset.name == "my_room" and preset.capture_samples == Job.samples
    demo = parse_args(["demo"])
    assert demo.samples == Job.samples
    addon.register()
    try:
        assert bpy.context.scene.vplace.samples == Job.samples
    finally:
        addon.unregister()


def test_the_one_time_cost_is_checked_against_two_cycles_frames_per_camera():
    rows = [
        _row("A", "vplace+refit", 256, 0.9, one_time_seconds=6.0),
        _row("B", "vplace+refit", 256, 0.9, one_time_seconds=6.0),
        _row("A", "cycles+oidn", None, 0.8, renderer="cycles", samples=16, frame_seconds=1.0),
        _row("B", "cycles+oidn", None, 0.8, renderer="cycles", samples=16, frame_seconds=2.0),
        _row("A", "cycles+oidn", None, 0.7, renderer="cycles", samples=4, frame_seconds=0.1),
    ]
    name = "s N=256: one-time cost per camera at most 2 Cycles + OIDN 16 spp frames"
    cost = {c["check"]: c for c in summary.targets(rows)}[name]
    # 6 s for two cameras: 3 s a camera, against 2 x 1.5 s.
    assert cost["met"] and cost["value"] == pytest.approx(2.0)
    assert "Match EEVEE" not in cost["detail"]
    rows[0] = _row("A", "vplace+refit", 256, 0.9, one_time_seconds=6.2)
    assert not {c["check"]: c for c in summary.targets(rows)}[name]["met"]
    # Where the match ran, the detail says how much of it its EEVEE renders took.
    rows[0] = replace(rows[0], details=RowDetails(match_seconds=3.0))
    detail = {c["check"]: c for c in summary.targets(rows)}[name]["detail"]
    assert "of it 1.50 s the EEVEE renders of 'Match EEVEE's direct light'" in detail


def test_held_out_views_are_made_in_the_region_and_removed_after():
    from types import SimpleNamespace

    from addon.report.config import GENERATED_PREFIX, ScenePreset
    from addon.scene.convert import build_scene
    from addon.scene.export import export_scene

    default_scene.open_blend(default_scene.builtin_scene("cornell"))
    scene = bpy.context.scene
    cam = scene.objects["Cornell camera"]
    cameras, objects = len(bpy.data.cameras), len(bpy.data.objects)
    native = build_scene(export_scene(scene))
    made = report.generate_held_out(scene, SimpleNamespace(scene=native), cam, 2, 0.0)
    assert [o.name for o in made] == [f"{GENERATED_PREFIX}1", f"{GENERATED_PREFIX}2"]
    for obj in made:
        assert obj.type == "CAMERA" and obj.data is not cam.data and obj.data.lens == cam.data.lens
        assert obj.name in scene.objects
        assert (obj.matrix_world.translation - cam.matrix_world.translation).length > 0
        # Turned away from the camera's heading, level.
        fwd = obj.matrix_world.to_3x3() @ mathutils.Vector((0, 0, -1))
        assert abs(fwd.z) < 1e-5
    report.remove_generated()
    assert (len(bpy.data.cameras), len(bpy.data.objects)) == (cameras, objects)
    # Made only where the scene names no held-out camera, unless asked.
    named = ScenePreset("x", ("A",), ("B",), (8, 8), 1, 1)
    bare = ScenePreset("x", ("A",), (), (8, 8), 1, 1)
    assert ReportConfig().generated_for(named) == 0
    assert ReportConfig().generated_for(bare) == 2
    assert ReportConfig(generated_views=1).generated_for(named) == 1


def test_the_scene_section_names_the_objects_the_vpls_do_not_light():
    info = {"vpl_specular": 1.0, "vpl_unlit": ["Chrome", "Pane"]}
    (line, _) = summary._light_lines(info)
    assert line == (
        "The written VPLs' specular factor: 1; they do not light 'Chrome', 'Pane' (sharp metal "
        "or glass, Light Linking), whose reflections are EEVEE's ray tracing's."
    )
    assert summary._light_lines({}) == []  # a run from before they were recorded


def test_a_held_out_view_says_whether_it_stands_in_the_region():
    far = {"camera": "CameraWest", "distance": 6.43, "radius": 3.29, "inside": False}
    assert summary.region_sentence(far) == (
        " It stands 6.4 m from CameraWest, outside the region around it (radius 3.3 m), which "
        "the coverage views stand for."
    )
    near = dict(far, distance=1.2, inside=True)
    assert "1.2 m from CameraWest, inside the region" in summary.region_sentence(near)
    assert summary.region_sentence(None) == ""


@pytest.mark.slow
def test_match_eevee_refits_vplace_refits_powers_to_eevees_direct_light_and_says_so(tmp_path):
    # The demo's --match-eevee, scored by the report: the same layout (vplace's rows are the
    # same), other powers for vplace+refit, the deficit per captured camera in the scene's
    # section, and the EEVEE renders it takes in the captures' time.
    change = {
        "with_eevee": False,
        "capture_curve": [],
        "budgets": [16],
        "seeds": [0],
        "methods": ["vplace", "vplace+refit"],
    }
    plain = report.run_report(
        tiny(**change, match_eevee="off"), tmp_path / "plain", log=lambda _line: None
    )
    matched = report.run_report(
        tiny(**change, match_eevee="on"), tmp_path / "matched", log=lambda _line: None
    )
    (name,) = plain["scenes"]
    assert plain["scenes"][name]["eevee_deficit_matched"] is None
    shares = matched["scenes"][name]["eevee_deficit_matched"]
    assert set(shares) >= set(FIT) and all(np.isfinite(list(shares.values())))
    assert matched["scenes"][name]["capture_seconds"] > plain["scenes"][name]["capture_seconds"]

    def ssim(result, method):
        return [r["ssim"] for r in _rows(result, renderer="evaluator", method=method)]

    assert ssim(matched, "vplace") == ssim(plain, "vplace")
    # The refit keeps the deficit only where EEVEE's image predicted on the matched views comes
    # out closer with it; each row says which, and the powers follow.
    refits = _rows(matched, renderer="evaluator", method="vplace+refit")
    choices = {json.dumps(r["extra"]["eevee_match"], sort_keys=True) for r in refits}
    (choice,) = [json.loads(c) for c in choices]
    assert choice["kept"] == all(w < o for w, o in choice["per_view"])
    assert all(r["extra"].get("eevee_match") is None for r in _rows(plain, method="vplace+refit"))
    if choice["kept"]:
        assert ssim(matched, "vplace+refit") != ssim(plain, "vplace+refit")
    else:
        assert ssim(matched, "vplace+refit") == ssim(plain, "vplace+refit")
    text = (tmp_path / "matched" / "report.md").read_text()
    assert "vplace+refit may match EEVEE's direct light (`--match-eevee`;" in text
    assert "--match-eevee" not in (tmp_path / "plain" / "report.md").read_text()


def test_a_blends_views_keep_its_render_shape(tmp_path):
    """``report --blend`` without ``--resolution`` scores the view the user renders: the
    render's shape (a portrait render, non-square pixels), 320 px on the long side; a built-in
    scene keeps its preset's size and ``--resolution`` wins over both."""
    from blender_util import cornell

    scene = cornell()
    blend = tmp_path / "portrait.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    scene.render.resolution_x, scene.render.resolution_y = 108, 192
    config = ReportConfig(blend=str(blend), fit_cameras=[scene.camera.name])
    (preset,) = config.presets()
    assert report.view_size(scene, preset, config) == (180, 320)
    scene.render.resolution_x, scene.render.resolution_y = 200, 100
    scene.render.pixel_aspect_x = 2.0
    assert report.view_size(scene, preset, config) == (320, 80)
    assert report.view_size(scene, preset, replace(config, resolution=(64, 48))) == (64, 48)
    builtin = ReportConfig(scenes=["cornell"])
    (cornell_preset,) = builtin.presets()
    assert report.view_size(scene, cornell_preset, builtin) == cornell_preset.resolution
