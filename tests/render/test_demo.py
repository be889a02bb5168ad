"""The main job end to end on a small Cornell box, with the one EEVEE render of the suite."""

import json

import numpy as np
import pytest
from blender_util import cornell
from PIL import Image

from addon import job as pipeline
from addon.capture import passes as capture
from addon.native import vplace
from addon.scene.export import VPL_MARKER
from addon.writeback import apply
from addon.writeback import eevee_render as eevee


def load_png_linear(path):
    c = np.asarray(Image.open(path).convert("RGB"), dtype=np.float64) / 255.0
    return vplace.images.srgb_to_linear(c)


def luminance(img):
    return img @ np.array([0.2126, 0.7152, 0.0722])


@pytest.mark.slow
def test_main_job_writes_everything_and_eevee_shows_what_the_evaluator_computed(tmp_path):
    scene = cornell()
    report = pipeline.run_main_job(
        scene,
        tmp_path,
        n_vpls=64,
        resolution=(48, 48),
        samples=64,
        truth_samples=256,
        eevee=True,
        log=print,
    )
    for name in (
        "scene.blend",
        "cycles_gi.png",
        "direct.png",
        "direct_plus_vpl.png",
        "eevee_vpl.png",
        "vpls.csv",
        "report.json",
        "report.md",
    ):
        assert (tmp_path / name).exists(), name
    assert json.loads((tmp_path / "report.json").read_text())["n_vpls"] == 64
    table = np.loadtxt(tmp_path / "vpls.csv", delimiter=",", skiprows=1)
    assert table.shape == (64, 10)  # position, normal, flux, the disk's radius
    radii = table[:, 9]
    assert (radii >= report.radius * (1 - 1e-6)).all()
    assert (radii <= vplace.MAX_RADIUS_FACTOR * report.radius * (1 + 1e-6)).all()
    # Scored against a 256 spp truth of the scene camera, not against the 64 spp capture.
    assert "ground truth" in report.reference.label and report.reference.samples == 256
    m = report.metrics
    # VPL indirect light brings the estimate closer to Cycles GI than direct light alone.
    assert m["rmse"] < 0.8 * m["rmse_direct_only"]
    assert m["relative_mse"] < 0.8 * m["relative_mse_direct_only"]
    assert report.evaluator.shadow_rays > 0
    # Every VPL with power is a light; those the refit switched off are not written.
    coll = apply.find_collection()
    written = int((table[:, 6:9].max(axis=1) > 0).sum())
    assert coll is not None and len(coll.objects) == report.lights_written == written > 0
    assert all(o.get(VPL_MARKER) for o in coll.objects)
    # EEVEE, scored in float against the same truth, shows what the evaluator computed: the
    # light its VPLs add (EEVEE with them less EEVEE without) is the evaluator's VPL light, and
    # its image is far closer to the truth than direct light alone.
    e = report.eevee
    # The box's lamp is the user's own light, no stand-in: Cycles rendering the lights EEVEE
    # renders gives Cycles' direct light, so all of EEVEE's direct-light error is its rendering.
    assert abs(e["attribution_stand_in_share"]) < 0.02, e
    # Its walls are plain colours: little of that error is the surfaces' colour as EEVEE
    # filters it (EEVEE's Diffuse Color pass against the truth's), some is the blocks' faces,
    # whose plane passes through the lamp.
    assert abs(e["attribution_colour_share"]) < 0.1, e
    assert e["attribution_cut_pixels"] > 0.0 and e["attribution_cut_brightness"] < 1.0, e
    truth = capture.capture(
        scene, resolution=(48, 48), samples=256, seed=pipeline.REFERENCE_SEED,
        cache_dir=tmp_path / "cache",
    )  # fmt: skip
    plain = eevee.render(scene, resolution=(48, 48), samples=4, setup=eevee.SETUPS["plain"])
    eevee_added = e["brightness"] - pipeline.score(plain.image, truth.gi)["brightness"]
    evaluator_added = m["brightness"] - m["brightness_direct_only"]
    print(f"evaluator {m}\nEEVEE {e}\nadded: EEVEE {eevee_added}, evaluator {evaluator_added}")
    assert abs(eevee_added / evaluator_added - 1) < 0.05
    assert e["ssim"] > m["ssim_direct_only"] + 0.05 and e["rmse"] < 0.8 * m["rmse_direct_only"]
    assert abs(m["brightness"] - 1) < 0.1
    # EEVEE's own direct light is measured apart (the Cornell box's lamp is a plain AREA light,
    # which EEVEE lights as Cycles does), and the error's parts add up.
    assert abs(e["direct_brightness"] - 1) < 0.05
    shares = [e[f"attribution_share_{k}"] for k in ("direct", "vpl", "rest")]
    assert sum(shares) == pytest.approx(1.0)
    text = (tmp_path / "report.md").read_text()
    assert "EEVEE's own direct light" in text
    # The box's lamp casts soft shadows without jitter: said, the lamp left as it is.
    assert "of your lamps (e.g. 'light')" in text and report.eevee_lamp_notes
    assert not scene.objects["light"].data.use_shadow_jitter
    # The PNGs are pictures of the same vplace.images.
    shown = luminance(load_png_linear(tmp_path / "eevee_vpl.png")).mean()
    ours = luminance(load_png_linear(tmp_path / "direct_plus_vpl.png")).mean()
    assert abs(shown / ours - 1) < 0.1
