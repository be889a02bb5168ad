"""vplace.job: the one method dispatch, the fit, compute (lay out, evaluate, score), the
baselines and the typed summaries, on the benchmark room (no Blender)."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest
import vplace
from views import view
from vplace import bench_layout
from vplace import job as vjob


@pytest.fixture(scope="module")
def room():
    scene, _ = bench_layout.build_scene(2)
    cap = bench_layout.synthetic_capture(48, 32)
    truth = vplace.uniform_vpls(scene, 128, seed=11)
    indirect, _ = vplace.evaluate(scene, view(cap), truth)
    fitted_view = view(cap, indirect=indirect, diffuse_indirect=indirect)
    direct = np.asarray(cap["direct"], np.float32)
    ref = vjob.Reference(
        fitted_view, direct, direct + indirect, indirect, "the room", camera="c", samples=1
    )
    return scene, fitted_view, ref


def settings(**change) -> vjob.LayoutSettings:
    return vjob.LayoutSettings(**{"n_vpls": 16, "iterations": 1, "cell_px": 8, **change})


@pytest.mark.parametrize("method", vjob.METHODS)
def test_lay_out_dispatches_every_method(room, method):
    scene, v, _ = room
    laid = vjob.lay_out(scene, [v], settings(method=method))
    assert 0 < len(laid.vpls) <= 16
    guided = method.startswith("vplace")
    assert (laid.layout is not None) == guided
    assert (laid.refit is not None) == (method == "vplace+refit")
    if laid.refit is not None:
        assert np.array_equal(laid.vpls.flux, laid.refit.vpls.flux) and laid.refit_seconds > 0
    assert laid.layout_seconds > 0
    assert laid.vpls.radius == pytest.approx(scene.near_field_radius)


def test_a_radius_and_a_timer_reach_the_layout(room):
    scene, v, _ = room
    timer = vjob.StageTimer(log=lambda _line: None)
    laid = vjob.lay_out(scene, [v], settings(method="uniform", radius=0.05), timer=timer)
    assert laid.vpls.radius == pytest.approx(0.05)
    assert list(timer.seconds) == ["uniform VPLs (n=16)"]


def test_compute_scores_against_the_reference(room):
    scene, v, ref = room
    out = vjob.compute(scene, [v], settings(method="vplace"), ref)
    assert out.fit is not None and out.laid.layout is not None
    assert out.indirect.shape == ref.gi.shape
    base = vjob.score(ref.direct, ref.gi)
    assert out.metrics["rmse_direct_only"] == pytest.approx(base["rmse"])
    assert out.metrics["rmse"] == pytest.approx(
        vjob.score(ref.direct + out.indirect, ref.gi)["rmse"]
    )
    assert out.metrics["rmse_indirect"] == pytest.approx(
        vplace.rmse(out.indirect, ref.gi - ref.direct)
    )


def test_the_refit_matches_eevees_direct_light_only_where_the_judge_says_it_helps(room):
    scene, v, ref = room
    cap = bench_layout.synthetic_capture(48, 32)
    plain = vjob.lay_out(scene, [v], settings(method="vplace+refit"))
    assert plain.match is None
    # A target raised where EEVEE's direct light falls short gives the VPLs more power (the
    # layout itself, placed for Cycles' light, is kept) where EEVEE's image would come out
    # closer with it: here a judge that wants more light.
    short = 0.5 * ref.modelled_indirect
    raised = view(cap, indirect=ref.modelled_indirect + short, diffuse_indirect=ref.gi)
    wanted = 1.5 * float(plain.vpls.flux.sum())

    def error(vpls, index):
        assert index == 0
        return (float(vpls.flux.sum()) - wanted) ** 2

    match = vjob.EeveeMatch([raised], [v], [0], error)
    more = vjob.lay_out(scene, [v], settings(method="vplace+refit"), match=match)
    # One matched view: judged on the view it was fitted to.
    assert more.match is not None and more.match.kept and not more.match.held_out
    assert more.match.with_match < more.match.without
    assert more.match.without == pytest.approx(math.sqrt(error(plain.vpls, 0)))
    assert np.array_equal(more.layout.vpls.position, plain.layout.vpls.position)
    assert more.vpls.flux.sum() > 1.2 * plain.vpls.flux.sum()
    out = vjob.compute(scene, [v], settings(method="vplace+refit"), ref, match=match)
    assert np.array_equal(out.vpls.flux, more.vpls.flux)
    # A judge that finds EEVEE's image the closer without it: the plain powers stay.
    kept_out = vjob.EeveeMatch([raised], [v], [0], lambda vpls, _i: float(vpls.flux.sum()))
    same = vjob.lay_out(scene, [v], settings(method="vplace+refit"), match=kept_out)
    assert same.match is not None and not same.match.kept
    assert np.array_equal(same.vpls.flux, plain.vpls.flux)
    # Two matched views: each is judged by the powers refitted to the other's deficit alone.
    # The raised view's deficit carries over to the other; the other's is none, so on the
    # raised view, judged left out, the powers are the plain ones and the judge says no gain.
    judged = []

    def both(vpls, index):
        judged.append((index, float(vpls.flux.sum())))
        return (float(vpls.flux.sum()) - wanted) ** 2

    two = vjob.EeveeMatch([raised, v], [v, v], [0, 1], both)
    out2 = vjob.lay_out(scene, [v, v], settings(method="vplace+refit"), match=two)
    assert out2.match is not None and out2.match.held_out
    plain2 = vjob.lay_out(scene, [v, v], settings(method="vplace+refit"))
    on_raised = [f for i, f in judged if i == 0]  # left out: refitted to view 1 (no deficit)
    assert on_raised[0] == pytest.approx(float(plain2.vpls.flux.sum()), rel=1e-6)
    on_other = [f for i, f in judged if i == 1]  # left out: refitted to the raised view
    assert on_other[0] > 1.1 * float(plain2.vpls.flux.sum())
    # No matched view: nothing to judge, nothing kept.
    none = vjob.EeveeMatch([v], [v], [], error)
    assert not vjob.lay_out(scene, [v], settings(method="vplace+refit"), match=none).match.kept


def _box_mean_by_loops(diff, mask, size):
    h, w = mask.shape
    out = np.zeros((h, w, 3))
    before = size // 2
    for y in range(h):
        for x in range(w):
            ys = slice(max(0, y - before), min(h, y - before + size))
            xs = slice(max(0, x - before), min(w, x - before + size))
            m = mask[ys, xs]
            if mask[y, x] and m.any():
                out[y, x] = diff[ys, xs][m].mean(axis=0)
    return out


def test_eevees_deficit_is_the_smooth_part_of_its_direct_light_on_the_surfaces():
    rng = np.random.default_rng(5)
    cycles = rng.uniform(0.0, 2.0, (9, 14, 3))
    eevee = rng.uniform(0.0, 2.0, (9, 14, 3))
    mask = rng.uniform(size=(9, 14)) > 0.3
    for size in (1, 4, 5, 20):
        got = vjob.eevee_deficit(cycles, eevee, mask, size)
        assert got.dtype == np.float32 and got.shape == (9, 14, 3)
        np.testing.assert_allclose(got, _box_mean_by_loops(cycles - eevee, mask, size), atol=1e-5)
    # A sharp edge (a sun patch's) is spread over the box; an emitter seen directly, masked
    # out, counts for nothing, however bright.
    edge = np.zeros((8, 16, 3))
    edge[:, 8:] = 1.0
    seen = np.ones((8, 16), bool)
    seen[4, 2] = False
    bright = edge.copy()
    bright[4, 2] = 1e6
    got = vjob.eevee_deficit(bright, np.zeros_like(edge), seen, 4)
    assert got[4, 2].tolist() == [0.0, 0.0, 0.0]
    assert got[0, 0, 0] == 0.0 and got[0, 15, 0] == pytest.approx(1.0)
    assert 0.0 < got[0, 7, 0] < got[0, 8, 0] < 1.0
    with pytest.raises(ValueError, match="one size"):
        vjob.eevee_deficit(cycles, eevee[:-1], mask, 4)
    with pytest.raises(ValueError, match="at least 1 pixel"):
        vjob.eevee_deficit(cycles, eevee, mask, 0)
    eevee[2, 3, 1] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        vjob.eevee_deficit(cycles, eevee, mask | True, 4)


def test_the_note_says_where_the_powers_make_up_for_eevees_direct_light():
    assert vjob.eevee_matched_notes({}) == []
    (line,) = vjob.eevee_matched_notes({"Camera": 0.034, "Side": -0.002})
    assert "Camera +3.4%, Side -0.2%" in line
    kept = {"kept": True, "with_match": 0.0035, "without": 0.0045}
    (line,) = vjob.eevee_matched_notes({"Camera": 0.034}, kept)
    assert "Camera +3.4%" in line and "RMSE 0.0035 with it, 0.0045 without" in line
    # Left out where it would not help: said so, with the figures, and no share.
    left = dict(kept, kept=False, with_match=0.127)
    (line,) = vjob.eevee_matched_notes({}, left)
    assert line.startswith("Match EEVEE's direct light was left out")
    assert "RMSE 0.127 with it, 0.0045 without" in line


def test_score_of_the_truth_is_perfect_and_ssim_needs_11_pixels():
    rng = np.random.default_rng(0)
    img = rng.random((16, 16, 3)).astype(np.float32)
    s = vjob.score(img, img)
    assert s["rmse"] == 0 and s["ssim"] == pytest.approx(1) and s["brightness"] == pytest.approx(1)
    assert np.isnan(vjob.score(img[:10, :10], img[:10, :10])["ssim"])
    assert vjob.score(2 * img, img)["brightness"] == pytest.approx(2, rel=1e-5)
    assert (s["hot_pixels"], s["worst_share"]) == (0.0, 0.0)
    # A second render of the truth adds the SSIM against the noise-free truth; none without.
    assert "ssim_noise_free" not in s
    assert vjob.score(img, img, other=img)["ssim_noise_free"] == pytest.approx(1)
    assert vjob.score(img, img, other=img)["rmse_noise_free"] == 0.0
    twin = vjob.score(img + 0.1, img, other=img, image_other=img + 0.2)["rmse_noise_free"]
    assert twin == pytest.approx((0.1 * 0.2) ** 0.5, rel=1e-5)
    assert np.isnan(
        vjob.score(img[:10, :10], img[:10, :10], other=img[:10, :10])["ssim_noise_free"]
    )


def test_outliers_find_hot_spots_and_where_the_error_sits():
    truth = np.full((20, 20, 3), 0.5, np.float32)
    spot = truth.copy()
    spot[3, 4] = 5.0  # one hot pixel: all the error in the worst 1 % (4 pixels)
    o = vjob.outliers(spot, truth)
    assert o["hot_pixels"] == pytest.approx(1 / 400) and o["worst_share"] == pytest.approx(1.0)
    # Twice the truth plus the floor is not hot; just above it is.
    edge = np.full_like(truth, vjob.HOT_FACTOR * 0.5 + vjob.HOT_FLOOR - 1e-3)
    assert vjob.outliers(edge, truth)["hot_pixels"] == 0.0
    assert vjob.outliers(edge + 2e-3, truth)["hot_pixels"] == 1.0
    # An error spread evenly: the worst 1 % hold 1 % of it.
    assert vjob.outliers(truth * 1.1, truth)["worst_share"] == pytest.approx(0.01)


def test_attribution_splits_eevees_error_into_parts_that_add_up():
    rng = np.random.default_rng(3)
    truth = rng.uniform(0.2, 1.0, (16, 24, 3))
    cycles_direct = 0.6 * truth
    evaluator_vpl = 0.35 * truth  # the evaluator misses 5 % of the truth
    eevee_direct = 0.9 * cycles_direct  # EEVEE's direct light 10 % dark
    eevee_vpl = evaluator_vpl.copy()
    eevee_vpl[2, 3] += 4.0  # one hot spot in EEVEE's VPL light
    eevee = eevee_direct + eevee_vpl
    a = vjob.attribute(eevee, eevee_direct, cycles_direct, evaluator_vpl, truth)
    assert set(a.rmse) == set(a.share) == set(vjob.ATTRIBUTION_PARTS)
    assert sum(a.share.values()) == pytest.approx(1.0)
    assert a.direct_brightness == pytest.approx(0.9)
    assert a.rmse["direct"] == pytest.approx(np.sqrt(((0.1 * cycles_direct) ** 2).mean()))
    assert a.rmse["rest"] == pytest.approx(np.sqrt(((0.05 * truth) ** 2).mean()))
    assert a.rmse["vpl"] == pytest.approx(4.0 / np.sqrt(16 * 24))  # 4 in each channel
    # The hot spot holds most of the error and is the VPL light's only hot pixel.
    assert a.share["vpl"] > 0.5 and a.vpl_hot_pixels == pytest.approx(1 / (16 * 24))
    assert a.vpl_worst_share == pytest.approx(1.0)
    # Its hot pixel stays with Cycles' direct light swapped in, and goes with the evaluator's
    # VPL light swapped in: it is the VPL light's, not the direct light's.
    assert a.hot_cycles_direct == pytest.approx(1 / (16 * 24)) and a.hot_evaluator_vpl == 0.0
    # Each swap leaves the other part's error: neither image is the truth.
    assert 0.9 < a.ssim_evaluator_vpl < 1.0 and 0.9 < a.ssim_cycles_direct < 1.0
    # EEVEE equal to the evaluator: no VPL part, the rest is all.
    same = vjob.attribute(cycles_direct + evaluator_vpl, cycles_direct, cycles_direct,
                          evaluator_vpl, truth)  # fmt: skip
    assert same.rmse["vpl"] < 1e-12 and same.rmse["direct"] == 0.0
    assert same.share["rest"] == pytest.approx(1.0)
    assert same.ssim_cycles_direct == pytest.approx(same.ssim_evaluator_vpl)
    with pytest.raises(ValueError, match="one shape"):
        vjob.attribute(eevee, eevee_direct[:8], cycles_direct, evaluator_vpl, truth)
    bad = truth.copy()
    bad[0, 0, 0] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        vjob.attribute(eevee, eevee_direct, cycles_direct, evaluator_vpl, bad)


def test_attribution_splits_eevees_direct_error_into_the_stand_ins_and_eevees_rendering():
    """Cycles rendering the stand-ins tells what vplace wrote from how EEVEE renders it: a room
    whose stand-in light misses a strip the sky lights (a window's reveal), rendered by EEVEE
    with a noisy patch elsewhere."""
    h, w = 12, 16
    cycles_direct = np.full((h, w, 3), 0.3)
    stand_ins = cycles_direct.copy()
    stand_ins[:, 14:] = 0.0  # the reveal the stand-in does not light
    eevee_direct = stand_ins.copy()
    eevee_direct[2:5, 2:6] += 0.2  # EEVEE's own error, elsewhere
    vpl = np.full((h, w, 3), 0.1)
    truth = cycles_direct + vpl
    a = vjob.attribute(eevee_direct + vpl, eevee_direct, cycles_direct, vpl, truth, None, stand_ins)
    strip, patch = 2 * h * 0.09, 12 * 0.04  # squared errors (per channel)
    assert a.stand_in_share == pytest.approx(strip / (strip + patch))
    assert a.share["direct"] == pytest.approx(1.0)
    assert a.stand_in_rmse == pytest.approx(np.sqrt(strip / (h * w)))
    # Stand-ins as Cycles' own direct light: all of part (a) is EEVEE's rendering.
    exact = vjob.attribute(
        eevee_direct + vpl, eevee_direct, cycles_direct, vpl, truth, None, truth - vpl
    )
    assert exact.stand_in_share == pytest.approx(0.0)
    assert exact.stand_in_rmse == pytest.approx(0.0, abs=1e-12)
    assert np.isnan(vjob.attribute(truth, cycles_direct, cycles_direct, vpl, truth).stand_in_share)
    with pytest.raises(ValueError, match="stand_ins must be"):
        vjob.attribute(truth, cycles_direct, cycles_direct, vpl, truth, None, stand_ins[:4])
    stand_ins[0, 0, 0] = np.inf
    with pytest.raises(ValueError, match="stand_ins holds NaN"):
        vjob.attribute(truth, cycles_direct, cycles_direct, vpl, truth, None, stand_ins)


def test_attribution_says_how_much_of_eevees_direct_error_is_where_emitters_are_seen():
    # A lit wall with a panel (an emitter, 20x brighter) the camera sees in its top rows: EEVEE
    # draws the panel's edge one pixel lower (anti-aliased its own way) and lights the wall right.
    h, w = 12, 16
    wall = np.full((h, w, 3), 0.2)
    emission = np.zeros((h, w, 3))
    emission[:3] = 4.0
    cycles_direct = wall + emission
    cycles_direct[:3] -= 0.2  # the panel's pixels see the panel, not the lit wall
    eevee_direct = cycles_direct.copy()
    eevee_direct[3] = 4.0  # the edge drawn a row lower
    vpl = np.full((h, w, 3), 0.1)
    truth = cycles_direct + vpl
    seen = vjob.seen_directly(emission, cycles_direct)
    assert seen.dtype == bool and seen[:3].all() and not seen[3:].any()
    a = vjob.attribute(eevee_direct + vpl, eevee_direct, cycles_direct, vpl, truth, seen)
    assert a.seen_pixels == pytest.approx(3 / h)
    # The error lies beside the panel, on the wall's pixels: none of it where the panel is seen.
    assert a.share["direct"] == pytest.approx(1.0) and a.seen_share == pytest.approx(0.0)
    eevee_direct[3] = 0.2
    eevee_direct[2] = 0.2  # now the edge drawn a row higher: the error is on the panel's pixels
    a = vjob.attribute(eevee_direct + vpl, eevee_direct, cycles_direct, vpl, truth, seen)
    assert a.seen_share == pytest.approx(1.0)
    # Without a mask, the split is unknown; a wrong mask is a clear error.
    assert np.isnan(vjob.attribute(truth, cycles_direct, cycles_direct, vpl, truth).seen_share)
    with pytest.raises(ValueError, match="bool mask"):
        vjob.attribute(truth, cycles_direct, cycles_direct, vpl, truth, seen[:4])
    with pytest.raises(ValueError, match="bool mask"):
        vjob.attribute(truth, cycles_direct, cycles_direct, vpl, truth, seen.astype(float))
    with pytest.raises(ValueError, match="one shape"):
        vjob.seen_directly(emission[:4], cycles_direct)
    # The world seen through a window counts as the emitters do; a dark pixel never does.
    assert not vjob.seen_directly(np.zeros((2, 2, 3)), np.zeros((2, 2, 3))).any()


def _ceiling_lamp(half: float = 0.25) -> vjob.LightShape:
    """A square lamp of half-size ``half`` at height 2, facing down, as an outline of corners
    and edge midpoints."""
    pts = [(x, y, 2.0) for x in (-half, 0.0, half) for y in (-half, 0.0, half) if (x, y) != (0, 0)]
    return vjob.LightShape(np.array(pts), np.array([0.0, 0.0, 2.0]), np.array([0.0, 0.0, -1.0]))


def test_the_planes_that_pass_through_a_light_are_found():
    lamp = _ceiling_lamp()
    # Points on the faces of a box below the lamp: a face whose plane x = 0.1 passes through the
    # lamp, a face whose plane x = 0.6 passes beside it, the floor, and a face above the lamp.
    pos = np.array([[0.1, 0.0, 1.0], [0.6, 0.0, 1.0], [0.0, 0.0, 0.0], [0.1, 0.0, 2.5]])
    nrm = np.array([[1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])
    cut = vjob.cut_by_lights(pos, nrm, [lamp], 0.02)
    assert cut.tolist() == [True, False, False, False]
    # The normal's sign does not matter (the plane is the same); a zero normal cuts nothing.
    assert vjob.cut_by_lights(pos, -nrm, [lamp], 0.02).tolist() == [True, False, False, False]
    assert not vjob.cut_by_lights(pos, np.zeros_like(nrm), [lamp], 0.02).any()
    # A plane through the lamp's edge touches it and does not cut it (within the tolerance).
    edge = vjob.cut_by_lights(np.array([[0.25, 0.0, 1.0]]), np.array([[1.0, 0, 0]]), [lamp], 0.02)
    assert not edge.any()
    # A sphere light faces every way: the face above it counts.
    sphere = vjob.LightShape(
        np.array([[0.1, 0, 2], [-0.1, 0, 2], [0, 0.1, 2], [0, -0.1, 2], [0, 0, 2.1], [0, 0, 1.9]]),
        np.array([0.0, 0.0, 2.0]),
    )
    assert vjob.cut_by_lights(pos, nrm, [sphere], 0.02).tolist() == [False, False, False, False]
    near = np.array([[0.05, 0.0, 2.5]])
    assert vjob.cut_by_lights(near, np.array([[1.0, 0, 0]]), [sphere], 0.02).all()
    # (H, W, 3) images work as well; no light cuts nothing; bad input is a clear error.
    img = np.broadcast_to(pos[:, None], (4, 5, 3))
    assert vjob.cut_by_lights(img, np.broadcast_to(nrm[:, None], (4, 5, 3)), [lamp], 0.02)[0].all()
    assert not vjob.cut_by_lights(pos, nrm, [], 0.02).any()
    with pytest.raises(ValueError, match="one shape"):
        vjob.cut_by_lights(pos, nrm[:2], [lamp], 0.02)
    with pytest.raises(ValueError, match="NaN"):
        vjob.cut_by_lights(np.full((1, 3), np.nan), nrm[:1], [lamp], 0.02)
    with pytest.raises(ValueError, match="tolerance"):
        vjob.cut_by_lights(pos, nrm, [lamp], -1.0)


def _lit(x: np.ndarray, n: np.ndarray, lamp: vjob.LightShape) -> np.ndarray:
    """The light ``lamp`` sends onto points ``x`` (normals ``n``), unoccluded, up to a factor:
    what a capture's direct light measures, from its outline's points."""
    total = np.zeros(len(x))
    for p in np.asarray(lamp.outline):
        d = p - x
        r = np.linalg.norm(d, axis=-1)
        cos_r = np.maximum((n * d).sum(-1), 0.0) / r
        cos_e = np.maximum(-(d @ np.asarray(lamp.facing)), 0.0) / r
        total += cos_r * cos_e / r**2
    return total


def test_the_share_of_light_on_cut_planes_tells_a_block_from_a_terminator():
    lamp = _ceiling_lamp()
    pos = np.array([[0.0, 0.0, 0.0], [0.1, 0.0, 1.0], [0.6, 0.0, 1.0]])
    nrm = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    # What a camera sees of a floor (2 m x 2 m) and the face of a block under the lamp (x =
    # 0.1, 1 m tall), sampled evenly: the face holds a real share of the lamp's light on them.
    g = np.linspace(-1.0, 1.0, 21)
    floor = np.stack(np.meshgrid(g, g, [0.0], indexing="ij"), -1).reshape(-1, 3)
    h = np.linspace(0.05, 0.95, 10)
    face = np.stack(np.meshgrid([0.1], np.linspace(-0.45, 0.45, 10), h, indexing="ij"), -1)
    face = face.reshape(-1, 3)
    x = np.concatenate([floor, face])
    n = np.concatenate([np.tile([0.0, 0.0, 1.0], (len(floor), 1)), np.tile([1.0, 0, 0], (100, 1))])
    area = np.concatenate([np.full(len(floor), 0.01), np.full(100, 0.009)])
    block = vjob.cut_share(x, n, area * _lit(x, n, lamp), lamp, 0.02)
    assert block > vjob.CUT_SHARE
    # A ball beside that floor, 3 m from the lamp's axis: the planes of its points along the
    # terminator pass through the lamp too, but they are lit edge on and hold next to none.
    k = np.arange(4000) + 0.5
    z = 1.0 - 2.0 * k / 4000
    phi = np.pi * (3.0 - np.sqrt(5.0)) * k
    ball_n = np.stack([np.sqrt(1 - z * z) * np.cos(phi), np.sqrt(1 - z * z) * np.sin(phi), z], -1)
    ball_x = np.array([3.0, 0.0, 0.3]) + 0.3 * ball_n
    both_x, both_n = np.concatenate([floor, ball_x]), np.concatenate([n[: len(floor)], ball_n])
    both_w = np.concatenate([area[: len(floor)], np.full(4000, 0.4 * np.pi * 0.09 / 4000)])
    assert vjob.cut_by_lights(ball_x, ball_n, [lamp], 0.02).any()
    ball = vjob.cut_share(both_x, both_n, both_w * _lit(both_x, both_n, lamp), lamp, 0.02)
    assert ball < 0.1 * vjob.CUT_SHARE
    # Nothing lit: no share; bad weights are a clear error.
    assert vjob.cut_share(pos, nrm, np.zeros(3), lamp, 0.02) == 0.0
    with pytest.raises(ValueError, match="one weight per point"):
        vjob.cut_share(pos, nrm, np.ones(2), lamp, 0.02)
    with pytest.raises(ValueError, match=">= 0"):
        vjob.cut_share(pos, nrm, np.array([1.0, -1.0, 0.0]), lamp, 0.02)


def test_attribution_says_how_much_of_eevees_direct_error_is_where_a_lights_plane_is_cut():
    # A room lit by one lamp, whose plane-cut pixels (two columns) EEVEE darkens to 0.8x, and a
    # noisy patch elsewhere.
    h, w = 12, 16
    cycles_direct = np.full((h, w, 3), 0.3)
    cut = np.zeros((h, w), bool)
    cut[:, :2] = True
    eevee_direct = cycles_direct.copy()
    eevee_direct[cut] *= 0.8
    eevee_direct[5:7, 8:10] += 0.06
    vpl = np.full((h, w, 3), 0.1)
    truth = cycles_direct + vpl
    a = vjob.attribute(eevee_direct + vpl, eevee_direct, cycles_direct, vpl, truth, None, None, cut)
    strip, patch = 2 * h * 0.06**2, 4 * 0.06**2
    assert a.cut_pixels == pytest.approx(2 / w)
    assert a.cut_share == pytest.approx(strip / (strip + patch))
    assert a.cut_brightness == pytest.approx(0.8)
    # Where the lights EEVEE renders are stand-ins, their own error in the cut pixels is not
    # EEVEE's darkening: measured against Cycles' render of the stand-ins, EEVEE there is right.
    stand_ins = cycles_direct.copy()
    stand_ins[cut] *= 0.8
    own = vjob.attribute(
        eevee_direct + vpl, eevee_direct, cycles_direct, vpl, truth, None, stand_ins, cut
    )
    assert own.cut_share == pytest.approx(0.0, abs=1e-12)
    assert own.cut_brightness == pytest.approx(1.0)
    assert own.stand_in_share == pytest.approx(strip / (strip + patch))
    none = vjob.attribute(truth, cycles_direct, cycles_direct, vpl, truth, None, None, ~cut & cut)
    assert none.cut_pixels == 0.0 and none.cut_share == 0.0 and np.isnan(none.cut_brightness)
    assert np.isnan(vjob.attribute(truth, cycles_direct, cycles_direct, vpl, truth).cut_share)
    with pytest.raises(ValueError, match="cut must be"):
        vjob.attribute(truth, cycles_direct, cycles_direct, vpl, truth, None, None, cut[:3])


def test_attribution_says_how_much_of_eevees_direct_error_is_the_surfaces_colour():
    # A rug of light and dark squares in a sun patch: EEVEE's colour of the rug is blurred (its
    # mipmaps), its light is right; and a shadow edge elsewhere that EEVEE draws a column off.
    h, w = 12, 16
    light = np.full((h, w, 3), 2.0)
    colour = np.full((h, w, 3), 0.5)
    colour[2:6, 2:10:2] = 0.9
    blurred = colour.copy()
    blurred[2:6, 2:10] = 0.7  # the squares' mean
    cycles_direct = light * colour
    cycles_direct[:, 12:] = 0.0  # a shadow over the right columns
    eevee_direct = light * blurred
    eevee_direct[:, 12:] = 0.0
    eevee_direct[:, 12] = 1.0  # its edge drawn a column further
    vpl = np.full((h, w, 3), 0.1)
    truth = cycles_direct + vpl
    part = vjob.colour_part(light, blurred, colour)
    assert part == pytest.approx(light * (blurred - colour))
    a = vjob.attribute(eevee_direct + vpl, eevee_direct, cycles_direct, vpl, truth, colour=part)
    rug, edge = 4 * 8 * 0.4**2, h * 1.0**2  # squared errors per channel
    assert a.colour_share == pytest.approx(rug / (rug + edge))
    assert a.colour_rmse == pytest.approx(np.sqrt(rug / (h * w)))
    assert np.isnan(vjob.attribute(truth, cycles_direct, cycles_direct, vpl, truth).colour_share)
    with pytest.raises(ValueError, match="colour must be"):
        vjob.attribute(truth, cycles_direct, cycles_direct, vpl, truth, colour=part[:3])
    with pytest.raises(ValueError, match="one shape"):
        vjob.colour_part(light[:3], blurred, colour)
    with pytest.raises(ValueError, match="NaN"):
        vjob.colour_part(np.full_like(light, np.inf), blurred, colour)


def test_baselines_share_the_fit_and_leave_the_method_out(room):
    scene, v, ref = room
    computed, compared = vjob.compute_with_baselines(
        scene, [v], settings(method="vplace"), ref, vjob.METHODS
    )
    assert set(compared) == set(vjob.METHODS) - {"vplace"}
    for b in compared.values():
        assert set(b.metrics) == set(computed.metrics) and b.seconds > 0


def test_method_name():
    assert vjob.method_name("vplace", True) == "vplace+refit"
    assert vjob.method_name("vplace", False) == "vplace"
    assert vjob.method_name("uniform", True) == "uniform"


def _summary(**change) -> vjob.JobSummary:
    fields = dict(
        scene="s", triangles=2, lights=1, views=["v"], skipped_views={}, resolution=[4, 3],
        samples=1, capture_render_seconds=0.5, n_vpls=8, lights_written=7,
        emitter_lights_written=0, method="uniform", alpha=1.0, iterations=3, profile="cosine",
        radius=0.1, seed=0, stage_seconds={"fit": 0.25},
        evaluator=vjob.EvaluatorSummary(10, 20, 0.5, 20.0), metrics={"rmse": 0.5},
    )  # fmt: skip
    return vjob.JobSummary(**{**fields, **change})


def test_summary_json_has_the_main_jobs_fields_only_when_asked():
    s = _summary(baselines={"rsm": vjob.Baseline({"rmse": 0.7}, 1.0)})
    short, full = s.to_dict(), s.to_dict(main_job=True)
    assert "baselines" not in short and "files" not in short
    assert full["baselines"] == {"rsm": {"metrics": {"rmse": 0.7}, "seconds": 1.0}}
    # The evaluator leaves out the figures a method does not have.
    assert short["evaluator"] == {"shadow_rays": 10, "pairs": 20, "seconds": 0.5,
                                  "rays_per_second": 20.0}  # fmt: skip
    assert list(full)[: len(short)] == list(short)  # the same order, the main job's after


def test_the_panel_reads_a_stored_summary_by_attribute():
    fit = vjob.FitSummary(0.9, 0.8, {"v": 0.9}, ["a"], {"a": 1.0}, {"b": "constant"})
    text = json.dumps(_summary(fit=fit).to_dict())
    report = vjob.PanelReport.from_json(text)
    assert report is not None and report.fit == fit
    assert (report.n_vpls, report.profile, report.metrics) == (8, "cosine", {"rmse": 0.5})
    assert vjob.PanelReport.from_json("") is None
    assert vjob.PanelReport.from_json(json.dumps({"fit": dataclasses.asdict(fit)})).n_vpls == 0
    assert report.eevee == {} and report.eevee_lines() == []  # no "Check in EEVEE"


def test_the_panel_says_whose_part_eevees_difference_is_after_a_check_in_eevee():
    eevee = {
        "ssim": 0.9612, "rmse": 0.0062, "direct_brightness": 0.9061,
        "attribution_share_direct": 0.49, "attribution_share_vpl": -0.004,
        "attribution_share_rest": 0.514, "attribution_stand_in_share": 0.03,
    }  # fmt: skip
    s = _summary(eevee=eevee)
    assert s.to_dict()["eevee"] == eevee  # kept for the panel when a check made it
    assert "eevee" not in _summary().to_dict()
    report = vjob.PanelReport.from_json(json.dumps(s.to_dict()))
    assert report is not None and report.eevee == eevee
    assert report.eevee_lines() == [
        "EEVEE: SSIM 0.961, RMSE 0.0062 (evaluator 0.5000)",
        "EEVEE's direct light: 0.91x Cycles'",
        "Of EEVEE's error, 49% is its direct light:",
        "  3% vplace's stand-ins, 46% EEVEE's rendering (not vplace's)",
        "0% its VPL light, 51% the evaluator's own",
    ]
    # Without Cycles' render of the stand-ins, (a) is not split.
    del eevee["attribution_stand_in_share"]
    lines = vjob.PanelReport(eevee=eevee).eevee_lines()
    assert lines[0] == "EEVEE: SSIM 0.961, RMSE 0.0062" and len(lines) == 4


def test_the_captures_decide_the_near_field_and_the_settings_can_forbid_it(room):
    scene, v, ref = room
    laid = vjob.lay_out(scene, [v], settings(method="vplace+refit"))
    choice = laid.near_field
    assert choice is not None and choice.views == 1
    assert choice.distance == pytest.approx(laid.vpls.near_field_distance) and choice.distance > 0
    assert laid.vpls.near_field == choice.on == (choice.with_gather < choice.without)
    # Captures that hold the gather's light on top of the VPLs': on.
    plain, _ = vplace.evaluate(scene, v, laid.vpls, near_field=False)
    gathered, _ = vplace.evaluate(scene, v, laid.vpls, near_field=True)
    assert (gathered - plain).max() > 0
    cap = bench_layout.synthetic_capture(48, 32)
    lifted = ref.modelled_indirect + (gathered - plain)
    assert vjob.choose_near_field(scene, [view(cap, indirect=lifted)], laid.vpls).on
    # Forbidden: the same lights, never judged, never with it; other methods are not judged.
    off = vjob.lay_out(scene, [v], settings(method="vplace+refit", near_field=False))
    assert off.near_field is None and not off.vpls.near_field
    assert np.array_equal(off.vpls.flux, laid.vpls.flux)
    assert vjob.lay_out(scene, [v], settings(method="uniform")).near_field is None
