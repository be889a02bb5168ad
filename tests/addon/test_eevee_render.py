"""The scored renders filter their pixels as the truth does (a one-pixel box in Cycles, EEVEE's
Gaussian of the same spread), trace soft shadows as "Set up EEVEE for vplace" has EEVEE trace
them, and give the user's own settings back."""

from functools import partial

import bpy
import numpy as np
import pytest
from blender_util import cornell

from addon.settings import override
from addon.writeback import eevee_render as eevee
from addon.writeback import eevee_setup


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


def test_every_eevee_setup_traces_soft_shadows_with_the_set_ups_rays_and_restores_the_users():
    scene = cornell()
    if not hasattr(scene.eevee, "shadow_ray_count"):  # a Blender without the setting
        assert eevee_setup.shadow_rays_for(scene) is None
        return
    assert scene.eevee.shadow_ray_count == 1  # Blender's default
    for name, setup in eevee.SETUPS.items():
        with override() as g:
            setup.configure(g, scene)
            if setup.engine != "CYCLES":
                assert scene.eevee.shadow_ray_count == eevee_setup.SHADOW_RAYS, name
        assert scene.eevee.shadow_ray_count == 1, name
    # What "Set up EEVEE for vplace" gives the scene is what the scored renders use.
    eevee_setup.set_up(scene, bake_volume=False)
    assert scene.eevee.shadow_ray_count == eevee_setup.SHADOW_RAYS


def test_eevees_filter_has_the_spread_of_the_truths_box():
    # EEVEE weighs a sample at distance d by exp(-d^2 / (2 (0.284 r)^2)) for r = filter_size
    # (its film_filter_weight); a one-pixel box has standard deviation sqrt(1 / 12) per axis.
    sigma = 0.284 * eevee.FILM_FILTER_SIZE
    assert sigma == pytest.approx((1 / 12) ** 0.5, rel=0.03)


def test_a_cached_eevee_render_is_reused_only_on_the_gpu_that_rendered_it(tmp_path, monkeypatch):
    # Two GPUs render the same scene differently, so the cache files EEVEE's image under the
    # GPU that rendered it. The render itself is faked (a flat EXR of the render's number): what
    # is tested is which calls render and which load.
    import OpenEXR

    scene = cornell()
    renders: list[str] = []
    gpu = {"now": None}

    def fake_render(name, what, **kwargs):
        renders.append(gpu["now"] or "?")
        gpu["now"] = gpu["now"] or "GPU A"  # Blender knows its GPU once it has rendered
        px = np.full((4, 4, 3), float(len(renders)), np.float32)
        OpenEXR.File({"type": OpenEXR.scanlineimage}, {"RGB": px}).write(scene.render.filepath)
        return {"FINISHED"}

    monkeypatch.setattr(eevee, "run_operator", fake_render)
    monkeypatch.setattr(eevee, "gpu_renderer", lambda: gpu["now"])
    go = partial(eevee.render, scene, resolution=(4, 4), samples=1, cache_dir=tmp_path)
    # Background mode, first EEVEE render: the GPU is not known, so it renders, and the image
    # is filed under the GPU it rendered on.
    assert go().image[0, 0, 0] == 1.0
    assert len(list(tmp_path.glob("render-*.npz"))) == 1
    assert go().image[0, 0, 0] == 1.0 and renders == ["?"]  # the same GPU: loaded
    gpu["now"] = "GPU B"
    assert go().image[0, 0, 0] == 2.0 and renders == ["?", "GPU B"]  # another GPU: rendered
    assert go().image[0, 0, 0] == 2.0
    gpu["now"] = "GPU A"
    assert go().image[0, 0, 0] == 1.0 and len(renders) == 2
    # Cycles renders on the CPU here: its key does not name a GPU, even before one is known.
    gpu["now"] = None
    cycles = eevee.SETUPS["cycles+oidn"]
    assert go(setup=cycles).image[0, 0, 0] == 3.0
    assert go(setup=cycles).image[0, 0, 0] == 3.0 and len(renders) == 3


def test_a_process_without_a_gpu_starts_blenders_gpu_context_once(monkeypatch):
    # Where the probe finds no GPU, later renders do not probe again (each probe is a render).
    eevee._start_gpu.cache_clear()
    monkeypatch.setattr(eevee, "_platform", lambda: None)
    assert eevee.gpu_renderer() is None
    assert eevee.gpu_renderer() is None
    info = eevee._start_gpu.cache_info()
    assert (info.misses, info.hits) == (1, 1)
    assert not [s for s in bpy.data.scenes if s.name.startswith("vplace GPU probe")]
    eevee._start_gpu.cache_clear()


@pytest.mark.slow
def test_a_render_asked_for_its_diffuse_color_pass_returns_it_and_caches_it(tmp_path):
    """The attribution holds EEVEE's Diffuse Color pass against Cycles' (``vplace.job.
    colour_part``): the same render, the same image, the pass beside it, cached with it."""
    scene = cornell()
    go = partial(eevee.render, scene, resolution=(32, 18), samples=1, setup=eevee.SETUPS["plain"])
    plain = go(cache_dir=tmp_path)
    with_colour = go(cache_dir=tmp_path, diffuse_color=True)
    assert plain.diffuse_color is None
    colour = with_colour.diffuse_color
    assert colour is not None and colour.shape == (18, 32, 3)
    # The box's walls are grey, red and green diffuse surfaces: colours in (0, 1), red and green
    # somewhere; the combined image is the same render's.
    assert 0.0 <= colour.min() and colour.max() < 1.0 and colour[..., 0].max() > 0.3
    assert (colour[..., 0] > 2 * colour[..., 1]).any() and (
        colour[..., 1] > 2 * colour[..., 0]
    ).any()
    assert np.allclose(with_colour.image, plain.image, atol=1e-3)
    assert len(list(tmp_path.glob("render-*.npz"))) == 2  # a render with the pass is its own
    again = go(cache_dir=tmp_path, diffuse_color=True)
    assert again.seconds == with_colour.seconds and np.array_equal(again.diffuse_color, colour)
    assert scene.view_layers[0].use_pass_diffuse_color is False  # given back


def test_a_scored_render_of_non_square_pixels_and_a_stereo_pair_is_one_sharp_square_view():
    """A scored render lines up with the captures whatever the user's pixel aspect (Blender
    cannot write non-square pixels as a multilayer EXR), stereo or depth of field; the user's
    settings come back."""
    scene = cornell()
    go = partial(eevee.render, scene, resolution=(16, 12), samples=1, seed=1)
    setup = eevee.SETUPS["cycles+oidn"]
    plain = go(setup=setup, diffuse_color=True)
    scene.render.pixel_aspect_y = 2.0
    scene.render.use_multiview = True
    scene.camera.data.dof.use_dof = True
    scene.camera.data.dof.aperture_fstop = 0.1
    odd = go(setup=setup, diffuse_color=True)
    np.testing.assert_array_equal(odd.image, plain.image)
    assert scene.render.pixel_aspect_y == 2.0 and scene.render.use_multiview
    assert scene.camera.data.dof.use_dof
