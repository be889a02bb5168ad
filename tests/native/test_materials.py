"""Textured and alpha-tested materials of the native scene: albedo at hits, rays through cut
texels, and bad input."""

import numpy as np
import pytest
import vplace

#: A 2 x 2 texture, row 0 at the top: red, green / blue, white; alpha 0, 1 / 1, 0.
TEXTURE = np.array(
    [[[1, 0, 0, 0], [0, 1, 0, 1]], [[0, 0, 1, 1], [1, 1, 1, 0]]],
    dtype=np.float32,
)


def floor_and_card(uvs="square", textures=(TEXTURE,), **materials):
    """A floor quad z = 0 over [-1, 1]^2 (material 0, albedo 0.5) and a card z = 1 over
    [-0.5, 0.5]^2 (material 1), UVs the unit square over each (u along x, v along y) unless
    ``uvs`` is given."""
    floor = [[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]]
    card = [[-0.5, -0.5, 1], [0.5, -0.5, 1], [0.5, 0.5, 1], [-0.5, 0.5, 1]]
    v = np.array([*floor, *card], dtype=np.float32)
    t = np.array([[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]], dtype=np.uint32)
    ids = np.array([0, 0, 1, 1], dtype=np.uint32)
    albedo = np.array([[0.5, 0.5, 0.5], [0.0, 0.0, 0.0]], dtype=np.float32)
    square = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=np.float32)
    if isinstance(uvs, str):
        uvs = np.stack([square[[0, 1, 2]], square[[0, 2, 3]]] * 2).astype(np.float32)
    light = vplace.Light.point((0, 0, 1.9), (10, 10, 10))
    return vplace.Scene(v, t, ids, albedo, [light], uvs=uvs, textures=list(textures), **materials)


def down_at(scene, xy):
    o = np.array([[x, y, 1.5] for x, y in xy], dtype=np.float32)
    d = np.tile(np.float32([0, 0, -1]), (len(xy), 1))
    return scene.intersect(o, d)


def test_albedo_at_hits_is_the_texture():
    tint = np.array([[1, 1, 1], [0.5, 1, 1]], dtype=np.float32)
    scene = floor_and_card(base_textures=[None, vplace.TextureMap(0)], texture_tint=tint)
    assert scene.texture_count == 1 and not scene.has_alpha_tests
    # Texel centres of the card: (u, v) = (0.25, 0.75) is the top-left texel, and so on.
    xy = [(-0.25, 0.25), (0.25, 0.25), (-0.25, -0.25), (0.25, -0.25), (0.9, 0.9)]
    t, tri, bary = down_at(scene, xy)
    np.testing.assert_allclose(t, [0.5, 0.5, 0.5, 0.5, 1.5], rtol=1e-6)
    assert list(tri[:4] // 2) == [1, 1, 1, 1] and tri[4] in (0, 1)
    albedo = scene.albedo_at(tri.astype(np.uint32), bary)
    expect = [[0.5, 0, 0], [0, 1, 0], [0, 0, 1], [0.5, 1, 1], [0.5, 0.5, 0.5]]
    np.testing.assert_allclose(albedo, expect, atol=1e-6)
    # Halfway between two texel centres: the mean of the two (bilinear).
    t, tri, bary = down_at(scene, [(0.0, 0.25)])
    np.testing.assert_allclose(scene.albedo_at(tri.astype(np.uint32), bary), [[0.25, 0.5, 0]])


def test_uv_transform_and_wrap():
    # uv * 2: the card shows the texture twice along each axis (repeat); extend clamps.
    rep = floor_and_card(base_textures=[None, vplace.TextureMap(0, uv_scale=(2, 2))])
    ext = floor_and_card(base_textures=[None, vplace.TextureMap(0, uv_scale=(2, 2), wrap="extend")])
    xy = [(-0.375, 0.375), (0.125, 0.375), (0.375, -0.125)]
    for scene, expect in (
        (rep, [[1, 0, 0], [1, 0, 0], [0, 1, 0]]),
        (ext, [[1, 0, 0], [0, 1, 0], [0, 1, 0]]),
    ):
        _, tri, bary = down_at(scene, xy)
        np.testing.assert_allclose(scene.albedo_at(tri.astype(np.uint32), bary), expect, atol=1e-6)
    assert vplace.TextureMap(0, uv_offset=(0.5, 0)).uv_offset == (0.5, 0.0)


def test_alpha_tests_let_rays_through_cut_texels():
    alpha = vplace.AlphaTest(0.0, 1.0, vplace.TextureMap(0, wrap="extend"))
    scene = floor_and_card(alpha_tests=[None, alpha])
    assert scene.has_alpha_tests and alpha.cutoff == 0.5 and alpha.source == "alpha"
    # Top-left and bottom-right texels have alpha 0: rays reach the floor there.
    # (Points off the diagonal the card's two triangles share.)
    corners = [(-0.4, 0.3), (0.4, 0.3), (-0.4, -0.3), (0.4, -0.3)]
    t, _, _ = down_at(scene, corners)
    np.testing.assert_allclose(t, [1.5, 0.5, 0.5, 1.5], rtol=1e-6)
    below = np.array([[-0.4, 0.3, 0.2], [0.4, 0.3, 0.2]], np.float32)
    above = below + np.float32([0, 0, 1.6])
    assert list(scene.occluded(below, above)) == [False, True]
    # The luminance of the colour instead (red 0.21 and blue 0.07 cut, green and white not).
    lum = vplace.AlphaTest(0.0, 1.0, vplace.TextureMap(0, wrap="extend"), source="luminance")
    scene = floor_and_card(alpha_tests=[None, lum])
    t, _, _ = down_at(scene, corners)
    np.testing.assert_allclose(t, [1.5, 0.5, 1.5, 0.5], rtol=1e-6)
    # A constant alpha below the cutoff removes the card: light paths never stop on it.
    scene = floor_and_card(alpha_tests=[None, vplace.AlphaTest(0.2)])
    vpls = vplace.uniform_vpls(scene, 200, seed=1)
    assert (vpls.position[:, 2] < 0.1).all()
    opaque = floor_and_card(alpha_tests=[None, vplace.AlphaTest(0.8)])
    vpls = vplace.uniform_vpls(opaque, 200, seed=1)
    assert (vpls.position[:, 2] > 0.9).any()


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"base_textures": [None, vplace.TextureMap(3)]}, "materials[1].texture: index 3"),
        ({"base_textures": [None]}, "base_textures must have one entry per material (2"),
        ({"alpha_tests": [None] * 3}, "alpha_tests must have one entry per material (2"),
        ({"texture_tint": np.ones((2, 4), np.float32)}, "texture_tint must have shape (2, 3)"),
        (
            {
                "texture_tint": -np.ones((2, 3), np.float32),
                "base_textures": [vplace.TextureMap(0)] * 2,
            },
            "materials[0].texture_tint",
        ),
        ({"textures": [np.zeros((2, 2, 2), np.float32)]}, "textures[0] must have shape (H, W, 3)"),
        ({"textures": [np.zeros((2, 2, 4), np.float64)]}, "textures[0] must have dtype float32"),
        ({"textures": [np.full((1, 1, 3), np.nan, np.float32)]}, "textures[0] holds a non-finite"),
        ({"textures": [np.zeros((0, 2, 3), np.float32)]}, "textures[0] is empty"),
        ({"uvs": np.zeros((3, 3, 2), np.float32)}, "uvs: expected (4, 3, 2)"),
        ({"uvs": np.zeros((4, 3, 3), np.float32)}, "uvs must have shape (N, 3, 2)"),
        ({"uvs": np.full((4, 3, 2), np.inf, np.float32)}, "uvs holds a non-finite value"),
        ({"uvs": None, "base_textures": [None, vplace.TextureMap(0)]}, "pass uvs"),
        (
            {"alpha_tests": [None, vplace.AlphaTest(np.nan)]},
            "materials[1].alpha_test holds a non-finite",
        ),
    ],
)
def test_bad_material_input(kwargs, message):
    with pytest.raises(vplace.InputError) as err:
        floor_and_card(**kwargs)
    assert message in str(err.value)


def test_bad_enum_and_query_input():
    with pytest.raises(vplace.InputError, match='wrap must be "repeat" or "extend"'):
        vplace.TextureMap(0, wrap="mirror")
    with pytest.raises(vplace.InputError, match='source must be "alpha" or "luminance"'):
        vplace.AlphaTest(0.0, 1.0, source="red")
    scene = floor_and_card()
    with pytest.raises(vplace.InputError, match="index 9 is out of bounds for 4 triangles"):
        scene.albedo_at(np.array([9], np.uint32), np.zeros((1, 2), np.float32))
    with pytest.raises(vplace.InputError, match="barycentrics must have shape"):
        scene.albedo_at(np.array([0], np.uint32), np.zeros((2, 2), np.float32))
    with pytest.raises(vplace.InputError, match="origins holds a non-finite"):
        scene.occluded(np.full((1, 3), np.nan, np.float32), np.zeros((1, 3), np.float32))
    with pytest.raises(vplace.InputError, match=r"directions must have shape \(1, 3\)"):
        scene.intersect(np.zeros((1, 3), np.float32), np.zeros((2, 3), np.float32))
    t, tri, bary = scene.intersect(np.zeros((0, 3), np.float32), np.zeros((0, 3), np.float32))
    assert t.shape == (0,) and tri.shape == (0,) and bary.shape == (0, 2)


def test_normal_at_is_the_triangles_winding_side():
    """``Scene.normal_at``: the unit geometric normal of each hit triangle (the floor and the
    card wind counter-clockwise seen from above: +z), zeros for a degenerate one."""
    scene = floor_and_card()
    _, tri, bary = down_at(scene, [(0.9, 0.9), (0.0, 0.0)])
    np.testing.assert_allclose(scene.normal_at(tri.astype(np.uint32), bary), [[0, 0, 1]] * 2)
    v = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 1, 0]], dtype=np.float32)
    flat = vplace.Scene(
        v,
        np.array([[0, 1, 2], [0, 3, 1]], dtype=np.uint32),
        np.zeros(2, np.uint32),
        np.array([[0.5, 0.5, 0.5]], np.float32),
        [vplace.Light.point((0, 0, 1), (1, 1, 1))],
    )
    normals = flat.normal_at(np.array([0, 1], np.uint32), np.zeros((2, 2), np.float32))
    np.testing.assert_allclose(normals, [[0, 0, 0], [0, 0, -1]])
    with pytest.raises(vplace.InputError, match="index 4 is out of bounds for 4 triangles"):
        scene.normal_at(np.array([4], np.uint32), np.zeros((1, 2), np.float32))


def test_linear_image_flips_decodes_and_averages():
    """Blender's bottom-first pixels come back top-first, RGB through the code table (round
    half to even), alpha kept only where asked; the mean is every texel's."""
    rng = np.random.default_rng(3)
    codes = rng.integers(0, 256, size=(3, 5, 4))
    pixels = (codes / 255.0).astype(np.float32)
    table = np.linspace(0.0, 2.0, 256, dtype=np.float32) ** 2
    out, mean = vplace.linear_image(pixels, table=table, alpha=True, name="t")
    assert out.shape == (3, 5, 4) and out.dtype == np.float32
    np.testing.assert_array_equal(out[..., :3], table[codes[::-1, :, :3]])
    np.testing.assert_array_equal(out[..., 3], pixels[::-1, :, 3])
    np.testing.assert_allclose(mean, out.reshape(-1, 4).mean(axis=0, dtype=np.float64), 1e-12)
    plain, _ = vplace.linear_image(pixels[..., :1].copy())
    np.testing.assert_array_equal(plain[..., :3], np.repeat(pixels[::-1, :, :1], 3, axis=-1))
    assert (plain[..., 3] == 1.0).all()


@pytest.mark.parametrize(
    ("pixels", "kwargs", "message"),
    [
        (np.zeros((2, 2, 4), np.float64), {}, "dtype float32"),
        (np.zeros((2, 2), np.float32), {}, "shape"),
        (np.zeros((0, 2, 4), np.float32), {}, "at least one texel"),
        (np.zeros((2, 2, 4), np.float32), {"table": np.zeros(255, np.float32)}, "table"),
    ],
)
def test_linear_image_bad_input(pixels, kwargs, message):
    with pytest.raises(vplace.InputError, match=message):
        vplace.linear_image(pixels, **kwargs)
