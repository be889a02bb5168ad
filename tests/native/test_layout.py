"""vplace.layout, the RSM baseline, the brute-force evaluator and SSIM."""

import math

import numpy as np
import pytest
import vplace

LIGHT = np.array([0.3, -0.2, 1.0])
POWER = 20.0
LUM = np.array([0.2126, 0.7152, 0.0722])


def box_scene() -> vplace.Scene:
    """The box [-1, 1]^2 x [0, 2], inward faces, albedo 0.5, a point light inside."""
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
    ids = np.zeros(len(t), dtype=np.uint32)
    albedo = np.array([[0.5, 0.5, 0.5]], dtype=np.float32)
    return vplace.Scene(v, t, ids, albedo, [vplace.Light.point(LIGHT.tolist(), [POWER] * 3)])


def floor_view(w: int) -> dict:
    """A w x w view of the floor from (0, 0, 1.9) looking straight down (+Y up in the image)."""
    cam = np.array([0.0, 0.0, 1.9])
    f, near, far = 1.9, 0.1, 10.0  # 1 / tan(fov / 2): the floor fills the image
    proj = np.array(
        [
            [f, 0, 0, 0],
            [0, f, 0, 0],
            [0, 0, (far + near) / (near - far), 2 * far * near / (near - far)],
            [0, 0, -1, 0],
        ]
    )
    view = np.eye(4)
    view[:3, 3] = -cam
    xs = ((np.arange(w) + 0.5) / w * 2 - 1).astype(np.float32)
    gx, gy = np.meshgrid(xs, -xs)
    pos = np.stack([gx, gy, np.zeros_like(gx)], axis=-1).astype(np.float32)
    albedo = np.where(pos[..., :1] < 0, [0.8, 0.2, 0.2], [0.5, 0.5, 0.5]).astype(np.float32)
    d = LIGHT - pos
    irr = POWER / (4 * math.pi) * d[..., 2] / np.linalg.norm(d, axis=-1) ** 3
    return {
        "position": np.ascontiguousarray(pos),
        "normal": np.ascontiguousarray(np.broadcast_to(np.float32([0, 0, 1]), pos.shape)),
        "albedo": albedo,
        "covered": np.ones((w, w), dtype=bool),
        "diffuse_direct": np.repeat((irr / math.pi)[..., None], 3, axis=-1).astype(np.float32),
        "camera_position": cam,
        "world_to_clip": proj @ view,
    }


@pytest.fixture(scope="module")
def setup():
    scene = box_scene()
    view = floor_view(32)
    ref = vplace.uniform_vpls(scene, 3000, seed=5)
    indirect, _ = vplace.evaluate(
        scene,
        view["position"],
        view["normal"],
        view["albedo"],
        view["covered"],
        ref["position"],
        ref["normal"],
        ref["flux"],
    )
    view["indirect"] = indirect
    return scene, view


def run_layout(scene, view, **kw):
    keys = ("position", "normal", "albedo", "covered", "diffuse_direct", "indirect")
    capture = {k: view[k] for k in (*keys, "diffuse_indirect") if k in view}
    return vplace.layout(
        scene,
        capture,
        camera_position=view["camera_position"],
        world_to_clip=view["world_to_clip"],
        **kw,
    )


def test_budget_energy_and_determinism(setup):
    scene, view = setup
    totals = []
    for alpha in (0.0, 0.5, 1.0):
        out = run_layout(
            scene, view, budget=40, alpha=alpha, cell_px=8, light_rays=300, iterate=False
        )
        assert len(out) == 40
        assert out.position.shape == out.normal.shape == out.flux.shape == (40, 3)
        assert int(out.counts.sum()) + out.offscreen_count + out.pool_count == 40
        assert out.counts.shape == (4, 4)
        assert out.errors == [] and out.best is None
        totals.append(float((out.flux.astype(np.float64) @ LUM).sum()))
    # The layout moves accuracy, not energy.
    assert max(totals) - min(totals) < 1e-4 * max(totals)
    a = run_layout(scene, view, budget=40, cell_px=8, light_rays=300, seed=3, iterate=False)
    b = run_layout(scene, view, budget=40, cell_px=8, light_rays=300, seed=3, iterate=False)
    c = run_layout(scene, view, budget=40, cell_px=8, light_rays=300, seed=4, iterate=False)
    assert np.array_equal(a.position, b.position) and np.array_equal(a.flux, b.flux)
    assert not np.array_equal(a.position, c.position)


def test_guided_allocation_follows_the_prediction(setup):
    scene, view = setup
    pred = np.zeros((4, 4))
    pred[0, 0] = 1.0
    base = run_layout(scene, view, budget=64, alpha=0.0, cell_px=8, light_rays=0, iterate=False)
    # A fit is optional: the native call takes the per-cell prediction directly.
    d = vplace._native.layout(
        scene,
        view["position"],
        view["normal"],
        view["albedo"],
        view["covered"],
        view["diffuse_direct"],
        view["camera_position"].tolist(),
        view["world_to_clip"].tolist(),
        predicted=pred,
        budget=64,
        alpha=1.0,
        cell_px=8,
        light_rays=0,
    )
    assert d["counts"][0, 0] > base.counts[0, 0]
    assert int(d["counts"].sum()) + d["pool_count"] == 64


def test_iteration_returns_its_best(setup):
    scene, view = setup
    out = run_layout(
        scene, view, budget=32, cell_px=8, light_rays=300, stride=2, iterations=4, tolerance=0.0
    )
    assert 1 <= len(out.errors) <= 4
    assert out.best is not None and out.error == min(out.errors)
    assert out.error <= out.errors[0]
    assert len(out) == 32
    assert len(out.seconds) == len(out.shadow_rays) == len(out.errors)


def test_iteration_reuses_shadow_rays_without_changing_the_result(setup):
    # Each iteration's error is the RMSE of its VPLs' image on the strided grid, whether its
    # shadow rays were traced or reused from the previous iteration.
    scene, view = setup
    stride = 2
    kw = {"budget": 48, "cell_px": 8, "light_rays": 300, "stride": stride, "iterations": 4}
    out = run_layout(scene, view, tolerance=0.0, seed=2, **kw)
    assert out.reused_rays[0] == 0
    assert sum(out.reused_rays[1:]) > 0
    sub = [
        np.ascontiguousarray(view[k][::stride, ::stride])
        for k in ("position", "normal", "albedo", "covered")
    ]
    img, stats = vplace.evaluate(scene, *sub, out.position, out.normal, out.flux)
    b = out.best
    assert out.shadow_rays[b] + out.reused_rays[b] == stats["shadow_rays"]
    diff = img.astype(np.float64) - view["indirect"][::stride, ::stride]
    assert out.errors[b] == pytest.approx(math.sqrt(np.mean(diff**2)), rel=1e-6)  # f32 residuals
    again = run_layout(scene, view, tolerance=0.0, seed=2, **kw)
    assert again.errors == out.errors and again.reused_rays == out.reused_rays
    assert np.array_equal(again.position, out.position) and np.array_equal(again.flux, out.flux)


def test_layout_input_errors(setup):
    scene, view = setup
    with pytest.raises(vplace.InputError, match="diffuse_direct"):
        run_layout(scene, {**view, "diffuse_direct": view["diffuse_direct"][:4]})
    with pytest.raises(vplace.InputError, match="alpha"):
        run_layout(scene, view, alpha=2.0, iterate=False)
    with pytest.raises(vplace.InputError, match="budget"):
        run_layout(scene, view, budget=0, iterate=False)
    with pytest.raises(vplace.InputError, match="diffuse_direct"):
        vplace.layout(
            scene,
            {k: view[k] for k in ("position", "normal", "albedo", "covered")},
            camera_position=[0, 0, 1],
            world_to_clip=np.eye(4),
        )


def test_rsm_baseline(setup):
    scene, _ = setup
    v = vplace.rsm_vpls(scene, 64)
    assert v["position"].shape == (64, 3)
    total = float(v["flux"].sum(axis=0) @ LUM)
    assert total == pytest.approx(0.5 * POWER, rel=1e-3)  # closed box, albedo 0.5
    w = vplace.rsm_vpls(scene, 64)
    assert np.array_equal(v["position"], w["position"])
    with pytest.raises(vplace.InputError):
        vplace.rsm_vpls(scene, 0)


def test_brute_force_evaluator_matches_the_bvh(setup):
    scene, view = setup
    v = vplace.uniform_vpls(scene, 16, seed=1)
    args = (
        scene,
        view["position"],
        view["normal"],
        view["albedo"],
        view["covered"],
        v["position"],
        v["normal"],
        v["flux"],
    )
    a, sa = vplace.evaluate(*args)
    b, sb = vplace.evaluate(*args, brute_force=True)
    assert np.array_equal(a, b)
    assert sa["shadow_rays"] == sb["shadow_rays"]


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


def test_layout_with_a_fit_on_the_benchmark_room():
    from vplace import bench_layout

    scene, _ = bench_layout.build_scene(4)
    cap = bench_layout.synthetic_capture(96, 64)
    g = (cap["position"], cap["normal"], cap["albedo"], cap["covered"])
    ref = vplace.uniform_vpls(scene, 256, seed=11)
    ind, _ = vplace.evaluate(scene, *g, ref["position"], ref["normal"], ref["flux"])
    cap["gi"] = (cap["direct"] + ind).astype(np.float32)
    model = vplace.fit(cap, cell_px=16)
    out = vplace.layout(
        scene,
        cap,
        camera_position=cap["camera_position"],
        world_to_clip=cap["world_to_clip"],
        fit=model,
        budget=48,
        light_rays=500,
    )
    assert len(out) == 48
    assert out.counts.shape == (4, 6)
    assert out.error == min(out.errors)
    # Every lit pixel is a candidate (pixels in the pillar's shadow or facing away are not).
    lit = (cap["diffuse_direct"] @ LUM > 0).sum()
    assert out.candidates >= lit
    assert out.strata_flux.shape == (4, 6, 3) and out.strata_flux.min() >= 0


def test_multi_bounce_emitters_add_the_indirect_irradiance(setup):
    scene, view = setup
    kw = {"budget": 64, "cell_px": 8, "light_rays": 300, "iterate": False}
    single = run_layout(scene, view, multi_bounce=False, **kw)
    assert single.indirect_source == "none"
    # Without an indirect pass or a fit, multi_bounce changes only the off-screen stratum.
    plain = run_layout(scene, view, **kw)
    assert plain.indirect_source == "none"
    assert np.allclose(plain.strata_flux, single.strata_flux)
    assert sum(plain.offscreen_flux) > sum(single.offscreen_flux)
    # A captured DiffInd pass: every pixel emitter reflects DiffDir + DiffInd.
    extra = np.full_like(view["diffuse_direct"], 0.05)
    captured = {**view, "diffuse_indirect": extra}
    out = run_layout(scene, captured, **kw)
    assert out.indirect_source == "captured"
    ratio = (out.strata_flux.astype(np.float64) @ LUM) / (single.strata_flux @ LUM)
    dd = view["diffuse_direct"][..., 0].reshape(4, 8, 4, 8).mean((1, 3))
    assert np.allclose(ratio, (dd + 0.05) / dd, rtol=2e-3)
    with pytest.raises(vplace.InputError, match="diffuse_indirect"):
        run_layout(scene, {**view, "diffuse_indirect": extra[:4]}, **kw)


def test_multi_bounce_uniform_vpls_carry_every_bounce():
    scene = box_scene()
    one = vplace.uniform_vpls(scene, 4000, seed=2)
    all_ = vplace.uniform_vpls(scene, 4000, seed=2, bounces=vplace.MAX_BOUNCES)
    # A closed box of albedo 0.5: bounce k reflects P * 0.5^k, all bounces about P.
    power = POWER
    assert float(one["flux"][:, 1].sum()) == pytest.approx(0.5 * power, rel=1e-3)
    assert float(all_["flux"][:, 1].sum()) == pytest.approx(power, rel=0.05)
    with pytest.raises(vplace.InputError):
        vplace.uniform_vpls(scene, 10, bounces=0)


def test_predicted_indirect_irradiance_of_a_held_out_view(setup):
    from vplace.layout import _emitter_irradiance

    _, view = setup
    predicted = np.arange(16, dtype=np.float64).reshape(4, 4) * 0.01
    irr, source = _emitter_irradiance(view, predicted, 8, True)
    assert source == "predicted" and irr.shape == view["diffuse_direct"].shape
    albedo = (view["albedo"] @ LUM).reshape(4, 8, 4, 8).mean((1, 3))
    added = (irr - view["diffuse_direct"])[..., 1].reshape(4, 8, 4, 8)
    assert np.allclose(added, (predicted / albedo)[:, None, :, None], rtol=1e-5)
    with pytest.raises(vplace.InputError, match="prediction has shape"):
        _emitter_irradiance(view, predicted[:2], 8, True)
    assert _emitter_irradiance(view, predicted, 8, False)[1] == "none"
