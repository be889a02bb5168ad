"""vplace.layout over one and several views, the RSM baseline, the brute-force evaluator and
SSIM."""

import math

import numpy as np
import pytest
import vplace
from views import view

LIGHT = np.array([0.3, -0.2, 1.0])
POWER = 20.0
LUM = np.array(vplace.LUMINANCE)


def box_mesh() -> tuple[np.ndarray, np.ndarray]:
    """Vertices and triangles of the box [-1, 1]^2 x [0, 2], faces inward."""
    corners = [
        [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)],
        [(-1, -1, 2), (-1, 1, 2), (1, 1, 2), (1, -1, 2)],
        [(-1, -1, 0), (-1, 1, 0), (-1, 1, 2), (-1, -1, 2)],
        [(1, -1, 0), (1, -1, 2), (1, 1, 2), (1, 1, 0)],
        [(-1, 1, 0), (1, 1, 0), (1, 1, 2), (-1, 1, 2)],
        [(-1, -1, 0), (-1, -1, 2), (1, -1, 2), (1, -1, 0)],
    ]
    v = np.array([p for q in corners for p in q], dtype=np.float32)
    t = np.array(
        [[b, b + 1, b + 2] for b in range(0, 24, 4)] + [[b, b + 2, b + 3] for b in range(0, 24, 4)],
        dtype=np.uint32,
    )
    return v, t


def box_scene() -> vplace.Scene:
    """The box of :func:`box_mesh`, albedo 0.5, a point light inside."""
    v, t = box_mesh()
    ids = np.zeros(len(t), dtype=np.uint32)
    albedo = np.array([[0.5, 0.5, 0.5]], dtype=np.float32)
    return vplace.Scene(v, t, ids, albedo, [vplace.Light.point(LIGHT.tolist(), [POWER] * 3)])


def floor_view(w: int, cam=(0.0, 0.0, 1.9), half=1.0) -> dict:
    """A w x w view from ``cam`` looking straight down (+Y up in the image) at the square of the
    floor of half side ``half`` under it."""
    cam = np.array(cam)
    f, near, far = cam[2] / half, 0.1, 10.0  # 1 / tan(fov / 2)
    proj = np.array(
        [
            [f, 0, 0, 0],
            [0, f, 0, 0],
            [0, 0, (far + near) / (near - far), 2 * far * near / (near - far)],
            [0, 0, -1, 0],
        ]
    )
    to_cam = np.eye(4)
    to_cam[:3, 3] = -cam
    xs = ((np.arange(w) + 0.5) / w * 2 - 1).astype(np.float32)
    gx, gy = np.meshgrid(xs, -xs)
    pos = np.stack([half * gx + cam[0], half * gy + cam[1], np.zeros_like(gx)], axis=-1)
    pos = pos.astype(np.float32)
    albedo = np.where(pos[..., :1] < 0, [0.8, 0.2, 0.2], [0.5, 0.5, 0.5]).astype(np.float32)
    d = LIGHT - pos
    irr = POWER / (4 * math.pi) * d[..., 2] / np.linalg.norm(d, axis=-1) ** 3
    dd = np.repeat((irr / math.pi)[..., None], 3, axis=-1).astype(np.float32)
    return {
        "position": np.ascontiguousarray(pos),
        "normal": np.ascontiguousarray(np.broadcast_to(np.float32([0, 0, 1]), pos.shape)),
        "albedo": albedo,
        "covered": np.ones((w, w), dtype=bool),
        "diffuse_direct": dd,
        "direct": dd * albedo,
        "depth": np.full((w, w), cam[2], np.float32),
        "camera_position": cam,
        "world_to_clip": proj @ to_cam,
    }


@pytest.fixture(scope="module")
def setup():
    scene = box_scene()
    d = floor_view(32)
    ref = vplace.uniform_vpls(scene, 3000, seed=5)
    indirect, _ = vplace.evaluate(scene, view(d), ref)
    d["indirect"] = indirect
    return scene, d


def lay_out(scene, d, fit=None, **kw):
    return vplace.layout(scene, [view(d)], vplace.LayoutParams(**kw), fit=fit)


def test_budget_energy_and_determinism(setup):
    scene, d = setup
    totals = []
    for alpha in (0.0, 0.5, 1.0):
        out = lay_out(scene, d, budget=40, alpha=alpha, cell_px=8, light_rays=300, iterate=False)
        vpls = out.vpls
        assert len(out) == len(vpls) == 40
        assert vpls.position.shape == vpls.normal.shape == vpls.flux.shape == (40, 3)
        assert int(out.counts[0].sum()) + out.offscreen_count + out.pool_count == 40
        assert out.counts[0].shape == (4, 4)
        assert out.errors == [] and out.best is None and out.error is None
        totals.append(float((vpls.flux.astype(np.float64) @ LUM).sum()))
    # The layout moves accuracy, not energy.
    assert max(totals) - min(totals) < 1e-4 * max(totals)
    kw = {"budget": 40, "cell_px": 8, "light_rays": 300, "iterate": False}
    a = lay_out(scene, d, seed=3, **kw).vpls
    b = lay_out(scene, d, seed=3, **kw).vpls
    c = lay_out(scene, d, seed=4, **kw).vpls
    assert np.array_equal(a.position, b.position) and np.array_equal(a.flux, b.flux)
    assert not np.array_equal(a.position, c.position)
    assert a.profile == "cosine" and a.radius == pytest.approx(scene.near_field_radius)
    assert lay_out(scene, d, profile="omni", radius=0.3, **kw).vpls.radius == pytest.approx(0.3)


def test_pixel_emitters_carry_the_light_the_light_paths_measure(setup):
    """The first hits of light paths that a view sees measure the direct light its pixels
    receive. Where the pixels' footprints are off (the floor's normals bent by 60 degrees:
    ``r^2 omega / cos`` grows), the VPLs drawn from the pixels carry their emitters' flux
    scaled back (``Layout.pixel_flux_scale``); the straight view keeps its own."""
    scene, d = setup
    kw = {"budget": 64, "cell_px": 8, "light_rays": 4000, "iterate": False, "alpha": 0.0}
    straight = lay_out(scene, d, **kw)
    assert straight.pixel_flux_scale == 1.0
    t = math.radians(60.0)
    bent = dict(
        d,
        normal=np.ascontiguousarray(
            np.broadcast_to(np.float32([math.sin(t), 0.0, math.cos(t)]), d["position"].shape)
        ),
    )
    out = lay_out(scene, bent, **kw)
    assert 0.1 < out.pixel_flux_scale < 0.6
    # The strata keep the pixels' own flux (so does the allocation): the bent view's is larger.
    raw = sum(float((f.astype(np.float64) @ LUM).sum()) for f in out.strata_flux)
    own = sum(float((f.astype(np.float64) @ LUM).sum()) for f in straight.strata_flux)
    assert raw > 1.8 * own

    # The VPLs carry about the straight view's light.
    def lum(o: vplace.Layout) -> float:
        return float((o.vpls.flux.astype(np.float64) @ LUM).sum())

    assert lum(out) == pytest.approx(lum(straight), rel=0.15)


def test_guided_allocation_follows_the_prediction(setup):
    scene, d = setup
    # A view whose indirect light sits in its top-left corner: the fit predicts it there.
    ys, xs = np.mgrid[0:32, 0:32]
    corner = np.exp(-((xs / 8.0) ** 2 + (ys / 8.0) ** 2))[..., None]
    lit = {**d, "indirect": np.repeat(corner, 3, -1).astype(np.float32)}
    fitted = vplace.fit(scene, [view(lit)], vplace.FitParams(cell_px=8))
    pred = fitted.predict(view(lit).without_indirect())
    assert pred.shape == (4, 4) and pred[0, 0] == pred.max()
    kw = {"budget": 64, "cell_px": 8, "light_rays": 0, "iterate": False}
    base = lay_out(scene, lit, alpha=0.0, **kw)
    guided = lay_out(scene, lit, fit=fitted, alpha=1.0, **kw)
    assert guided.counts[0][0, 0] > base.counts[0][0, 0]
    assert int(guided.counts[0].sum()) + guided.pool_count == 64


def test_iteration_returns_its_best(setup):
    scene, d = setup
    out = lay_out(
        scene, d, budget=32, cell_px=8, light_rays=300, stride=2, iterations=4, tolerance=0.0
    )
    assert 1 <= len(out.errors) <= 4
    assert out.best is not None and out.error == min(out.errors)
    assert out.error <= out.errors[0]
    assert len(out) == 32
    assert len(out.seconds) == len(out.shadow_rays) == len(out.errors)
    # A view without its indirect image gives the one-shot layout.
    once = vplace.layout(
        scene,
        [view(d).without_indirect()],
        vplace.LayoutParams(budget=32, cell_px=8, light_rays=300),
    )
    assert once.errors == [] and once.best is None


def test_iteration_reuses_shadow_rays_without_changing_the_result(setup):
    # Each iteration's error is the RMSE of its VPLs' image on the strided grid, whether its
    # shadow rays were traced or reused from the previous iteration.
    scene, d = setup
    stride = 2
    kw = {"budget": 48, "cell_px": 8, "light_rays": 300, "stride": stride, "iterations": 4}
    out = lay_out(scene, d, tolerance=0.0, seed=2, **kw)
    assert out.reused_rays[0] == 0
    assert sum(out.reused_rays[1:]) > 0
    camera = ("world_to_clip", "camera_position")
    sub = {k: np.ascontiguousarray(v[::stride, ::stride]) for k, v in d.items() if k not in camera}
    sub.update({k: d[k] for k in camera})
    img, stats = vplace.evaluate(scene, view(sub), out.vpls)
    b = out.best
    assert out.shadow_rays[b] + out.reused_rays[b] == stats.shadow_rays
    diff = img.astype(np.float64) - d["indirect"][::stride, ::stride]
    assert out.errors[b] == pytest.approx(math.sqrt(np.mean(diff**2)), rel=1e-6)  # f32 residuals
    again = lay_out(scene, d, tolerance=0.0, seed=2, **kw)
    assert again.errors == out.errors and again.reused_rays == out.reused_rays
    assert np.array_equal(again.vpls.position, out.vpls.position)
    assert np.array_equal(again.vpls.flux, out.vpls.flux)


def test_layout_input_errors(setup):
    scene, d = setup
    with pytest.raises(vplace.InputError, match="alpha"):
        lay_out(scene, d, alpha=2.0, iterate=False)
    with pytest.raises(vplace.InputError, match="budget"):
        lay_out(scene, d, budget=0, iterate=False)
    with pytest.raises(vplace.InputError, match="at least one View"):
        vplace.layout(scene, [])
    with pytest.raises(vplace.InputError, match="radius"):
        lay_out(scene, d, radius=-1.0, iterate=False)


def test_two_views_share_one_vpl_set(setup):
    scene, d = setup
    kw = {"budget": 64, "cell_px": 8, "light_rays": 300, "iterate": False}
    one = lay_out(scene, d, **kw)
    # The same view twice: its surfaces are counted once, so the emitters and their flux are
    # those of one view.
    twice = vplace.layout(scene, [view(d, "a"), view(d, "b")], vplace.LayoutParams(**kw))
    assert len(twice.counts) == 2 and twice.shared_pixels == 32 * 32
    assert twice.candidates == one.candidates
    flux = lambda out: sum(float(f.astype(np.float64).sum()) for f in out.strata_flux)  # noqa: E731
    assert flux(twice) == pytest.approx(flux(one), rel=1e-6)
    assert twice.counts[1].sum() == 0
    # Two views of different halves of the floor: each holds what only it sees.
    left = floor_view(16, cam=(-0.5, 0.0, 0.95), half=0.5)
    right = floor_view(16, cam=(0.5, 0.0, 0.95), half=0.5)
    both = vplace.layout(
        scene, [view(left, "left"), view(right, "right")], vplace.LayoutParams(**kw)
    )
    assert both.shared_pixels == 0
    alone = [lay_out(scene, v, **kw) for v in (left, right)]
    for i in range(2):
        np.testing.assert_array_equal(both.strata_flux[i], alone[i].strata_flux[0])
    # A light-path hit that either view sees is dropped: its pixels stand for it.
    assert both.light_hits_on_screen == sum(a.light_hits_on_screen for a in alone)


def test_iteration_and_refit_over_two_views(setup):
    scene, _ = setup
    ref = vplace.uniform_vpls(scene, 3000, seed=5)
    left = floor_view(16, cam=(-0.5, 0.0, 0.95), half=0.5)
    right = floor_view(16, cam=(0.5, 0.0, 0.95), half=0.5)
    views = []
    for name, v in (("left", left), ("right", right)):
        v["indirect"], _ = vplace.evaluate(scene, view(v), ref)
        views.append(view(v, name))
    out = vplace.layout(
        scene, views, vplace.LayoutParams(budget=48, cell_px=8, light_rays=300, stride=2)
    )
    assert out.errors and out.error <= out.errors[0]
    r = vplace.refit(scene, views, out.vpls, vplace.RefitParams(stride=2))
    assert r.error_after <= r.error_before
    # The refit's pixels are both views' strided pixels.
    assert r.pixels == 2 * 8 * 8


def test_rsm_baseline(setup):
    scene, _ = setup
    v = vplace.rsm_vpls(scene, 64)
    assert v.position.shape == (64, 3)
    total = float(v.flux.sum(axis=0) @ LUM)
    assert total == pytest.approx(0.5 * POWER, rel=1e-3)  # closed box, albedo 0.5
    w = vplace.rsm_vpls(scene, 64)
    assert np.array_equal(v.position, w.position)
    with pytest.raises(vplace.InputError):
        vplace.rsm_vpls(scene, 0)


def test_brute_force_evaluator_matches_the_bvh(setup):
    scene, d = setup
    v = vplace.uniform_vpls(scene, 16, seed=1)
    a, sa = vplace.evaluate(scene, view(d), v)
    b, sb = vplace.evaluate(scene, view(d), v, brute_force=True)
    assert np.array_equal(a, b)
    assert sa.shadow_rays == sb.shadow_rays


def _display_luma(img: np.ndarray) -> np.ndarray:
    c = np.clip(img.astype(np.float64), 0.0, 1.0)
    s = np.where(c <= 0.0031308, 12.92 * c, 1.055 * c ** (1 / 2.4) - 0.055)
    return s @ LUM


@pytest.mark.parametrize("shape", [(11, 11), (24, 31), (64, 48)])
def test_ssim_matches_scikit_image(shape):
    skimage_metrics = pytest.importorskip("skimage.metrics")
    rng = np.random.default_rng(shape[0] * 100 + shape[1])
    h, w = shape
    ref = (rng.random((h, w, 3)) * 1.5).astype(np.float32)  # some values above 1 clamp
    smooth = np.cumsum(rng.random((h, w, 3)), axis=1) / w
    img = np.clip(ref * 0.7 + 0.3 * smooth + rng.normal(0, 0.05, (h, w, 3)), 0, None).astype(
        np.float32
    )
    ours = vplace.ssim(img, ref)
    theirs = skimage_metrics.structural_similarity(
        _display_luma(img),
        _display_luma(ref),
        gaussian_weights=True,
        sigma=1.5,
        use_sample_covariance=False,
        data_range=1.0,
    )
    assert ours == pytest.approx(theirs, abs=1e-4)
    assert vplace.ssim(ref, ref) == pytest.approx(1.0, abs=1e-12)


def test_ssim_input_errors():
    a = np.zeros((10, 12, 3), dtype=np.float32)
    with pytest.raises(vplace.InputError, match="at least 11"):
        vplace.ssim(a, a)
    b = np.zeros((12, 12, 3), dtype=np.float32)
    with pytest.raises(vplace.InputError, match="image"):
        vplace.ssim(b[:11], b)
    with pytest.raises(vplace.InputError, match="float32"):
        vplace.ssim(b.astype(np.float64), b)


def _noisy_truths(sigma, seed=3):
    """A smooth, textured linear image in the display range and two renders of it with
    independent noise (as two seeds of a path tracer give)."""
    h, w = 72, 96
    y, x = np.mgrid[0:h, 0:w].astype(np.float32)
    clean = 0.25 + 0.12 * np.sin(x / 6) * np.cos(y / 9) + 0.1 * ((x // 16) % 2)
    clean = np.repeat(clean[..., None], 3, axis=2).astype(np.float32)
    rng = np.random.default_rng(seed)
    a, b = (clean * (1 + rng.normal(0, sigma, clean.shape)) for _ in range(2))
    return clean, a.astype(np.float32), b.astype(np.float32)


def test_noise_free_ssim_scores_against_the_truth_without_its_noise():
    clean, a, b = _noisy_truths(0.12)
    estimates = {
        "close": (clean * 0.96 + 0.005).astype(np.float32),
        "flat": np.full_like(clean, float(clean.mean())),
        "half": (clean * 0.5).astype(np.float32),
    }
    assert vplace.ssim(b, a) < 0.8  # the two truths disagree: the noise is not small
    for name, img in estimates.items():
        exact = vplace.ssim(img, clean)
        plain = vplace.ssim(img, a)
        free = vplace.ssim_noise_free(img, a, b)
        assert free == pytest.approx(exact, abs=0.02), name
        if name == "close":
            assert exact - plain > 0.1  # what the truth's noise costs a good image
    # The order of the estimates is the order against the clean image.
    scores = {k: vplace.ssim_noise_free(v, a, b) for k, v in estimates.items()}
    assert scores["close"] > scores["half"] and scores["close"] > scores["flat"]
    # The ceiling: what the clean image itself scores against the noisy truth.
    assert vplace.ssim_ceiling(a, b) == pytest.approx(vplace.ssim(clean, a), abs=0.02)
    # One render twice: plain SSIM, and a ceiling of 1.
    img = estimates["close"]
    assert vplace.ssim_noise_free(img, a, a) == pytest.approx(vplace.ssim(img, a), abs=1e-12)
    assert vplace.ssim_ceiling(a, a) == pytest.approx(1.0, abs=1e-12)


def test_noise_free_rmse_scores_against_the_truth_without_its_noise():
    clean, a, b = _noisy_truths(0.12)
    img = (clean * 1.08).astype(np.float32)  # independent of both renders
    exact = vplace.rmse(img, clean)
    assert vplace.rmse(img, a) > 1.5 * exact
    assert vplace.rmse_noise_free(img, a, img, b) == pytest.approx(exact, rel=0.1)
    # An image built on a render's passes: the same image built on the other render's passes.
    # Here the truth's own render scores about 0 against the noise-free truth, never NaN.
    assert vplace.rmse_noise_free(a, a, b, b) == 0.0
    with pytest.raises(vplace.InputError, match="image_other"):
        vplace.rmse_noise_free(img, a, img[:-1], b)


def test_noise_free_ssim_input_errors():
    _, a, b = _noisy_truths(0.05)
    with pytest.raises(vplace.InputError, match="other"):
        vplace.ssim_noise_free(a, a, b[:-1])
    with pytest.raises(vplace.InputError, match="float32"):
        vplace.ssim_noise_free(a, a, b.astype(np.float64))
    with pytest.raises(vplace.InputError, match="at least 11"):
        vplace.ssim_ceiling(a[:10], b[:10])
    bad = b.copy()
    bad[4, 5, 1] = np.nan
    with pytest.raises(vplace.InputError, match="other holds a non-finite value"):
        vplace.ssim_ceiling(a, bad)
    with pytest.raises(vplace.InputError, match="truth holds a non-finite value"):
        vplace.ssim_noise_free(a, bad, b)
    with pytest.raises(vplace.InputError, match="image"):
        vplace.ssim_noise_free(a[:, :-1], a, b)


def test_layout_with_a_fit_on_the_benchmark_room():
    from vplace import bench_layout

    scene, _ = bench_layout.build_scene(4)
    cap = bench_layout.synthetic_capture(96, 64)
    ref = vplace.uniform_vpls(scene, 256, seed=11)
    ind, _ = vplace.evaluate(scene, view(cap), ref)
    v = view(cap, indirect=ind)
    model = vplace.fit(scene, [v], vplace.FitParams(cell_px=16))
    out = vplace.layout(scene, [v], vplace.LayoutParams(budget=48, light_rays=500), fit=model)
    assert len(out) == 48
    assert out.counts[0].shape == (4, 6)
    assert out.error == min(out.errors)
    # Every lit pixel is a candidate (pixels in the pillar's shadow or facing away are not).
    lit = (cap["diffuse_direct"] @ LUM > 0).sum()
    assert out.candidates >= lit
    assert out.strata_flux[0].shape == (4, 6, 3) and out.strata_flux[0].min() >= 0


def test_multi_bounce_emitters_add_the_indirect_irradiance(setup):
    scene, d = setup
    kw = {"budget": 64, "cell_px": 8, "light_rays": 300, "iterate": False}
    single = lay_out(scene, d, multi_bounce=False, **kw)
    assert single.indirect_source == ["none"]
    # Without an indirect pass or a fit, multi_bounce changes only the off-screen stratum.
    plain = lay_out(scene, d, **kw)
    assert plain.indirect_source == ["none"]
    assert np.allclose(plain.strata_flux[0], single.strata_flux[0])
    assert sum(plain.offscreen_flux) > sum(single.offscreen_flux)
    # A captured DiffInd pass: every pixel emitter reflects DiffDir + DiffInd.
    extra = np.full_like(d["diffuse_direct"], 0.05)
    out = lay_out(scene, {**d, "diffuse_indirect": extra}, **kw)
    assert out.indirect_source == ["captured"]
    ratio = (out.strata_flux[0].astype(np.float64) @ LUM) / (single.strata_flux[0] @ LUM)
    dd = d["diffuse_direct"][..., 0].reshape(4, 8, 4, 8).mean((1, 3))
    assert np.allclose(ratio, (dd + 0.05) / dd, rtol=2e-3)


def test_multi_bounce_uniform_vpls_carry_every_bounce():
    scene = box_scene()
    one = vplace.uniform_vpls(scene, 4000, seed=2)
    all_ = vplace.uniform_vpls(scene, 4000, seed=2, bounces=vplace.MAX_BOUNCES)
    # A closed box of albedo 0.5: bounce k reflects P * 0.5^k, all bounces about P.
    power = POWER
    assert float(one.flux[:, 1].sum()) == pytest.approx(0.5 * power, rel=1e-3)
    assert float(all_.flux[:, 1].sum()) == pytest.approx(power, rel=0.05)
    with pytest.raises(vplace.InputError):
        vplace.uniform_vpls(scene, 10, bounces=0)


def test_predicted_indirect_irradiance_of_a_held_out_view(setup):
    # A held-out view (no DiffInd) with a fit: each pixel emitter reflects DiffDir plus the grey
    # irradiance max(0, prediction_k) / (mean albedo luminance of cell k).
    scene, d = setup
    flat = {**d, "diffuse_direct": np.full_like(d["diffuse_direct"], 0.1)}
    fitted = vplace.fit(scene, [view(flat)], vplace.FitParams(cell_px=8))
    held = view(flat).without_indirect()
    pred = np.maximum(fitted.predict(held), 0.0)
    kw = {"budget": 64, "cell_px": 8, "light_rays": 0, "iterate": False}
    out = vplace.layout(scene, [held], vplace.LayoutParams(**kw), fit=fitted)
    single = vplace.layout(scene, [held], vplace.LayoutParams(multi_bounce=False, **kw))
    assert out.indirect_source == ["predicted"]
    albedo = (d["albedo"] @ LUM).reshape(4, 8, 4, 8).mean((1, 3))
    ratio = (out.strata_flux[0].astype(np.float64) @ LUM) / (single.strata_flux[0] @ LUM)
    assert np.allclose(ratio, (0.1 + pred / albedo) / 0.1, rtol=1e-4)
