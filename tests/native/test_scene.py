"""The native scene, views, VPL sets, uniform VPLs, evaluator and metrics: results and bad
input."""

import numpy as np
import pytest
import vplace
import vplace.job
from views import view


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
    return {"position": pos, "normal": nor, "albedo": alb, "covered": np.ones((w, w), bool)}


def one_vpl(profile="cosine", radius=0.0):
    return vplace.VplSet(
        np.array([[0.2, -0.1, 1.0]], np.float32),
        np.array([[0, 0, -1]], np.float32),
        np.array([[1.0, 2.0, 0.5]], np.float32),
        profile=profile,
        radius=radius,
    )


def test_scene_and_vpls():
    scene = vplace.Scene(*quad_scene())
    assert scene.triangle_count == 2 and scene.light_count == 1
    assert scene.diagonal == pytest.approx(np.sqrt(8), rel=1e-6)
    assert scene.near_field_radius == pytest.approx(vplace.NEAR_FIELD_FRACTION * scene.diagonal)
    v = vplace.uniform_vpls(scene, 50, seed=1)
    assert len(v) == 50 and v.position.shape == (50, 3) and v.position.dtype == np.float32
    assert v.profile == "cosine" and v.radius == pytest.approx(scene.near_field_radius)
    np.testing.assert_allclose(v.normal, np.tile([0, 0, 1], (50, 1)), atol=1e-6)
    again = vplace.uniform_vpls(scene, 50, seed=1)
    for k in ("position", "normal", "flux"):
        assert np.array_equal(getattr(v, k), getattr(again, k))
    omni = vplace.uniform_vpls(scene, 50, seed=1, profile="omni", radius=0.25)
    assert omni.radius == 0.25 and np.array_equal(omni.blender_power, 2 * omni.flux)
    assert np.array_equal(v.blender_power, v.flux)


def test_vpl_set_checks_its_input():
    p = np.zeros((2, 3), np.float32)
    n = np.tile(np.float32([0, 0, 1]), (2, 1))
    f = np.ones((2, 3), np.float32)
    s = vplace.VplSet(p, n, f)
    assert len(s) == 2 and s.radius == 0.0
    assert np.array_equal(s.with_flux(2 * f).flux, 2 * f)
    with pytest.raises(vplace.InputError, match="must be unit length"):
        vplace.VplSet(p, np.zeros_like(n), f)
    with pytest.raises(vplace.InputError, match=r"normal must have shape \(2, 3\)"):
        vplace.VplSet(p, n[:1], f)
    with pytest.raises(vplace.InputError, match="radius"):
        vplace.VplSet(p, n, f, radius=-1.0)
    with pytest.raises(vplace.InputError, match="profile must be 'cosine' or 'omni'"):
        vplace.VplSet(p, n, f, profile="phong")
    with pytest.raises(vplace.InputError, match="flux"):
        vplace.VplSet(p, n, -f)


def test_evaluate_matches_formula_for_one_vpl():
    scene = vplace.Scene(*quad_scene())
    g = floor_gbuffer()
    pos = g["position"]
    for profile in ("cosine", "omni"):
        vpls = one_vpl(profile)
        img, stats = vplace.evaluate(scene, view(g), vpls)
        y, f = vpls.position[0], vpls.flux[0]
        d = y - pos
        r2 = (d**2).sum(-1)
        cos = d[..., 2] / np.sqrt(r2)
        i = cos / np.pi if profile == "cosine" else 0.5 / np.pi
        expect = 0.5 / np.pi * f * (i * cos / r2)[..., None]
        np.testing.assert_allclose(img, expect, rtol=1e-5)
        assert stats.shadow_rays == 64 and stats.pairs == 64


def test_progress_and_cancel():
    scene = vplace.Scene(*quad_scene())
    v = view(floor_gbuffer(32))
    vpls = vplace.uniform_vpls(scene, 4)
    p = vplace.Progress()
    vplace.evaluate(scene, v, vpls, tile=8, progress=p)
    assert p.total == 16 and p.done == 16
    p.cancel()
    with pytest.raises(vplace.CancelledError):
        vplace.evaluate(scene, v, vpls, progress=p)


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


def test_view_checks_its_passes_once():
    g = floor_gbuffer()
    with pytest.raises(vplace.InputError, match=r"normal must have shape \(8, 8, 3\)"):
        view(g, normal=g["normal"][:4])
    with pytest.raises(vplace.InputError, match=r"diffuse_color must have shape \(8, 8, 3\)"):
        view(g, diffuse_color=g["albedo"][:, :4])
    with pytest.raises(vplace.InputError, match="covered must have dtype bool"):
        vplace.View(
            **{k: g[k] for k in ("position", "normal", "albedo")},
            covered=g["covered"].astype(np.uint8),
            depth=np.ones((8, 8), np.float32),
            direct=g["albedo"],
            diffuse_direct=g["albedo"],
            camera_position=[0, 0, 1],
            world_to_clip=np.eye(4).tolist(),
        )
    with pytest.raises(vplace.InputError, match="must be C-contiguous"):
        vplace.View(
            position=np.asfortranarray(g["position"]),
            **{k: g[k] for k in ("normal", "albedo", "covered")},
            depth=np.ones((8, 8), np.float32),
            direct=g["albedo"],
            diffuse_direct=g["albedo"],
            camera_position=[0, 0, 1],
            world_to_clip=np.eye(4).tolist(),
        )
    with pytest.raises(vplace.InputError, match="singular"):
        view(g, world_to_clip=np.zeros((4, 4)))
    # A non-finite G-buffer value on a covered pixel is an error naming the pass and pixel ...
    bad = g["position"].copy()
    bad[2, 3, 1] = np.inf
    with pytest.raises(vplace.InputError, match=r'position \(covered pixel 19 of view "view"\)'):
        view(g, position=bad)
    # ... and ignored on an uncovered one.
    cov = g["covered"].copy()
    cov[2, 3] = False
    scene = vplace.Scene(*quad_scene())
    img, _ = vplace.evaluate(scene, view(g, position=bad, covered=cov), one_vpl())
    assert np.isfinite(img).all() and img[2, 3].sum() == 0
    # A non-finite lighting value masks the pixel and is counted.
    lit = np.full_like(g["albedo"], 0.1)
    lit[4, 4, 0] = np.nan
    v = view(g, diffuse_direct=lit)
    assert v.masked_pixels == 1 and not v.covered[4, 4] and v.covered.sum() == 63
    assert not v.has_indirect and view(g, indirect=lit).has_indirect
    assert not view(g, indirect=lit).without_indirect().has_indirect


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
    assert list(vplace.LUMINANCE) == pytest.approx([0.2126, 0.7152, 0.0722])


def test_errors_are_vplace_errors():
    assert issubclass(vplace.InputError, vplace.VplaceError)
    assert issubclass(vplace.VplaceError, Exception)
    assert issubclass(vplace.InternalError, vplace.VplaceError)


def test_vpl_radii_are_the_patches_they_stand_for():
    # A 10 x 10 grid of spacing a: an inner VPL's 8th nearest VPL is a diagonal one (a sqrt 2),
    # so it stands for a patch of radius a sqrt 2 / sqrt 8 = a / 2, and its disk covers
    # DISK_PATCHES of them: radius a / 2 * sqrt(DISK_PATCHES); an isolated one gets the cap.
    a = 0.1
    grid = [(a * (i % 10), a * (i // 10), 0.0) for i in range(100)] + [(40.0, 0.0, 0.0)]
    p = np.array(grid, np.float32)
    n = np.tile(np.float32([0, 0, 1]), (len(p), 1))
    s = vplace.VplSet(p, n, np.ones_like(p), radius=0.01)
    r = s.radii
    assert r.dtype == np.float32 and r.shape == (101,)
    assert vplace.DISK_PATCHES == 2.0
    assert r[55] == pytest.approx(a / 2 * np.sqrt(2.0), rel=1e-5)
    assert r[-1] == pytest.approx(vplace.MAX_RADIUS_FACTOR * 0.01, rel=1e-6)
    assert (r >= 0.01).all() and (r <= vplace.MAX_RADIUS_FACTOR * 0.01 * (1 + 1e-6)).all()
    assert np.array_equal(s.with_flux(2 * np.ones_like(p)).radii, r)  # positions only
    assert (vplace.VplSet(p, n, np.ones_like(p), profile="omni", radius=0.01).radii == 0).all()
    assert (vplace.VplSet(p, n, np.ones_like(p)).radii == 0).all()


def corner_gbuffer(w=24, s=0.02):
    """A concave corner seen head-on: the wall ``x = 0`` (left half, normal +X, unlit) and the
    floor ``z = 0`` (right half, normal +Z, lit: diffuse direct 1)."""
    c = np.arange(w)
    left = c < w // 2
    z = np.where(left, (w // 2 - c - 0.5) * s, 0.0)
    x = np.where(left, 0.0, (c - w // 2 + 0.5) * s)
    y = (np.arange(w) + 0.5) * s
    pos = np.stack(np.broadcast_arrays(x[None, :], y[:, None], z[None, :]), -1)
    nor = np.where(left[None, :, None], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]) * np.ones((w, w, 1))
    dd = np.where(left[None, :, None], 0.0, 1.0) * np.ones((w, w, 3))
    return {
        "position": pos.astype(np.float32),
        "normal": nor.astype(np.float32),
        "albedo": np.full((w, w, 3), 0.5, np.float32),
        "covered": np.ones((w, w), bool),
        "diffuse_direct": dd.astype(np.float32),
    }


def corner_vpls(flux: float) -> vplace.VplSet:
    """Two floor-facing VPLs above :func:`corner_gbuffer`'s corner, each of ``flux`` a channel."""
    return vplace.VplSet(
        np.array([[0.3, 0.2, 0.5], [0.1, 0.3, 0.4]], np.float32),
        np.array([[0, 0, -1], [0, 0, -1]], np.float32),
        np.full((2, 3), flux, np.float32),
        radius=0.05,
    )


def test_near_field_light_fills_a_corner_only_when_asked():
    w = 24
    v = view(corner_gbuffer(w))
    scene = vplace.Scene(*quad_scene())
    vpls = corner_vpls(0.0)
    plain, stats = vplace.evaluate(scene, v, vpls)
    near, near_stats = vplace.evaluate(scene, v, vpls, near_field=True)
    assert stats.near_field_distance == 0.0 and not plain.any()
    # Half the median of the set's near-field radii.
    assert near_stats.near_field_distance == pytest.approx(0.5 * float(np.median(vpls.radii)))
    assert vpls.near_field_distance == near_stats.near_field_distance
    omni = vplace.VplSet(vpls.position, vpls.normal, vpls.flux, profile="omni", radius=0.05)
    assert omni.near_field_distance == 0.0
    # The unlit wall beside the corner takes light from the lit floor; the floor takes none
    # from the dark wall, and the wall's light falls off away from the corner.
    row = near[w // 2, :, 0]
    assert row[w // 2 - 1] > 0.05 and (row[w // 2 :] == 0).all()
    assert row[w // 2 - 1] > row[w // 2 - 3] >= row[0]


def test_the_gather_alone_is_what_evaluate_adds_and_bad_images_are_refused():
    w = 24
    v = view(corner_gbuffer(w))
    scene = vplace.Scene(*quad_scene())
    vpls = corner_vpls(0.2)
    plain, _ = vplace.evaluate(scene, v, vpls, near_field=False)
    gathered, _ = vplace.evaluate(scene, v, vpls, near_field=True)
    near = vplace.near_field_light(scene, v, plain, vpls.near_field_distance)
    assert near.shape == (w, w, 3) and near.dtype == np.float32 and near.max() > 0.05
    # Bit for bit what evaluate adds, from one evaluation of the VPLs.
    assert np.array_equal(plain + near, gathered)
    assert not vplace.near_field_light(scene, v, plain, 0.0).any()
    with pytest.raises(vplace.InputError, match=r"vpl_indirect must have shape \(24, 24, 3\)"):
        vplace.near_field_light(scene, v, plain[:-1], 0.1)
    with pytest.raises(vplace.InputError, match="dtype float32"):
        vplace.near_field_light(scene, v, plain.astype(np.float64), 0.1)
    bad = plain.copy()
    bad[3, 5, 1] = np.nan
    with pytest.raises(vplace.InputError, match=r"non-finite value at pixel \(3, 5\)"):
        vplace.near_field_light(scene, v, bad, 0.1)
    for distance in (-0.1, float("inf"), float("nan")):
        with pytest.raises(vplace.InputError, match="distance must be finite"):
            vplace.near_field_light(scene, v, plain, distance)


def test_the_gather_needs_the_vpls_light_only_where_its_reach_says():
    w = 24
    v = view(corner_gbuffer(w))
    scene = vplace.Scene(*quad_scene())
    vpls = corner_vpls(0.2)
    distance = vpls.near_field_distance
    plain, _ = vplace.evaluate(scene, v, vpls, near_field=False)
    near = vplace.near_field_light(scene, v, plain, distance)
    receivers, sources = vplace.near_field_reach(v, distance)
    assert receivers.shape == sources.shape == (w, w) and receivers.dtype == np.bool_
    assert receivers.any() and not receivers.all() and not near[~receivers].any()
    # Evaluated only where the reach says, the VPLs give those pixels the same light, the
    # rest none, and the gather comes out bit for bit the same.
    part, stats = vplace.evaluate(scene, v.restricted(sources), vpls, near_field=False)
    assert np.array_equal(part[sources], plain[sources]) and not part[~sources].any()
    assert np.array_equal(vplace.near_field_light(scene, v, part, distance), near)
    full = vplace.evaluate(scene, v, vpls, near_field=False)[1]
    assert stats.pairs < full.pairs
    assert not vplace.near_field_reach(v, 0.0)[0].any()
    with pytest.raises(vplace.InputError, match="distance"):
        vplace.near_field_reach(v, float("nan"))
    with pytest.raises(vplace.InputError, match=r"mask must have shape \(24, 24\)"):
        v.restricted(sources[:-1])
    with pytest.raises(vplace.InputError, match="dtype bool"):
        v.restricted(sources.astype(np.float32))


def test_a_set_takes_the_near_field_where_its_captures_show_it():
    w = 24
    g = corner_gbuffer(w)
    scene = vplace.Scene(*quad_scene())
    vpls = corner_vpls(0.2)
    plain, _ = vplace.evaluate(scene, view(g), vpls, near_field=False)
    gathered, _ = vplace.evaluate(scene, view(g), vpls, near_field=True)
    assert (gathered >= plain).all() and (gathered - plain).max() > 0.05
    # Captures whose indirect light holds the corner's light: on, and the set says so.
    corner = vplace.job.choose_near_field(scene, [view(g, indirect=gathered)], vpls)
    assert corner.on and corner.with_gather < 1e-6 < corner.without
    assert corner.views == 1 and corner.distance == pytest.approx(vpls.near_field_distance)
    # Captures without it: off (the gather would count light the captures do not have).
    flat = vplace.job.choose_near_field(scene, [view(g, indirect=plain)], vpls)
    assert not flat.on and flat.without < 1e-6 < flat.with_gather
    # Nothing to judge on (no indirect image), or nothing to gather (points): off.
    assert not vplace.job.choose_near_field(scene, [view(g)], vpls).on
    points = vplace.VplSet(vpls.position, vpls.normal, vpls.flux, profile="omni", radius=0.05)
    assert not vplace.job.choose_near_field(scene, [view(g, indirect=gathered)], points).on
    # evaluate() follows the set's own choice unless told, and the choice survives new flux.
    on = vpls.with_near_field(True)
    assert on.near_field and not vpls.near_field and "near field" in repr(on)
    assert np.array_equal(vplace.evaluate(scene, view(g), on)[0], gathered)
    assert np.array_equal(vplace.evaluate(scene, view(g), on, near_field=False)[0], plain)
    assert np.array_equal(vplace.evaluate(scene, view(g), vpls)[0], plain)
    assert on.with_flux(np.asarray(on.flux)).near_field


def _open_room_in_dome(dome):
    """A room [-1, 1]^2 x [0, 2] open on its -y side inside a cube of half size ``dome``."""
    quads = [
        [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)],
        [(-1, -1, 2), (-1, 1, 2), (1, 1, 2), (1, -1, 2)],
        [(-1, 1, 0), (1, 1, 0), (1, 1, 2), (-1, 1, 2)],
        [(-1, -1, 0), (-1, 1, 0), (-1, 1, 2), (-1, -1, 2)],
        [(1, -1, 0), (1, -1, 2), (1, 1, 2), (1, 1, 0)],
    ]
    d = dome
    quads += [
        [(-d, -d, -d), (-d, d, -d), (d, d, -d), (d, -d, -d)],
        [(-d, -d, d), (d, -d, d), (d, d, d), (-d, d, d)],
        [(-d, -d, -d), (d, -d, -d), (d, -d, d), (-d, -d, d)],
        [(-d, d, -d), (-d, d, d), (d, d, d), (d, d, -d)],
        [(-d, -d, -d), (-d, -d, d), (-d, d, d), (-d, d, -d)],
        [(d, -d, -d), (d, d, -d), (d, d, d), (d, -d, d)],
    ]
    v = np.array([p for q in quads for p in q], dtype=np.float32)
    t = np.array(
        [[4 * k, 4 * k + 1, 4 * k + 2] for k in range(len(quads))]
        + [[4 * k, 4 * k + 2, 4 * k + 3] for k in range(len(quads))],
        dtype=np.uint32,
    )
    return v, t


def test_where_a_camera_looks_keeps_a_sky_dome_out_of_the_working_scale():
    """A camera 1.5 m outside a room open towards it, inside a 2 km dome: all round it sees
    mostly the dome, looking in it sees the room (``looks``); bad ``looks`` are refused."""
    v, t = _open_room_in_dome(2000.0)
    ids = np.zeros(len(t), dtype=np.uint32)
    albedo = np.full((1, 3), 0.5, dtype=np.float32)
    lamp = [vplace.Light.point([0.0, 0.0, 1.5], [10.0, 10.0, 10.0])]
    eye = np.array([[0.0, -2.5, 1.0]], dtype=np.float32)
    look = np.array([[0.0, 1.0, 0.0]], dtype=np.float32)
    all_round = vplace.Scene(v, t, ids, albedo, lamp, eyes=eye)
    looking = vplace.Scene(v, t, ids, albedo, lamp, eyes=eye, looks=look)
    assert all_round.scale == all_round.diagonal
    assert looking.scale < 12.0
    with pytest.raises(vplace.InputError):
        vplace.Scene(v, t, ids, albedo, lamp, eyes=eye, looks=np.vstack([look, look]))
    with pytest.raises(vplace.InputError):
        vplace.Scene(v, t, ids, albedo, lamp, eyes=eye, looks=np.full((1, 3), np.nan, np.float32))
