"""vplace.par2d_measure: the PAR 2D speed-against-error measurement the report plots."""

from __future__ import annotations

import numpy as np
from vplace import par2d_measure


def test_rows_per_method_against_exact():
    rows, exact = par2d_measure.measure(size=24, rays=(2, 8), seed=1)
    assert [(r.method, r.rays) for r in rows] == [
        ("exact", None),
        ("par", None),
        ("monte_carlo", 2),
        ("monte_carlo", 8),
    ]
    assert exact.shape == (24, 24, 3) and exact.max() > 0
    assert rows[0].rmse == 0.0 and all(r.pixels == 24 * 24 for r in rows)
    assert all(r.seconds > 0 for r in rows)
    mc = [r.rmse for r in rows if r.method == "monte_carlo"]
    assert mc[0] > 0 and mc[1] < mc[0] * 1.5  # more rays, not much worse


def test_the_scene_is_seeded():
    a, b = par2d_measure.random_scene(3, 5, seed=2), par2d_measure.random_scene(3, 5, seed=2)
    bounds = (-1.0, -1.0, 1.0, 1.0)
    assert np.array_equal(a.light_map(bounds, 8, 8, "exact"), b.light_map(bounds, 8, 8, "exact"))
    assert par2d_measure.rmse(np.ones(4), np.zeros(4)) == 1.0
