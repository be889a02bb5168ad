"""Match EEVEE's direct light (``writeback.match_eevee``): the main job renders EEVEE's direct
light on the captured view first and refits the VPL powers to what it lacks; the layout, the
user's lights and every setting stay as they were."""

import json

import bpy
import numpy as np
import pytest
from blender_util import cornell

from addon import job as pipeline
from addon.writeback import apply, match_eevee

pytestmark = pytest.mark.slow


def _run(scene, out, **options):
    return pipeline.run_main_job(
        scene,
        out,
        eevee=False,
        truth_samples=None,
        baselines=(),
        log=lambda _line: None,
        size=64,
        samples=32,
        n_vpls=32,
        **options,
    )


def test_the_refit_matches_eevees_direct_light_where_it_helps_and_nothing_else_changes(tmp_path):
    scene = cornell()
    plain = _run(scene, tmp_path / "plain", match_eevee="off")
    before = apply.find_collection()
    assert before is not None and not plain.eevee_matched
    settings = (scene.render.engine, scene.render.resolution_x, scene.eevee.taa_render_samples)
    matched = _run(scene, tmp_path / "matched", match_eevee="on")
    # EEVEE's direct light of the box's lamp differs from Cycles' (on llvmpipe a little
    # brighter): EEVEE renders the one captured view, the refit is offered the difference, and
    # keeps it only where EEVEE's image predicted on that view comes out closer with it.
    report = json.loads((tmp_path / "matched" / "report.json").read_text())
    choice = report["eevee_match"]
    assert choice["kept"] == all(w < o for w, o in choice["per_view"])
    assert np.isfinite([choice["with_match"], choice["without"]]).all()
    assert plain.eevee_match is None
    a = np.loadtxt(tmp_path / "plain" / "vpls.csv", delimiter=",", skiprows=1)
    b = np.loadtxt(tmp_path / "matched" / "vpls.csv", delimiter=",", skiprows=1)
    assert np.array_equal(a[:, :6], b[:, :6])  # the same layout: positions and normals
    text = (tmp_path / "matched" / "report.md").read_text()
    if choice["kept"]:
        (share,) = matched.eevee_matched.values()
        assert np.isfinite(share) and share != 0.0
        assert not np.allclose(a[:, 6:9], b[:, 6:9])  # other powers
        assert "The VPL powers make up for EEVEE's direct light" in text
    else:
        assert matched.eevee_matched == {}
        assert np.array_equal(a[:, 6:9], b[:, 6:9])  # the plain refit's powers
        assert "Match EEVEE's direct light was left out" in text
    # The renders' stand-ins are gone, the written lights replaced, every setting restored.
    assert bpy.data.collections.get(match_eevee.COLLECTION) is None
    assert apply.find_collection() is not None
    assert (scene.render.engine, scene.render.resolution_x, scene.eevee.taa_render_samples) == (
        settings
    )
    assert report["eevee_matched"] == matched.eevee_matched
    assert any(stage.startswith("EEVEE's direct light") for stage in report["stage_seconds"])


def test_left_to_decide_it_matches_the_box_whose_lamp_a_block_cuts_and_gives_the_same_lights(
    tmp_path,
):
    # The default ("auto"): the camera sees the blocks' faces, whose planes pass through the
    # box's lamp, so EEVEE renders and the lights are those of "on", the same file twice.
    scene = cornell()
    on = _run(scene, tmp_path / "on", match_eevee="on")
    auto = _run(scene, tmp_path / "auto")
    _run(scene, tmp_path / "again")
    csv = [(tmp_path / n / "vpls.csv").read_bytes() for n in ("on", "auto", "again")]
    assert csv[0] == csv[1] == csv[2]
    assert auto.eevee_match == on.eevee_match is not None
    # With the lamp's shadow off EEVEE does not darken the blocks: nothing renders.
    scene.objects["light"].data.use_shadow = False
    _run(scene, tmp_path / "unshadowed")
    report = json.loads((tmp_path / "unshadowed" / "report.json").read_text())
    assert report["eevee_match"] is None
    assert not any(stage.startswith("EEVEE's direct light") for stage in report["stage_seconds"])
