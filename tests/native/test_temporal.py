"""vplace.temporal: the temporal error, the matching of VPLs over frames, the keyed lights
between frames."""

from __future__ import annotations

import numpy as np
import pytest
import vplace
import vplace.job
from views import view
from vplace import bench_layout, temporal


def _grey(value: float, shape: tuple[int, int] = (12, 16)) -> np.ndarray:
    return np.full((*shape, 3), value, dtype=np.float32)


def test_a_static_pair_has_no_temporal_error_whatever_its_error():
    rng = np.random.default_rng(0)
    truth = rng.random((12, 16, 3)).astype(np.float32)
    image = truth * 0.5 + 0.1  # wrong on every frame, but the same wrong
    assert temporal.temporal_error([image, image, image], [truth, truth, truth]) == 0.0


def test_following_the_truth_exactly_has_no_temporal_error():
    truths = [_grey(v) for v in (0.2, 0.4, 0.3)]
    images = [t + 0.05 for t in truths]  # a constant offset: changes exactly as the truth
    assert temporal.temporal_error(images, truths) == pytest.approx(0.0, abs=1e-7)


def test_a_known_flicker_gives_its_amplitude_over_the_mean():
    c, d = 0.5, 0.1
    truths = [_grey(c)] * 4
    images = [_grey(c), _grey(c + d), _grey(c), _grey(c + d)]
    # Every frame-to-frame change is +-d against the truth's 0: d per pixel, over c.
    assert temporal.temporal_error(images, truths) == pytest.approx(d / c, rel=1e-5)
    # Half the pixels flickering: half of it.
    half = [_grey(c) for _ in range(4)]
    for k in (1, 3):
        half[k][:6] += d
    assert temporal.temporal_error(half, truths) == pytest.approx(0.5 * d / c, rel=1e-5)
    # Step by step: one flicker, at the second step only.
    once = [_grey(c), _grey(c), _grey(c + d), _grey(c + d)]
    steps = temporal.temporal_steps(once, truths)
    assert steps == pytest.approx([0.0, d / c, 0.0], abs=1e-6)
    assert temporal.temporal_error(once, truths) == pytest.approx(d / c / 3, rel=1e-5)
    # Over another luminance (a part of an image against the whole's mean): d over that.
    assert temporal.temporal_error(images, truths, over=4 * c) == pytest.approx(d / (4 * c))


def test_the_temporal_error_refuses_what_it_cannot_score():
    with pytest.raises(ValueError, match="at least two frames"):
        temporal.temporal_error([_grey(1)], [_grey(1)])
    with pytest.raises(ValueError, match="2 images against 3"):
        temporal.temporal_error([_grey(1)] * 2, [_grey(1)] * 3)
    with pytest.raises(ValueError, match="shape"):
        temporal.temporal_error([_grey(1)] * 2, [_grey(1, (4, 4))] * 2)


def test_greedy_match_takes_the_cheapest_pairs_and_leaves_the_dear_ones():
    cost = np.array([[0.0, 0.09, 1.0], [0.05, 0.01, 1.0]])
    assert temporal.greedy_match(cost, 0.15).tolist() == [0, 1, -1]
    assert temporal.greedy_match(np.zeros((0, 2))).tolist() == [-1, -1]


def _set(pos, nrm=None, flux=None) -> vplace.VplSet:
    pos = np.asarray(pos, dtype=np.float32)
    n = len(pos)
    nrm = np.tile([0.0, 0.0, 1.0], (n, 1)) if nrm is None else nrm
    flux = np.ones((n, 3)) if flux is None else flux
    return vplace.VplSet(
        pos,
        np.ascontiguousarray(nrm, dtype=np.float32),
        np.ascontiguousarray(flux, dtype=np.float32),
        radius=0.01,
    )


def test_track_keeps_a_vpl_that_moves_a_little_in_its_slot_and_is_deterministic():
    a = _set([[0, 0, 0], [1, 0, 0], [2, 0, 0]])
    # The same lights listed in another order and moved by 2 cm: matched by position.
    b = _set([[2.02, 0, 0], [0.02, 0, 0], [1.02, 0, 0]], flux=[[3, 3, 3], [1, 1, 1], [2, 2, 2]])
    k = temporal.track([a, b], diagonal=10.0)
    assert k.position.shape == (2, 3, 3)
    assert k.index.tolist() == [[0, 1, 2], [1, 2, 0]]
    assert k.energy[1].tolist() == [1.0, 2.0, 3.0]
    k2 = temporal.track([a, b], diagonal=10.0)
    for name in ("position", "normal", "power", "index"):
        assert np.array_equal(getattr(k, name), getattr(k2, name))


def test_sets_sharing_their_positions_are_matched_vpl_by_vpl():
    # One shared layout: two neighbours 2 cm apart, each lit on one frame. Matched by position
    # the second would take the first's slot and the light would jump; shared, each stands.
    pos = [[0, 0, 0], [0.02, 0, 0], [3, 0, 0]]
    a = _set(pos, flux=[[1, 1, 1], [0, 0, 0], [2, 2, 2]])
    b = _set(pos, flux=[[0, 0, 0], [1, 1, 1], [2, 2, 2]])
    k = temporal.track([a, b], diagonal=10.0)
    assert k.index.tolist() == [[0, -1, 2], [-1, 1, 2]]
    assert k.energy.tolist() == [[1.0, 0.0, 2.0], [0.0, 1.0, 2.0]]
    for s in range(3):
        assert np.array_equal(k.position[0, s], k.position[1, s])
    # Not shared (the second set moved by a millimetre): matched by position, one slot moves.
    moved = _set([[0.001, 0, 0], [0.021, 0, 0], [3, 0, 0]], flux=[[0, 0, 0], [1, 1, 1], [2, 2, 2]])
    assert temporal.track([a, moved], diagonal=10.0).position.shape[1] == 2


def test_a_vpl_that_jumps_gets_a_new_slot_and_the_old_one_goes_dark_where_it_stands():
    a = _set([[0, 0, 0]])
    b = _set([[5, 0, 0]])  # half a diagonal away: far beyond its patch
    k = temporal.track([a, b], diagonal=10.0)
    assert k.position.shape[1] == 2
    assert k.energy.tolist() == [[1.0, 0.0], [0.0, 1.0]]
    # Dark slots hold the position and colour of their nearest lit frame.
    assert k.position[1, 0].tolist() == [0, 0, 0]
    assert k.position[0, 1].tolist() == [5, 0, 0]
    assert k.color[0, 1].tolist() == [1.0, 1.0, 1.0]


def test_a_vpl_is_matched_only_within_the_patch_it_stands_for():
    # A lone VPL's patch is the set's radius, here below MIN_PATCH_DIAGONALS of the diagonal:
    # 0.1 m in a room of 10 m. 3 cm of the diagonal is 3 patch radii: its light would sweep
    # over surfaces neither frame lights, so it fades out and another fades in.
    a = _set([[0, 0, 0]])
    assert temporal.track([a, _set([[0.3, 0, 0]])], diagonal=10.0).position.shape[1] == 2
    assert temporal.track([a, _set([[0.09, 0, 0]])], diagonal=10.0).position.shape[1] == 1
    # A VPL that stands for a larger patch (sparse neighbours) may move farther within it.
    far = [[0, 0, 0], [0.8, 0, 0], [0, 0.8, 0]]  # patches of 0.8 / sqrt(2), capped at 10 radii
    moved = [[0.3, 0, 0], [1.1, 0, 0], [0.3, 0.8, 0]]
    big = temporal.track(
        [vplace.VplSet(*_cols(far), radius=0.05), vplace.VplSet(*_cols(moved), radius=0.05)],
        diagonal=10.0,
    )
    assert big.position.shape[1] == 3


def _cols(pos) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    n = len(pos)
    return (
        np.asarray(pos, dtype=np.float32),
        np.tile(np.float32([0, 0, 1]), (n, 1)),
        np.ones((n, 3), dtype=np.float32),
    )


def test_a_turned_vpl_costs_its_normal_term():
    a = _set([[0, 0, 0]])
    b = _set([[0, 0, 0]], nrm=[[0.0, 0.0, -1.0]])  # flipped: 1 - cos = 2, cost 1.0
    assert temporal.track([a, b], diagonal=10.0).position.shape[1] == 2


def test_unlit_vpls_get_no_slot():
    a = _set([[0, 0, 0], [1, 0, 0]], flux=[[1, 1, 1], [0, 0, 0]])
    assert temporal.track([a], diagonal=10.0).position.shape[1] == 1


def test_at_frame_gives_the_captured_sets_back_and_blends_between_them():
    a = _set([[0, 0, 0], [1, 0, 0]], flux=[[1, 0.5, 0.5], [2, 2, 2]])
    b = _set([[0.06, 0, 0], [1, 0, 0.06]], flux=[[3, 1.5, 1.5], [2, 2, 2]])
    k = temporal.track([a, b], diagonal=10.0)
    at_a = temporal.at_frame(k, [1, 5], 1)
    assert np.allclose(at_a.position, a.position) and np.allclose(at_a.flux, a.flux)
    assert np.allclose(temporal.at_frame(k, [1, 5], 5).flux, b.flux)
    mid = temporal.at_frame(k, [1, 5], 3)
    assert np.allclose(mid.position, [[0.03, 0, 0], [1, 0, 0.03]])
    # Energy and colour are keyed apart (as Blender's keys): energy 2 of colour (1, .5, .5).
    assert np.allclose(mid.flux[0], [2.0, 1.0, 1.0])
    # Held before the first and after the last frame.
    assert np.allclose(temporal.at_frame(k, [1, 5], -3).flux, a.flux)
    assert np.allclose(temporal.at_frame(k, [1, 5], 9).flux, b.flux)


def test_a_light_fading_out_is_half_as_bright_half_way():
    a = _set([[0, 0, 0]])
    b = _set([[9, 0, 0]])
    k = temporal.track([a, b], diagonal=10.0)
    mid = temporal.at_frame(k, [0, 2], 1)
    assert len(mid) == 2
    assert np.allclose(sorted(mid.flux[:, 0]), [0.5, 0.5])
    assert np.allclose(sorted(mid.position[:, 0]), [0.0, 9.0])  # each where it stands


def test_between_frames_the_lights_keep_their_keyed_disks_so_a_cross_fade_is_linear():
    """A light fading out beside one fading in keeps its own frame's disk, as Blender
    interpolates the keyed sizes: the evaluator's image half way is then the mean of the two
    frames' images. With the disks of the interpolated set's spacing it was not."""
    scene, _ = bench_layout.build_scene(2)
    cap = view(bench_layout.synthetic_capture(40, 28))
    every = vplace.uniform_vpls(scene, 160, seed=1)
    x = np.asarray(every.position)[:, 0]

    def part(keep: np.ndarray) -> vplace.VplSet:
        cols = (np.ascontiguousarray(np.asarray(c)[keep]) for c in (every.position, every.normal))
        return vplace.VplSet(*cols, np.asarray(every.flux)[keep], radius=every.radius)

    # The lights move from one half of the room to the other: more than a patch apart.
    a, b = part(x < -0.2), part(x > 0.2)
    k = temporal.track([a, b], diagonal=scene.diagonal)
    assert len(a) >= 10 and len(b) >= 100
    assert not (k.lit[0] & k.lit[1]).any()  # no light moves: each fades out or in
    mid = temporal.at_frame(k, [0, 2], 1)
    assert mid.radii_given
    lit = k.energy[0] + k.energy[1] > 0
    assert np.allclose(mid.radii, (0.5 * (k.radii[0] + k.radii[1]))[lit], rtol=1e-6)
    ia, _ = vplace.evaluate(scene, cap, a)
    ib, _ = vplace.evaluate(scene, cap, b)
    im, _ = vplace.evaluate(scene, cap, mid)
    blend = 0.5 * (ia + ib)
    assert np.abs(im - blend).max() <= 1e-4 * blend.max()
    # The spacing's disks instead (what the evaluator took before): 1.5 % of the peak off.
    spaced = vplace.VplSet(mid.position, mid.normal, mid.flux, radius=mid.radius)
    assert not spaced.radii_given
    other, _ = vplace.evaluate(scene, cap, spaced)
    assert np.abs(other - blend).max() > 100 * np.abs(im - blend).max()


def test_a_shared_layout_refits_each_frame_as_the_still_layout_does(monkeypatch):
    """Each frame's refit is the still layout's (``vplace.job.refit_powers``): the captures at
    the refit's own stride (2 here, where the iteration's is 4), one scale per VPL; but not the
    coverage views' penalty, which would hold the union's VPLs at other frames' powers. (Before,
    the frames refitted at the iteration's stride: on ``skyroom_afternoon`` the keyed lights'
    indirect light came out 0.92-0.94x the truth's on frames 1-3, the still layouts' 0.97x.)"""
    frames = [_frame(monkeypatch, 1.0), _frame(monkeypatch, 2.0)]
    cap = bench_layout.synthetic_capture(32, 24, *bench_layout.cameras(3)[2])
    lit = np.full_like(cap["albedo"], 0.1)  # a coverage view's target: light-path VPLs
    cover = view(cap, vplace.coverage.PREFIX + "0", indirect=lit, diffuse_indirect=lit)
    seen: list[tuple[list[str], int, int, list[str]]] = []
    together: list[tuple[list[list[str]], int, int, list[str]]] = []
    refit, refit_frames = vplace.refit, vplace.refit_frames

    def spy(scene, views, vpls, params=None, *, coverage=None, progress=None):
        seen.append(
            (
                [v.name for v in views],
                params.stride,
                params.group,
                [v.name for v in coverage or []],
            )
        )
        return refit(scene, views, vpls, params, coverage=coverage, progress=progress)

    def spy_frames(scenes, frames, vpls, params=None, *, coverage=None, progress=None):
        names = [[v.name for v in f] for f in frames]
        together.append((names, params.stride, params.group, [v.name for v in coverage or []]))
        return refit_frames(scenes, frames, vpls, params, coverage=coverage, progress=progress)

    monkeypatch.setattr(vplace, "refit", spy)
    monkeypatch.setattr(vplace, "refit_frames", spy_frames)
    settings = vplace.job.LayoutSettings(n_vpls=32, iterations=1)
    scenes = [s for s, _ in frames]
    views = [[*v, cover] for _, v in frames]
    still = vplace.job.lay_out(scenes[0], views[0], settings)
    assert still.refit is not None
    assert seen == [(["view 0", "view 1"], 2, vplace.RefitParams.DEFAULT.group, ["coverage 0"])]
    assert vplace.stride_for(views[0]) == 4  # the iteration's, which the frames had used
    seen.clear()
    temporal.shared_layout(scenes, views, settings)
    # Each frame's own layout (n // 2 VPLs, a still layout), then the union refitted on each
    # frame: at the same stride, without the penalty; both frames at once (their lamp's power
    # alone differs: the same G-buffers and occluders).
    still_refit = (["view 0", "view 1"], 2, 1, ["coverage 0"])
    assert seen == [still_refit, still_refit]
    assert together == [([["view 0", "view 1"]] * 2, 2, 1, [])]


def test_frames_refit_together_where_their_light_alone_differs(monkeypatch):
    """``vplace.job.refit_frame_powers``: the frames that share G-buffers and occluders are
    refitted in one call (their shadow rays traced once), each as ``refit_powers`` refits it
    alone (without the coverage penalty); a frame whose camera moved gets a call of its own."""
    (s1, v1), (s2, v2) = _frame(monkeypatch, 1.0), _frame(monkeypatch, 2.0)
    cams = bench_layout.cameras(3)
    caps = [bench_layout.synthetic_capture(32, 24, c, t) for c, t in (cams[2], cams[1])]
    s3, v3 = s2, bench_layout.views_of(s2, caps)  # the camera moved
    assert not vplace.job.same_gbuffers(v1, v3) and vplace.job.same_gbuffers(v1, v2)
    union = vplace.uniform_vpls(s1, 24, seed=2)
    calls: list[int] = []
    refit_frames = vplace.refit_frames

    def spy(scenes, frames, *a, **k):
        calls.append(len(frames))
        return refit_frames(scenes, frames, *a, **k)

    monkeypatch.setattr(vplace, "refit_frames", spy)
    scenes, views = [s1, s3, s2], [v1, v3, v2]
    got = vplace.job.refit_frame_powers(scenes, views, union, group=1)
    assert calls == [2, 1]
    for s, v, r in zip(scenes, views, got, strict=True):
        alone = vplace.job.refit_powers(s, v, union, group=1, hold_unseen=False)
        assert np.array_equal(r.scales, alone.scales)
    assert not np.array_equal(got[0].scales, got[2].scales)
    with pytest.raises(ValueError, match="3 scenes for 2"):
        vplace.job.refit_frame_powers(scenes, views[:2], union)


def test_a_set_with_radii_given_checks_them_and_keeps_them():
    pos, nrm, flux = _cols([[0, 0, 0], [1, 0, 0]])
    s = vplace.VplSet(pos, nrm, flux, radius=0.01, radii=np.float32([0.2, 0.3]))
    assert s.radii.tolist() == pytest.approx([0.2, 0.3]) and s.radii_given
    assert s.with_flux(flux * 2).radii.tolist() == pytest.approx([0.2, 0.3])
    assert "radii given" in repr(s)
    for bad, match in (
        (np.float32([0.2]), "radii"),
        (np.float64([0.2, 0.3]), "float32"),
        (np.float32([0.2, -1.0]), "radii\\[1\\]"),
        (np.float32([0.2, np.nan]), "radii\\[1\\]"),
    ):
        with pytest.raises(vplace.InputError, match=match):
            vplace.VplSet(pos, nrm, flux, radius=0.01, radii=bad)
    with pytest.raises(vplace.InputError, match="omni"):
        vplace.VplSet(pos, nrm, flux, profile="omni", radii=np.float32([0.2, 0.3]))
    # The refit computes the radii from the spacing itself: it refuses a set with radii given.
    scene, _ = bench_layout.build_scene(2)
    cap = view(bench_layout.synthetic_capture(8, 6))
    with pytest.raises(vplace.InputError, match="radii given"):
        vplace.refit(scene, [cap], s)


def _frame(monkeypatch, power_scale: float):
    """The bench room with its lamp at ``power_scale`` times its power, and two captures."""
    monkeypatch.setattr(bench_layout, "POWER", bench_layout.POWER * power_scale)
    scene, _ = bench_layout.build_scene(4)
    cams = bench_layout.cameras(2)
    caps = [bench_layout.synthetic_capture(32, 24, c, t) for c, t in cams]
    return scene, bench_layout.views_of(scene, caps)


def test_a_shared_layout_keeps_its_positions_and_refits_each_frames_powers(monkeypatch):
    """Two frames, the second with its lamp 3x as bright: one set of positions (each frame adds
    n // 2 VPLs), the second frame's refitted light about 3x the first's."""
    (s1, v1), (s3, v3) = _frame(monkeypatch, 1.0), _frame(monkeypatch, 3.0)
    settings = vplace.job.LayoutSettings(n_vpls=32, iterations=1)
    a, b = temporal.shared_layout([s1, s3], [v1, v3], settings)
    assert 16 < len(a) == len(b) <= 32
    assert np.array_equal(a.position, b.position) and np.array_equal(a.normal, b.normal)
    ratio = float(np.asarray(b.flux).sum() / np.asarray(a.flux).sum())
    assert 2.4 < ratio < 3.6
    # Tracked, every VPL keeps its own slot: nothing fades, nothing sweeps.
    keyed = temporal.track([a, b], diagonal=s1.diagonal)
    assert keyed.position.shape[1] == int(keyed.lit.any(axis=0).sum()) <= len(a)
    assert np.array_equal(keyed.position[0], keyed.position[1])
    with pytest.raises(ValueError, match="2 scenes for 1"):
        temporal.shared_layout([s1, s3], [v1], settings)
    with pytest.raises(ValueError, match="no frames"):
        temporal.shared_layout([], [], settings)
    with pytest.raises(ValueError, match="'vplace' does not"):
        temporal.shared_layout([s1], [v1], vplace.job.LayoutSettings(method="vplace"))
