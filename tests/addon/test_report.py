"""The speed-against-error report: one tiny Cornell run through every stage, the target checks,
and configuration errors."""

import csv
import json

import bpy
import numpy as np
import pytest

from addon import default_scene, report
from addon.report import ReportConfig, ReportError, Row

TINY = {
    "scenes": ["cornell"],
    "budgets": [8, 16],
    "resolution": (32, 32),
    "capture_samples": 8,
    "truth_samples": 32,
    "cycles_samples": [4],
    "seeds": [0, 1],
    "eevee": True,
    "par2d": False,
}


@pytest.fixture(scope="module")
def tiny_report(tmp_path_factory):
    out = tmp_path_factory.mktemp("report")
    blend = default_scene.builtin_scene("cornell")
    mtime = blend.stat().st_mtime_ns
    lines: list[str] = []
    result = report.run_report(ReportConfig(**TINY), out, log=lines.append)
    return out, result, lines, blend, mtime


@pytest.mark.slow
def test_tiny_report_scores_every_method_on_both_views(tiny_report):
    _, result, lines, _, _ = tiny_report
    rows = result["rows"]
    views = {(r["view"], r["role"]) for r in rows}
    assert views == {
        ("Cornell camera", "fit"),
        (report.PRESETS["cornell"].held_out_view, "held-out"),
    }
    for view, role in views:
        mine = [r for r in rows if r["view"] == view]
        methods = {(r["method"], r["n_vpls"]) for r in mine}
        expected = {("direct", None), ("cycles", None)}
        for n in (8, 16):
            expected |= {("uniform", n), ("rsm", n), ("vplace", n)}
            if role == "fit":
                expected.add(("vplace+refit", n))
        assert methods == expected
        for r in mine:
            assert np.isfinite([r["rmse"], r["relative_mse"], r["ssim"], r["seconds"]]).all()
            assert -1.0 <= r["ssim"] <= 1.0 and r["rmse"] >= 0.0 and r["seconds"] >= 0.0
            if r["n_vpls"] is not None:
                assert r["shadow_rays"] > 0 and r["evaluate_seconds"] > 0.0
        # The VPLs add light the direct image lacks: every method beats direct only in RMSE.
        direct = next(r for r in mine if r["method"] == "direct")
        assert all(r["rmse"] < direct["rmse"] for r in mine if r["n_vpls"] == 16)
    refit = [r for r in rows if r["method"] == "vplace+refit"]
    assert all(r["extra"]["refit_error_after"] <= r["extra"]["refit_error_before"] for r in refit)
    # The held-out view's vplace never iterates (it has no indirect image to compare with).
    held = [r for r in rows if r["role"] == "held-out" and r["method"] == "vplace"]
    assert all(r["extra"]["iteration_errors"] == [] for r in held)
    assert any("report written" in line for line in lines)
    # Two seeds for the stochastic layouts, one run of the deterministic RSM; means per group.
    fit_rows = [r for r in rows if r["role"] == "fit" and r["n_vpls"] == 8]
    assert sorted(r["seed"] for r in fit_rows if r["method"] == "uniform") == [0, 1]
    assert [r["seed"] for r in fit_rows if r["method"] == "rsm"] == [None]
    means = {(m["view"], m["method"], m["n_vpls"]): m for m in result["means"]}
    mean = means[("Cornell camera", "uniform", 8)]
    runs = [r["ssim"] for r in fit_rows if r["method"] == "uniform"]
    assert mean["ssim"] == pytest.approx(np.mean(runs)) and mean["extra"]["seeds"] == 2
    assert mean["extra"]["ssim_std"] == pytest.approx(np.std(runs))


@pytest.mark.slow
def test_tiny_report_writes_csv_json_plots_and_markdown(tiny_report):
    out, result, _, _, _ = tiny_report
    with (out / "results.csv").open() as f:
        table = list(csv.DictReader(f))
    assert len(table) == len(result["rows"])
    assert json.loads((out / "results.json").read_text())["rows"] == result["rows"]
    pngs = sorted(p.name for p in out.glob("*.png"))
    assert "error_vs_vpls.png" in pngs
    assert sum(n.startswith("error_vs_time_cornell") for n in pngs) == 2
    assert sum(n.startswith("grid_cornell") for n in pngs) == 2
    for name in pngs:
        assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "eevee_cornell.png" in pngs  # the preview of the fit view's vplace layout
    md = (out / "report.md").read_text()
    assert "| vplace | 16 |" in md and "ground truth 32 spp" in md


@pytest.mark.slow
def test_report_leaves_the_blend_untouched_and_reuses_cached_renders(tiny_report, tmp_path):
    out, result, _, blend, mtime = tiny_report
    assert blend.stat().st_mtime_ns == mtime
    assert bpy.context.scene.camera.name == "Cornell camera"  # the held-out view was temporary
    assert bpy.data.collections.get("vplace VPLs") is None
    cached = sorted(p.name for p in (out / "cache").iterdir())
    # fit and held-out view: capture, ground truth, one Cycles curve point each.
    assert len(cached) == 6
    second = report.run_report(
        ReportConfig(**{**TINY, "methods": ["uniform"], "budgets": [8]}, cache_dir=out / "cache"),
        tmp_path,
        log=lambda _line: None,
    )
    assert sorted(p.name for p in (out / "cache").iterdir()) == cached
    first = [r for r in result["rows"] if r["method"] in ("uniform", "direct", "cycles")]
    first = [r for r in first if r["n_vpls"] in (None, 8)]
    for a, b in zip(first, second["rows"], strict=True):
        assert (a["view"], a["method"], a["rmse"], a["ssim"]) == (
            b["view"], b["method"], b["rmse"], b["ssim"],
        )  # fmt: skip


def _row(view, method, n, ssim, rmse):
    return Row("sponza", view, "fit", method, n, None, rmse, 0.0, ssim, 0.0, 0.0, 0.0)


def test_targets_report_the_margin_and_rising_errors():
    rows = [
        _row("A", "uniform", 64, 0.50, 0.30),
        _row("A", "uniform", 256, 0.60, 0.20),
        _row("A", "rsm", 64, 0.55, 0.25),
        _row("A", "rsm", 256, 0.62, 0.26),  # RMSE rises with N
        _row("A", "vplace", 64, 0.60, 0.20),
        _row("A", "vplace", 256, 0.70, 0.10),
    ]
    checks = {c["check"]: c for c in report.targets(rows)}
    vs_rsm = checks["sponza A (fit) N=256: vplace SSIM >= rsm + 0.05"]
    assert vs_rsm["met"] and vs_rsm["value"] == pytest.approx(0.08)
    vs_uniform = checks["sponza A (fit) N=256: vplace SSIM >= uniform + 0.05"]
    assert vs_uniform["met"] and vs_uniform["value"] == pytest.approx(0.10)
    rsm_rmse = checks["sponza A (fit) rsm: rmse falls as N grows"]
    assert not rsm_rmse["met"] and "N 64->256" in rsm_rmse["detail"]
    assert checks["sponza A (fit) vplace: one_minus_ssim falls as N grows"]["met"]
    rows[5] = _row("A", "vplace", 256, 0.64, 0.10)
    miss = next(c for c in report.targets(rows) if c["check"].endswith("rsm + 0.05"))
    assert not miss["met"] and miss["value"] == pytest.approx(0.02)
    assert "difference +0.0200" in miss["detail"]


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"methods": ["magic"]}, "unknown methods"),
        ({"budgets": [0, 8]}, "positive"),
        ({"budgets": []}, "positive"),
        ({"scenes": ["attic"]}, "unknown scenes"),
        ({"cycles_samples": [0]}, "at least 1"),
        ({"budgets": [100000]}, "not supported"),
    ],
)
def test_bad_configuration_is_a_clear_error(change, message, tmp_path):
    with pytest.raises(ReportError, match=message):
        report.run_report(ReportConfig(**{**TINY, **change}), tmp_path)
    assert not (tmp_path / "results.csv").exists()


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
