"""What a render depends on, as a hash, and the render cache's size limit.

A cached capture (``capture.py``) or EEVEE render (``eevee.py``) is reused only when nothing
that changes its pixels has changed: :func:`scene_signature` hashes what Blender reads to render
the scene, independent of what vplace exports, at the current frame:

- each rendered object's data: a mesh's vertex positions, faces and material slots, other
  data's settings, and the object's modifiers with their settings;
- every material of the rendered objects and the world: their whole node trees (every node's
  type and settings, every input's value, every link, node groups followed), and each image they
  use: its file path with the file's size and modification time, or a packed image's size, or a
  generated image's parameters, its colour space and alpha mode, and for an image edited in
  memory and not saved, its pixels;
- each rendered object's name, world matrix and ray visibility (camera, diffuse, glossy,
  transmission, volume, shadow), holdout and shadow-catcher flags; vplace's own objects (lights
  and stand-ins it writes) by their names without Blender's ".001" suffix, which says only that
  an older object of the name was there when they were written: the stand-ins that "Match
  EEVEE's direct light" writes for its render took one beside the last run's written lights,
  so the second run of a file missed the first's render and rendered again;
- every light's settings (all of its plain properties);
- the render settings (``scene.render``: film, motion blur...) and the engine's
  (``scene.cycles`` and the view layer's Cycles settings, or ``scene.eevee``); not what
  vplace's renders set themselves (size, samples, seed, passes, colour management).

Everything is read at the current frame, so animated transforms and animated node values key
each frame; the frame number itself does not (two frames that render the same image share it).

Left out: mesh deformation (armatures, shape keys) that the exported geometry, evaluated at the
frame the export ran, does not show at another frame; a texture file rewritten with the same
size and modification time.

:func:`prune` keeps a cache directory under :data:`CACHE_LIMIT_BYTES`, removing the least
recently used entries first (a cache hit touches its file).
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from pathlib import Path
from typing import Any

import bpy
import numpy as np

from ..scene.export import base_name, is_vplace

#: The most bytes a render cache directory keeps (captures and EEVEE renders together).
CACHE_LIMIT_BYTES = 4 << 30

#: Node properties that change how a node tree looks, not what it computes.
_UI_PROPERTIES = frozenset(
    {
        "location",
        "location_absolute",
        "width",
        "height",
        "dimensions",
        "select",
        "show_options",
        "show_preview",
        "show_texture",
        "hide",
        "color",
        "color_tag",
        "use_custom_color",
        "label",
        "bl_description",
        "bl_icon",
        "bl_label",
        "bl_width_default",
        "bl_width_min",
        "bl_width_max",
        "bl_height_default",
        "bl_height_min",
        "bl_height_max",
        "warning_propagation",
    }
)
_SIMPLE = frozenset({"BOOLEAN", "INT", "FLOAT", "ENUM", "STRING"})
#: Properties Blender 5 keeps only for old scripts (always true; reading them warns).
_DEPRECATED = frozenset({"use_nodes"})
#: What every data-block has (name, user count, session id, tags): bookkeeping, not content.
#: ``session_uid`` changes each time a file is opened, so it must never reach a key.
_ID_PROPERTIES = frozenset(p.identifier for p in bpy.types.ID.bl_rna.properties)


def plain_values(struct: Any, skip: Iterable[str] = ()) -> list[tuple[str, Any]]:
    """``(identifier, value)`` of every plain property of an RNA struct (numbers, flags,
    enums, strings; arrays as tuples), in RNA order."""
    skipped = {*skip, *_DEPRECATED}
    if isinstance(struct, bpy.types.ID):
        skipped |= _ID_PROPERTIES
    out: list[tuple[str, Any]] = []
    for prop in struct.bl_rna.properties:
        key = prop.identifier
        if key in skipped or key == "rna_type" or prop.type not in _SIMPLE:
            continue
        try:
            value = getattr(struct, key)
        except (AttributeError, RuntimeError):
            continue
        if prop.type in {"INT", "FLOAT", "BOOLEAN"} and getattr(prop, "is_array", False):
            value = tuple(np.asarray(value, dtype=np.float64).ravel().tolist())
        elif isinstance(value, set):
            value = tuple(sorted(value))
        out.append((key, value))
    return out


def image_signature(image: bpy.types.Image) -> tuple[Any, ...]:
    """What an image's pixels depend on (see the module docs)."""
    base: tuple[Any, ...] = (
        image.name,
        image.source,
        image.colorspace_settings.name,
        image.alpha_mode,
    )
    if image.packed_file is not None:
        base += ("packed", image.packed_file.size)
    elif image.source == "GENERATED":
        base += (
            "generated",
            image.generated_type,
            tuple(image.generated_color),
            image.generated_width,
            image.generated_height,
        )
    else:
        path = bpy.path.abspath(image.filepath)
        try:
            st = os.stat(path)
            base += ("file", path, st.st_size, st.st_mtime_ns)
        except OSError:
            base += ("missing", path)
    if image.is_dirty and image.has_data:
        pixels = np.empty(len(image.pixels), dtype=np.float32)
        image.pixels.foreach_get(pixels)
        base += ("edited", hashlib.sha256(pixels.tobytes()).hexdigest())
    return base


def _socket_value(socket: Any) -> Any:
    value = getattr(socket, "default_value", None)
    if value is None or isinstance(value, (int, float, bool, str)):
        return value
    if isinstance(value, bpy.types.ID):
        return ("ID", value.name_full)
    try:
        return tuple(np.asarray(value, dtype=np.float64).ravel().tolist())
    except (TypeError, ValueError):
        return repr(value)


def tree_signature(tree: bpy.types.NodeTree | None, seen: set[str] | None = None) -> list[Any]:
    """Every node (type, settings, input values, image), every link, and the node groups it
    uses (each group written out once per ``seen``)."""
    if tree is None:
        return []
    seen = set() if seen is None else seen
    if not tree.is_embedded_data:  # a node group: written out once, then named
        if tree.name_full in seen:
            return [("group", tree.name_full)]
        seen.add(tree.name_full)
    out: list[Any] = [("tree", tree.name_full)]
    for node in sorted(tree.nodes, key=lambda n: n.name):
        item: list[Any] = [node.bl_idname, node.name, plain_values(node, _UI_PROPERTIES)]
        item += [(s.identifier, _socket_value(s)) for s in node.inputs if s.enabled]
        image = getattr(node, "image", None)
        if isinstance(image, bpy.types.Image):
            item.append(image_signature(image))
        group = getattr(node, "node_tree", None)
        if isinstance(group, bpy.types.NodeTree):
            item.append(tree_signature(group, seen))
        out.append(item)
    out += [
        (
            link.from_node.name,
            link.from_socket.identifier,
            link.to_node.name,
            link.to_socket.identifier,
            link.is_muted,
        )
        for link in tree.links
    ]
    return out


#: Settings that every vplace render sets itself (capture and EEVEE renders): they do not
#: key the cache. ``preview_*`` (viewport) settings are left out too.
_OVERRIDDEN = {
    "render": frozenset(
        {
            "engine",
            "resolution_x",
            "resolution_y",
            "resolution_percentage",
            "filepath",
            "use_border",
            "use_crop_to_border",
            "use_single_layer",
            "use_compositing",
            "use_sequencer",
            "use_lock_interface",
            "pixel_aspect_x",
            "pixel_aspect_y",
            "use_multiview",
            "use_motion_blur",
            "use_persistent_data",
            "file_extension",  # the output format's, which vplace's renders set
        }
    ),
    "cycles": frozenset(
        {
            "device",
            "samples",
            "seed",
            "use_adaptive_sampling",
            "use_denoising",
            "denoiser",
            "use_animated_seed",
            "pixel_filter_type",
            "filter_width",
        }
    ),
    "eevee": frozenset({"taa_render_samples", "use_raytracing", "use_fast_gi"}),
}


def _settings(struct: Any, overridden: frozenset[str]) -> list[tuple[str, Any]]:
    return [
        (k, v)
        for k, v in plain_values(struct, overridden)
        if not k.startswith(("preview_", "use_pass_"))
    ]


#: Mesh hashes kept while :func:`meshes_unchanged` is open (None outside it).
_MESH_MEMO: ContextVar[dict[tuple[object, ...], str] | None] = ContextVar(
    "vplace_mesh_memo", default=None
)


@contextmanager
def meshes_unchanged() -> Iterator[None]:
    """Within it, each mesh's hash is computed once and reused by every later
    :func:`scene_signature`: for a run of renders of one scene that edits no mesh between
    them (a job's captures; on Sponza the meshes' hash took 32 of a key's 45 ms). A mesh's
    hash reads its own vertices, not the frame's deformation, so it holds across frames."""
    token = _MESH_MEMO.set({})
    try:
        yield
    finally:
        _MESH_MEMO.reset(token)


def _data_hash(data: bpy.types.ID, name: str | None = None) -> str:
    """:func:`data_signature`'s hash of the data itself, by ``name`` (default its own); a
    mesh's is computed once within :func:`meshes_unchanged`."""
    if not isinstance(data, bpy.types.Mesh):
        return _hash_of(data, (), name)
    sizes = (len(data.vertices), len(data.loops), len(data.polygons))
    memo = _MESH_MEMO.get()
    if memo is None:
        return _hash_of(data, sizes, name)
    key = (data.session_uid, data.name_full, name, *sizes)
    if key not in memo:
        memo[key] = _hash_of(data, sizes, name)
    return memo[key]


def _hash_of(data: bpy.types.ID, sizes: tuple[int, ...], name: str | None = None) -> str:
    """The hash of :func:`_data_hash` (``sizes``: a mesh's vertex, loop and face counts)."""
    name = data.name_full if name is None else name
    h = hashlib.sha256(repr((type(data).__name__, name)).encode())
    if isinstance(data, bpy.types.Mesh):
        co = np.empty(3 * sizes[0], dtype=np.float32)
        data.vertices.foreach_get("co", co)
        loops = np.empty(sizes[1], dtype=np.int32)
        data.loops.foreach_get("vertex_index", loops)
        faces = np.empty(sizes[2], dtype=np.int32)
        data.polygons.foreach_get("loop_total", faces)
        for arr in (co, loops, faces):
            h.update(arr.tobytes())
        h.update(repr([m.name_full if m else None for m in data.materials]).encode())
    elif not isinstance(data, (bpy.types.Light, bpy.types.Camera)):
        h.update(repr(plain_values(data)).encode())
    return h.hexdigest()


def data_signature(obj: bpy.types.Object, done: dict[str, str], ours: bool = False) -> str:
    """A hash of an object's data as the render evaluates it: a mesh's vertex positions and
    faces, other data's plain settings, and the object's modifiers (``done`` memoizes data
    shared by several objects); ``ours``: vplace wrote ``obj``, whose data is named without
    Blender's suffix (module docs)."""
    data = obj.data
    if data is None:
        return ""
    name = data.name_full
    if name not in done:
        done[name] = _data_hash(data, base_name(name) if ours else None)
    return done[name] + _modifiers(obj)


def _modifiers(obj: bpy.types.Object) -> str:
    """An object's modifiers with their settings, as :func:`data_signature` hashes them."""
    return repr([(m.type, m.show_render, plain_values(m)) for m in getattr(obj, "modifiers", ())])


def _material_signature(mat: bpy.types.Material | None, seen: set[str]) -> list[Any]:
    if mat is None:
        return [None]
    return [mat.name_full, plain_values(mat), tree_signature(mat.node_tree, seen)]


_RAY_VISIBILITY = (
    "visible_camera",
    "visible_diffuse",
    "visible_glossy",
    "visible_transmission",
    "visible_volume_scatter",
    "visible_shadow",
    "is_holdout",
    "is_shadow_catcher",
)


def _linking_signature(obj: bpy.types.Object) -> list[object]:
    """An object's Light Linking (Blender 4.0 on): the objects and collections its receiver and
    blocker collections hold, each with its link state."""
    linking = getattr(obj, "light_linking", None)
    out: list[object] = []
    for attr in ("receiver_collection", "blocker_collection"):
        coll = getattr(linking, attr, None) if linking is not None else None
        if coll is None:
            out.append(None)
            continue
        pairs = [
            *zip(coll.objects, coll.collection_objects, strict=True),
            *zip(coll.children, coll.collection_children, strict=True),
        ]
        entries = [(member.name_full, e.light_linking.link_state) for member, e in pairs]
        out.append((coll.name_full, sorted(entries)))
    return out


def scene_signature(
    scene: bpy.types.Scene,
    engine: str,
    *,
    skip: Iterable[bpy.types.Object] = (),
    view_layer: bpy.types.ViewLayer | None = None,
) -> str:
    """A hash of what Blender reads to render ``scene`` with ``engine`` (``"CYCLES"`` or
    ``"BLENDER_EEVEE"``) beyond vplace's export, at the current frame (see the module docs);
    ``skip``: objects the render hides (vplace's lights in a capture). The settings vplace's
    renders set themselves (size, samples, seed, passes, colour management) are left out."""
    h = hashlib.sha256()
    seen: set[str] = set()
    hidden = {o.name_full for o in skip}
    materials: dict[str, bpy.types.Material] = {}
    done: dict[str, str] = {}
    depsgraph = bpy.context.evaluated_depsgraph_get()  # matrices after the latest edits
    shown = []  # (the name hashed, vplace's, the object)
    for o in scene.objects:
        if not (o.hide_render or o.name_full in hidden):
            ours = is_vplace(o)  # named without Blender's suffix (module docs)
            shown.append((base_name(o.name_full) if ours else o.name_full, ours, o))
    for name, ours, obj in sorted(shown, key=lambda p: (p[0], p[2].name_full)):
        matrix = obj.evaluated_get(depsgraph).matrix_world
        h.update(repr((name, obj.type, [list(r) for r in matrix])).encode())
        h.update(data_signature(obj, done, ours).encode())
        h.update(repr([getattr(obj, k, None) for k in _RAY_VISIBILITY]).encode())
        linking = _linking_signature(obj)
        if any(linking):  # (objects without keep the keys they had before it was hashed)
            h.update(repr(linking).encode())
        for slot in getattr(obj, "material_slots", ()):
            if slot.material is not None:
                materials[slot.material.name_full] = slot.material
        if obj.type == "LIGHT":
            h.update(repr(plain_values(obj.data)).encode())
            h.update(repr(tree_signature(obj.data.node_tree, seen)).encode())
        elif obj.type == "LIGHT_PROBE":
            h.update(repr(plain_values(obj.data)).encode())
    for name in sorted(materials):
        h.update(repr(_material_signature(materials[name], seen)).encode())
    world = scene.world
    if world is not None:
        h.update(repr(plain_values(world)).encode())
        h.update(repr(tree_signature(world.node_tree, seen)).encode())
    h.update(repr(_settings(scene.render, _OVERRIDDEN["render"])).encode())
    layer = view_layer or scene.view_layers[0]
    h.update(repr(_settings(layer, frozenset())).encode())
    if engine == "CYCLES":
        h.update(repr(_settings(scene.cycles, _OVERRIDDEN["cycles"])).encode())
        h.update(repr(_settings(layer.cycles, frozenset())).encode())
    else:
        h.update(repr(_settings(scene.eevee, _OVERRIDDEN["eevee"])).encode())
        # A nested struct of its own: the ray tracing's maximum roughness, denoising, ...
        h.update(repr(_settings(scene.eevee.ray_tracing_options, frozenset())).encode())
    h.update(engine.encode())
    return h.hexdigest()


def touch(path: Path) -> None:
    """Marks a cache entry as just used (for :func:`prune`)."""
    try:
        os.utime(path)
    except OSError:
        pass


def prune(cache_dir: Path, limit: int = CACHE_LIMIT_BYTES, keep: Path | None = None) -> int:
    """Removes the least recently used ``.npz`` entries of ``cache_dir`` until the rest fit in
    ``limit`` bytes (never ``keep``, the entry just written); returns how many were removed."""
    try:
        entries = [(p.stat(), p) for p in Path(cache_dir).glob("*.npz")]
    except OSError:
        return 0
    total = sum(st.st_size for st, _ in entries)
    removed = 0
    for st, path in sorted(entries, key=lambda e: e[0].st_mtime_ns):
        if total <= limit:
            break
        if keep is not None and path == keep:
            continue
        try:
            path.unlink()
        except OSError:
            continue
        total -= st.st_size
        removed += 1
    return removed
