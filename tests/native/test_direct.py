"""Every light kind and the direct-light estimator (``vplace.direct_light``): closed-form
irradiance for a world and an emissive square, shadowing, linearity, determinism, and bad input
as ``InputError`` (never a panic)."""

import math

import numpy as np
import pytest
import vplace
from views import view

FLOOR = np.array([[-3, -3, 0], [3, -3, 0], [3, 3, 0], [-3, 3, 0]], dtype=np.float32)
QUAD = np.array([[0, 1, 2], [0, 2, 3]], dtype=np.uint32)


def point_view(points):
    """A 1 x N view of upward-facing floor points."""
    pos = np.array(points, np.float32).reshape(1, -1, 3)
    nor = np.zeros_like(pos)
    nor[..., 2] = 1.0
    return view(
        {
            "position": pos,
            "normal": nor,
            "albedo": np.full_like(pos, 0.5),
            "covered": np.ones(pos.shape[:2], bool),
        }
    )


def floor_scene(lights, extra=None, emission=None):
    """The floor (material 0) and optionally ``extra`` quads (material 1, vertices (4k, 3))."""
    verts, tris, ids = [FLOOR], [QUAD], [np.zeros(2, np.uint32)]
    if extra is not None:
        for k in range(len(extra) // 4):
            verts.append(np.asarray(extra[4 * k : 4 * k + 4], np.float32))
            tris.append(QUAD + 4 * (k + 1))
            ids.append(np.ones(2, np.uint32))
    albedo = np.full((2, 3), 0.5, np.float32)
    return vplace.Scene(
        np.concatenate(verts),
        np.concatenate(tris).astype(np.uint32),
        np.concatenate(ids).astype(np.uint32),
        albedo,
        lights,
        emission=emission,
    )


def square_view_factor(half: float, height: float) -> float:
    """View factor from a point to a parallel square of side 2 ``half`` centred ``height``
    above it (four corner rectangles)."""
    x = y = half / height
    sx, sy = math.sqrt(1 + x * x), math.sqrt(1 + y * y)
    corner = (x / sx * math.atan(y / sx) + y / sy * math.atan(x / sy)) / (2 * math.pi)
    return 4 * corner


def test_uniform_world_gives_its_radiance():
    color = (0.2, 0.4, 0.8)
    scene = floor_scene([vplace.Light.world(color, 1.5)])
    got = vplace.direct_light(scene, point_view([(0, 0, 0), (1, 1, 0)]), samples=256, seed=1)
    # An open upward-facing point: irradiance pi L, Diffuse Direct = E / pi = L.
    np.testing.assert_allclose(got[0], np.tile(np.array(color) * 1.5, (2, 1)), rtol=0.02)


def test_emissive_square_gives_its_view_factor():
    radiance = np.array([3.0, 2.0, 1.0], np.float32)
    square = [(-1, -1, 1), (1, -1, 1), (1, 1, 1), (-1, 1, 1)]
    emission = np.array([[0, 0, 0], radiance], np.float32)
    scene = floor_scene([], square, emission)
    assert scene.emissive_triangle_count == 2
    got = vplace.direct_light(scene, point_view([(0, 0, 0)]), samples=1024, seed=2)[0, 0]
    np.testing.assert_allclose(got, radiance * square_view_factor(1.0, 1.0), rtol=0.02)


@pytest.mark.parametrize(
    "light",
    [
        vplace.Light.point((0, 0, 2), (100, 100, 100)),
        vplace.Light.point((0, 0, 2), (100, 100, 100), radius=0.3, soft_falloff=False),
        vplace.Light.spot((0, 0, 2), (0, 0, -1), 1.3, (100, 100, 100), blend=0.4, radius=0.1),
        vplace.Light.area((0, 0, 2), (0, 0, -1), (1, 0, 0), "rectangle", 0.6, 0.3, (50, 50, 50)),
        vplace.Light.area((0, 0, 2), (0, 0, -1), (1, 0, 0), "ellipse", 0.6, 0.3, (50, 50, 50)),
        vplace.Light.area((0, 0, 2), (0, 0, -1), (1, 0, 0), "square", 0.6, 0.6, (50, 50, 50), 2.4),
        vplace.Light.sun((0, 0, -1), (3, 3, 3)),
        vplace.Light.sun((0, 0, -1), (3, 3, 3), angle=0.2),
        vplace.Light.world((1, 1, 1), 1.0),
    ],
    ids=lambda light: light.kind,
)
def test_every_kind_is_shadowed_linear_and_deterministic(light):
    points = [(0.1, -0.05, 0), (2.5, 2.2, 0)]  # off the quads' diagonals
    open_floor = floor_scene([light])
    lit = vplace.direct_light(open_floor, point_view(points), samples=64, seed=3)
    assert lit[0, 0].min() > 0 and np.isfinite(lit).all()
    again = vplace.direct_light(open_floor, point_view(points), samples=64, seed=3)
    np.testing.assert_array_equal(lit, again)
    # A roof at 1 m over the first point (not over the second) shadows it completely.
    roof = [(-0.5, -0.5, 1), (0.5, -0.5, 1), (0.5, 0.5, 1), (-0.5, 0.5, 1)]
    if light.kind == "world":  # the sky needs a closed box around the point
        roof = [(-9, -9, 1), (9, -9, 1), (9, 9, 1), (-9, 9, 1)]
    shadowed = vplace.direct_light(floor_scene([light], roof), point_view(points), samples=64)
    assert shadowed[0, 0].max() < 0.25 * lit[0, 0].max()
    if light.kind != "world":
        assert shadowed[0, 1].max() > 0.5 * lit[0, 1].max()
    # Twice the lights' power, twice the light (exactly: same samples).
    doubled = vplace.direct_light(
        floor_scene([light, light]), point_view(points), samples=64, seed=3
    )
    np.testing.assert_allclose(doubled, 2 * lit, rtol=0.15, atol=1e-6)


def test_world_image_is_importance_sampled_and_rotated():
    # A black sky with one bright patch around +X at 45 degrees elevation.
    h, w = 32, 64
    img = np.zeros((h, w, 3), np.float32)
    row, col = h // 4, w // 2  # u = 0.5: +X in Blender's convention, 45 degrees up
    img[row - 1 : row + 1, col - 1 : col + 1] = 50.0
    point = point_view([(0, 0, 0)])
    wall = [(0.5, -2, 0), (0.5, 2, 0), (0.5, 2, 3), (0.5, -2, 3)]  # blocks +X
    sky = vplace.Light.world((1, 1, 1), 1.0, image=img)
    lit = vplace.direct_light(floor_scene([sky]), point, samples=256, seed=4)[0, 0]
    blocked = vplace.direct_light(floor_scene([sky], wall), point, samples=256, seed=4)[0, 0]
    assert lit.min() > 0.1 and blocked.max() < 0.05 * lit.max()
    # Turned by 180 degrees about Z, the patch is at -X: the wall at +X no longer blocks it.
    turn = [[-1, 0, 0], [0, -1, 0], [0, 0, 1]]
    turned = vplace.Light.world((1, 1, 1), 1.0, image=img, rotation=turn)
    unblocked = vplace.direct_light(floor_scene([turned], wall), point, samples=256, seed=4)
    np.testing.assert_allclose(unblocked[0, 0], lit, rtol=0.1)


NAN = float("nan")


@pytest.mark.parametrize(
    "make",
    [
        lambda: vplace.Light.point((0, NAN, 1), (1, 1, 1)),
        lambda: vplace.Light.point((0, 0, 1), (1, 1, 1), radius=-1.0),
        lambda: vplace.Light.point((0, 0, 1), (1, 1, 1), radius=NAN),
        lambda: vplace.Light.spot((0, 0, 1), (0, 0, -1), 0.5, (1, 1, 1), blend=1.5),
        lambda: vplace.Light.spot((0, 0, 1), (0, 0, 0), 0.5, (1, 1, 1)),
        lambda: vplace.Light.area((0, 0, 1), (0, 0, -1), (1, 0, 0), "hexagon", 1, 1, (1, 1, 1)),
        lambda: vplace.Light.area((0, 0, 1), (0, 0, -1), (1, 0, 0), "square", -1, 1, (1, 1, 1)),
        lambda: vplace.Light.area((0, 0, 1), (0, 0, -1), (1, 0, 0), "disk", 1, 1, (1, 1, 1), NAN),
        lambda: vplace.Light.sun((0, 0, -1), (1, 1, 1), angle=NAN),
        lambda: vplace.Light.sun((0, 0, -1), (1, 1, 1), angle=-0.1),
        lambda: vplace.Light.world((1, 1, 1), NAN),
        lambda: vplace.Light.world(image=np.ones((4, 8, 4), np.float32)),
        lambda: vplace.Light.world(image=np.ones((4, 8, 3), np.float64)),
        lambda: vplace.Light.world(image=np.full((4, 8, 3), NAN, np.float32)),
        lambda: vplace.Light.world(image=-np.ones((4, 8, 3), np.float32)),
        lambda: vplace.Light.world(image=np.zeros((0, 8, 3), np.float32)),
        lambda: vplace.Light.world(image=np.ones((4, 8, 3), np.float32), rotation=np.eye(3) * 2),
        lambda: vplace.Light.world(rotation=[[NAN, 0, 0], [0, 1, 0], [0, 0, 1]]),
    ],
)
def test_bad_light_is_an_input_error(make):
    with pytest.raises(vplace.InputError):
        floor_scene([make()])


@pytest.mark.parametrize(
    "emission",
    [
        np.ones((1, 3), np.float32),  # one row for two materials
        np.ones((2, 4), np.float32),
        np.ones((2, 3), np.float64),
        np.array([[0, 0, 0], [NAN, 1, 1]], np.float32),
        np.array([[0, 0, 0], [-1, 1, 1]], np.float32),
    ],
)
def test_bad_emission_is_an_input_error(emission):
    square = [(-1, -1, 1), (1, -1, 1), (1, 1, 1), (-1, 1, 1)]
    with pytest.raises(vplace.InputError):
        floor_scene([], square, emission)


def test_direct_light_bad_samples():
    scene = floor_scene([vplace.Light.sun((0, 0, -1), (1, 1, 1))])
    with pytest.raises(vplace.InputError):
        vplace.direct_light(scene, point_view([(0, 0, 0)]), samples=0)
    with pytest.raises(vplace.InputError):
        vplace.direct_light(scene, point_view([(0, 0, 0)]), samples=vplace.MAX_DIRECT_SAMPLES + 1)
    with pytest.raises(OverflowError):
        vplace.direct_light(scene, point_view([(0, 0, 0)]), samples=-1)
