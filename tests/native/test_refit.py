"""vplace.refit: non-negative least squares on the VPL powers against the indirect image."""

import numpy as np
import pytest
import vplace
from test_layout import box_scene, floor_view

G = ("position", "normal", "albedo", "covered")


def inward_vpls() -> dict:
    """VPLs on the ceiling and walls of the test box facing in, and one on the floor facing up
    (no floor pixel sees it)."""
    rows = [
        ((0.5, 0.5, 1.99), (0, 0, -1), (1.0, 1.0, 1.0)),
        ((-0.6, 0.2, 1.99), (0, 0, -1), (0.5, 0.8, 1.0)),
        ((0.0, -0.7, 1.99), (0, 0, -1), (1.2, 0.6, 0.3)),
        ((-0.99, 0.0, 0.6), (1, 0, 0), (0.8, 0.8, 0.8)),
        ((0.99, -0.4, 1.0), (-1, 0, 0), (0.4, 1.0, 0.4)),
        ((0.2, 0.99, 0.3), (0, -1, 0), (1.0, 0.5, 0.5)),
        ((0.0, 0.0, 0.01), (0, 0, 1), (2.0, 2.0, 2.0)),
    ]
    return {
        k: np.array([r[i] for r in rows], dtype=np.float32)
        for i, k in enumerate(("position", "normal", "flux"))
    }


def render(scene, view, vpls) -> np.ndarray:
    img, _ = vplace.evaluate(
        scene, *(view[k] for k in G), vpls["position"], vpls["normal"], vpls["flux"]
    )
    return img


@pytest.fixture(scope="module")
def setup():
    scene = box_scene()
    view = floor_view(32)
    ref = vplace.uniform_vpls(scene, 3000, seed=5)
    view["indirect"] = render(scene, view, ref)
    return scene, view


def test_recovers_known_scales(setup):
    scene, view = setup
    base = inward_vpls()
    truth = np.array([0.5, 2.0, 1.0, 0.0, 1.5, 0.8, 3.0])
    target = render(scene, view, {**base, "flux": (base["flux"] * truth[:, None]).astype("f4")})
    capture = {k: view[k] for k in G}
    out = vplace.refit(scene, capture, base, indirect=target, stride=2, ridge=0.0)
    assert isinstance(out, vplace.Refit)
    assert len(out) == 7 and out.pixels == 16 * 16
    np.testing.assert_allclose(out.scales[:6], truth[:6], atol=1e-4)
    assert out.scales[6] == pytest.approx(1.0, abs=1e-9)  # unseen: the ridge keeps its power
    assert out.error_after < 1e-3 * out.error_before
    assert out.flux.dtype == np.float32 and out.flux.shape == (7, 3)
    np.testing.assert_allclose(out.flux, base["flux"] * out.scales[:, None], rtol=1e-6)
    assert np.array_equal(out.position, base["position"])
    assert np.array_equal(out.normal, base["normal"])
    assert out.shadow_rays == 6 * out.pixels and out.seconds > 0
    # The default ridge pulls toward 1 (a trade: less error reduction on this tiny case, no
    # overfitting on real views), and a weaker one lands closer to the truth.
    near = vplace.refit(scene, capture, base, indirect=target, stride=2)
    weak = vplace.refit(scene, capture, base, indirect=target, stride=2, ridge=1e-3)
    assert weak.error_after < near.error_after < near.error_before
    np.testing.assert_allclose(weak.scales[:6], truth[:6], atol=0.05)
    assert np.abs(near.scales[:6] - 1).sum() < np.abs(weak.scales[:6] - 1).sum()


def test_never_worse_and_deterministic(setup):
    scene, view = setup
    vpls = vplace.uniform_vpls(scene, 48, seed=2)
    for ridge in (0.0, 1e-3, 1.0):
        a = vplace.refit(scene, view, vpls, ridge=ridge)
        b = vplace.refit(scene, view, vpls, ridge=ridge)
        assert a.error_after <= a.error_before
        assert np.array_equal(a.scales, b.scales) and a.error_after == b.error_after
    # The first bounce of 3000 VPLs from 48: the refit helps.
    assert a.error_after < a.error_before
    # The error before is the RMSE of the evaluator's image on the strided grid.
    img = render(scene, view, vpls)
    assert a.error_before == pytest.approx(
        vplace.rmse(img[::4, ::4].copy(), view["indirect"][::4, ::4].copy()), rel=1e-5
    )


def test_scales_stay_non_negative(setup):
    scene, view = setup
    base = inward_vpls()
    out = vplace.refit(scene, {k: view[k] for k in G}, base, indirect=-view["indirect"])
    assert out.scales.min() >= 0.0 and out.flux.min() >= 0.0
    np.testing.assert_array_equal(out.scales[:6], 0.0)  # all the light they give is wrong
    assert out.error_after <= out.error_before


def test_gi_and_direct_or_indirect(setup):
    scene, view = setup
    vpls = vplace.uniform_vpls(scene, 16, seed=1)
    direct = np.full_like(view["indirect"], 0.25)
    cap = {**{k: view[k] for k in G}, "gi": view["indirect"] + direct, "direct": direct}
    a = vplace.refit(scene, cap, vpls)
    b = vplace.refit(scene, cap, vpls, indirect=(cap["gi"] - direct).astype(np.float32))
    np.testing.assert_array_equal(a.scales, b.scales)


def test_a_layout_passes_through(setup):
    scene, view = setup
    capture = {k: view[k] for k in (*G, "diffuse_direct", "indirect")}
    lay = vplace.layout(
        scene,
        capture,
        camera_position=view["camera_position"],
        world_to_clip=view["world_to_clip"],
        budget=32,
        cell_px=8,
        light_rays=300,
        iterations=2,
    )
    out = vplace.refit(scene, capture, lay, stride=2)
    assert len(out) == len(lay) == 32
    assert np.array_equal(out.position, lay.position)
    np.testing.assert_allclose(out.flux, lay.flux * out.scales[:, None], rtol=1e-6)
    assert out.error_after <= out.error_before


def test_progress_and_cancel(setup):
    scene, view = setup
    vpls = vplace.uniform_vpls(scene, 8, seed=1)
    p = vplace.Progress()
    vplace.refit(scene, view, vpls, progress=p)
    assert p.total >= 2 and p.done == p.total
    p = vplace.Progress()
    p.cancel()
    with pytest.raises(vplace.CancelledError):
        vplace.refit(scene, view, vpls, progress=p)


def test_input_errors(setup):
    scene, view = setup
    vpls = vplace.uniform_vpls(scene, 8, seed=1)
    cap = {k: view[k] for k in G}
    ind = view["indirect"]
    with pytest.raises(vplace.InputError, match="indirect"):
        vplace.refit(scene, cap, vpls, indirect=ind[:16])
    with pytest.raises(vplace.InputError, match="float32"):
        vplace.refit(scene, cap, vpls, indirect=ind.astype(np.float64))
    nan = ind.copy()
    nan[3, 5, 1] = np.nan
    with pytest.raises(vplace.InputError, match="non-finite"):
        vplace.refit(scene, cap, vpls, indirect=nan)
    empty = {k: np.zeros((0, 3), np.float32) for k in ("position", "normal", "flux")}
    with pytest.raises(vplace.InputError, match="VPLs is empty"):
        vplace.refit(scene, cap, empty, indirect=ind)
    with pytest.raises(vplace.InputError, match="vpl_flux"):
        vplace.refit(scene, cap, {**vpls, "flux": vpls["flux"][:3]}, indirect=ind)
    with pytest.raises(vplace.InputError, match="'flux'"):
        vplace.refit(scene, cap, {"position": vpls["position"], "normal": vpls["normal"]})
    with pytest.raises(vplace.InputError, match="'gi'"):
        vplace.refit(scene, cap, vpls)
    with pytest.raises(vplace.InputError, match="albedo"):
        vplace.refit(scene, {**cap, "albedo": cap["albedo"][:, :8]}, vpls, indirect=ind)
    with pytest.raises(vplace.InputError, match="stride"):
        vplace.refit(scene, cap, vpls, indirect=ind, stride=0)
    with pytest.raises(vplace.InputError, match="ridge"):
        vplace.refit(scene, cap, vpls, indirect=ind, ridge=-1.0)
    with pytest.raises(vplace.InputError, match="profile"):
        vplace.refit(scene, cap, vpls, indirect=ind, profile="spot")
