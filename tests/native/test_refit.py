"""vplace.refit: non-negative least squares on the VPL powers against the views' indirect
images."""

import numpy as np
import pytest
import vplace
import vplace.job
from test_layout import box_mesh, box_scene, floor_view
from views import view


def inward_vpls() -> vplace.VplSet:
    """VPLs on the ceiling and walls of the test box facing in, and one on the floor facing up
    (no floor pixel sees it); no near-field radius (exact recovery below)."""
    rows = [
        ((0.5, 0.5, 1.99), (0, 0, -1), (1.0, 1.0, 1.0)),
        ((-0.6, 0.2, 1.99), (0, 0, -1), (0.5, 0.8, 1.0)),
        ((0.0, -0.7, 1.99), (0, 0, -1), (1.2, 0.6, 0.3)),
        ((-0.99, 0.0, 0.6), (1, 0, 0), (0.8, 0.8, 0.8)),
        ((0.99, -0.4, 1.0), (-1, 0, 0), (0.4, 1.0, 0.4)),
        ((0.2, 0.99, 0.3), (0, -1, 0), (1.0, 0.5, 0.5)),
        ((0.0, 0.0, 0.01), (0, 0, 1), (2.0, 2.0, 2.0)),
    ]
    cols = [np.array([r[i] for r in rows], dtype=np.float32) for i in range(3)]
    return vplace.VplSet(*cols)


def known_scales(scene, d):
    """:func:`inward_vpls`, known scales for them (the seventh VPL unseen), and a view whose
    indirect image is theirs scaled so."""
    base = inward_vpls()
    truth = np.array([0.5, 2.0, 1.0, 0.0, 1.5, 0.8, 3.0])
    target, _ = vplace.evaluate(
        scene, view(d), base.with_flux((base.flux * truth[:, None]).astype("f4"))
    )
    return base, truth, view(d, indirect=target)


@pytest.fixture(scope="module")
def setup():
    scene = box_scene()
    d = floor_view(32)
    ref = vplace.uniform_vpls(scene, 3000, seed=5)
    d["indirect"], _ = vplace.evaluate(scene, view(d), ref)
    return scene, d


def test_recovers_known_scales(setup):
    scene, d = setup
    base, truth, v = known_scales(scene, d)
    out = vplace.refit(scene, [v], base, vplace.RefitParams(stride=2, ridge=0.0, group=1))
    assert isinstance(out, vplace.Refit)
    assert len(out) == 7 and out.pixels == 16 * 16
    np.testing.assert_allclose(out.scales[:6], truth[:6], atol=1e-4)
    assert out.scales[6] == pytest.approx(1.0, abs=1e-9)  # unseen: the ridge keeps its power
    assert out.error_after < 1e-3 * out.error_before
    flux = out.vpls.flux
    assert flux.dtype == np.float32 and flux.shape == (7, 3)
    np.testing.assert_allclose(flux, base.flux * out.scales[:, None], rtol=1e-6)
    assert np.array_equal(out.vpls.position, base.position)
    assert np.array_equal(out.vpls.normal, base.normal)
    assert (out.vpls.profile, out.vpls.radius) == (base.profile, base.radius)
    assert out.shadow_rays == 6 * out.pixels and out.seconds > 0
    # The default ridge pulls toward 1 (a trade: less error reduction on this tiny case, no
    # overfitting on real views), and a weaker one lands closer to the truth.
    near = vplace.refit(scene, [v], base, vplace.RefitParams(stride=2, group=1))
    weak = vplace.refit(scene, [v], base, vplace.RefitParams(stride=2, ridge=1e-3, group=1))
    assert weak.error_after < near.error_after < near.error_before
    np.testing.assert_allclose(weak.scales[:6], truth[:6], atol=0.05)
    assert np.abs(near.scales[:6] - 1).sum() < np.abs(weak.scales[:6] - 1).sum()


def test_max_scale_bounds_the_refit_where_it_fits_rendered_coverage_views(setup):
    # The known scales above (up to 2 on a seen VPL), refitted with the bound the job puts on
    # fits that include coverage views rendered by Cycles: the scale the captures ask for
    # beyond it ends at the bound, and the others are refitted as the bound allows.
    scene, d = setup
    base, _, v = known_scales(scene, d)
    assert vplace.RefitParams().max_scale == float("inf")  # no bound by default
    free = vplace.refit(scene, [v], base, vplace.RefitParams(stride=2, ridge=0.0))
    bounded = vplace.refit(scene, [v], base, vplace.RefitParams(stride=2, ridge=0.0, max_scale=1.6))
    upper = 1.6 * max(bounded.gain, 1.0)
    assert free.scales[1] > upper  # the bound binds
    assert bounded.scales[1] == pytest.approx(upper, rel=1e-9)
    assert np.all((bounded.scales >= 0) & (bounded.scales <= upper))
    assert free.error_after < bounded.error_after < bounded.error_before
    for bad in (0.5, float("nan")):
        with pytest.raises(vplace.InputError, match="max_scale"):
            vplace.refit(scene, [v], base, vplace.RefitParams(max_scale=bad))
    # The job bounds a fit only where a capture is a rendered coverage view (by its name).
    params = vplace.job._refit_params
    rendered = view(d, name=f"{vplace.coverage.RENDERED_PREFIX}1")
    assert params([v], None).max_scale == float("inf")
    assert params([v, rendered], None).max_scale == vplace.job.REGION_MAX_SCALE == 2.0


def test_power_groups_scale_neighbouring_vpls_together(setup):
    scene, d = setup
    vpls = vplace.uniform_vpls(scene, 48, seed=2)
    # One scale per VPL by default (with the coverage views' penalty, it beat groups of 8 on
    # every view of the built-in scenes).
    assert vplace.RefitParams().group == vplace.RefitParams.DEFAULT.group == 1
    assert "group=1" in repr(vplace.RefitParams())
    single = vplace.refit(scene, [view(d)], vpls)
    assert single.groups == 48 and len(np.unique(single.scales)) > 6
    out = vplace.refit(scene, [view(d)], vpls, vplace.RefitParams(group=8))
    assert out.groups == 6 and len(out) == 48
    # One scale per group: at most 6 distinct scales, each shared by the VPLs of its group.
    assert len(np.unique(out.scales)) <= 6
    with pytest.raises(vplace.InputError, match="group"):
        vplace.refit(scene, [view(d)], vpls, vplace.RefitParams(group=0))


def test_coverage_holds_a_vpl_that_lights_what_no_capture_saw(setup):
    """A wall VPL lighting the ceiling more than the floor, tripled in the floor's target: the
    refit follows the floor alone and triples it; a coverage view of the ceiling (which the
    floor camera cannot see) holds it nearer its light-path power."""
    scene, d = setup
    base = inward_vpls()
    truth = np.ones(7)
    truth[4] = 3.0
    target, _ = vplace.evaluate(
        scene, view(d), base.with_flux((base.flux * truth[:, None]).astype("f4"))
    )
    capture = view(d, indirect=target)
    pos = d["position"].copy()
    pos[..., 2] = 2.0
    ceiling = view(
        d, name="ceiling", position=pos, normal=np.broadcast_to(np.float32([0, 0, -1]), pos.shape)
    )
    p = vplace.RefitParams(stride=2, ridge=1e-3)
    assert p.unseen_weight == 1.0 and "unseen_weight=1.0" in repr(p)
    alone = vplace.refit(scene, [capture], base, p)
    held = vplace.refit(scene, [capture], base, p, coverage=[ceiling])
    assert alone.unseen_pixels == 0 and held.unseen_pixels == 16 * 16
    assert alone.scales[4] == pytest.approx(3.0, abs=0.05)
    assert 1.0 < held.scales[4] < 2.5
    # The floor the capture sees is not unseen; a weight of 0 turns the penalty off.
    seen = vplace.refit(scene, [capture], base, p, coverage=[capture])
    assert seen.unseen_pixels == 0 and np.array_equal(seen.scales, alone.scales)
    off = vplace.refit(
        scene,
        [capture],
        base,
        vplace.RefitParams(stride=2, ridge=1e-3, unseen_weight=0.0),
        coverage=[ceiling],
    )
    assert np.array_equal(off.scales, alone.scales)
    for bad in (-1.0, float("nan")):
        with pytest.raises(vplace.InputError, match="unseen_weight"):
            vplace.refit(
                scene, [capture], base, vplace.RefitParams(unseen_weight=bad), coverage=[ceiling]
            )


def test_a_dim_capture_weighs_as_much_as_a_bright_one(setup):
    """Two captures of the floor, one a fifth as bright: each view's pixels weigh by the
    inverse of its light (the weighted targets keeping their energy), so the dim one's relative
    error counts as the bright one's; ``balance_views=False`` sums plain pixel errors."""
    scene, d = setup
    base = vplace.uniform_vpls(scene, 24, seed=3)
    target, _ = vplace.evaluate(scene, view(d), base)
    bright = view(d, indirect=target)
    dim = view(d, name="dim", indirect=np.ascontiguousarray(0.2 * target, dtype=np.float32))
    p = vplace.RefitParams(stride=2, ridge=1e-3)
    assert p.balance_views and "balance_views=True" in repr(p)
    out = vplace.refit(scene, [bright, dim], base, p)
    w = np.asarray(out.view_weights)
    assert w[1] / w[0] == pytest.approx(5.0, rel=1e-6)
    # The weighted targets hold the unweighted energy: w0^2 + (0.2 w1)^2 == 1 + 0.2^2 (the
    # dim target is 0.2x in float32).
    assert (w[0] ** 2 + (0.2 * w[1]) ** 2) == pytest.approx(1.04, rel=1e-6)
    off = vplace.RefitParams(stride=2, ridge=1e-3, balance_views=False)
    assert not off.balance_views
    plain = vplace.refit(scene, [bright, dim], base, off)
    assert plain.view_weights == [1.0, 1.0]
    # The two targets disagree by 5x: balanced, the fit lands nearer the dim one's light.
    assert np.median(out.scales) < np.median(plain.scales)
    # One view, or views equally bright: nothing to balance.
    assert vplace.refit(scene, [dim], base, p).view_weights == [1.0]
    assert vplace.refit(scene, [bright, bright], base, p).view_weights == [1.0, 1.0]


def test_never_worse_and_deterministic(setup):
    scene, d = setup
    vpls = vplace.uniform_vpls(scene, 48, seed=2)
    v = view(d)
    for ridge in (0.0, 1e-3, 1.0):
        a = vplace.refit(scene, [v], vpls, vplace.RefitParams(ridge=ridge))
        b = vplace.refit(scene, [v], vpls, vplace.RefitParams(ridge=ridge))
        assert a.error_after <= a.error_before
        assert np.array_equal(a.scales, b.scales) and a.error_after == b.error_after
    # The first bounce of 3000 VPLs from 48: the refit helps.
    assert a.error_after < a.error_before
    # The error before is the RMSE of the evaluator's image on the strided grid.
    img, _ = vplace.evaluate(scene, v, vpls)
    assert a.error_before == pytest.approx(
        vplace.rmse(img[::4, ::4].copy(), d["indirect"][::4, ::4].copy()), rel=1e-5
    )


def test_scales_stay_non_negative(setup):
    scene, d = setup
    out = vplace.refit(scene, [view(d, indirect=-d["indirect"])], inward_vpls())
    assert out.scales.min() >= 0.0 and out.vpls.flux.min() >= 0.0
    np.testing.assert_array_equal(out.scales[:6], 0.0)  # all the light they give is wrong
    assert out.error_after <= out.error_before


def test_a_layout_passes_through(setup):
    scene, d = setup
    v = view(d)
    lay = vplace.layout(
        scene, [v], vplace.LayoutParams(budget=32, cell_px=8, light_rays=300, iterations=2)
    )
    out = vplace.refit(scene, [v], lay.vpls, vplace.RefitParams(stride=2))
    assert len(out) == len(lay) == 32
    assert np.array_equal(out.vpls.position, lay.vpls.position)
    np.testing.assert_allclose(out.vpls.flux, lay.vpls.flux * out.scales[:, None], rtol=1e-6)
    assert out.error_after <= out.error_before


def test_progress_and_cancel(setup):
    scene, d = setup
    vpls = vplace.uniform_vpls(scene, 8, seed=1)
    p = vplace.Progress()
    vplace.refit(scene, [view(d)], vpls, progress=p)
    assert p.total >= 2 and p.done == p.total
    p = vplace.Progress()
    p.cancel()
    with pytest.raises(vplace.CancelledError):
        vplace.refit(scene, [view(d)], vpls, progress=p)


def test_input_errors(setup):
    scene, d = setup
    vpls = vplace.uniform_vpls(scene, 8, seed=1)
    v = view(d)
    with pytest.raises(vplace.InputError, match="at least one View"):
        vplace.refit(scene, [], vpls)
    with pytest.raises(vplace.InputError, match="indirect image"):
        vplace.refit(scene, [v.without_indirect()], vpls)
    # NaN in the target masks the pixel when the view is made (counted, never used).
    nan = d["indirect"].copy()
    nan[3, 5, 1] = np.nan
    masked = view(d, indirect=nan)
    assert masked.masked_pixels == 1
    assert vplace.refit(scene, [masked], vpls, vplace.RefitParams(stride=1)).pixels == 32 * 32 - 1
    empty = np.zeros((0, 3), np.float32)
    with pytest.raises(vplace.InputError, match="VPLs is empty"):
        vplace.refit(scene, [v], vplace.VplSet(empty, empty, empty))
    with pytest.raises(vplace.InputError, match="stride"):
        vplace.refit(scene, [v], vpls, vplace.RefitParams(stride=0))
    with pytest.raises(vplace.InputError, match="ridge"):
        vplace.refit(scene, [v], vpls, vplace.RefitParams(ridge=-1.0))


def test_the_ridge_is_chosen_by_held_out_blocks():
    scene = box_scene()
    d = floor_view(128)
    base, _, v = known_scales(scene, d)
    assert vplace.RefitParams().select_ridge and not vplace.RefitParams(ridge=1.0).select_ridge
    out = vplace.refit(scene, [v], base, vplace.RefitParams(stride=2, free_gain=False, group=1))
    # The VPLs reproduce the target exactly: the weakest pull predicts left-out blocks best.
    assert [r for r, _ in out.cv] == [0.01, 0.1, 1.0, 10.0, 100.0]
    assert out.ridge == 0.01 and min(e for _, e in out.cv) == out.cv[0][1]
    given = vplace.refit(scene, [v], base, vplace.RefitParams(stride=2, ridge=0.01, group=1))
    assert given.cv == [] and given.ridge == 0.01
    np.testing.assert_allclose(given.scales, out.scales, atol=1e-9)


def test_the_gain_carries_the_captures_total_to_vpls_no_pixel_sees():
    """A target that is every VPL at 2.5 times its power: the cross-validation takes the pull
    toward the captures' gain, and the VPL no floor pixel sees gets 2.5 too; without
    ``free_gain`` it keeps its light-path power."""
    scene = box_scene()
    d = floor_view(128)
    base = inward_vpls()
    target, _ = vplace.evaluate(scene, view(d), base.with_flux((base.flux * 2.5).astype("f4")))
    v = view(d, indirect=target)
    out = vplace.refit(scene, [v], base, vplace.RefitParams(stride=2, group=1))
    assert out.gain == pytest.approx(2.5, rel=1e-5)
    assert [r for r, _ in out.gain_cv] == [0.01, 0.1, 1.0, 10.0, 100.0]
    assert min(e for _, e in out.gain_cv) < min(e for _, e in out.cv)
    np.testing.assert_allclose(out.scales, 2.5, rtol=1e-3)
    fixed = vplace.refit(scene, [v], base, vplace.RefitParams(stride=2, free_gain=False, group=1))
    assert fixed.gain == 1.0 and fixed.gain_cv == []
    assert fixed.scales[6] == pytest.approx(1.0, abs=1e-9)


def test_frames_whose_light_alone_differs_refit_together_as_each_alone(setup):
    """``refit_frames``: three frames of one floor, each lit by other powers (the scene's lamp
    moved for the second), refitted at once: each result is the one ``refit`` gives it alone,
    bit for bit, from the shadow rays of one frame. Frames that do not share their G-buffers
    or occluders are refused with the reason."""
    scene, d = setup
    v, t = box_mesh()
    ids = np.zeros(len(t), dtype=np.uint32)
    albedo = np.array([[0.5, 0.5, 0.5]], dtype=np.float32)
    moved = vplace.Scene(v, t, ids, albedo, [vplace.Light.point([-0.4, 0.3, 1.2], [5.0] * 3)])
    assert scene.same_occluders(moved) and moved.same_occluders(scene)
    base = inward_vpls()
    frames = []
    for s in ([0.5, 2.0, 1.0, 0.0, 1.5, 0.8, 3.0], [1.5, 0.5, 1.0, 2.0, 0.5, 0.8, 3.0], [1] * 7):
        target, _ = vplace.evaluate(
            scene, view(d), base.with_flux(base.flux * np.float32(s)[:, None])
        )
        frames.append([view(d, indirect=target)])
    scenes = [scene, moved, scene]
    params = vplace.RefitParams(stride=2, group=1)
    together = vplace.refit_frames(scenes, frames, base, params)
    assert len(together) == 3
    for s, f, got in zip(scenes, frames, together, strict=True):
        alone = vplace.refit(s, f, base, params)
        assert np.array_equal(got.scales, alone.scales)
        assert np.array_equal(got.vpls.flux, alone.vpls.flux)
        assert (got.ridge, got.cv, got.gain, got.error_after) == (
            alone.ridge,
            alone.cv,
            alone.gain,
            alone.error_after,
        )
        assert got.shadow_rays == alone.shadow_rays  # traced once for all three
    assert not np.array_equal(together[0].scales, together[1].scales)
    # Another camera, other occluders, a frame without views, a scene short: one-line errors.
    other = dict(d, albedo=d["albedo"] * np.float32(0.5))
    with pytest.raises(vplace.InputError, match="G-buffer differs"):
        vplace.refit_frames(
            [scene, scene], [frames[0], [view(other, indirect=frames[1][0].indirect)]], base
        )
    cube_v = np.vstack([v, v * np.float32(0.1) + np.float32([0, 0, 1])])  # a box in the box
    cube_t = np.vstack([t, t + len(v)])
    walled = vplace.Scene(cube_v, cube_t, np.zeros(len(cube_t), np.uint32), albedo, [])
    assert not scene.same_occluders(walled)
    with pytest.raises(vplace.InputError, match="triangles or surfaces differ"):
        vplace.refit_frames([scene, walled], frames[:2], base)
    with pytest.raises(vplace.InputError, match="frame 1 has no view"):
        vplace.refit_frames([scene, scene], [frames[0], []], base)
    with pytest.raises(vplace.InputError, match="2 scenes for 3 frames"):
        vplace.refit_frames([scene, scene], frames, base)
    with pytest.raises(vplace.InputError, match="at least one frame"):
        vplace.refit_frames([], [], base)
