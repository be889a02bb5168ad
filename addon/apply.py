"""Write-back: one Blender light per VPL in the ``vplace VPLs`` collection (DESIGN: Write-back).

Re-running replaces that collection and the lights in it, and nothing else. The cosine profile
becomes an AREA disk facing along the surface normal with power ``Phi``; the omni profile a
POINT light (radius 0) with power ``2 Phi``. EEVEE culls lights whose intensity falls below
``scene.eevee.light_threshold``; rather than change that scene setting, each VPL light gets a
custom cutoff distance of twice the scene's diagonal, so EEVEE never culls it inside the scene.
"""

from __future__ import annotations

from dataclasses import dataclass

import bpy
import numpy as np
from mathutils import Vector

from .export import VPL_MARKER

COLLECTION_NAME = "vplace VPLs"
#: EEVEE renders 8,192 lights; beyond 65,536 it drops them (DESIGN). We refuse more than this.
MAX_VPLS = 8192


class WriteBackError(ValueError):
    """The VPLs cannot be written; the message says why."""


@dataclass
class VplSet:
    """VPLs as arrays: positions (N, 3), unit normals (N, 3), reflected flux (N, 3) watts."""

    position: np.ndarray
    normal: np.ndarray
    flux: np.ndarray

    def __len__(self) -> int:
        return int(self.position.shape[0])


def find_collection(name: str = COLLECTION_NAME) -> bpy.types.Collection | None:
    """The VPL collection vplace wrote earlier, if any."""
    coll = bpy.data.collections.get(name)
    if coll is None:
        return None
    if not coll.get(VPL_MARKER, False):
        raise WriteBackError(
            f"a collection named {name!r} exists but was not made by vplace; "
            "rename it so vplace can write its own"
        )
    return coll


def clear_vpls(name: str = COLLECTION_NAME) -> int:
    """Removes the VPL collection, its objects and their light data. Returns how many."""
    coll = find_collection(name)
    if coll is None:
        return 0
    return _remove_collection(coll)


def _remove_collection(coll: bpy.types.Collection) -> int:
    """Removes a vplace collection with the objects and lights vplace made in it."""
    count = 0
    for obj in list(coll.objects):
        if not obj.get(VPL_MARKER, False):
            # Something the user put into our collection: keep it, in the scene's collection
            # if ours was its only one (an object in no collection would be lost on save).
            if len(obj.users_collection) == 1:
                bpy.context.scene.collection.objects.link(obj)
            coll.objects.unlink(obj)
            continue
        data = obj.data
        bpy.data.objects.remove(obj)
        if data is not None and data.users == 0:
            bpy.data.lights.remove(data)
        count += 1
    bpy.data.collections.remove(coll)
    return count


_DOWN = Vector((0.0, 0.0, -1.0))


def _new_vpl_object(
    coll: bpy.types.Collection,
    i: int,
    vpls: VplSet,
    power: np.ndarray,
    profile: str,
    size: float,
    cutoff: float,
    shadows: bool,
) -> bpy.types.Object:
    """Light ``i`` of ``vpls`` as a new light object in ``coll``."""
    energy = float(power.max())
    light = bpy.data.lights.new(f"vplace VPL {i:04d}", "AREA" if profile == "cosine" else "POINT")
    light.energy = energy
    light.color = tuple(float(c) / energy for c in power) if energy > 0 else (1.0, 1.0, 1.0)
    light.use_custom_distance = True
    light.cutoff_distance = cutoff
    light.use_shadow = shadows
    if profile == "cosine":
        light.shape = "DISK"
        light.size = size
    else:
        light.shadow_soft_size = 0.0
        light.use_soft_falloff = False
    obj = bpy.data.objects.new(light.name, light)
    obj.location = tuple(float(c) for c in vpls.position[i])
    obj.rotation_mode = "QUATERNION"
    obj.rotation_quaternion = _DOWN.rotation_difference(Vector(vpls.normal[i].tolist()))
    obj[VPL_MARKER] = True
    obj["vplace_index"] = i
    obj["vplace_flux"] = [float(c) for c in vpls.flux[i]]
    coll.objects.link(obj)
    return obj


def write_vpls(
    scene: bpy.types.Scene,
    vpls: VplSet,
    *,
    profile: str = "cosine",
    disk_size: float | None = None,
    shadows: bool = True,
    scene_diagonal: float = 10.0,
    name: str = COLLECTION_NAME,
) -> bpy.types.Collection:
    """Writes ``vpls`` as lights in a fresh VPL collection linked to ``scene``.

    ``disk_size`` is the AREA disk diameter (default: 0.2% of ``scene_diagonal``).
    """
    n = len(vpls)
    if profile not in {"cosine", "omni"}:
        raise WriteBackError(f"profile must be 'cosine' or 'omni', got {profile!r}")
    if n > MAX_VPLS:
        raise WriteBackError(
            f"{n} VPLs is more than EEVEE can render ({MAX_VPLS}); lower the VPL budget"
        )
    for what, arr in (("position", vpls.position), ("normal", vpls.normal), ("flux", vpls.flux)):
        if arr.shape != (n, 3) or not np.isfinite(arr).all():
            raise WriteBackError(f"VPL {what} must be a finite (N, 3) array")
    find_collection(name)  # refuses a foreign collection of that name before any change
    size = disk_size if disk_size is not None else 2e-3 * scene_diagonal
    power = vpls.flux * (2.0 if profile == "omni" else 1.0)
    # Build the new collection unlinked; only a complete one replaces the old one.
    coll = bpy.data.collections.new(name + " (writing)")
    coll[VPL_MARKER] = True
    try:
        for i in range(n):
            _new_vpl_object(coll, i, vpls, power[i], profile, size, 2.0 * scene_diagonal, shadows)
    except BaseException:
        _remove_collection(coll)
        raise
    clear_vpls(name)
    coll.name = name
    scene.collection.children.link(coll)
    return coll
