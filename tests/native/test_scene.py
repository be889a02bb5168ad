"""The native scene, uniform VPLs, evaluator and metrics: results and bad input."""

import numpy as np
import pytest
import vplace


def quad_scene(lights=None):
    v = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], dtype=np.float32)
    t = np.array([[0, 1, 2], [0, 2, 3]], dtype=np.uint32)
    m = np.zeros(2, dtype=np.uint32)
    a = np.full((1, 3), 0.5, dtype=np.float32)
    if lights is None:
        lights = [vplace.Light.point((0, 0, 1), (10, 10, 10))]
    return v, t, m, a, lights


def floor_gbuffer(w=8):
    xs = (np.arange(w) + 0.5) / w * 2 - 1
    gx, gy = np.meshgrid(xs, -xs)
    pos = np.stack([gx, gy, np.zeros_like(gx)], axis=-1).astype(np.float32)
    nor = np.zeros_like(pos)
    nor[..., 2] = 1
    alb = np.full_like(pos, 0.5)
    return pos, nor, alb, np.ones((w, w), dtype=bool)


def test_scene_and_vpls():
    scene = vplace.Scene(*quad_scene())
    assert scene.triangle_count == 2 and scene.light_count == 1
    assert scene.diagonal == pytest.approx(np.sqrt(8), rel=1e-6)
    v = vplace.uniform_vpls(scene, 50, seed=1)
    assert v["position"].shape == (50, 3) and v["position"].dtype == np.float32
    np.testing.assert_allclose(v["normal"], np.tile([0, 0, 1], (50, 1)), atol=1e-6)
    again = vplace.uniform_vpls(scene, 50, seed=1)
    assert all(np.array_equal(v[k], again[k]) for k in v)


def test_evaluate_matches_formula_for_one_vpl():
    scene = vplace.Scene(*quad_scene())
    pos, nor, alb, cov = floor_gbuffer()
    y = np.array([[0.2, -0.1, 1.0]], dtype=np.float32)
    m = np.array([[0, 0, -1]], dtype=np.float32)
    f = np.array([[1.0, 2.0, 0.5]], dtype=np.float32)
    for profile in ("cosine", "omni"):
        img, stats = vplace.evaluate(scene, pos, nor, alb, cov, y, m, f, profile=profile, r_min=0.0)
        d = y[0] - pos
        r2 = (d**2).sum(-1)
        cos = d[..., 2] / np.sqrt(r2)
        i = cos / np.pi if profile == "cosine" else 0.5 / np.pi
        expect = 0.5 / np.pi * f[0] * (i * cos / r2)[..., None]
        np.testing.assert_allclose(img, expect, rtol=1e-5)
        assert stats["shadow_rays"] == 64


def test_progress_and_cancel():
    scene = vplace.Scene(*quad_scene())
    pos, nor, alb, cov = floor_gbuffer(32)
    vpls = vplace.uniform_vpls(scene, 4)
    p = vplace.Progress()
    vplace.evaluate(scene, pos, nor, alb, cov, *vpls.values(), tile=8, progress=p)
    assert p.total == 16 and p.done == 16
    p.cancel()
    with pytest.raises(vplace.CancelledError):
        vplace.evaluate(scene, pos, nor, alb, cov, *vpls.values(), progress=p)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda a: a.__setitem__(0, a[0].astype(np.float64)), "vertices must have dtype float32"),
        (lambda a: a.__setitem__(0, a[0][:, :2].copy()), "vertices must have shape (N, 3)"),
        (lambda a: a.__setitem__(0, np.asfortranarray(np.tile(a[0], (1, 1)))[::2]), "vertices"),
        (lambda a: a[0].__setitem__((1, 0), np.nan), "vertices holds a non-finite value"),
        (lambda a: a.__setitem__(1, a[1].astype(np.int32)), "triangles must have dtype uint32"),
        (lambda a: a.__setitem__(1, np.zeros((0, 3), np.uint32)), "scene triangles is empty"),
        (lambda a: a[1].__setitem__((0, 0), 7), "triangles[0]: index 7 is out of bounds"),
        (lambda a: a.__setitem__(2, np.zeros(3, np.uint32)), "material_ids: expected (2,)"),
        (lambda a: a[3].__setitem__((0, 0), 2.0), "albedo[0] = 2 is out of range"),
        (lambda a: a.__setitem__(0, [[0, 0, 0]]), "vertices must be a numpy array"),
    ],
)
def test_scene_bad_input(change, message):
    args = list(quad_scene())
    change(args)
    with pytest.raises(vplace.InputError) as err:
        vplace.Scene(*args)
    assert message in str(err.value)


def test_zero_lights_and_bad_vpl_calls():
    scene = vplace.Scene(*quad_scene(lights=[]))
    with pytest.raises(vplace.InputError, match="scene lights is empty"):
        vplace.uniform_vpls(scene, 8)
    scene = vplace.Scene(*quad_scene())
    with pytest.raises(vplace.InputError, match="n = 0 is out of range"):
        vplace.uniform_vpls(scene, 0)
    with pytest.raises(OverflowError):
        vplace.uniform_vpls(scene, -1)
    with pytest.raises(vplace.InputError, match="power"):
        vplace.Scene(*quad_scene(lights=[vplace.Light.point((0, 0, 1), (-1, 0, 0))]))
    with pytest.raises(vplace.InputError, match="half_angle"):
        vplace.Scene(*quad_scene(lights=[vplace.Light.spot((0, 0, 1), (0, 0, -1), 0.0, (1, 1, 1))]))


def test_evaluate_bad_input():
    scene = vplace.Scene(*quad_scene())
    pos, nor, alb, cov = floor_gbuffer()
    v = vplace.uniform_vpls(scene, 4)
    vp, vn, vf = v["position"], v["normal"], v["flux"]
    with pytest.raises(vplace.InputError, match=r"normal must have shape \(8, 8, 3\)"):
        vplace.evaluate(scene, pos, nor[:4], alb, cov, vp, vn, vf)
    with pytest.raises(vplace.InputError, match="covered must have dtype bool"):
        vplace.evaluate(scene, pos, nor, alb, cov.astype(np.uint8), vp, vn, vf)
    bad = pos.copy()
    bad[2, 3, 1] = np.inf
    with pytest.raises(vplace.InputError, match=r"position \(covered pixel\) holds a non-finite"):
        vplace.evaluate(scene, bad, nor, alb, cov, vp, vn, vf)
    cov2 = cov.copy()
    cov2[2, 3] = False  # the same NaN outside the covered pixels is ignored
    img, _ = vplace.evaluate(scene, bad, nor, alb, cov2, vp, vn, vf)
    assert np.isfinite(img).all() and img[2, 3].sum() == 0
    with pytest.raises(vplace.InputError, match=r"vpl_normal must have shape \(4, 3\)"):
        vplace.evaluate(scene, pos, nor, alb, cov, vp, vn[:2], vf)
    with pytest.raises(vplace.InputError, match="profile must be 'cosine' or 'omni'"):
        vplace.evaluate(scene, pos, nor, alb, cov, vp, vn, vf, profile="phong")
    with pytest.raises(vplace.InputError, match="r_min"):
        vplace.evaluate(scene, pos, nor, alb, cov, vp, vn, vf, r_min=-1.0)
    with pytest.raises(vplace.InputError, match="must be unit length"):
        vplace.evaluate(scene, pos, nor, alb, cov, vp, np.zeros_like(vn), vf)
    with pytest.raises(vplace.InputError, match="must be C-contiguous"):
        vplace.evaluate(scene, np.asfortranarray(pos), nor, alb, cov, vp, vn, vf)


def test_metrics():
    a = np.zeros((2, 2, 3), np.float32)
    b = np.ones((2, 2, 3), np.float32)
    assert vplace.rmse(a, b) == pytest.approx(1.0)
    assert vplace.relative_mse(a, b) == pytest.approx(1 / 1.01)
    with pytest.raises(vplace.InputError, match=r"image must have shape \(2, 2, 3\)"):
        vplace.rmse(a[:1], b)
    a[0, 0, 0] = np.nan
    with pytest.raises(vplace.InputError, match="non-finite"):
        vplace.rmse(a, b)


def test_errors_are_vplace_errors():
    assert issubclass(vplace.InputError, vplace.VplaceError)
    assert issubclass(vplace.VplaceError, Exception)
    assert issubclass(vplace.InternalError, vplace.VplaceError)
