"""The settings classes of each stage (issue 19): the core's defaults, keyword construction,
named presets, and what the core decided (whether a layout iterated)."""

import vplace
from test_layout import box_scene, floor_view
from views import view


def test_layout_params_take_the_core_defaults_and_keywords():
    d = vplace.LayoutParams()
    assert (d.budget, d.alpha, d.cell_px, d.light_rays, d.bounces, d.seed) == (
        256,
        1.0,
        None,
        16384,
        None,
        0,
    )
    assert (d.multi_bounce, d.stride, d.iterations, d.tolerance, d.step, d.iterate) == (
        True,
        4,
        3,
        0.01,
        0.5,
        True,
    )
    assert (d.profile, d.radius, d.tile) == ("cosine", None, 16)
    p = vplace.LayoutParams(budget=64, seed=1)
    assert (p.budget, p.seed, p.iterations) == (64, 1, 3)
    assert repr(vplace.LayoutParams.DEFAULT) == repr(d)
    assert not vplace.LayoutParams.SINGLE_PASS.iterate
    assert "budget=64" in repr(p) and "iterate=True" in repr(p)


def test_fit_and_refit_params_take_the_core_defaults():
    f = vplace.FitParams()
    assert (f.cell_px, f.surface_only, f.folds, f.select, f.min_cv_gain) == (
        16,
        True,
        5,
        True,
        1e-3,
    )
    assert (f.collinear_rtol, f.rank_rtol, f.ridge_above, f.seed) == (1e-6, None, 1e6, 0x5EED)
    plain = vplace.FitParams.PLAIN_OLS
    assert (plain.select, plain.surface_only, plain.folds) == (False, False, 0)
    r = vplace.RefitParams()
    assert (r.stride, r.ridge) == (4, 0.1)
    assert vplace.RefitParams(stride=2).stride == 2
    # Leave-one-view-out by default (with three or more views), blocks when asked.
    assert r.leave_out_views and "leave_out_views=True" in repr(r)
    assert not vplace.RefitParams(leave_out_views=False).leave_out_views
    # The captures' gain tried by the cross-validation by default.
    assert r.free_gain and "free_gain=True" in repr(r)
    assert not vplace.RefitParams(free_gain=False).free_gain


def test_the_layout_says_whether_it_iterated():
    scene = box_scene()
    d = floor_view(16)
    ref = vplace.uniform_vpls(scene, 500, seed=5)
    d["indirect"], _ = vplace.evaluate(scene, view(d), ref)
    params = vplace.LayoutParams(budget=16, cell_px=8, light_rays=100)
    assert vplace.layout(scene, [view(d)], params).iteration == "ran"
    once = vplace.layout(scene, [view(d), view(d).without_indirect()], params)
    assert once.iteration == "no indirect image in view 1" and once.errors == []
    off = vplace.layout(scene, [view(d)], vplace.LayoutParams.SINGLE_PASS)
    assert off.iteration == "off"
