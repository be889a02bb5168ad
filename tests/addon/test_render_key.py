"""The render cache key covers what Blender reads beyond vplace's export (node trees, images,
ray visibility, engine settings), not what vplace's renders set themselves; the cache keeps to
its size limit, least recently used first."""

import os
import time

import bpy
import numpy as np
import pytest
from blender_util import cornell

from addon.capture import passes as capture
from addon.capture import render_key
from addon.compat import eevee_engine
from addon.scene.export import VPL_MARKER


def key(scene):
    cam = scene.camera
    return capture.capture_key(scene, cam, (16, 16), 4, 0)


def _principled(scene):
    mat = next(o.active_material for o in scene.objects if o.type == "MESH" and o.active_material)
    node = next(n for n in mat.node_tree.nodes if n.type in {"BSDF_PRINCIPLED", "BSDF_DIFFUSE"})
    return mat, node


@pytest.mark.parametrize(
    "change",
    [
        "vertex moved",
        "modifier",
        "roughness input",
        "new node linked",
        "ray visibility",
        "max bounces",
        "film transparent",
        "world strength",
        "light spread",
        "light linking",
        "light linking state",
    ],
)
def test_what_the_render_reads_changes_the_key(change):
    scene = cornell()
    before = key(scene)
    mat, node = _principled(scene)
    if change == "vertex moved":
        bpy.data.objects["tallBox"].data.vertices[0].co.z += 0.01
    elif change == "modifier":
        bpy.data.objects["tallBox"].modifiers.new("bevel", "BEVEL")
    elif change == "roughness input":
        node.inputs["Roughness"].default_value = 0.123
    elif change == "new node linked":
        noise = mat.node_tree.nodes.new("ShaderNodeTexNoise")
        mat.node_tree.links.new(noise.outputs["Color"], node.inputs[0])
    elif change == "ray visibility":
        bpy.data.objects["tallBox"].visible_shadow = False
    elif change == "max bounces":
        scene.cycles.max_bounces = 3
    elif change == "film transparent":
        scene.render.film_transparent = True
    elif change == "world strength":
        bg = next(n for n in scene.world.node_tree.nodes if n.type == "BACKGROUND")
        bg.inputs["Strength"].default_value = 2.5
    elif change == "light spread":
        bpy.data.objects["light"].data.spread = 1.0
    elif change.startswith("light linking"):
        receivers = bpy.data.collections.new("receivers")
        receivers.objects.link(bpy.data.objects["tallBox"])
        bpy.data.objects["light"].light_linking.receiver_collection = receivers
        if change == "light linking state":
            before = key(scene)
            receivers.collection_objects[0].light_linking.link_state = "EXCLUDE"
    assert key(scene) != before, change


@pytest.mark.parametrize(
    "change", ["eevee shadow rays", "eevee ray tracing max roughness", "eevee denoise"]
)
def test_what_eevee_reads_changes_its_key(change):
    scene = cornell()
    before = render_key.scene_signature(scene, eevee_engine())
    if change == "eevee shadow rays":
        scene.eevee.shadow_ray_count = 3
    elif change == "eevee ray tracing max roughness":
        scene.eevee.ray_tracing_options.trace_max_roughness = 0.9
    else:
        scene.eevee.ray_tracing_options.use_denoise = False
    assert render_key.scene_signature(scene, eevee_engine()) != before, change


def test_what_vplace_sets_itself_or_only_moves_a_node_keeps_the_key():
    scene = cornell()
    before = key(scene)
    _, node = _principled(scene)
    node.location.x += 300  # how the tree looks, not what it computes
    node.select = not node.select
    scene.cycles.samples = 17  # every capture sets its own samples, seed, size and passes
    scene.cycles.seed = 5
    scene.render.resolution_x = 123
    scene.render.filepath = "/tmp/elsewhere"
    scene.view_settings.view_transform = "AgX"  # measured renders use the Standard view
    scene.view_layers[0].use_pass_mist = True
    scene.render.use_motion_blur = True  # measured renders are sharp (settings.measured_frame)
    assert key(scene) == before


def _light(scene, name, *, marked):
    data = bpy.data.lights.new(name, "AREA")
    obj = bpy.data.objects.new(name, data)
    if marked:
        obj[VPL_MARKER] = True
    scene.collection.objects.link(obj)
    return obj


def _signature(scene):
    return render_key.scene_signature(scene, eevee_engine())


def test_vplaces_objects_key_by_their_names_without_blenders_suffix():
    """The stand-ins "Match EEVEE's direct light" writes for its render take ".001" names
    beside the last run's written lights: a render of the same scene all the same, which the
    second run must find in the cache (a new EEVEE render may differ: README, "The second
    run's EEVEE render of the match"). A user's object keys by its whole name."""
    scene = cornell()
    ours = _light(scene, "vplace emitter 000 (lamp)", marked=True)
    before = _signature(scene)
    ours.name = ours.data.name = "vplace emitter 000 (lamp).001"
    assert ours.name.endswith(".001") and _signature(scene) == before
    ours.location.x += 0.1  # still a render of what it shows
    assert _signature(scene) != before
    ours.location.x -= 0.1
    theirs = _light(scene, "lamp", marked=False)
    mine = _signature(scene)
    theirs.name = "lamp.001"
    assert _signature(scene) != mine


def test_the_key_survives_saving_and_reopening_the_file(tmp_path):
    scene = cornell()
    before = key(scene)
    path = tmp_path / "cornell.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path), copy=True)
    bpy.ops.wm.open_mainfile(filepath=str(path))  # new session ids for every data-block
    assert key(bpy.context.scene) == before


def test_an_image_file_keys_by_its_content_on_disk(tmp_path):
    scene = cornell()
    mat, node = _principled(scene)
    path = tmp_path / "tex.png"
    img = bpy.data.images.new("tex", 4, 4)
    img.filepath_raw = str(path)
    img.file_format = "PNG"
    img.save()
    tex = mat.node_tree.nodes.new("ShaderNodeTexImage")
    tex.image = bpy.data.images.load(str(path))
    mat.node_tree.links.new(tex.outputs["Color"], node.inputs[0])
    before = key(scene)
    assert key(scene) == before
    time.sleep(0.01)
    path.write_bytes(path.read_bytes() + b"\0")  # the file changed on disk
    assert key(scene) != before


def _entry(directory, name, size, age):
    path = directory / name
    path.write_bytes(b"\0" * size)
    stamp = time.time() - age
    os.utime(path, (stamp, stamp))
    return path


def test_prune_removes_the_least_recently_used_entries_first(tmp_path):
    old = _entry(tmp_path, "capture-old.npz", 400, age=300)
    mid = _entry(tmp_path, "capture-mid.npz", 400, age=200)
    new = _entry(tmp_path, "render-new.npz", 400, age=100)
    other = _entry(tmp_path, "notes.txt", 5000, age=500)  # not a cache entry: kept
    render_key.touch(old)  # used just now: the most recent
    assert render_key.prune(tmp_path, limit=900, keep=new) == 1
    assert old.exists() and not mid.exists() and new.exists() and other.exists()
    # The entry just written is never removed, even when it alone is over the limit.
    assert render_key.prune(tmp_path, limit=10, keep=new) == 1
    assert new.exists() and not old.exists()


def test_a_capture_hit_touches_its_file_and_the_cache_keeps_its_limit(tmp_path, monkeypatch):
    scene = cornell()
    capture.capture(scene, resolution=(8, 8), samples=1, cache_dir=tmp_path)
    (first,) = tmp_path.glob("capture-*.npz")
    os.utime(first, (1, 1))
    capture.capture(scene, resolution=(8, 8), samples=1, cache_dir=tmp_path)
    assert first.stat().st_mtime > 1  # a hit counts as a use
    monkeypatch.setattr(render_key, "CACHE_LIMIT_BYTES", first.stat().st_size + 1)
    monkeypatch.setattr(render_key.prune, "__defaults__", (render_key.CACHE_LIMIT_BYTES, None))
    capture.capture(scene, resolution=(8, 8), samples=2, cache_dir=tmp_path)
    assert [p for p in tmp_path.glob("capture-*.npz")] != [first]
    assert len(list(tmp_path.glob("capture-*.npz"))) == 1
    assert np.isfinite(capture.Capture.load(next(tmp_path.glob("capture-*.npz"))).combined).all()


def test_a_job_hashes_each_mesh_once_and_the_key_is_the_same(monkeypatch):
    """Within ``meshes_unchanged`` (a job's captures) each mesh is read once and the key is
    the one computed outside it; a mesh edited after the scope closes changes the next key."""
    scene = cornell()
    outside = key(scene)
    reads = []
    hash_of = render_key._hash_of
    monkeypatch.setattr(
        render_key, "_hash_of", lambda d, *a: reads.append(d.name) or hash_of(d, *a)
    )
    meshes = {o.data.name for o in scene.objects if o.type == "MESH" and not o.hide_render}
    with render_key.meshes_unchanged():
        first = key(scene)
        reads_first = sorted(n for n in reads if n in meshes)
        assert key(scene) == first == outside
    assert reads_first == sorted(meshes)
    assert sorted(n for n in reads if n in meshes) == sorted(meshes)  # the second read none
    bpy.data.objects["tallBox"].data.vertices[0].co.z += 0.01
    with render_key.meshes_unchanged():
        assert key(scene) != outside
