"""The main job end to end on a small Cornell box, with the one EEVEE render of the suite."""

import json

import numpy as np
import pytest
from blender_util import cornell
from PIL import Image

from addon import apply, images, pipeline
from addon.export import VPL_MARKER


def load_png_linear(path):
    c = np.asarray(Image.open(path).convert("RGB"), dtype=np.float64) / 255.0
    return images.srgb_to_linear(c)


def luminance(img):
    return img @ np.array([0.2126, 0.7152, 0.0722])


@pytest.mark.slow
def test_main_job_writes_everything_and_vpls_bring_eevee_close_to_cycles(tmp_path):
    scene = cornell()
    report = pipeline.run_main_job(
        scene, tmp_path, n_vpls=64, resolution=(48, 48), samples=64, eevee=True, log=print
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
    assert np.loadtxt(tmp_path / "vpls.csv", delimiter=",", skiprows=1).shape == (64, 9)
    m = report["metrics"]
    # VPL indirect light brings the estimate closer to Cycles GI than direct light alone.
    assert m["rmse"] < 0.8 * m["rmse_direct_only"]
    assert m["relative_mse"] < 0.8 * m["relative_mse_direct_only"]
    assert report["evaluator"]["shadow_rays"] > 0
    coll = apply.find_collection()
    assert coll is not None and len(coll.objects) == 64
    assert all(o.get(VPL_MARKER) for o in coll.objects)
    # EEVEE with the VPLs is as bright as the evaluator's direct + VPL image, and clearly
    # brighter than direct light alone; with every bounce (pixel emitters reflect DiffDir +
    # DiffInd) and the power refit, the evaluator's image is as bright as Cycles GI.
    gi = luminance(load_png_linear(tmp_path / "cycles_gi.png")).mean()
    eevee = luminance(load_png_linear(tmp_path / "eevee_vpl.png")).mean()
    direct = luminance(load_png_linear(tmp_path / "direct.png")).mean()
    ours = luminance(load_png_linear(tmp_path / "direct_plus_vpl.png")).mean()
    print(
        f"mean luminance: Cycles GI {gi:.4f}, evaluator direct + VPLs {ours:.4f}, "
        f"EEVEE + VPLs {eevee:.4f}, direct {direct:.4f}"
    )
    assert abs(eevee / ours - 1) < 0.15
    assert eevee > 1.15 * direct
    assert direct < ours and abs(ours / gi - 1) < 0.1
