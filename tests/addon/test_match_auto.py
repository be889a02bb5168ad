"""Match EEVEE's direct light left to decide (``Job.match_eevee`` "auto", the default): EEVEE
renders the captured views' direct light only where a surface the cameras see cuts one of the
user's lamps, which EEVEE darkens (``docs/EEVEE_NOTES.md``, Q11); elsewhere nothing renders and
the layout is the plain refit's. The renders themselves are
``tests/render/test_match_eevee.py``'s; here they are stood in for, so that the decision is
tested without EEVEE."""

import bpy
import numpy as np
import pytest
from blender_util import add_glowing_panel, addon_cornell, cornell

from addon import job as pipeline
from addon.errors import AddonError
from addon.native import vplace
from addon.writeback import apply, cut_lights, eevee_render, match_eevee


@pytest.fixture
def prepared():
    scene = cornell()
    job = pipeline.Job(size=32, samples=2, n_vpls=16)
    prepared = pipeline.prepare(scene, job, pipeline.quiet_timer())
    return scene, job, prepared


def _decide(monkeypatch, scene, prepared, job, result=None):
    """``pipeline.eevee_match`` with EEVEE's renders stood in for: (what it returned, whether it
    would have rendered, the lines it logged)."""
    calls, lines = [], []

    def render(_scene, *, resolution, **_kwargs):
        calls.append(1)
        if isinstance(result, Exception):
            raise result
        return eevee_render.EeveeImage(np.zeros((resolution[1], resolution[0], 3), np.float32), 0.0)

    monkeypatch.setattr(eevee_render, "render", render)
    got = pipeline.eevee_match(scene, prepared, job, pipeline.StageTimer(log=lines.append))
    return got, bool(calls), lines


def test_auto_matches_only_where_a_lamp_the_cameras_see_is_cut(monkeypatch, prepared):
    scene, job, prep = prepared
    assert job.match_eevee == "auto"
    # The box's blocks stand beside its ceiling lamp and the camera sees their faces.
    assert match_eevee.cut_lamps_seen(scene, prep.captures) == ["light"]
    got, rendered, lines = _decide(monkeypatch, scene, prep, job)
    assert rendered and isinstance(got[0], vplace.job.EeveeMatch) and got[0].matched
    assert prep.cut_lamps == ["light"]  # for the write-back's notes
    assert any("Match EEVEE's direct light (auto)" in line and "'light'" in line for line in lines)
    # A lamp whose shadow is off is not darkened: nothing renders, the plain refit stays.
    scene.objects["light"].data.use_shadow = False
    assert match_eevee.cut_lamps_seen(scene, prep.captures) == []
    assert _decide(monkeypatch, scene, prep, job)[:2] == ((None, {}), False)
    assert prep.cut_lamps == []
    assert _decide(monkeypatch, scene, prep, job)[:2] == ((None, {}), False)
    # "on" renders all the same; "off" never; nor does a method without a refit.
    on = pipeline.Job(size=32, samples=2, n_vpls=16, match_eevee="on")
    assert _decide(monkeypatch, scene, prep, on)[1]
    scene.objects["light"].data.use_shadow = True
    off = pipeline.Job(size=32, samples=2, n_vpls=16, match_eevee="off")
    assert _decide(monkeypatch, scene, prep, off)[:2] == ((None, {}), False)
    plain = pipeline.Job(size=32, samples=2, n_vpls=16, method="vplace")
    prep.cut_lamps = []
    assert _decide(monkeypatch, scene, prep, plain)[:2] == ((None, {}), False)
    assert prep.cut_lamps == ["light"]  # found all the same, for the notes


def test_auto_goes_on_without_the_match_where_eevee_cannot_render(monkeypatch, prepared):
    scene, job, prep = prepared
    failed = AddonError("the BLENDER_EEVEE_NEXT render of scene 'Scene' did not finish: no GPU")
    got, rendered, lines = _decide(monkeypatch, scene, prep, job, failed)
    assert rendered and got == (None, {})
    assert bpy.data.collections.get(match_eevee.COLLECTION) is None  # its stand-ins gone
    assert any(
        line.startswith("[vplace] warning: Match EEVEE's direct light (auto) left out")
        and "no GPU" in line
        for line in lines
    )
    # Asked for, it is the user's error to see.
    on = pipeline.Job(size=32, samples=2, n_vpls=16, match_eevee="on")
    with pytest.raises(AddonError, match="no GPU"):
        _decide(monkeypatch, scene, prep, on, failed)


def test_only_the_pixels_given_are_tested_and_only_the_users_shadowed_lamps():
    scene = cornell()
    lamp = scene.objects["light"]
    centre = np.asarray(lamp.matrix_world.translation)
    # One point whose plane (normal +x) passes through the lamp's centre, one whose plane
    # (normal +z, facing the lamp from below) does not cut it; equally lit.
    position = np.array([[[centre[0], centre[1], centre[2] - 0.5]] * 2], np.float32)
    normal = np.array([[[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]], np.float32)
    cut = np.array([[True, False]])
    light = np.ones((1, 2))
    assert cut_lights.lamps_cut_in(scene, [(position, normal, cut, light)]) == ["light"]
    assert cut_lights.lamps_cut_in(scene, [(position, normal, ~cut, light)]) == []
    assert cut_lights.lamps_cut_in(scene, [(position, normal, np.zeros_like(cut), light)]) == []
    # Both tested: the cut point holds half the light, then a thousandth of it.
    both = np.ones_like(cut)
    assert cut_lights.lamps_cut_in(scene, [(position, normal, both, light)]) == ["light"]
    dim = np.array([[1e-3, 1.0]])
    assert cut_lights.lamps_cut_in(scene, [(position, normal, both, dim)]) == []
    lamp.hide_render = True
    assert cut_lights.lamps_cut_in(scene, [(position, normal, cut, light)]) == []
    lamp.hide_render = False
    scene.eevee.use_shadows = False  # EEVEE shadows nothing: it darkens nothing
    assert cut_lights.lamps_cut_in(scene, [(position, normal, cut, light)]) == []


def test_a_balls_terminator_under_the_lamp_is_no_cause_to_render(monkeypatch):
    """A curved surface's planes pass through every lamp along its terminator, lit edge on:
    the box without its blocks and with a ball on its floor has such pixels, which hold next
    to none of the captured direct light, so "auto" renders nothing (it rendered before)."""
    scene = cornell()
    for name in ("tallBox", "shortBox"):
        scene.objects[name].hide_render = True
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.25, location=(0.0, 0.0, 0.25))
    bpy.context.object.modifiers.new("smooth", "SUBSURF")
    bpy.ops.object.shade_smooth()
    bpy.context.view_layer.update()
    job = pipeline.Job(size=48, samples=2, n_vpls=16)
    prep = pipeline.prepare(scene, job, pipeline.quiet_timer())
    shape = cut_lights.light_shape(scene.objects["light"])
    c = prep.captures[0]
    assert vplace.job.cut_by_lights(c.position[c.covered], c.normal[c.covered], [shape], 0.02).any()
    assert match_eevee.cut_lamps_seen(scene, prep.captures) == []
    assert _decide(monkeypatch, scene, prep, job)[:2] == ((None, {}), False)
    assert prep.cut_lamps == []


def test_the_setting_takes_three_values():
    with pytest.raises(AddonError, match="match_eevee must be one of"):
        pipeline.Job(match_eevee=True).validate()  # type: ignore[arg-type]
    for value in pipeline.MATCH_EEVEE:
        pipeline.Job(match_eevee=value).validate()


def test_the_panel_says_when_auto_left_the_match_out(monkeypatch, capfd):
    def fail(*_args, **_kwargs):
        raise AddonError("the EEVEE render did not finish: no GPU")

    monkeypatch.setattr(eevee_render, "render", fail)
    with addon_cornell() as scene:
        assert scene.vplace.match_eevee == "auto"
        assert bpy.ops.vplace.apply() == {"FINISHED"}  # the lights are written all the same
        assert apply.find_collection() is not None
    out = capfd.readouterr()
    assert "Match EEVEE's direct light (auto) left out: the EEVEE render did not finish" in (
        out.out + out.err
    )


def test_the_second_run_of_a_file_finds_the_first_runs_match_render(monkeypatch):
    """The match's EEVEE render lights the scene with stand-ins of its own, which take ".001"
    names beside the stand-ins the last run wrote; the render is the same all the same, and
    the second "Lay out and apply" must load it from the cache rather than render it again
    (EEVEE on llvmpipe does not render it bit for bit again, and the lights moved: README,
    "The second run's EEVEE render of the match")."""
    keys = []

    def render(scene, *, resolution, camera=None, samples=None, setup=None, **_kwargs):
        camera = camera or scene.camera
        names = sorted(
            o.name for o in scene.objects if o.get("vplace_emitter") and not o.hide_render
        )
        keys.append(
            (
                eevee_render._key(
                    scene, camera, resolution, samples, setup.engine, setup, 0, "stub"
                ),
                names,
            )
        )
        return eevee_render.EeveeImage(np.zeros((resolution[1], resolution[0], 3), np.float32), 0.0)

    monkeypatch.setattr(eevee_render, "render", render)
    with addon_cornell(match_eevee="on") as scene:
        add_glowing_panel(scene, 5.0)
        bpy.context.view_layer.update()
        for _ in range(2):
            assert bpy.ops.vplace.apply() == {"FINISHED"}
        written = [o.name for o in apply.find_collection().objects if o.get("vplace_emitter")]
    assert written and len(keys) == 2
    (first, first_names), (second, second_names) = keys
    assert first_names and all(n.endswith(".001") for n in second_names)  # beside the first's
    assert second == first
