"""Issue 23: the animated scenes, the frames of ``--animate``, and the keyed write-back of
``addon.animation.run_animated_job`` (tiny captures: 24 px, 2 spp)."""

from __future__ import annotations

import bpy
import numpy as np
import pytest
from blender_util import data_snapshot, diff, empty_file
from mathutils import Vector

from addon import animation
from addon.capture.passes import capture
from addon.compat import action_fcurves
from addon.errors import AddonError
from addon.job import Job, StageTimer
from addon.native import vplace
from addon.scene.export import VPL_MARKER
from addon.scenes import animated
from addon.scenes.registry import build_cornell_moving
from addon.writeback import apply, keyed


def test_frames_of_an_animation():
    assert animation.animated_frames(1, 24, 8) == [1, 9, 17, 24]
    assert animation.animated_frames(3, 3, 1) == [3]
    assert animation.animated_frames(1, 9, 4) == [1, 5, 9]


@pytest.mark.parametrize(
    "args, says",
    [
        ((5, 1, 1), "the frame range 5..1 is empty"),
        ((1, 5, 0), "the animation step must be at least 1 frame, got 0"),
        ((1, 5, -2), "the animation step must be at least 1 frame, got -2"),
        ((1, 1000, 1), "are 1000 frames, more than the 120"),
    ],
)
def test_bad_frames_are_one_error_naming_them(args, says):
    with pytest.raises(AddonError, match=says):
        animation.animated_frames(*args)


def _keys(owner: bpy.types.ID) -> dict[tuple[str, int], list[tuple[float, float]]]:
    action = owner.animation_data.action
    return {
        (fc.data_path, fc.array_index): [tuple(k.co) for k in fc.keyframe_points]
        for fc in action_fcurves(action)
    }


def _mean_luminance(scene: bpy.types.Scene, frame: int) -> tuple[float, float]:
    """(left half, right half) mean luminance of a tiny Cycles capture's direct light."""
    cap = capture(scene, resolution=(24, 24), samples=4, seed=0, frame=frame)
    lum = cap.diffuse_direct @ np.array([0.2126, 0.7152, 0.0722])
    return float(lum[:, :12].mean()), float(lum[:, 12:].mean())


def test_eevee_flicker_is_split_into_its_parts():
    """``attribute_flicker``: with the truth T = D + I and EEVEE E = D_e + V_e, a flicker only in
    EEVEE's direct light is all part (a); one only in EEVEE's light of the VPLs (the evaluator's
    steady) is all part (b); the evaluator's own drift from the truth is part (c). Each part is
    over the truth's mean luminance, so a part that is the whole equals the whole."""
    rng = np.random.default_rng(0)
    frames = 4
    direct = [np.full((6, 8, 3), 0.6) + 0.1 * t for t in range(frames)]  # Cycles' direct, moving
    indirect = [np.full((6, 8, 3), 0.4) for _ in range(frames)]
    truths = [d + i for d, i in zip(direct, indirect, strict=True)]
    flick = [rng.uniform(-0.05, 0.05, (6, 8, 1)) * np.ones(3) for _ in range(frames)]
    # (a) only: EEVEE's direct light flickers, its VPL light is the evaluator's, the truth's
    eevee_direct = [d + f for d, f in zip(direct, flick, strict=True)]
    eevee = [d + i for d, i in zip(eevee_direct, indirect, strict=True)]
    parts = animation.attribute_flicker(eevee, eevee_direct, direct, indirect, truths)
    assert parts["direct"] > 0.01
    assert parts["direct"] == pytest.approx(parts["eevee"])
    assert parts["vpl"] == pytest.approx(0.0, abs=1e-12)
    assert parts["evaluator"] == pytest.approx(0.0, abs=1e-12)
    # (b) only: EEVEE's VPL light flickers around the evaluator's
    eevee = [d + i + f for d, i, f in zip(direct, indirect, flick, strict=True)]
    parts = animation.attribute_flicker(eevee, direct, direct, indirect, truths)
    assert parts["vpl"] == pytest.approx(parts["eevee"]) and parts["direct"] == pytest.approx(
        0.0, abs=1e-12
    )
    # (c): the evaluator's VPL light misses a change of the truth's indirect light
    vpl = [i - 0.05 * t for t, i in enumerate(indirect)]
    eevee = [d + v for d, v in zip(direct, vpl, strict=True)]
    parts = animation.attribute_flicker(eevee, direct, direct, vpl, truths)
    assert parts["evaluator"] == pytest.approx(parts["eevee"]) and parts["vpl"] == pytest.approx(
        0.0, abs=1e-12
    )
    assert parts["evaluator"] == pytest.approx(0.05 * 1.0 / np.mean([t.mean() for t in truths]))


def test_cornell_moving_keys_its_lamp_and_the_light_follows():
    empty_file()
    scene = build_cornell_moving(bpy.context.scene)
    lamp = scene.objects[animated.CORNELL_LAMP]
    keys = _keys(lamp)
    assert [k[0] for k in keys[("location", 0)]] == list(animated.FRAMES)
    energy = _keys(lamp.data)[("energy", 0)]
    assert energy[1][1] == pytest.approx(animated.CORNELL_LAMP_DIM * energy[0][1])
    assert (scene.frame_start, scene.frame_end) == animated.FRAMES
    first, last = _mean_luminance(scene, 1), _mean_luminance(scene, 24)
    # The lamp moves from the left to the right and dims: the left half darkens much more.
    assert last[0] / first[0] < 0.6
    assert last[0] / first[0] < 0.8 * (last[1] / first[1])
    assert scene.frame_current == 1  # the capture put the frame back


def test_skyroom_afternoon_sweeps_its_sun():
    empty_file()
    scene = animated.build_skyroom_afternoon(bpy.context.scene)
    sky = scene.world.node_tree.nodes[animated.SKY_NODE]
    keys = _keys(scene.world.node_tree)
    path = f'nodes["{animated.SKY_NODE}"].sun_rotation'
    assert [k[0] for k in keys[(path, 0)]] == list(animated.FRAMES)
    scene.frame_set(12)
    assert animated.SKY_SUN_ROTATIONS[0] < sky.sun_rotation < animated.SKY_SUN_ROTATIONS[1]
    scene.frame_set(1)
    cap = [
        capture(scene, resolution=(32, 18), samples=4, seed=0, frame=f).diffuse_direct
        for f in animated.FRAMES
    ]
    lum = [c @ np.array([0.2126, 0.7152, 0.0722]) for c in cap]
    # The sun patches move: pixels lit at one end of the afternoon are dark at the other.
    moved = np.abs(lum[0] - lum[1]) > 0.5 * max(lum[0].max(), lum[1].max())
    assert moved.sum() >= 3


def _animate(tmp_path, name: str) -> animation.AnimationSummary:
    job = Job(n_vpls=16, size=24, samples=2, iterations=1, cache_dir=tmp_path / "cache")
    return animation.run_animated_job(
        bpy.context.scene,
        tmp_path / name,
        (1, 24, 23),
        job=job,
        score_between=False,
        log=lambda _line: None,
    )


def _stands_still(keys: dict) -> bool:
    """Whether a light's location keys hold one value on every frame."""
    return all(len({v for _, v in keys[("location", axis)]}) == 1 for axis in range(3))


def _written_keys() -> dict[str, dict]:
    coll = bpy.data.collections[apply.COLLECTION_NAME]
    return {
        o.name: {**_keys(o), **_keys(o.data)}
        for o in coll.objects
        if o.get("vplace_slot") is not None
    }


def test_the_animated_job_keys_one_set_of_lights_the_same_on_a_rerun(tmp_path):
    empty_file()
    scene = build_cornell_moving(bpy.context.scene)
    bpy.context.view_layer.update()
    scene.frame_set(7)
    scene.render.image_settings.file_format = "PNG"  # as test_operators: a saved file has it set
    before = data_snapshot()
    actions = len(bpy.data.actions)
    done = _animate(tmp_path, "a")
    assert scene.frame_current == 7
    assert diff(before, data_snapshot()) == []  # only the VPL collection is new
    first = _written_keys()
    # One shared set of positions (vplace.temporal.shared_layout): at most the budget of 16
    # lights, each standing where it stands on both frames; only the powers change.
    assert 0 < len(first) == done.slots <= 16
    assert all(_stands_still(keys) for keys in first.values())
    for keys in first.values():
        # Location, rotation, energy, colour and the disk's size (the patch the VPL stands
        # for) keyed on both captured frames, linearly.
        assert {p for p, _ in keys} == {
            "location",
            "rotation_quaternion",
            "energy",
            "color",
            "size",
        }
        assert all([k[0] for k in v] == [1.0, 24.0] for v in keys.values())
    coll = bpy.data.collections[apply.COLLECTION_NAME]
    for o in coll.objects:
        for fc in action_fcurves(o.animation_data.action):
            assert {k.interpolation for k in fc.keyframe_points} == {"LINEAR"}
    # A light lit on one frame only is keyed to 0 W on the other.
    energies = np.array([[v for _, v in keys[("energy", 0)]] for keys in first.values()])
    assert (energies >= 0).all() and (energies.max(axis=1) > 0).all()
    lit = (energies > 0).sum(axis=0)
    assert (0 < lit).all() and (lit <= 16).all()  # each frame's VPLs the refit kept, no more
    # The keyed lights at a captured frame are that frame's lights: Blender's evaluated power.
    scene.frame_set(24)
    total = sum(o.data.energy * np.array(o.data.color) for o in coll.objects)
    refit = [r for r in done.rows if r["frame"] == 24 and r["image"] == animation.KEYED]
    assert len(refit) == 1 and total.max() > 0
    scene.frame_set(7)

    again = _animate(tmp_path, "b")
    assert again.slots == done.slots
    assert _written_keys() == first
    # One collection of lights and one of the frames' region (a camera standing still: one
    # sphere), each replaced by the re-run.
    marked = sorted(c.name for c in bpy.data.collections if c.get(VPL_MARKER))
    assert marked == sorted([apply.REGION_NAME, apply.COLLECTION_NAME])
    region = bpy.data.collections[apply.REGION_NAME].objects
    assert [o.name for o in region if o.empty_display_type == "SPHERE"] == ["vplace region 1"]
    assert apply.clear_vpls() == done.slots
    apply.clear_vpls(apply.REGION_NAME)
    assert len(bpy.data.actions) == actions  # the keyed lights' actions went with them
    assert diff(before, data_snapshot()) == []
    # The copy of the file opens at the user's frame, with the keyed lights.
    bpy.ops.wm.open_mainfile(filepath=str(tmp_path / "a" / "scene.blend"))
    assert bpy.context.scene.frame_current == 7
    assert len(bpy.data.collections[apply.COLLECTION_NAME].objects) == done.slots
    # The files: a frame column, both frames, every image kind.
    csv = (tmp_path / "a" / "results.csv").read_text().splitlines()
    assert csv[0].startswith("frame,captured,image,ssim")
    assert {line.split(",")[0] for line in csv[1:]} == {"1", "24"}
    assert set(done.temporal_error) == {animation.KEYED, animation.STILL, animation.DIRECT}
    # At the captured frames the keyed lights are the shared set refitted to that frame: they
    # carry its bounce light (the truth's brightness within 15 %; direct light alone: 0.5).
    for f in (1, 24):
        k, d = (
            next(r for r in done.rows if r["frame"] == f and r["image"] == kind)
            for kind in (animation.KEYED, animation.DIRECT)
        )
        assert abs(k["brightness"] - 1.0) < 0.15 and k["brightness"] - d["brightness"] > 0.3


def _one_vpl_on_two_frames():
    """An empty file's scene and one VPL tracked over two frames."""
    import vplace

    empty_file()
    one = vplace.VplSet(
        np.zeros((1, 3), np.float32),
        np.array([[0, 0, 1]], np.float32),
        np.ones((1, 3), np.float32),
        radius=0.01,
    )
    return bpy.context.scene, vplace.temporal.track([one, one], diagonal=10.0)


def test_a_keyed_sun_is_dark_where_the_frame_has_none():
    from addon.writeback.stand_ins import SunLight

    scene, tracked = _one_vpl_on_two_frames()
    sun = SunLight((0.0, 0.0, 1.0), (2.0, 2.0, 1.0), 0.01)
    keyed.write_keyed(scene, [1, 5], tracked, suns=[sun, None])
    obj = apply.world_sun_light(scene)
    assert obj is not None
    energy = _keys(obj.data)[("energy", 0)]
    assert energy == [(1.0, 2.0), (5.0, 0.0)]


def test_a_rerun_keys_its_lights_with_actions_of_their_own_names():
    scene, tracked = _one_vpl_on_two_frames()
    names = []
    for _ in range(3):
        coll = keyed.write_keyed(scene, [1, 5], tracked)
        names.append(
            sorted(
                block.animation_data.action.name
                for obj in coll.objects
                for block in (obj, obj.data)
                if block.animation_data is not None
            )
        )
    assert names[0] and names[1] == names[0] and names[2] == names[0]  # no ".001" on re-runs
    assert not any(".001Action" in a.name for a in bpy.data.actions)


def test_the_keyed_lights_leave_the_unlit_objects_out_as_the_still_ones_do():
    scene, tracked = _one_vpl_on_two_frames()
    mesh = bpy.data.meshes.new("chrome")
    chrome = bpy.data.objects.new("chrome", mesh)
    scene.collection.objects.link(chrome)
    for _ in range(2):  # re-running replaces the receiver collection with the lights
        coll = keyed.write_keyed(scene, [1, 5], tracked, unlit=["chrome"])
    assert apply.unlit_objects(coll) == ["chrome"]
    assert {c.name for c in chrome.users_collection} == {
        scene.collection.name,
        apply.COLLECTION_NAME + apply.UNLIT_SUFFIX,
    }
    apply.clear_vpls()
    assert [c.name for c in chrome.users_collection] == [scene.collection.name]


def test_a_sky_portal_is_keyed_as_the_sky_changes():
    """The same opening on both frames: one portal light, its power and facing keyed; a portal
    that moved is written as the first frame's, unkeyed; portals in the emitters are not
    written twice."""
    from addon.writeback.stand_ins import EmitterLight

    scene, tracked = _one_vpl_on_two_frames()

    def portal(power, facing, x=0.0):
        return EmitterLight((x, -1, 1), facing, (1, 0, 0), "RECTANGLE", 1, 1.2, power, "p", True)

    morning = portal((2.0, 2.0, 3.0), (0.0, 1.0, 0.0))
    evening = portal((1.0, 0.5, 0.5), (0.0, 0.8, -0.6))
    keyed.write_keyed(scene, [1, 5], tracked, emitters=[morning], portals=[[morning], [evening]])
    (obj,) = [o for o in scene.objects if o.get("vplace_portal")]
    keys = _keys(obj.data)
    assert keys[("energy", 0)] == [(1.0, 3.0), (5.0, 1.0)]
    assert [v for _, v in keys[("color", 1)]] == pytest.approx([2.0 / 3.0, 0.5])
    scene.frame_set(5)
    facing = obj.matrix_world.to_3x3() @ Vector((0.0, 0.0, -1.0))
    assert tuple(facing) == pytest.approx((0.0, 0.8, -0.6), abs=1e-4)
    moved = portal((1.0, 1.0, 1.0), (0.0, 1.0, 0.0), x=0.5)
    keyed.write_keyed(scene, [1, 5], tracked, portals=[[morning], [moved]])
    (obj,) = [o for o in scene.objects if o.get("vplace_portal")]
    assert obj.data.animation_data is None and obj.data.energy == pytest.approx(3.0)


@pytest.mark.slow
def test_eevee_renders_the_keyed_lights_at_each_frame(tmp_path):
    """EEVEE with the keyed lights at both ends of cornell_moving: at the truth's brightness on
    each frame. Lights stuck at frame 1's power would make frame 24 (lamp at 0.4) about 1.7x
    too bright; lights missing would make it about 0.5x."""
    empty_file()
    build_cornell_moving(bpy.context.scene)
    bpy.context.view_layer.update()
    job = Job(n_vpls=32, size=32, samples=4, cache_dir=tmp_path / "cache")
    done = animation.run_animated_job(
        bpy.context.scene,
        tmp_path / "out",
        (1, 24, 23),
        job=job,
        truth_samples=64,
        eevee=True,
        eevee_still=True,
        volume_once=True,
        volume_per_frame=True,
        log=lambda _line: None,
    )
    keys_after = _written_keys()
    rows = {r["frame"]: r for r in done.rows if r["image"] == animation.EEVEE}
    assert sorted(rows) == [1, 24]
    for r in rows.values():
        assert 0.8 < r["brightness"] < 1.2, r
    assert animation.EEVEE in done.temporal_error
    # ... with its temporal error split, and EEVEE's direct light of each frame measured
    assert set(done.flicker) == set(animation.FLICKER_PARTS)
    assert len(done.eevee_direct_brightness) == 2
    assert all(0.8 < b < 1.2 for b in done.eevee_direct_brightness)
    # Each frame's still layout rendered too, then the keyed lights written back, the same.
    still = {r["frame"]: r for r in done.rows if r["image"] == animation.EEVEE_STILL}
    assert sorted(still) == [1, 24]
    for f in (1, 24):  # at a captured frame the shared set stands in for the frame's own layout
        assert 0.8 < still[f]["brightness"] < 1.2
        assert rows[f]["ssim"] > still[f]["ssim"] - 0.05  # 0.025 and 0.006 below, 16 VPLs a frame
    assert len(keys_after) == done.slots and all(keys_after.values())
    # The volume baked once, at frame 1: rendered at both frames, and removed after.
    once = [r["frame"] for r in done.rows if r["image"] == animation.VOLUME_ONCE]
    assert once == [1, 24] and animation.VOLUME_ONCE in done.temporal_error
    # Baked again at each frame: the volume follows the lamp (frame 1 as baked once; at frame
    # 24, where the lamp gives 0.4 of its light, darker than the volume baked at frame 1), and
    # its seconds hold the bakes.
    per = {r["frame"]: r for r in done.rows if r["image"] == animation.VOLUME_PER_FRAME}
    first = {r["frame"]: r for r in done.rows if r["image"] == animation.VOLUME_ONCE}
    assert sorted(per) == [1, 24] and animation.VOLUME_PER_FRAME in done.temporal_error
    assert per[1]["ssim"] == pytest.approx(first[1]["ssim"], abs=0.01)
    assert per[24]["brightness"] < first[24]["brightness"] - 0.05
    assert per[24]["seconds"] > first[24]["seconds"]
    assert not any(o.type == "LIGHT_PROBE" for o in bpy.data.objects)


def test_the_panel_animates_the_lights_undoably(tmp_path, monkeypatch):
    """ "Frames: animate" in the panel: "Lay out and apply" keys the lights over the frames."""
    import addon
    from addon.ui import operators

    monkeypatch.setattr(operators, "cache_dir", lambda: tmp_path / "cache")
    addon.register()
    try:
        empty_file()
        scene = build_cornell_moving(bpy.context.scene)
        bpy.context.view_layer.update()
        s = scene.vplace
        s.capture_size, s.samples, s.vpl_budget, s.iterations = 24, 2, 16, 1
        s.view_mode = "animate"
        s.frame_start, s.frame_end, s.frame_step = 1, 24, 23
        assert s.view_set().mode == "active" and s.animate_frames() == (1, 24, 23)
        assert "UNDO" in operators.VPLACE_OT_apply.bl_options
        assert bpy.ops.vplace.apply() == {"FINISHED"}
        lights = [
            o for o in apply.find_collection().objects if o.get(keyed.SLOT_PROPERTY) is not None
        ]
        assert 0 < len(lights) <= 16  # one shared set of positions, within the budget
        for o in lights:
            assert [k[0] for k in _keys(o.data)[("energy", 0)]] == [1.0, 24.0]
            assert _stands_still(_keys(o))
        assert scene.frame_current == 1
        s.frame_step = 1
        s.frame_end = 500
        with pytest.raises(RuntimeError, match="more than the 120"):
            bpy.ops.vplace.apply()
    finally:
        addon.unregister()


def test_report_animate_scores_every_frame_and_plots_them(tmp_path):
    """``report --blend F --animate``: every frame from START to END scored (the middle one
    between the captured ones), the temporal error's steps, a plot."""
    import json

    from addon import cli

    empty_file()
    build_cornell_moving(bpy.context.scene)
    blend = tmp_path / "moving.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    out = tmp_path / "report"
    argv = ["report", "--blend", str(blend), "--animate", "1", "3", "2", "--budgets", "16"]
    argv += ["--resolution", "24", "24", "--capture-samples", "2", "--truth-samples", "8"]
    argv += ["--cycles-samples", "1", "--no-eevee", "--out", str(out)]
    assert cli.main(argv) == 0
    summary = json.loads((out / "animation.json").read_text())
    assert summary["frames"] == [1, 3] and summary["scored_frames"] == [1, 2, 3]
    assert summary["n_vpls"] == 16
    images = {animation.KEYED, animation.STILL, animation.DIRECT, animation.cycles_kind(1)}
    # The report renders each frame's truth twice: the truth's own noise is a row, and every
    # other image is also scored against the noise-free truth.
    images.add(animation.TRUTH_AGAIN)
    assert set(summary["temporal_steps"]) == images
    for kind, steps in summary["temporal_steps"].items():
        assert len(steps) == 2
        assert np.mean(steps) == pytest.approx(summary["temporal_error"][kind])
    for r in summary["rows"]:
        assert ("ssim_noise_free" in r) == (r["image"] != animation.TRUTH_AGAIN)
    again = [r for r in summary["rows"] if r["image"] == animation.TRUTH_AGAIN]
    assert [r["frame"] for r in again] == [1, 2, 3] and all(r["ssim"] < 1.0 for r in again)
    lines = (out / "results.csv").read_text().splitlines()
    assert "ssim_noise_free" in lines[0].split(",")
    assert sorted({int(r.split(",")[0]) for r in lines[1:]}) == [1, 2, 3]
    md = (out / "animation.md").read_text()
    assert "the truth, another seed" in md
    # The one-time cost of a captured frame is stated; no 16 spp frame here to weigh it against.
    assert "A captured frame of the keyed lights costs" in md and "spp frame of" not in md
    assert (out / "animation.png").read_bytes()[:4] == b"\x89PNG"


def test_a_captured_frames_cost_is_weighed_against_a_cycles_frame():
    """Issue 23's yardstick: a captured frame's captures and keyed layout against one Cycles +
    OIDN 16 spp frame, the export's wall time beside it."""
    costs = [animation.FrameCost(1, 0.9, 0.6, 0.25), animation.FrameCost(5, 0.7, 0.4, 0.25)]
    summary = animation.AnimationSummary(
        "s", [1, 5], [1, 5], [16, 9], 8, 8, "t", costs=costs, keyed_layout_seconds=0.2,
        seconds_per_frame={animation.cycles_kind(16): 0.4},
    )  # fmt: skip
    text = animation.captured_frame_cost(summary)
    assert text.startswith(
        "A captured frame of the keyed lights costs 0.60 s once: the captures' Cycles render "
        "(0.50 s, as first rendered) and its share of the keyed layout (0.10 s), 1.50x a "
        "Cycles + OIDN 16 spp frame of this size (0.40 s; at most 1x is the aim)."
    )
    assert "(0.80 s a frame in this run;" in text
    assert text in animation.animation_report(summary)
    del summary.seconds_per_frame[animation.cycles_kind(16)]
    assert "spp frame" not in animation.captured_frame_cost(summary)


def test_eevees_own_gi_is_scored_with_the_worlds_sun_as_the_users_lamp():
    """``users_sun``: EEVEE extracts next to nothing from a sky (the sky-lit room's ray tracing +
    volume got 0.035x Cycles' light), so the alternatives get the lamp a user adds: a SUN lamp
    of each frame's sun, keyed, counted as the user's (unmarked: a set-up without VPLs renders
    it and its cache key holds it), EEVEE's extraction off; all of it gone after the block."""
    from addon.capture.passes import hide_vpls, vpl_objects
    from addon.settings import override
    from addon.writeback import eevee_setup
    from addon.writeback.stand_ins import SunLight

    scene, tracked = _one_vpl_on_two_frames()
    scene.world = bpy.data.worlds.new("sky")
    keyed.write_keyed(scene, [1, 5], tracked)  # vplace's own lights, hidden by the set-ups
    sun = SunLight((0.0, 0.6, 0.8), (2.0, 2.0, 1.0), 0.01)
    before = data_snapshot()
    counts = [len(c) for c in (bpy.data.objects, bpy.data.lights, bpy.data.actions)]
    with eevee_setup.users_sun(scene, [None], [1]) as lamp:  # no sun: nothing changes
        assert not lamp and diff(before, data_snapshot()) == []
    with eevee_setup.users_sun(scene, [sun, None], [1, 5]) as lamp, override() as g:
        assert lamp
        hide_vpls(g)
        (obj,) = [o for o in scene.objects if o.type == "LIGHT" and o.data.type == "SUN"]
        assert obj not in vpl_objects(scene)
        assert not any(c.hide_render for c in obj.users_collection)
        assert scene.world.sun_threshold == 0.0
        assert _keys(obj.data)[("energy", 0)] == [(1.0, 2.0), (5.0, 0.0)]
        scene.frame_set(1)
        facing = obj.matrix_world.to_3x3() @ Vector((0.0, 0.0, 1.0))
        assert tuple(facing) == pytest.approx((0.0, 0.6, 0.8), abs=1e-4)
    with eevee_setup.users_sun(scene, [sun]) as lamp:  # a still: one unkeyed lamp
        (obj,) = [o for o in scene.objects if o.type == "LIGHT" and o.data.type == "SUN"]
        assert lamp and obj.data.animation_data is None and obj.data.energy == 2.0
    assert scene.world.sun_threshold == 10.0
    assert [len(c) for c in (bpy.data.objects, bpy.data.lights, bpy.data.actions)] == counts
    assert eevee_setup.USERS_SUN_COLLECTION not in bpy.data.collections
    assert diff(before, data_snapshot()) == []


def test_a_moving_camera_keeps_one_working_scale_over_the_frames(tmp_path):
    """Each frame's scene takes the working scale of the region seen from the camera at every
    captured frame (``animation.frame_eyes``): over a kilometre of ground, the region seen from
    a camera that rises differs per frame, and so would the VPLs' size."""
    empty_file()
    scene = build_cornell_moving(bpy.context.scene)
    bpy.ops.mesh.primitive_plane_add(size=1000.0, location=(0.0, 0.0, -0.5))
    cam = scene.camera
    cam.keyframe_insert("location", frame=1)
    cam.location.z += 3.0
    cam.keyframe_insert("location", frame=24)
    job = Job(n_vpls=16, size=24, samples=2, cache_dir=tmp_path / "cache")
    timer = StageTimer(lambda _line: None)
    prepared = animation.capture_frames(scene, [1, 24], job, timer)
    scales = [p.scene.scale for p in prepared]
    assert scales[0] == scales[1] < 0.5 * prepared[0].scene.diagonal
    # each frame on its own would see another region
    alone = [
        vplace.Scene(
            p.exported.vertices,
            p.exported.triangles,
            p.exported.material_ids,
            p.exported.albedo,
            [],
            eyes=animation.frame_eyes(scene, [f])[0],
            looks=animation.frame_eyes(scene, [f])[1],
        ).scale
        for p, f in zip(prepared, (1, 24), strict=True)
    ]
    assert abs(alone[1] - alone[0]) > 0.05 * alone[0], alone
    assert scene.frame_current == 1
