"""EEVEE set up for vplace's lights: every setting that would drop, dim or double their light is
named, "Set up EEVEE for vplace" fixes it without touching the user's objects, and the written
lights carry the shadow settings that keep the pool from overflowing."""

import math

import bpy
import numpy as np
import pytest
from blender_util import addon_cornell, data_snapshot, diff

from addon.native import vplace
from addon.writeback import apply, eevee_setup


@pytest.fixture
def scene():
    with addon_cornell() as sc:
        sc.eevee.light_threshold = 1e-4  # the box's lamp reaches 31 m (see the faded-lamp test)
        yield sc


def write(scene, n, seed=0, **kwargs):
    rng = np.random.default_rng(seed)
    pos = rng.uniform(-0.8, 0.8, (n, 3)).astype(np.float32) + np.float32([0, 0, 1])
    up = np.tile(np.float32([0, 0, 1]), (n, 1))
    flux = rng.uniform(0.1, 1.0, (n, 3)).astype(np.float32)
    return apply.write_vpls(scene, vplace.VplSet(pos, up, flux), scene_diagonal=3.5, **kwargs)


def settings(found):
    return {p.setting for p in found}


def test_no_vpls_no_problems(scene):
    scene.eevee.use_shadows = False
    assert eevee_setup.problems(scene) == []


def test_every_problem_is_named_and_set_up_fixes_it(scene):
    coll = write(scene, 300)
    e = scene.eevee
    e.shadow_pool_size = "64"  # 256 pages for about 1,500 wanted
    e.use_raytracing, e.fast_gi_method = True, "GLOBAL_ILLUMINATION"
    if hasattr(e, "use_fast_gi"):  # Blender 4.5 on (4.2's fast GI is on with ray tracing)
        e.use_fast_gi = True
    coll.objects[0].data.use_custom_distance = False
    probe = bpy.data.objects.new("users volume", bpy.data.lightprobes.new("users", "VOLUME"))
    scene.collection.objects.link(probe)
    bg = scene.world.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (0.05, 0.05, 0.05, 1)
    bg.inputs["Strength"].default_value = 1.0
    found = eevee_setup.problems(scene)
    assert settings(found) == {
        "scene.eevee.shadow_pool_size",
        "Light.use_custom_distance",
        "scene.eevee.fast_gi_method",
        "users volume.capture_indirect",
        "world",
    }
    pool = next(p for p in found if p.setting == "scene.eevee.shadow_pool_size")
    # 300 VPL disks and the box's own area light, 5 pages each.
    assert "1505 shadow pages" in pool.message and "64 MB pool holds 256" in pool.message
    before = data_snapshot()
    changed = eevee_setup.set_up(scene, bake_volume=False)
    assert any("shadow_pool_size = '512'" in c for c in changed)
    assert "scene.eevee.shadow_ray_count = 4" in changed
    assert e.fast_gi_method == "AMBIENT_OCCLUSION_ONLY" and e.use_raytracing
    volume = eevee_setup.vplace_volume(scene)
    assert volume is not None and not volume.data.capture_indirect
    lo, hi = eevee_setup.scene_bounds(scene)
    assert all(2 * s >= 1.14 * (b - a) for s, a, b in zip(volume.scale, lo, hi, strict=True))
    # What is left is the user's own: their edited light and their own probe volume; the
    # warnings send the user to what fixes them, not to the set-up again.
    left = eevee_setup.problems(scene)
    assert settings(left) == {"Light.use_custom_distance", "users volume.capture_indirect"}
    assert [p.remedy for p in left] == [
        "Lay out and apply again writes them as vplace sets them",
        "",
    ]
    assert all("Set up" not in p.advice() for p in left)
    assert all(
        "Set up EEVEE for vplace fixes it" in p.advice()
        for p in found
        if p.setting[:6] in ("scene.", "world")
    )
    # Only scene settings and vplace's own collection changed, never the user's objects.
    changes = diff(before, data_snapshot())
    assert changes and all(d.startswith("/scenes/Scene/eevee/") for d in changes), changes
    # A second set-up replaces vplace's volume, it does not add one.
    eevee_setup.set_up(scene, bake_volume=False)
    assert sum(o.type == "LIGHT_PROBE" for o in scene.objects) == 2


def test_shadows_off_and_unshadowed_vpls_are_named(scene):
    coll = write(scene, 20)
    scene.eevee.use_shadows = False
    assert settings(eevee_setup.problems(scene)) == {"scene.eevee.use_shadows"}
    scene.eevee.use_shadows = True
    coll.objects[3].data.use_shadow = False
    (problem,) = eevee_setup.problems(scene)
    assert problem.setting == "Light.use_shadow" and "1 VPL lights cast no shadow" in str(problem)


def test_written_lights_take_the_coarsest_shadows_and_only_the_brightest_are_shadowed(
    scene, monkeypatch
):
    monkeypatch.setattr(apply, "MAX_SHADOWED_VPLS", 5)
    coll = write(scene, 12, seed=3)
    lights = sorted(coll.objects, key=lambda o: o["vplace_index"])
    assert all(
        o.data.shadow_maximum_resolution == pytest.approx(apply.SHADOW_TEXEL_DIAGONALS * 3.5)
        and not o.data.use_shadow_jitter
        for o in lights
    )
    lum = np.array([np.dot(o.data.color, vplace.LUMINANCE) * o.data.energy for o in lights])
    shadowed = {o["vplace_index"] for o in lights if o.data.use_shadow}
    assert shadowed == {lights[i]["vplace_index"] for i in np.argsort(-lum)[:5]}
    # More lights unshadowed than the cap explains: named.
    assert not eevee_setup.problems(scene)


def test_a_lamp_eevee_fades_inside_the_scene_is_named_and_set_up_lets_it_reach():
    with addon_cornell() as scene:
        write(scene, 8)
        lamp = scene.objects["light"].data  # 9.5 W: at threshold 0.01 EEVEE fades it by 3.09 m
        assert scene.eevee.light_threshold == pytest.approx(0.01)
        assert eevee_setup.lamp_reach(lamp, 0.01) == pytest.approx(3.0884, abs=1e-3)
        (problem,) = eevee_setup.problems(scene)
        assert problem.setting == "scene.eevee.light_threshold"
        assert "'light' reaches 3.09 m" in problem.message
        eevee_setup.set_up(scene, bake_volume=False)
        lo, hi = eevee_setup.scene_bounds(scene)
        reach = eevee_setup.lamp_reach(lamp, scene.eevee.light_threshold)
        need = eevee_setup.LAMP_REACH_DIAGONALS * (hi - lo).length
        assert need <= reach < 1.01 * need
        assert not eevee_setup.problems(scene)
        # A custom distance is the user's own choice: then the threshold does not apply.
        scene.eevee.light_threshold = 0.01
        lamp.use_custom_distance = True
        assert not eevee_setup.faded_lamps(scene)


def test_the_pool_estimate_and_choice():
    assert eevee_setup.pool_for(100) == 32  # 128 pages * 0.9 >= 100
    assert eevee_setup.pool_for(2000) == 1024
    assert eevee_setup.pool_for(10**6) == 1024  # the largest there is


def test_the_operator_is_undoable_and_reports_what_it_changed(scene):
    write(scene, 8)
    scene.eevee.use_shadows = False
    assert bpy.ops.vplace.setup_eevee() == {"FINISHED"}
    assert scene.eevee.use_shadows
    assert "UNDO" in bpy.types.VPLACE_OT_setup_eevee.bl_options


def _notes(scene, word, cut=()):
    """The lamp notes that name ``word`` (``cut``: the lamps the cameras see cut)."""
    return [n for n in eevee_setup.lamp_notes(scene, cut) if word in n]


def test_the_users_soft_lamps_without_jitter_are_noted_and_never_changed(scene):
    lamp = scene.objects["light"]  # the box's area light, jitter off as Blender makes it
    write(scene, 4)  # vplace's VPL lights (unjittered, by design) are not the user's lamps
    assert eevee_setup.unjittered_lamps(scene) == ["light"]
    (note,) = _notes(scene, "Jitter")
    assert "1 of your lamps (e.g. 'light')" in note
    # vplace's own stand-ins are jittered and never noted; a set-up does not touch the lamp.
    eevee_setup.set_up(scene, bake_volume=False)
    assert not lamp.data.use_shadow_jitter and eevee_setup.unjittered_lamps(scene) == ["light"]
    lamp.data.use_shadow_jitter = True
    assert _notes(scene, "Jitter") == []
    lamp.data.use_shadow_jitter, lamp.data.use_shadow = False, False
    assert eevee_setup.lamp_notes(scene) == []  # no shadow, no noise (nor darkened planes)
    lamp.data.use_shadow = True
    lamp.hide_render = True
    assert eevee_setup.lamp_notes(scene) == []
    # A sun's jitter gains nothing measurable: not noted.
    sun = bpy.data.objects.new("sun", bpy.data.lights.new("sun", "SUN"))
    sun.data.angle = 0.1
    scene.collection.objects.link(sun)
    assert eevee_setup.unjittered_lamps(scene) == []


def test_a_lamp_that_a_surfaces_plane_passes_through_is_noted(scene):
    """The lamps the cameras see cut (``Prepared.cut_lamps``, found on the captures:
    ``tests/addon/test_match_auto.py``) are noted while they are the user's shadowed lamps;
    EEVEE darkens those surfaces (``tests/render/test_eevee_cut_lights.py``)."""
    lamp = scene.objects["light"]
    write(scene, 4)  # vplace's own lights are not the user's lamps
    (note,) = _notes(scene, "plane", ["light"])
    assert "1 of your lamps (e.g. 'light')" in note and "darkens" in note
    assert _notes(scene, "plane") == [] and _notes(scene, "plane", ["gone"]) == []
    # A lamp that casts no shadow is not darkened; nor is one that lights nothing.
    lamp.data.use_shadow = False
    assert _notes(scene, "plane", ["light"]) == []
    lamp.data.use_shadow = True
    lamp.hide_render = True
    assert _notes(scene, "plane", ["light"]) == []
    # The write-back keeps them for the panel.
    lamp.hide_render = False
    write(scene, 4, cut_lamps=["light"])
    assert apply.stored_cut_lamps() == ["light"]
    write(scene, 4)
    assert apply.stored_cut_lamps() == []


def test_a_ground_no_camera_sees_neither_stretches_the_volume_nor_the_lamps_reach(scene):
    """The region the cameras saw (``vplace.Scene.region``, kept on the VPL collection) is what
    the probe volume spans and what the lamps must reach, not a kilometre of ground under the
    box (before: a volume of 1 km with the box inside one probe cell)."""
    bpy.ops.mesh.primitive_plane_add(size=1000.0, location=(0.0, 0.0, -0.5))
    plain = eevee_setup.scene_bounds(scene)
    assert (plain[1] - plain[0]).length > 1000.0
    rng = np.random.default_rng(0)
    pos = rng.uniform(-0.8, 0.8, (8, 3)).astype(np.float32) + np.float32([0, 0, 1])
    vpls = vplace.VplSet(pos, np.tile(np.float32([0, 0, 1]), (8, 1)), np.ones((8, 3), np.float32))
    box = ((-1.0, -1.0, 0.0), (1.0, 1.0, 2.0))
    coll = apply.write_vpls(scene, vpls, scene_diagonal=6.9, region=box)
    assert list(coll[apply.REGION_KEY]) == [-1.0, -1.0, 0.0, 1.0, 1.0, 2.0]
    lo, hi = eevee_setup.scene_bounds(scene)
    assert (tuple(lo), tuple(hi)) == box
    volume = eevee_setup.new_volume(scene, scene.collection, margin=eevee_setup.VOLUME_MARGIN)
    assert max(volume.scale) < 2.0
    lamp = scene.objects["light"].data
    scene.eevee.light_threshold = 0.01  # the lamp reaches 3.09 m
    scene.eevee.light_threshold = eevee_setup.threshold_for(scene)
    need = eevee_setup.LAMP_REACH_DIAGONALS * (hi - lo).length
    assert need <= eevee_setup.lamp_reach(lamp, scene.eevee.light_threshold) < 1.01 * need
    # written without a region (a scene whose cameras see most of it): the meshes' bounds
    write(scene, 8)
    assert apply.stored_region() is None
    assert eevee_setup.scene_bounds(scene) == plain


def test_an_area_lights_spread_is_noted_as_what_eevee_ignores(scene):
    lamp = scene.objects["light"]  # the box's area light, spread 180 degrees as Blender makes it
    lamp.data.use_shadow_jitter = True
    assert eevee_setup.spread_lamps(scene) == [] and _notes(scene, "Spread") == []
    lamp.data.spread = math.radians(60.0)
    assert eevee_setup.spread_lamps(scene) == [("light", pytest.approx(60.0))]
    (note,) = _notes(scene, "Spread")
    assert "Spread of 1 of your area lights (e.g. 'light', 60 degrees)" in note
    lamp.hide_render = True
    assert eevee_setup.lamp_notes(scene) == []


def test_lights_with_disks_get_the_fast_gi_of_their_near_field(scene):
    rng = np.random.default_rng(5)
    n = 40
    pos = rng.uniform(-0.8, 0.8, (n, 3)).astype(np.float32) + np.float32([0, 0, 1])
    up = np.tile(np.float32([0, 0, 1]), (n, 1))
    flux = rng.uniform(0.1, 1.0, (n, 3)).astype(np.float32)
    vpls = vplace.VplSet(pos, up, flux, radius=0.035)
    # A set without the near-field gather (as every new set) keeps ambient occlusion only.
    apply.write_vpls(scene, vpls, scene_diagonal=3.5)
    assert apply.stored_near_field() == 0.0
    vpls = vpls.with_near_field(True)
    coll = apply.write_vpls(scene, vpls, scene_diagonal=3.5)
    near = vpls.near_field_distance
    assert near > 0 and coll[apply.NEAR_FIELD_KEY] == pytest.approx(near)
    assert apply.stored_near_field() == pytest.approx(near)
    e = scene.eevee
    e.use_raytracing, e.fast_gi_method = True, "AMBIENT_OCCLUSION_ONLY"
    changed = eevee_setup.set_up(scene, bake_volume=False)
    # EEVEE gathers the light between nearby surfaces within the lights' distance, as the
    # evaluator does with near_field=True, and no further.
    assert e.fast_gi_method == "GLOBAL_ILLUMINATION" and e.use_raytracing
    assert e.fast_gi_distance == pytest.approx(near, rel=1e-6)
    assert any("fast_gi_distance" in c for c in changed)
    assert "scene.eevee.fast_gi_method" not in settings(eevee_setup.problems(scene))
    # Reaching further counts the VPLs' bounce twice: named, with the distance to use.
    e.fast_gi_distance = 4 * near
    (problem,) = [p for p in eevee_setup.problems(scene) if p.setting.endswith("fast_gi_method")]
    assert f"{near:.3g}" in problem.message
    # Points (radius 0) gather nothing: ambient-occlusion-only fast GI.
    points = vplace.VplSet(pos, up, flux).with_near_field(True)
    apply.write_vpls(scene, points, scene_diagonal=3.5)
    assert apply.stored_near_field() == 0.0
    eevee_setup.set_up(scene, bake_volume=False)
    assert e.fast_gi_method == "AMBIENT_OCCLUSION_ONLY"


def test_each_scene_keeps_its_own_probe_volume(scene):
    """ "Set up EEVEE for vplace" in one scene replaces that scene's probe volume only."""
    bg = scene.world.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (0.05, 0.05, 0.05, 1)
    bg.inputs["Strength"].default_value = 1.0
    other = bpy.data.scenes.new("B")
    other.world = scene.world
    other.collection.objects.link(bpy.data.objects["tallBox"])
    write(scene, 4)
    write(other, 3, seed=1)
    eevee_setup.set_up(scene, bake_volume=False)
    mine = eevee_setup.vplace_volume(scene)
    eevee_setup.set_up(other, bake_volume=False)
    theirs = eevee_setup.vplace_volume(other)
    assert mine is not None and theirs is not None and mine != theirs
    assert eevee_setup.vplace_volume(scene) == mine and mine.name in bpy.data.objects
    eevee_setup.set_up(scene, bake_volume=False)  # again: its own replaced, B's kept
    assert eevee_setup.vplace_volume(other) == theirs
    assert (
        len([o for o in bpy.data.objects if o.type == "LIGHT_PROBE" and o.get("vplace_vpl")]) == 2
    )


@pytest.mark.parametrize("profile", ["cosine", "omni"])
def test_set_up_makes_room_for_every_shadow_a_large_budget_writes(scene, profile):
    """1,000 VPLs: the shadowed ones fit the largest pool beside the user's lamp (768 POINT
    lights alone would take 4,608 of its 4,096 pages), so "Set up EEVEE" clears the problem."""
    n = 1000
    rng = np.random.default_rng(0)
    pos = rng.uniform(-0.8, 0.8, (n, 3)).astype(np.float32) + np.float32([0, 0, 1])
    up = np.tile(np.float32([0, 0, 1]), (n, 1))
    flux = rng.uniform(0.1, 1.0, (n, 3)).astype(np.float32)
    vpls = vplace.VplSet(pos, up, flux, profile=profile)
    coll = apply.write_vpls(scene, vpls, scene_diagonal=3.5)
    shadowed = sum(o.data.use_shadow for o in coll.objects)
    per = apply.SHADOW_PAGES["AREA" if profile == "cosine" else "POINT"]
    user = apply.user_shadow_pages(scene)  # the box's AREA lamp: 5
    assert shadowed == (613 if profile == "omni" else 736) and user == 5
    assert shadowed * per + user <= 0.9 * apply.MAX_POOL_PAGES
    eevee_setup.set_up(scene, bake_volume=False)
    assert not {"scene.eevee.shadow_pool_size", "Light.use_shadow"} & settings(
        eevee_setup.problems(scene)
    )


def test_set_up_refuses_before_it_changes_anything(scene):
    """A collection of the user's named like vplace's probes: refused with the scene as it was."""
    write(scene, 4)
    bg = scene.world.node_tree.nodes["Background"]
    bg.inputs["Strength"].default_value = 1.0
    bg.inputs["Color"].default_value = (0.05, 0.05, 0.05, 1)
    scene.collection.children.link(bpy.data.collections.new(eevee_setup.PROBE_COLLECTION))
    scene.eevee.use_raytracing = False
    before = data_snapshot()
    with pytest.raises(vplace.VplaceError, match="was not made by vplace"):
        eevee_setup.set_up(scene, bake_volume=False)
    assert diff(before, data_snapshot()) == []
