"""vplace.par2d: analytic 2D direct lighting, numpy in and out."""

import math

import numpy as np
import pytest
import vplace
from vplace.par2d import METHODS, Scene2D, irradiance, light_map

WHITE = [1.0, 1.0, 1.0]


def rect(x0, y0, x1, y1):
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], dtype=np.float64)


def unit_light_scene():
    return Scene2D.from_lights([rect(2.0, -0.5, 3.0, 0.5)], [[2.0, 1.0, 0.5]])


def test_single_light_matches_the_closed_form():
    scene = unit_light_scene()
    expected = 2.0 * math.atan(0.25) / (2.0 * math.pi)
    for method in ("par", "exact"):
        out = scene.irradiance(np.zeros((1, 2)), method)
        assert out.shape == (1, 3) and out.dtype == np.float64
        np.testing.assert_allclose(out[0], [2 * expected, expected, 0.5 * expected], rtol=1e-13)


def test_seam_rotation_invariance():
    light = rect(-3.0, -0.5, -2.0, 0.5)
    occ = rect(-1.5, 0.0, -1.0, 0.1)
    expected = (2.0 * math.atan(0.25) - math.atan(0.1)) / (2.0 * math.pi)
    for k in range(16):
        a = 2.0 * math.pi * k / 16 + (0.0 if k == 0 else 1e-3)
        rot = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
        scene = Scene2D.from_lights([light @ rot.T], [WHITE], [occ @ rot.T])
        for method in ("par", "exact"):
            v = scene.irradiance(np.zeros((1, 2)), method)[0, 0]
            assert abs(v - expected) < 1e-13, (k, method, v)


def test_inside_and_on_the_boundary():
    scene = Scene2D([rect(0, 0, 1, 1), rect(2, 0, 3, 1)], [[3.0, 2.0, 1.0], [0, 0, 0]])
    pts = np.array([[0.5, 0.5], [0.0, 0.5], [1.0, 1.0], [2.5, 0.5], [2.0, 0.2], [3.0, 0.0]])
    for method in METHODS:
        out = scene.irradiance(pts, method, rays=16)
        np.testing.assert_array_equal(out[:3], [[3.0, 2.0, 1.0]] * 3)
        np.testing.assert_array_equal(out[3:], np.zeros((3, 3)))


def test_monte_carlo_agrees_with_exact_within_4_standard_errors():
    scene = Scene2D.from_lights([rect(2.0, -0.5, 3.0, 0.5)], [WHITE], [rect(1.0, -0.2, 1.3, 0.1)])
    pts = np.array([[0.0, 0.0], [0.5, -1.0], [4.0, 0.2], [1.5, 1.5]])
    rays = 200_000
    exact = scene.irradiance(pts, "exact")[:, 0]
    mc = scene.irradiance(pts, "monte_carlo", rays=rays, seed=3)[:, 0]
    se = np.sqrt(exact * (1.0 - exact) / rays)  # Bernoulli rays of value 0 or 1
    assert np.all(se > 0)
    assert np.all(np.abs(mc - exact) <= 4.0 * se), (mc, exact, se)


def test_monte_carlo_is_deterministic_per_seed():
    scene = unit_light_scene()
    pts = np.array([[0.0, 0.0], [1.0, 1.0]])
    a = scene.irradiance(pts, "monte_carlo", rays=64, seed=5)
    np.testing.assert_array_equal(a, scene.irradiance(pts, "monte_carlo", rays=64, seed=5))
    assert not np.array_equal(a, scene.irradiance(pts, "monte_carlo", rays=64, seed=6))


def test_par_is_wrong_for_a_straddling_occluder():
    def bar(y0, y1):
        return np.array([[-1, y0 - 0.05], [1, y1 - 0.05], [1, y1 + 0.05], [-1, y0 + 0.05]])

    scene = Scene2D.from_lights([bar(1.5, 2.5)], [WHITE], [bar(2.5, 1.5)])
    p = np.zeros((1, 2))
    exact = scene.irradiance(p, "exact")[0, 0]
    par = scene.irradiance(p, "par")[0, 0]
    mc = scene.irradiance(p, "monte_carlo", rays=200_000, seed=1)[0, 0]
    assert abs(mc - exact) <= 4.0 * math.sqrt(exact * (1 - exact) / 200_000)
    assert abs(par - exact) > 0.2 * exact


def test_light_map_matches_pointwise_irradiance():
    scene = Scene2D.from_lights([rect(2.0, -0.5, 3.0, 0.5)], [WHITE], [rect(1.0, -0.2, 1.3, 0.1)])
    w, h = 9, 4
    img = scene.light_map((-1.0, -2.0, 4.0, 2.0), w, h, "exact")
    assert img.shape == (h, w, 3) and img.dtype == np.float64
    xs = -1.0 + (np.arange(w) + 0.5) / w * 5.0
    ys = 2.0 - (np.arange(h) + 0.5) / h * 4.0
    pts = np.stack(np.meshgrid(xs, ys), axis=-1).reshape(-1, 2)
    np.testing.assert_array_equal(img.reshape(-1, 3), scene.irradiance(pts, "exact"))
    free = light_map([rect(2.0, -0.5, 3.0, 0.5)], [WHITE], [], (-1.0, -2.0, 4.0, 2.0), w, h)
    assert np.all(free >= img) and np.any(free > img)


def test_functions_and_accessors():
    out = irradiance(np.zeros((2, 2)), [rect(2.0, -0.5, 3.0, 0.5)], [WHITE], method="par")
    assert out.shape == (2, 3)
    messy = np.array([[2, -0.5], [2, -0.5], [2.5, -0.5], [3, -0.5], [3, 0.5], [2, 0.5]][::-1])
    scene = Scene2D([messy, rect(0, 5, 1, 6)], [WHITE, [0, 0, 0]])
    assert scene.polygon(0).shape == (4, 2)
    assert (len(scene), scene.polygon_count, scene.light_count) == (2, 2, 1)
    with pytest.raises(vplace.InputError):
        scene.polygon(5)


def test_progress_and_cancel():
    scene = unit_light_scene()
    progress = vplace.Progress()
    scene.light_map((-1, -1, 1, 1), 8, 6, progress=progress)
    assert progress.done == progress.total == 6
    progress.cancel()
    with pytest.raises(vplace.CancelledError):
        scene.light_map((-1, -1, 1, 1), 8, 6, progress=progress)


@pytest.mark.parametrize(
    ("polygons", "emission", "match"),
    [
        ([], np.zeros((0, 3)), "empty"),
        ([rect(0, 0, 1, 1)], [[1.0, -1.0, 0.0]], "emission"),
        ([rect(0, 0, 1, 1)], [[float("nan"), 0.0, 0.0]], "non-finite"),
        ([rect(0, 0, 1, 1)], [[1.0, 1.0]], "shape"),
        ([np.zeros((3, 3))], [WHITE], "shape"),
        ([[[0, 0], [1, 0]]], [WHITE], "shape"),
        ([[[0, 0], [2, 0], [1, 0.5], [2, 1], [0, 1]]], [WHITE], "not convex"),
        ([[[0, 0], [1, 0], [2, 0]]], [WHITE], "zero area"),
        ([[[0, 0], [1, float("inf")], [0, 1]]], [WHITE], "non-finite"),
    ],
)
def test_bad_scene_input(polygons, emission, match):
    with pytest.raises(vplace.InputError, match=match):
        Scene2D(polygons, emission)


def test_bad_query_input():
    scene = unit_light_scene()
    with pytest.raises(vplace.InputError, match="shape"):
        scene.irradiance(np.zeros((3, 3)))
    with pytest.raises(vplace.InputError, match="non-finite"):
        scene.irradiance(np.array([[0.0, float("nan")]]))
    with pytest.raises(vplace.InputError, match="method"):
        scene.irradiance(np.zeros((1, 2)), "sweep")  # type: ignore[arg-type]
    with pytest.raises(vplace.InputError, match="rays"):
        scene.irradiance(np.zeros((1, 2)), "monte_carlo", rays=0)
    with pytest.raises(vplace.InputError, match="bounds"):
        scene.light_map((1.0, 0.0, 0.0, 1.0), 4, 4)
    with pytest.raises(vplace.InputError):
        scene.light_map((0.0, 0.0, 1.0, 1.0), 0, 4)
    with pytest.raises(vplace.InputError, match="lights"):
        Scene2D.from_lights([], np.zeros((0, 3)))
    with pytest.raises(vplace.InputError, match="positive emission"):
        Scene2D.from_lights([rect(0, 0, 1, 1)], [[0.0, 0.0, 0.0]])
