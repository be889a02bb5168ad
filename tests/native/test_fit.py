"""Features and regression (issue 3): the pipeline on one and several views, the hard cases, and
a property test against numpy.linalg.lstsq."""

import json
import math

import numpy as np
import pytest
import vplace
from hypothesis import HealthCheck, assume, example, given, settings
from hypothesis import strategies as st
from vplace import _native
from vplace.bench_fit import (
    light_scene,
    numpy_extract,
    numpy_fit,
    synthetic_capture,
    synthetic_view,
)

FEATURE_NAMES = [name for name, *_ in vplace.feature_registry()]

EPS = np.finfo(np.float64).eps
PLAIN = {"select": False, "collinear_rtol": 0.0, "ridge_above": math.inf}
# Every feature of the views, no selection: what numpy's lstsq fits.
EVERY = {**PLAIN, "surface_only": False}


def lstsq(x, y):
    """Reference OLS with intercept: (intercept, coefficients, fitted)."""
    a = np.column_stack([np.ones(len(y)), x])
    sol, *_ = np.linalg.lstsq(a, y, rcond=None)
    return sol[0], sol[1:], a @ sol


def standardized_cond(x):
    xs = (x - x.mean(0)) / x.std(0)
    s = np.linalg.svd(xs, compute_uv=False)
    return s[0] / s[-1]


def check_invariants(r):
    """No panic got us here; outputs finite, weights sum to 1 or are all zero."""
    assert math.isfinite(r.intercept) and math.isfinite(r.r2)
    assert all(math.isfinite(v) for v in r.coefficients.values())
    w = np.array(list(r.weights.values()))
    assert np.all(np.isfinite(w)) and np.all(w >= 0)
    assert abs(w.sum() - 1) < 1e-12 or np.all(w == 0)
    assert np.all(np.isfinite(r.fitted))
    assert r.adjusted_r2 is None or math.isfinite(r.adjusted_r2)
    assert set(r.kept) | set(r.dropped) == set(r.feature_names)
    assert not set(r.kept) & set(r.dropped)


def coef_vector(r):
    return np.array([r.coefficients.get(n, 0.0) for n in r.feature_names])


def rng_design(n, p, seed):
    rng = np.random.default_rng(seed)
    return rng.standard_normal((n, p)), rng


def fit_capture(cap, **kw):
    """The fit on the one view of a synthetic capture."""
    return vplace.fit(light_scene(cap), [synthetic_view(cap)], vplace.FitParams(**kw))


def features(cap, **kw):
    return vplace.extract_features(light_scene(cap), synthetic_view(cap), **kw)


# --- the pipeline on a capture ------------------------------------------------------------


def test_registry():
    assert len(FEATURE_NAMES) == 14 and len(set(FEATURE_NAMES)) == 14
    for name, doc, origin, surface in _native.feature_registry():
        assert doc and origin in ("paper", "ours")
        assert surface == (name not in ("depth", "coverage", "normal_variance", "depth_variance"))
    assert {"light_cosine", "reflectance", "coverage", "depth_variance"} <= set(FEATURE_NAMES)


def test_extraction_matches_numpy():
    cap = synthetic_capture(203, 117)
    nat = features(cap, cell_px=16)
    ref = numpy_extract(cap, 16)
    assert np.array_equal(nat.cells, ref["cells"])
    assert (nat.cells_x, nat.cells_y) == (13, 8)
    np.testing.assert_allclose(nat.values, ref["values"], rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(nat.label, ref["label"], rtol=1e-6, atol=1e-7)
    assert nat.masked_pixels == 0
    assert nat.empty_cells == 13 * 8 - len(nat.cells) > 0


def test_fit_capture_table_json_predict():
    cap = synthetic_capture(320, 200)
    r = fit_capture(cap)
    check_invariants(r)
    assert r.n_cells + r.empty_cells == 20 * 13
    assert r.r2 > 0.9 and r.cv_r2 is not None and r.folds == 5
    assert r.dropped["reflectance"].startswith("unavailable")
    assert r.dropped["normal_x"] == "constant over the cells"
    text = str(r)
    assert "R^2" in text and "dropped:" in text
    for name in r.kept:
        assert name in text
    # Save and load.
    back = vplace.Fit.from_json(r.to_json())
    assert back.to_json() == r.to_json() and str(back) == str(r)
    assert back.kept == r.kept and back.coefficients == r.coefficients
    assert json.loads(r.to_json())["views"][0]["name"] == "synthetic"
    assert r.view_names == ["synthetic"] and r.view_r2["synthetic"] == pytest.approx(r.r2)
    # The same view without its indirect image: the prediction equals the fitted values.
    grid = back.predict(synthetic_view(cap, indirect=False))
    cells = features(cap)
    assert grid.shape == (13, 20)
    np.testing.assert_allclose(grid.reshape(-1)[cells.cells], r.fitted, rtol=1e-9, atol=1e-12)
    empty = np.setdiff1d(np.arange(grid.size), cells.cells)
    assert np.all(grid.reshape(-1)[empty] == 0)


def test_fit_capture_matches_numpy_plain_ols():
    cap = synthetic_capture(256, 160)
    r = fit_capture(cap, **EVERY)
    cells = features(cap)  # the same input (extraction is compared above)
    ref = numpy_fit(cells.values, cells.label)
    # Plain OLS keeps every non-constant feature; compare with lstsq on the same columns.
    cond = r.condition_number
    tol = 100 * cond * EPS * max(1.0, np.abs(ref["coefficients"]).max())
    assert np.abs(coef_vector(r) - ref["coefficients"]).max() <= tol
    assert abs(r.r2 - ref["r2"]) < 1e-9


def scene_with(lights):
    v = np.array([[0, 0, -50], [0.1, 0, -50], [0, 0.1, -50]], np.float32)
    ids, alb = np.zeros(1, np.uint32), np.full((1, 3), 0.5, np.float32)
    return vplace.Scene(v, np.array([[0, 1, 2]], np.uint32), ids, alb, lights)


def test_strongest_light_comes_from_the_scene():
    cap = synthetic_capture(64, 48)
    view = synthetic_view(cap)
    no_light = vplace.fit(scene_with([]), [view])
    assert no_light.light is None
    assert no_light.dropped["light_cosine"].startswith("unavailable")
    point = vplace.Light.point([0, 1, 2.5], [1.0, 1.0, 1.0])
    sun = vplace.Light.sun([0, 0, -2], [3.0, 3.0, 3.0])
    r = vplace.fit(scene_with([point, sun]), [view])
    assert r.light == ("direction", [0.0, 0.0, -1.0])
    # A point light whose irradiance at the mean covered position beats the sun's 3 W/m^2.
    strong = vplace.Light.point([0, 1, 2.5], [1000.0, 1000.0, 1000.0])
    r = vplace.fit(scene_with([sun, strong]), [view])
    assert r.light == ("position", [0.0, 1.0, 2.5])


def test_one_fit_over_several_views():
    a = synthetic_capture(96, 64, seed=1)
    b = synthetic_capture(64, 96, seed=2)
    scene = light_scene(a)
    va, vb = synthetic_view({**a, "name": "a"}), synthetic_view({**b, "name": "b"})
    both = vplace.fit(scene, [va, vb], vplace.FitParams(**EVERY))
    check_invariants(both)
    ca, cb = vplace.extract_features(scene, va), vplace.extract_features(scene, vb)
    assert both.n_cells == len(ca.cells) + len(cb.cells)
    assert both.view_names == ["a", "b"]
    # One design matrix: the same fit as numpy's on the stacked cells, one Min-Max range.
    ref = numpy_fit(np.vstack([ca.values, cb.values]), np.concatenate([ca.label, cb.label]))
    assert abs(both.r2 - ref["r2"]) < 1e-9
    lo = np.minimum(ca.values.min(0), cb.values.min(0))
    np.testing.assert_allclose(both.feature_min, lo)
    # R^2 per view, over each view's own cells.
    fitted = both.fitted
    for name, c, part in (
        ("a", ca, fitted[: len(ca.cells)]),
        ("b", cb, fitted[len(ca.cells) :]),
    ):
        y = c.label
        r2 = 1 - ((y - part) ** 2).sum() / ((y - y.mean()) ** 2).sum()
        assert both.view_r2[name] == pytest.approx(r2, abs=1e-12)
    with pytest.raises(vplace.InputError, match="views is empty"):
        vplace.fit(scene, [])
    with pytest.raises(vplace.InputError, match="it has no indirect image"):
        vplace.fit(scene, [va, synthetic_view(b, indirect=False)])


# --- hard cases ---------------------------------------------------------------------------


def test_constant_feature():
    x, rng = rng_design(80, 3, 1)
    x[:, 1] = 4.5
    y = x @ [1.0, 0.0, -2.0] + 0.3 + 0.01 * rng.standard_normal(80)
    r = vplace.fit_design(x, y, vplace.FitParams(**PLAIN))
    check_invariants(r)
    assert r.dropped == {"x1": "constant over the cells"}
    b0, b, _ = lstsq(x[:, [0, 2]], y)
    tol = 100 * r.condition_number * EPS * 10
    np.testing.assert_allclose(coef_vector(r)[[0, 2]], b, atol=tol)
    assert abs(r.intercept - b0) < tol


@pytest.mark.parametrize("kind", ["duplicated", "collinear"])
def test_duplicated_and_collinear_feature(kind):
    x, rng = rng_design(120, 3, 2)
    if kind == "duplicated":
        x[:, 2] = x[:, 0]
    else:
        x[:, 2] = x[:, 0] + x[:, 1]
    y = x[:, 0] - 0.5 * x[:, 1] + 0.05 * rng.standard_normal(120)
    r = vplace.fit_design(x, y, vplace.FitParams(select=False))
    check_invariants(r)
    assert r.kept == ["x0", "x1"]
    assert r.dropped["x2"].startswith("collinear with x0")
    fitted = lstsq(x, y)[2]  # rank-deficient: lstsq's minimum-norm solution
    np.testing.assert_allclose(r.fitted, fitted, atol=1e-10)
    _, b_red, _ = lstsq(x[:, :2], y)
    np.testing.assert_allclose(coef_vector(r)[:2], b_red, atol=1e3 * r.condition_number * EPS)
    # Without the collinearity check the solver still answers finitely (the basic solution of
    # the pivoted QR, whose fitted values equal lstsq's minimum-norm ones).
    plain = vplace.fit_design(x, y, vplace.FitParams(**PLAIN))
    check_invariants(plain)
    assert plain.rank == 2 and math.isinf(plain.condition_number)
    np.testing.assert_allclose(plain.fitted, fitted, atol=1e-10)


@pytest.mark.parametrize("params", [{}, PLAIN])
def test_more_features_than_cells(params):
    x, rng = rng_design(6, 12, 3)
    y = rng.standard_normal(6)
    r = vplace.fit_design(x, y, vplace.FitParams(**params))
    check_invariants(r)
    assert r.adjusted_r2 is None or len(r.kept) < 5
    if not params:
        # Six centered rows span at most five directions: the rest is collinear.
        assert len(r.kept) <= 5
        assert sum(v.startswith("collinear") for v in r.dropped.values()) >= 12 - 5
    else:
        assert r.rank <= 5 and math.isinf(r.condition_number)
        # Interpolation: both solvers reproduce y exactly.
        np.testing.assert_allclose(r.fitted, y, atol=1e-9)
        np.testing.assert_allclose(lstsq(x, y)[2], y, atol=1e-9)


def test_single_cell():
    r = vplace.fit_design(np.array([[1.0, 2.0, 3.0]]), np.array([0.7]))
    check_invariants(r)
    assert r.kept == [] and r.intercept == 0.7 and r.adjusted_r2 is None
    assert all(v == "constant over the cells" for v in r.dropped.values())
    # A capture of a single one-pixel cell.
    cap = synthetic_capture(1, 1)
    rc = fit_capture(cap, cell_px=1)
    check_invariants(rc)
    assert rc.n_cells == 1 and rc.kept == []


def test_all_labels_zero():
    x, _ = rng_design(50, 4, 4)
    r = vplace.fit_design(x, np.zeros(50))
    check_invariants(r)
    assert r.kept == [] and r.intercept == 0.0 and r.r2 == 1.0
    assert all(v == "the label is constant" for v in r.dropped.values())
    cap = synthetic_capture(64, 48)
    cap["indirect"] = np.zeros_like(cap["direct"])
    rc = fit_capture(cap)
    check_invariants(rc)
    assert rc.kept == [] and all(w == 0 for w in rc.weights.values())


def test_non_finite_design_is_an_error():
    x, _ = rng_design(10, 2, 5)
    y = np.ones(10)
    for bad_x, bad_y, what in [(x.copy(), y, "x"), (x, y.copy(), "y")]:
        (bad_x if what == "x" else bad_y).reshape(-1)[3] = np.nan
        with pytest.raises(vplace.InputError, match=f"{what} holds a non-finite value"):
            _native.fit_design(bad_x, bad_y)
    y_inf = y.copy()
    y_inf[0] = np.inf
    with pytest.raises(vplace.InputError, match="non-finite"):
        vplace.fit_design(x, y_inf)


def test_non_finite_lighting_is_masked_and_a_non_finite_gbuffer_refused():
    cap = synthetic_capture(64, 48)
    cap["indirect"][0, 0, 1] = np.nan
    cap["direct"][47, 0] = -np.inf
    cap["diffuse_direct"] = cap["diffuse_direct"].copy()
    cap["diffuse_direct"][20, 20, 2] = np.nan
    r = fit_capture(cap)
    check_invariants(r)
    assert r.masked_pixels == 3
    assert "3 non-finite pixels masked" in str(r)
    for name, index in (("position", (5, 7, 0)), ("depth", (10, 10))):
        bad = synthetic_capture(16, 16)
        bad[name][index] = np.inf
        with pytest.raises(vplace.InputError, match=f"{name} \\(covered pixel"):
            synthetic_view(bad)
    everything = synthetic_capture(8, 8)
    everything["indirect"][:] = np.nan
    with pytest.raises(vplace.InputError, match="usable pixels is empty"):
        fit_capture(everything)


def test_features_spanning_1e_8_to_1e8():
    x, rng = rng_design(200, 5, 6)
    scale = np.array([1e-8, 1e-4, 1.0, 1e4, 1e8])
    xs = x * scale
    y = x @ [1.0, -1.0, 2.0, 0.5, -0.25] + 0.01 * rng.standard_normal(200)
    r = vplace.fit_design(xs, y, vplace.FitParams(**PLAIN))
    check_invariants(r)
    assert r.condition_number < 10  # standardized columns: well posed
    _, b, fitted = lstsq(x, y)  # the same problem on unit-scale columns
    tol = 100 * r.condition_number * EPS * np.abs(b).max()
    np.testing.assert_allclose(coef_vector(r) * scale, b, rtol=0, atol=tol)
    np.testing.assert_allclose(r.fitted, fitted, atol=1e-9)
    check_invariants(vplace.fit_design(xs, y))


def test_condition_number_1e12():
    x, _ = rng_design(300, 3, 7)
    x[:, 1] = x[:, 0] + 1e-12 * x[:, 1]
    y = 2 * x[:, 0] + 3 * x[:, 1] + x[:, 2]
    cond_ref = standardized_cond(x)
    assert 1e11 < cond_ref < 1e14
    # Plain OLS: coefficients equal lstsq's within a tolerance derived from the condition number.
    r = vplace.fit_design(x, y, vplace.FitParams(**PLAIN))
    check_invariants(r)
    assert r.condition_number == pytest.approx(cond_ref, rel=1e-2)
    _, b, _ = lstsq(x, y)
    tol = 100 * r.condition_number * EPS * np.abs(b).max()
    np.testing.assert_allclose(coef_vector(r), b, rtol=0, atol=tol)
    np.testing.assert_allclose(coef_vector(r), [2, 3, 1], rtol=0, atol=tol)
    # The ridge fallback above 1e6: a capped condition, the same predictions.
    ridge = vplace.fit_design(x, y, vplace.FitParams(select=False, collinear_rtol=0.0))
    check_invariants(ridge)
    assert ridge.ridge_lambda > 0
    np.testing.assert_allclose(ridge.fitted, y, atol=1e-6 * np.abs(y).max())
    # Defaults: the near-duplicate is dropped as collinear.
    d = vplace.fit_design(x, y)
    check_invariants(d)
    assert d.dropped["x1"].startswith("collinear with x0")


def test_cells_with_no_geometry():
    cap = synthetic_capture(96, 64)
    cap["covered"][:, :48] = False  # left half is background
    r = fit_capture(cap)
    check_invariants(r)
    assert r.empty_cells >= 3 * 4 and r.n_cells + r.empty_cells == 6 * 4
    cap["covered"][:] = False
    with pytest.raises(vplace.InputError, match="usable pixels is empty"):
        fit_capture(cap)


def test_one_pixel_cells():
    cap = synthetic_capture(24, 16)
    cells = features(cap, cell_px=1)
    assert (cells.cells_x, cells.cells_y) == (24, 16)
    assert np.all(cells.pixels == 1)
    ys, xs = np.divmod(cells.cells, 24)
    np.testing.assert_allclose(cells.values[:, 5], cap["position"][ys, xs, 0], rtol=1e-7)
    assert np.all(cells.values[:, [12, 13]] == 0)  # variances of one pixel
    r = fit_capture(cap, cell_px=1)
    check_invariants(r)
    assert "coverage" in r.dropped  # every non-empty one-pixel cell is fully covered


def test_bad_arguments_are_input_errors():
    x, _ = rng_design(10, 2, 8)
    with pytest.raises(vplace.InputError, match="dtype float64"):
        _native.fit_design(x.astype(np.float32), np.ones(10))
    with pytest.raises(vplace.InputError, match=r"y must have shape \(10,\)"):
        _native.fit_design(x, np.ones(9))
    with pytest.raises(vplace.InputError, match="ridge_above"):
        vplace.fit_design(x, np.ones(10), vplace.FitParams(ridge_above=0.5))
    cap = synthetic_capture(8, 8)
    with pytest.raises(vplace.InputError, match="cell_px"):
        fit_capture(cap, cell_px=0)
    cap["depth"] = cap["depth"][:4]
    with pytest.raises(vplace.InputError, match="depth must have shape"):
        fit_capture(cap)
    with pytest.raises(vplace.InputError, match=r"not a vplace\.fit"):
        vplace.Fit.from_json('{"format": "other"}')
    with pytest.raises(vplace.InputError, match="fitted on a design matrix"):
        vplace.fit_design(x, np.arange(10.0)).predict(synthetic_view(synthetic_capture(8, 8)))


# --- property test --------------------------------------------------------------------------


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    n=st.integers(2, 200),
    p=st.integers(1, 8),
    seed=st.integers(0, 2**32 - 1),
    log_scale=st.floats(-6, 6),
)
# Found by hypothesis: a column whose offset is 1e5 times its spread.
@example(n=71, p=1, seed=784, log_scale=-5.0)
def test_random_well_conditioned_problems_match_lstsq(n, p, seed, log_scale):
    assume(n >= p + 2)
    x, rng = rng_design(n, p, seed)
    x = x * 10.0**log_scale + rng.standard_normal(p)
    y = x @ rng.standard_normal(p) + rng.standard_normal(n)
    cond = standardized_cond(x)
    assume(cond < 1e4)
    r = vplace.fit_design(x, y, vplace.FitParams(**PLAIN))
    check_invariants(r)
    _, b, fitted = lstsq(x, y)
    assert r.condition_number == pytest.approx(cond, rel=1e-6)
    scale = np.abs(x).max(0) / x.std(0)  # the raw problem's extra conditioning
    tol = 1e3 * cond * EPS * (np.abs(b) + np.abs(y).max() / x.std(0)) * scale
    assert np.all(np.abs(coef_vector(r) - b) <= tol)
    # Fitted values are sums of terms b_j x_j that cancel when a column's offset dwarfs its spread.
    magnitude = np.abs(y).max() + (np.abs(b) * np.abs(x).max(0)).sum()
    # The bound holds for each solution's distance from the exact fitted values; lstsq's are
    # rounded as much as ours, so the two may differ by twice it.
    np.testing.assert_allclose(r.fitted, fitted, rtol=0, atol=2 * 1e3 * cond * EPS * magnitude)
    sst = ((y - y.mean()) ** 2).sum()
    assert r.r2 == pytest.approx(1 - ((y - fitted) ** 2).sum() / sst, abs=1e-9)


def test_the_default_fit_keeps_to_the_surface_and_holds_other_views_to_its_range():
    cap = synthetic_capture(256, 160)
    model = fit_capture(cap)
    view_features = ("depth", "coverage", "normal_variance", "depth_variance")
    for name in view_features:
        assert model.dropped[name].startswith("excluded: depends on the view")
    assert not set(view_features) & set(model.kept)
    # The label grows with height on the wall: position_z explains it, and is kept.
    assert "position_z" in model.kept
    # The same surfaces seen 100 m higher up (as another view's unseen part of the scene may
    # lie): the linear model is held at the edge of its range, never extended 100 m.
    far = {**cap, "position": cap["position"] + np.float32([0, 0, 100])}
    view = synthetic_view(far, indirect=False)
    grid = model.predict(view)
    top = features(cap).label.max()
    assert 0.0 <= grid.min() and grid.max() <= top
    outside = dict(model.out_of_range(view))
    assert outside["position_z"] == 1.0
    assert all(f == 0.0 for f in dict(model.out_of_range(synthetic_view(cap))).values())
