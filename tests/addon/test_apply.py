"""Write-back: one VPL collection, replaced on re-run; nothing else touched."""

import bpy
import numpy as np
import pytest
from blender_util import cornell, data_snapshot, diff

from addon.native import vplace
from addon.scene.export import VPL_MARKER, export_scene
from addon.writeback import apply


def some_vpls(n, seed=0, profile="cosine"):
    rng = np.random.default_rng(seed)
    normal = rng.normal(size=(n, 3))
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    return vplace.VplSet(
        rng.uniform(-0.9, 0.9, size=(n, 3)).astype(np.float32),
        normal.astype(np.float32),
        rng.uniform(0.0, 0.1, size=(n, 3)).astype(np.float32),
        profile=profile,
    )


@pytest.mark.parametrize("profile", ["cosine", "omni"])
def test_rerun_replaces_only_the_vpl_collection(profile):
    scene = cornell()
    before = data_snapshot()
    n_lights = len(bpy.data.lights)
    apply.write_vpls(scene, some_vpls(10, profile=profile), scene_diagonal=3.4)
    first = sorted((o.name, o.data.name) for o in apply.find_collection().objects)
    apply.write_vpls(scene, some_vpls(7, seed=1, profile=profile), scene_diagonal=3.4)
    # The new lights, written beside the old, take their own names once the old are gone.
    again = sorted((o.name, o.data.name) for o in apply.find_collection().objects)
    assert again == first[:7]
    colls = [c for c in bpy.data.collections if c.get(VPL_MARKER)]
    assert [c.name for c in colls] == [apply.COLLECTION_NAME]
    assert len(colls[0].objects) == 7
    assert len(bpy.data.lights) == n_lights + 7  # no orphaned light data left behind
    assert diff(before, data_snapshot()) == []
    light = colls[0].objects[0]
    want = "AREA" if profile == "cosine" else "POINT"
    assert light.data.type == want and light.data.use_custom_distance
    # The light's emission axis (local -Z) is the VPL normal.
    axis = -np.array(light.matrix_basis.to_3x3().col[2])
    np.testing.assert_allclose(axis, some_vpls(7, seed=1).normal[0], atol=1e-5)
    power = np.array(light.data.color) * light.data.energy
    scale = 1.0 if profile == "cosine" else 2.0
    np.testing.assert_allclose(power, scale * some_vpls(7, seed=1).flux[0], rtol=1e-5)
    assert apply.clear_vpls() == 7
    assert not any(c.get(VPL_MARKER) for c in bpy.data.collections)
    assert len(bpy.data.lights) == n_lights
    assert diff(before, data_snapshot()) == []


def test_a_rerun_leaves_a_users_block_its_name():
    """A name the user's own object or light holds stays theirs through re-runs; every other
    light takes its own name back."""
    scene = cornell()
    mine = bpy.data.objects.new("vplace VPL 0001", bpy.data.lights.new("vplace VPL 0003", "SPOT"))
    scene.collection.objects.link(mine)
    for seed in (0, 1, 2):
        apply.write_vpls(scene, some_vpls(5, seed=seed), scene_diagonal=3.4)
        objects = sorted(o.name for o in apply.find_collection().objects)
        lights = sorted(o.data.name for o in apply.find_collection().objects)
        assert objects[0] == "vplace VPL 0000" and objects[2:] == [
            f"vplace VPL {i:04d}" for i in (2, 3, 4)
        ]
        assert objects[1].startswith("vplace VPL 0001.")
        assert lights[3].startswith("vplace VPL 0003.")
        assert [n for n in lights if "." not in n] == [f"vplace VPL {i:04d}" for i in (0, 1, 2, 4)]
        assert mine.name == "vplace VPL 0001" and mine.data.name == "vplace VPL 0003"


def test_vpls_are_not_exported_as_scene_lights():
    scene = cornell()
    apply.write_vpls(scene, some_vpls(5), scene_diagonal=3.4)
    exported = export_scene(scene)
    assert [light.name for light in exported.lights] == ["light"]


def test_user_collection_with_our_name_is_not_touched():
    scene = cornell()
    user = bpy.data.collections.new(apply.COLLECTION_NAME)
    scene.collection.children.link(user)
    with pytest.raises(apply.WriteBackError, match="was not made by vplace"):
        apply.write_vpls(scene, some_vpls(3), scene_diagonal=3.4)
    assert bpy.data.collections.get(apply.COLLECTION_NAME) is user


def test_bad_vpl_sets_are_refused():
    scene = cornell()
    flux = some_vpls(3).flux
    flux[1, 1] = np.nan
    with pytest.raises(vplace.InputError, match="non-finite"):
        some_vpls(3).with_flux(flux)
    n = apply.MAX_VPLS + 1
    up = np.tile(np.float32([0, 0, 1]), (n, 1))
    too_many = vplace.VplSet(np.zeros((n, 3), np.float32), up, np.zeros((n, 3), np.float32))
    with pytest.raises(apply.WriteBackError, match="more than EEVEE can render"):
        apply.write_vpls(scene, too_many)
    assert bpy.data.collections.get(apply.COLLECTION_NAME) is None


def region_marks() -> apply.RegionMarks:
    pose = vplace.coverage.Pose(
        np.array([0.5, -0.2, 1.0]), np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0])
    )
    other = vplace.coverage.Pose(
        np.array([-0.4, 0.1, 0.8]), np.array([1.0, 1.0, -0.5]), np.array([0.0, 0.0, 1.0])
    )
    return apply.RegionMarks([np.array([0.0, -1.5, 1.0])], [0.9], [pose, other])


def test_the_region_is_drawn_in_its_own_collection_and_rewritten_in_place():
    """``write_region``: a sphere per camera and an arrow per coverage view whose +Z axis
    points where the view looks, in the marked collection ``vplace region``, which a re-run
    refills under the same names (keeping what the user put into it) and None removes; the
    VPL collection is not touched, and a user's collection of that name is refused."""
    scene = cornell()
    apply.write_vpls(scene, some_vpls(4), scene_diagonal=3.4)
    lights = sorted(o.name for o in apply.find_collection().objects)
    marks = region_marks()
    coll = apply.write_region(scene, marks)
    assert coll.name == apply.REGION_NAME and coll.get(VPL_MARKER)
    names = sorted(o.name for o in coll.objects)
    assert names == ["vplace region 1", "vplace region view 1", "vplace region view 2"]
    for obj, pose in zip(
        (coll.objects["vplace region view 1"], coll.objects["vplace region view 2"]),
        marks.poses,
        strict=True,
    ):
        z = obj.matrix_world.to_3x3().col[2]
        forward = pose.basis()[0]
        assert np.allclose(list(z), forward, atol=1e-5)
        assert np.allclose(list(obj.matrix_world.translation), pose.eye, atol=1e-6)
        assert obj.empty_display_size == pytest.approx(apply.REGION_ARROW * 0.9)
    mine = bpy.data.objects.new("my empty", None)
    coll.objects.link(mine)
    again = apply.write_region(scene, marks)
    assert again == coll and sorted(o.name for o in again.objects) == sorted([*names, "my empty"])
    assert len([c for c in bpy.data.collections if c.name.startswith(apply.REGION_NAME)]) == 1
    assert sorted(o.name for o in apply.find_collection().objects) == lights
    assert apply.write_region(scene, None) is None
    assert apply.find_collection(apply.REGION_NAME, scene) is None
    assert "my empty" in scene.collection.objects  # the user's object stays in the scene
    assert sorted(o.name for o in apply.find_collection().objects) == lights
    bpy.data.collections.new(apply.REGION_NAME)
    with pytest.raises(apply.WriteBackError, match="not made by vplace"):
        apply.write_region(scene, marks)


def test_an_animated_jobs_regions_are_drawn_once_each():
    """The frames of a camera that stands still share one sphere and their coverage views."""
    marks = region_marks()
    moved = apply.RegionMarks([np.array([1.0, -1.5, 1.0])], [0.7], marks.poses[:1])
    union = apply.union_of_regions([marks, None, marks, moved])
    assert union is not None and len(union.eyes) == 2 and union.radii == [0.9, 0.7]
    assert len(union.poses) == 2
    assert apply.union_of_regions([None, None]) is None


def test_clear_operator_is_undoable_and_reports():
    """Clear removes the lights and the last run's report of them."""
    import addon

    addon.register()
    try:
        scene = cornell()
        apply.write_vpls(scene, some_vpls(4), scene_diagonal=3.4)
        scene.vplace.last_report = '{"n_vpls": 4}'
        assert "UNDO" in addon.ui.operators.VPLACE_OT_clear_vpls.bl_options
        assert bpy.ops.vplace.clear_vpls() == {"FINISHED"}
        assert bpy.data.collections.get(apply.COLLECTION_NAME) is None
        assert scene.vplace.last_report == ""
    finally:
        addon.unregister()


def test_failure_half_way_keeps_the_previous_vpls(monkeypatch):
    scene = cornell()
    apply.write_vpls(scene, some_vpls(5), scene_diagonal=3.4)
    before = data_snapshot()
    old_names = sorted(o.name for o in apply.find_collection().objects)
    real = apply._new_vpl_object

    def failing(coll, i, *args):
        if i == 3:
            raise RuntimeError("injected failure while writing VPL 3")
        return real(coll, i, *args)

    monkeypatch.setattr(apply, "_new_vpl_object", failing)
    with pytest.raises(RuntimeError, match="injected failure"):
        apply.write_vpls(scene, some_vpls(9, seed=2), scene_diagonal=3.4)
    assert sorted(o.name for o in apply.find_collection().objects) == old_names
    assert [c.name for c in bpy.data.collections if c.get(VPL_MARKER)] == [apply.COLLECTION_NAME]
    assert not [o for o in bpy.data.objects if o.get(VPL_MARKER) and not o.users_collection]
    assert diff(before, data_snapshot()) == []


def test_user_object_put_in_the_vpl_collection_survives_a_rerun():
    """It stays in the collection through a re-run; clearing puts it in the scene's."""
    scene = cornell()
    coll = apply.write_vpls(scene, some_vpls(2), scene_diagonal=3.4)
    mine = bpy.data.objects.new("my empty", None)
    coll.objects.link(mine)
    again = apply.write_vpls(scene, some_vpls(2, seed=5), scene_diagonal=3.4)
    assert again == coll and coll.objects.get("my empty") is mine
    assert apply.clear_vpls() == 2
    assert bpy.data.objects.get("my empty") is mine
    assert scene.collection.objects.get("my empty") is mine


def test_the_unlit_objects_are_excluded_from_the_vpls_light_and_nothing_else():
    """``unlit`` (``native_view.vpl_unlit``): every VPL light's Light Linking receiver
    collection holds those objects excluded; the stand-ins light them still. Re-running
    replaces the receiver collection with the lights, clearing removes it, and the user's
    objects are as they were (in their own collections only)."""
    scene = cornell()
    before = data_snapshot()
    box = bpy.data.objects["tallBox"]
    own = [c.name for c in box.users_collection]
    apply.write_vpls(scene, some_vpls(4), scene_diagonal=3.4, unlit=["tallBox", "no such"])
    coll = apply.write_vpls(scene, some_vpls(3, seed=1), scene_diagonal=3.4, unlit=["tallBox"])
    receivers = [c for c in bpy.data.collections if c.get(VPL_MARKER) and c is not coll]
    assert [c.name for c in receivers] == [apply.COLLECTION_NAME + apply.UNLIT_SUFFIX]
    assert receivers[0] not in scene.collection.children_recursive
    assert list(receivers[0].objects) == [box]
    assert receivers[0].collection_objects[0].light_linking.link_state == "EXCLUDE"
    assert all(o.light_linking.receiver_collection == receivers[0] for o in coll.objects)
    assert apply.unlit_objects(coll) == ["tallBox"]
    apply.write_vpls(scene, some_vpls(3, seed=1), scene_diagonal=3.4)
    assert [c.name for c in bpy.data.collections if c.get(VPL_MARKER)] == [apply.COLLECTION_NAME]
    apply.write_vpls(scene, some_vpls(3, seed=1), scene_diagonal=3.4, unlit=["tallBox"])
    apply.clear_vpls()
    assert not any(c.get(VPL_MARKER) for c in bpy.data.collections)
    assert [c.name for c in box.users_collection] == own
    assert diff(before, data_snapshot()) == []


def _vpl_lights(scene):
    return sorted(o.name for o in scene.objects if o.type == "LIGHT" and o.get(VPL_MARKER))


def test_each_scene_keeps_its_own_lights():
    """Writing or clearing one scene's lights leaves another scene's alone."""
    a = cornell()
    b = bpy.data.scenes.new("B")
    b.collection.objects.link(bpy.data.objects["tallBox"])
    apply.write_vpls(a, some_vpls(3), scene_diagonal=3.4)
    apply.write_vpls(b, some_vpls(4, seed=1), scene_diagonal=3.4)
    assert len(_vpl_lights(a)) == 3 and len(_vpl_lights(b)) == 4
    assert apply.find_collection(scene=a) is not apply.find_collection(scene=b)
    apply.write_vpls(b, some_vpls(2, seed=2), scene_diagonal=3.4)
    assert len(_vpl_lights(a)) == 3 and len(_vpl_lights(b)) == 2
    assert apply.clear_vpls(scene=b) == 2
    assert len(_vpl_lights(a)) == 3 and apply.find_collection(scene=b) is None


def test_a_rerun_keeps_what_the_user_did_with_the_collection():
    """Renamed, moved under another collection, excluded from the view layer, hidden: a re-run
    writes its lights into the same collection, as the user left it."""
    scene = cornell()
    coll = apply.write_vpls(scene, some_vpls(3), scene_diagonal=3.4)
    coll.name = "my lights"
    parent = bpy.data.collections.new("Parent")
    scene.collection.children.link(parent)
    scene.collection.children.unlink(coll)
    parent.children.link(coll)
    coll.hide_render = True
    layer = bpy.context.view_layer.layer_collection.children["Parent"].children["my lights"]
    layer.exclude = True
    again = apply.write_vpls(scene, some_vpls(5, seed=1), scene_diagonal=3.4)
    assert again == coll and coll.name == "my lights" and list(parent.children) == [coll]
    assert coll.hide_render
    assert bpy.context.view_layer.layer_collection.children["Parent"].children[0].exclude
    assert len(coll.objects) == 5 and len(_vpl_lights(scene)) == 5
    assert [c for c in bpy.data.collections if c.get(VPL_MARKER)] == [coll]


def test_lights_left_by_a_deleted_collection_go_with_the_next_run():
    """The Outliner's delete of the collection keeps its objects, in the collection above: the
    next run (or clear) takes them away, so no light shines twice."""
    scene = cornell()
    coll = apply.write_vpls(scene, some_vpls(3), scene_diagonal=3.4)
    for obj in list(coll.objects):
        scene.collection.objects.link(obj)
    bpy.data.collections.remove(coll)
    assert len(_vpl_lights(scene)) == 3
    apply.write_vpls(scene, some_vpls(2, seed=1), scene_diagonal=3.4)
    assert len(_vpl_lights(scene)) == 2
    for obj in list(apply.find_collection().objects):
        scene.collection.objects.link(obj)
    bpy.data.collections.remove(apply.find_collection())
    assert apply.clear_vpls() == 2 and _vpl_lights(scene) == []
