"""Write-back: one Blender light per VPL in the ``vplace VPLs`` collection (DESIGN: Write-back).

Re-running replaces that collection and the lights in it, and nothing else. The cosine profile
becomes an AREA disk facing along the surface normal with power ``Phi``; the omni profile a
POINT light (radius 0) with power ``2 Phi``. EEVEE culls lights whose intensity falls below
``scene.eevee.light_threshold``; rather than change that scene setting, each VPL light gets a
custom cutoff distance of twice the scene's diagonal, so EEVEE never culls it inside the scene.
"""

from __future__ import annotations

import bpy
import numpy as np
from mathutils import Vector

from .errors import WriteBackError
from .export import VPL_MARKER
from .native import vplace

COLLECTION_NAME = "vplace VPLs"
#: EEVEE renders 8,192 lights; beyond 65,536 it drops them (DESIGN). We refuse more than this.
MAX_VPLS = 8192


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
    position: np.ndarray,
    normal: np.ndarray,
    flux: np.ndarray,
    power: np.ndarray,
    profile: str,
    size: float,
    cutoff: float,
    shadows: bool,
) -> bpy.types.Object:
    """VPL ``i`` as a new light object in ``coll``."""
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
    obj.location = tuple(float(c) for c in position)
    obj.rotation_mode = "QUATERNION"
    obj.rotation_quaternion = _DOWN.rotation_difference(Vector(normal.tolist()))
    obj[VPL_MARKER] = True
    obj["vplace_index"] = i
    obj["vplace_flux"] = [float(c) for c in flux]
    coll.objects.link(obj)
    return obj


def write_vpls(
    scene: bpy.types.Scene,
    vpls: vplace.VplSet,
    *,
    disk_size: float | None = None,
    shadows: bool = True,
    scene_diagonal: float = 10.0,
    name: str = COLLECTION_NAME,
) -> bpy.types.Collection:
    """Writes ``vpls`` as lights (by their profile) in a fresh VPL collection linked to ``scene``.

    ``disk_size`` is the AREA disk diameter (default: 0.2% of ``scene_diagonal``).
    """
    n = len(vpls)
    if n > MAX_VPLS:
        raise WriteBackError(
            f"{n} VPLs is more than EEVEE can render ({MAX_VPLS}); lower the VPL budget"
        )
    find_collection(name)  # refuses a foreign collection of that name before any change
    size = disk_size if disk_size is not None else 2e-3 * scene_diagonal
    position, normal, flux = vpls.position, vpls.normal, vpls.flux
    power = vpls.blender_power
    # Build the new collection unlinked; only a complete one replaces the old one.
    coll = bpy.data.collections.new(name + " (writing)")
    coll[VPL_MARKER] = True
    try:
        for i in range(n):
            _new_vpl_object(
                coll,
                i,
                position[i],
                normal[i],
                flux[i],
                power[i],
                vpls.profile,
                size,
                2.0 * scene_diagonal,
                shadows,
            )
    except BaseException:
        _remove_collection(coll)
        raise
    clear_vpls(name)
    coll.name = name
    scene.collection.children.link(coll)
    return coll
