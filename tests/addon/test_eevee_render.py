"""The scored renders filter their pixels as the truth does (a one-pixel box in Cycles, EEVEE's
Gaussian of the same spread) and give the user's own filter back."""

import pytest
from blender_util import cornell

from addon.settings import override
from addon.writeback import eevee_render as eevee


def test_every_setup_filters_as_the_truth_and_restores_the_users_filter():
    scene = cornell()
    scene.render.filter_size = 2.5  # the user's own choices
    scene.cycles.pixel_filter_type, scene.cycles.filter_width = "GAUSSIAN", 2.0
    for name, setup in eevee.SETUPS.items():
        with override() as g:
            setup.configure(g, scene)
            if setup.engine == "CYCLES":
                assert (scene.cycles.pixel_filter_type, scene.cycles.filter_width) == (
                    "BOX",
                    1.0,
                ), name
            else:
                assert scene.render.filter_size == eevee.FILM_FILTER_SIZE, name
        assert scene.render.filter_size == pytest.approx(2.5)
        assert (scene.cycles.pixel_filter_type, scene.cycles.filter_width) == ("GAUSSIAN", 2.0)


def test_eevees_filter_has_the_spread_of_the_truths_box():
    # EEVEE weighs a sample at distance d by exp(-d^2 / (2 (0.284 r)^2)) for r = filter_size
    # (its film_filter_weight); a one-pixel box has standard deviation sqrt(1 / 12) per axis.
    sigma = 0.284 * eevee.FILM_FILTER_SIZE
    assert sigma == pytest.approx((1 / 12) ** 0.5, rel=0.03)
