"""What Rust computes is what Blender shows: 64 VPLs written as lights and rendered by Cycles
(original light hidden, direct light only) agree with the evaluator's image of the same VPLs on
the same G-buffer, for both emission profiles.

The cosine profile (the default: AREA disks of the near-field radius) is compared on every pixel
near its VPLs too: the evaluator's kernel is the disk's irradiance, so there is no hot spot on
one side only. The omni profile is a point light on both sides, whose ``1 / r^2`` field varies a
lot inside one pixel within ``NEAR`` of a VPL (Cycles integrates the pixel's area, the evaluator
takes one sample): those pixels are left out for it, and counted. Pixels that straddle two
surfaces are left out for both (the box-filtered G-buffer averages their positions and normals;
their normal is shorter than 1).

Cycles noise is measured in the test from two renders with different seeds; at the sample count
used it must be well below the 5% agreement bound, or the test says so and fails.
"""

import bpy
import numpy as np
import pytest
from blender_util import cornell

from addon.capture import passes as capture
from addon.capture.native_view import view_of
from addon.native import vplace
from addon.scene import export
from addon.scene.convert import build_scene
from addon.writeback import apply

RES = (64, 64)
SAMPLES = 1024
N_VPLS = 64
NEAR = 0.1  # metres, about 3 pixel footprints at 64 px across the 2 m box


def rel(a, b, mask):
    return float(np.linalg.norm((a - b)[mask]) / np.linalg.norm(b[mask]))


@pytest.fixture(scope="module")
def cornell_gbuffer():
    scene = cornell()
    native = build_scene(export.export_scene(scene))
    gbuf = capture.capture(scene, resolution=RES, samples=16)
    return scene, native, gbuf


@pytest.mark.slow
@pytest.mark.parametrize("profile", ["cosine", "omni"])
def test_evaluator_matches_cycles_render_of_written_vpls(cornell_gbuffer, profile):
    scene, native, gbuf = cornell_gbuffer
    # Disks no larger than the scene's near-field radius (the set's radius a tenth of it, so
    # the largest patch disk, MAX_RADIUS_FACTOR times it, is that): a disk as large as a sparse
    # VPL's patch may reach past a wall, which Cycles hides and the evaluator's kernel (and
    # EEVEE, whose shadow map sits at the centre: tests/render/test_eevee.py) do not.
    small = native.near_field_radius / vplace.MAX_RADIUS_FACTOR
    vpls = vplace.uniform_vpls(native, N_VPLS, seed=3, profile=profile, radius=small)
    bpy.data.objects["light"].hide_render = True
    try:
        apply.write_vpls(scene, vpls, scene_diagonal=native.diagonal)
        a = capture.capture(scene, resolution=RES, samples=SAMPLES, seed=1, include_vpls=True)
        b = capture.capture(scene, resolution=RES, samples=SAMPLES, seed=2, include_vpls=True)
    finally:
        bpy.data.objects["light"].hide_render = False
        apply.clear_vpls()
    dist = np.linalg.norm(gbuf.position[:, :, None, :] - vpls.position[None, None], axis=-1)
    near = (dist.min(axis=-1) < NEAR) if profile == "omni" else np.zeros_like(gbuf.covered)
    mixed = np.abs(np.linalg.norm(gbuf.normal, axis=-1) - 1.0) > 1e-3
    mask = gbuf.covered & ~near & ~mixed
    assert mask.mean() > 0.7, f"only {mask.mean():.1%} of the pixels are compared"
    cycles = 0.5 * (a.direct + b.direct)
    noise = rel(a.direct, b.direct, mask) / 2.0  # relative noise of the two-render mean
    ours, _ = vplace.evaluate(native, view_of(gbuf), vpls)
    error = rel(ours, cycles, mask)
    print(
        f"{profile}: relative RMSE {error:.4f}, Cycles noise {noise:.4f} at {SAMPLES} spp x 2, "
        f"{near.sum()} pixels within {NEAR} m of a VPL and {mixed.sum()} straddling surfaces "
        f"left out of {near.size}; disk radii {vpls.radii.min():.3f}-{vpls.radii.max():.3f} m"
    )
    assert noise < 0.025, f"Cycles noise {noise:.3f} too high to test a 5% agreement"
    assert error < 0.05, f"relative RMSE {error:.4f} (Cycles noise {noise:.4f})"
