"""The animated write-back (issue 23): one set of lights keyed over the captured frames.

``vplace.temporal.track`` matches each frame's VPLs into slots; each slot becomes one light of
the ``vplace VPLs`` collection, made as the still write-back makes a VPL's light
(``apply._new_vpl_object``: disk, cutoff, shadow settings) and keyed on every captured frame:
``location``, ``rotation_quaternion`` (facing along the VPL's normal), the light's ``energy``
and ``color``; a slot that is dark on a frame is keyed to 0 W there, where it stands. Every key
is linear, so the frames between the captured ones interpolate (``vplace.temporal.at_frame``
computes the same lights for the evaluator). Quaternions keep the sign of the previous frame's,
so their component-wise interpolation turns the short way.

The world's sun (``stand_ins.world_sun``) is one SUN light keyed the same way (rotation,
energy, colour; 0 W on a frame where the sun lights nothing the views see). Lights for emissive
meshes are written as on the first frame, unkeyed. A sky portal (``portals``) found on every
frame in the same opening is one light keyed the same way (rotation: the way the sky's light
enters; energy and colour: what it lets in as the sky changes); else the first frame's are
written unkeyed.

As the still write-back does, the new collection is built unlinked and replaces the old one
only when complete, so nothing else in the file changes.
"""

from __future__ import annotations

from collections.abc import Sequence

import bpy
import numpy as np
from mathutils import Quaternion, Vector

from ..compat import make_keys_linear
from ..errors import WriteBackError
from ..native import vplace
from . import apply
from .stand_ins import EmitterLight, SunLight

#: The custom property on a keyed light: the slot it stands for.
SLOT_PROPERTY = "vplace_slot"


def _quaternions(normals: np.ndarray) -> list[Quaternion]:
    """A light's rotation on each frame (facing along the normal), each of the sign nearest the
    previous frame's."""
    down = Vector((0.0, 0.0, -1.0))
    out: list[Quaternion] = []
    for n in normals:
        q = down.rotation_difference(Vector(n.tolist()))
        if out and out[-1].dot(q) < 0.0:
            q.negate()
        out.append(q)
    return out


def _key_light(
    obj: bpy.types.Object,
    frames: Sequence[int],
    positions: np.ndarray | None,
    quaternions: Sequence[Quaternion],
    energy: np.ndarray,
    color: np.ndarray,
    sizes: np.ndarray | None = None,
) -> None:
    """Keys ``obj`` (and its light) on ``frames``, with ``sizes`` the AREA disk's diameter
    too; every key linear."""
    obj.rotation_mode = "QUATERNION"
    light = obj.data
    for k, frame in enumerate(frames):
        if positions is not None:
            obj.location = tuple(float(c) for c in positions[k])
            obj.keyframe_insert("location", frame=frame)
        obj.rotation_quaternion = quaternions[k]
        obj.keyframe_insert("rotation_quaternion", frame=frame)
        light.energy = float(energy[k])
        light.color = tuple(float(c) for c in color[k])
        light.keyframe_insert("energy", frame=frame)
        light.keyframe_insert("color", frame=frame)
        if sizes is not None:
            light.size = float(sizes[k])
            light.keyframe_insert("size", frame=frame)
    for owner in (obj, light):
        make_keys_linear(owner)
        owner.animation_data.action[apply.VPL_MARKER] = True


def write_keyed(
    scene: bpy.types.Scene,
    frames: Sequence[int],
    keyed: vplace.temporal.Keyed,
    *,
    shadows: bool = True,
    scene_diagonal: float = 10.0,
    specular: float = 0.0,
    emitters: Sequence[EmitterLight] = (),
    suns: Sequence[SunLight | None] = (),
    portals: Sequence[Sequence[EmitterLight]] = (),
    region: apply.Region | None = None,
    closed: bool = False,
    unlit: Sequence[str] = (),
    name: str = apply.COLLECTION_NAME,
) -> bpy.types.Collection:
    """Writes the slots of ``keyed`` (one per light, keyed on ``frames``), the world's sun of
    each frame (``suns``, one per frame, or none), the sky portals of each frame (``portals``,
    one list per frame, or none; a portal in ``emitters`` is left to them) and ``emitters``
    into a fresh VPL collection
    linked to ``scene`` (see the module docs); the :data:`apply.MAX_SHADOWED_VPLS` slots
    brightest on some frame cast shadows; ``unlit`` are the objects they do not light
    (``apply.exclude_receivers``); ``region`` is kept on the collection (``apply.REGION_KEY``),
    and ``closed`` (``apply.CLOSED_KEY``). The scene's current frame is kept."""
    slots = keyed.position.shape[1]
    if len(frames) != keyed.position.shape[0]:
        raise WriteBackError(f"{len(frames)} frames for {keyed.position.shape[0]} keyed frames")
    if slots > apply.MAX_VPLS:
        raise WriteBackError(
            f"{slots} keyed lights is more than EEVEE can render ({apply.MAX_VPLS}); lower the "
            "VPL budget or animate fewer frames"
        )
    apply.find_collection(
        name, scene
    )  # refuses a foreign collection of that name before any change
    point = 0.5 * apply.POINT_DISK_DIAGONALS * scene_diagonal
    radii = keyed.radii if keyed.radius > 0 else np.full(keyed.radii.shape, point)
    cosine = keyed.profile == "cosine"
    lum = keyed.power @ np.asarray(vplace.LUMINANCE, dtype=np.float64)  # (F, S)
    brightest = lum.max(axis=0, initial=0.0)
    stand_ins = len(emitters) + max(map(len, portals), default=0)
    cap = apply.shadow_cap(scene, keyed.profile, stand_ins, any(s is not None for s in suns))
    shadowed = set(np.argsort(-brightest, kind="stable")[:cap].tolist())
    energy, color = keyed.energy, keyed.color
    current = scene.frame_current
    coll = apply.new_collection(name, region, closed)
    try:
        for s in range(slots):
            if brightest[s] <= 0.0:
                continue
            first = int(np.argmax(keyed.lit[:, s]))
            obj = apply._new_vpl_object(
                coll,
                s,
                keyed.position[first, s],
                keyed.normal[first, s],
                keyed.flux[first, s],
                np.maximum(keyed.power[first, s], 1e-30),
                keyed.profile,
                float(radii[first, s]),
                apply.CUTOFF_DIAGONALS * scene_diagonal,
                shadows and s in shadowed,
                apply.SHADOW_TEXEL_DIAGONALS * scene_diagonal,
                specular,
            )
            obj[SLOT_PROPERTY] = s
            obj.name = obj.data.name = slot_name(s)
            _key_light(
                obj,
                frames,
                keyed.position[:, s],
                _quaternions(keyed.normal[:, s]),
                energy[:, s],
                color[:, s],
                2.0 * radii[:, s] if cosine else None,
            )
        cutoff = apply.CUTOFF_DIAGONALS * scene_diagonal
        for j, e in enumerate(e for e in emitters if not (portals and e.portal)):
            apply._new_emitter_object(coll, j, e, cutoff, shadows)
        if portals:
            _write_keyed_portals(coll, frames, portals, cutoff, shadows)
        lit_suns = [s for s in suns if s is not None]
        if lit_suns:
            write_keyed_sun(coll, frames, suns, lit_suns[0])
        apply.exclude_receivers(coll, unlit)
    except BaseException:
        apply.remove_collection(coll)
        raise
    finally:
        if scene.frame_current != current:
            scene.frame_set(current)
    coll = apply.replace_collection(scene, coll, name)
    for obj in coll.objects:  # the old lights are gone: their names are free again
        if obj.get(SLOT_PROPERTY) is not None:
            obj.name = obj.data.name = slot_name(obj[SLOT_PROPERTY])
    return coll


def slot_name(slot: int) -> str:
    """The name of a keyed light (object and light data)."""
    return f"vplace VPL slot {slot:04d}"


#: A portal is the same opening on two frames when its centre moved less than this share of its
#: size.
PORTAL_MOVE = 0.05


def _write_keyed_portals(
    coll: bpy.types.Collection,
    frames: Sequence[int],
    portals: Sequence[Sequence[EmitterLight]],
    cutoff: float,
    shadows: bool,
) -> None:
    """The sky portals of each frame: keyed where every frame has the same openings, else the
    first frame's, unkeyed (module docs)."""
    first = list(portals[0])

    def same(a: EmitterLight, b: EmitterLight) -> bool:
        gap = np.linalg.norm(np.subtract(a.position, b.position))
        return bool(gap <= PORTAL_MOVE * max(a.size, a.size_y))

    keyed = all(
        len(p) == len(first) and all(same(a, b) for a, b in zip(first, p, strict=True))
        for p in portals
    )
    for j, e in enumerate(first):
        obj = apply._new_emitter_object(coll, j, e, cutoff, shadows)
        if not keyed or len(portals) < 2:
            continue
        quats: list[Quaternion] = []
        for p in portals:
            q = apply.emitter_rotation(p[j].normal, e.tangent)
            if quats and quats[-1].dot(q) < 0.0:
                q.negate()
            quats.append(q)
        power = np.array([p[j].power for p in portals], dtype=np.float64)
        energy = power.max(axis=1)
        color = power / np.maximum(energy, 1e-30)[:, None]
        _key_light(obj, frames, None, quats, energy, color)


def write_keyed_sun(
    coll: bpy.types.Collection,
    frames: Sequence[int],
    suns: Sequence[SunLight | None],
    first: SunLight,
) -> None:
    """The world's sun as one SUN light keyed over ``frames`` (0 W where ``suns`` has none)."""
    obj = apply.new_sun_object(coll, first)
    up = Vector((0.0, 0.0, 1.0))
    quats: list[Quaternion] = []
    energy = np.zeros(len(frames))
    color = np.ones((len(frames), 3))
    last = first
    for k, sun in enumerate(suns):
        held = sun if sun is not None else last
        q = up.rotation_difference(Vector(held.direction))
        if quats and quats[-1].dot(q) < 0.0:
            q.negate()
        quats.append(q)
        irradiance = np.asarray(held.irradiance, dtype=np.float64)
        color[k] = irradiance / max(float(irradiance.max()), 1e-30)
        if sun is not None:
            energy[k] = float(irradiance.max())
            last = sun
    _key_light(obj, frames, None, quats, energy, color)
