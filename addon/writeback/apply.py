"""Write-back: one Blender light per VPL in the ``vplace VPLs`` collection (DESIGN: Write-back).

Each scene of a file has its own VPL collection: the collection vplace marked in that scene's
hierarchy, found by its mark and role (:data:`ROLE_KEY`), not by its name, so a user may rename
it, move it under another collection, exclude it from the view layer or hide it. Re-running
replaces the lights in it (the collection, with the user's settings and objects, stays), and
nothing else: not another scene's lights. Lights of vplace's left in the scene outside it (its
collection deleted in the Outliner, which keeps the objects) go with the next run or clear.

The lights are the ones the evaluator renders (``vplace.VplSet`` carries profile and near-field
radius):

- cosine profile: an AREA disk of diameter ``2 R_j`` (``R_j`` the VPL's near-field radius,
  ``VplSet.radii``: two patches of the size it stands for) facing along the surface normal,
  power ``Phi``: Blender's disk is exactly the near-field kernel of ``vplace_core::shading``, so
  EEVEE and Cycles show no hot spot the evaluator did not compute.
  Omni profile: a POINT light of radius 0, power ``2 Phi``, a point on both sides (its near
  field is singular in Blender and in the evaluator alike; see ``shading.rs``).
- ``diffuse_factor`` 1, ``transmission_factor`` and ``volume_factor`` 0. ``specular_factor``
  (``Prepared.vpl_specular``, ``capture.native_view.vpl_specular``) is 1 when the scene has
  rough glossy layers (``export.ROUGH_GLOSS``: the evaluator counts the VPLs' light on them,
  and so must EEVEE) and the captures see at least as much glossy light on them as on the
  sharp ones, else 0: a VPL's disk shows as a mirrored spot on sharp glossy surfaces, whose
  reflections EEVEE's ray tracing makes.
- EEVEE culls a light whose intensity falls below ``scene.eevee.light_threshold`` and, with a
  custom distance, fades it as ``(1 - (d / cutoff)^4)^2`` (``light_influence_attenuation`` in
  EEVEE's source). Each VPL light gets a custom cutoff of :data:`CUTOFF_DIAGONALS` scene
  diagonals (the working scale, ``vplace.Scene.scale``: the bounds' diagonal, or twice the
  region the cameras see where that is less): no two points of the region are farther apart
  than one diagonal, where the fade then loses 0.32 % (two diagonals lost 12 %). The scene's
  own threshold is left alone.
- Shadows: EEVEE keeps every shadowed light's shadow map in a pool of pages (256 x 256 each,
  4 per MB of ``scene.eevee.shadow_pool_size``, at most 4,096). A light the pool cannot hold
  loses its shadow silently and leaks through walls (Sponza, 256 VPLs, Blender's defaults:
  6,405 pages wanted, 2,048 held, the image 1.4x too bright). So every VPL light's
  ``shadow_maximum_resolution`` is :data:`SHADOW_TEXEL_DIAGONALS` of the scene diagonal: no
  finer than the coarsest level EEVEE makes (one page per cube face: about
  :data:`SHADOW_PAGES` pages per light; on Sponza 0.2 m and 2 m gave the same image), and the
  jitter is off (the evaluator's shadow ray leaves the light's centre; jitter re-renders the
  maps at every sample). Only the :data:`MAX_SHADOWED_VPLS` brightest VPLs are shadowed, fewer
  where their pages and the other lights' would fill more than :data:`POOL_SHARE` of the
  largest pool (:func:`shadowed_vpls`: 736 AREA or 613 POINT lights beside one AREA lamp).
- Emissive meshes: EEVEE does not light with them, so the lights of
  :mod:`.emitter_lights` (one AREA light per open side of each emissive polygon) are written
  into the same collection, shadowed with jittered soft shadows
  (:data:`STAND_IN_SHADOW_SETTINGS`), specular 1, custom cutoff as the VPLs.
- Sky portals (``portals``): one AREA rectangle in each opening through which the sky reaches
  the cameras' region, written as the emitters are (shadows unjittered,
  :data:`PORTAL_SHADOW_SETTINGS`) and marked ``vplace_portal``; EEVEE must then light with the
  world no more (``eevee_setup.camera_only``).
- The world's sun (a compact lobe of a world image far brighter than the rest of the sky,
  ``emitter_lights.world_sun``): EEVEE lights a room through its windows with the world's
  probes only, without the sun's patches (the sky-lit room: 0.09x Cycles' direct light with the
  world's volume), so a SUN light of the sun's direction, irradiance and angle is written too
  (when it lights at least 0.1 % of some captured view: else it only adds EEVEE's shadow
  leaks), shadowed; EEVEE must then not extract the sun from the world itself (its sun threshold 0,
  what "Set up EEVEE for vplace" and the scored renders set).
- Objects the VPLs must not light (``unlit``: ``capture.native_view.vpl_unlit``, sharp metal
  and glass when the VPLs have specular): every VPL light's Light Linking receiver collection
  (:data:`UNLIT_SUFFIX`, not linked to the scene, marked as vplace's) holds them as excluded.
  The user's objects are linked into it (it is among their collections, outside the scene)
  and nothing of theirs is set; re-running replaces it with the VPL collection, and clearing
  the VPLs removes it. The stand-ins keep lighting them (Cycles' direct light does).
- VPLs whose refitted power is zero are not written (a light that gives nothing still costs
  EEVEE a shadow map); each light keeps its VPL's index as ``vplace_index``.

The region the lights were laid out for (issue 20: the cameras' region and the coverage views
that stand for it, ``vplace.coverage``) is drawn in the viewport by :func:`write_region`, in a
collection of its own (:data:`REGION_NAME`, marked and replaced as the VPL collection is):
one sphere empty per camera (its eye, the region's radius) and one arrow empty per coverage
view (its eye, pointing where it looked). Empties render nothing.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import bpy
import numpy as np
from mathutils import Matrix, Quaternion, Vector

from ..errors import WriteBackError
from ..native import vplace
from ..scene.export import VPL_MARKER, base_name
from .stand_ins import EmitterLight, SunLight

if TYPE_CHECKING:
    from ..settings import SettingsGuard

COLLECTION_NAME = "vplace VPLs"
#: The VPL collection's custom property holding the name it was written under
#: (:data:`COLLECTION_NAME`, or the EEVEE match's own): what :func:`find_collection` looks for
#: in a scene, whatever the collection is called now.
ROLE_KEY = "vplace_collection"
#: The VPL collection's custom property holding the box of the region the cameras saw
#: (``vplace.Scene.region``: min x, y, z, max x, y, z), where it set the working scale: the EEVEE
#: set-up fits its probe volume and lamp reach to it (``eevee_setup.scene_bounds``).
REGION_KEY = "vplace_region"
#: The VPL collection's custom property that says the cameras work in a closed room
#: (``stand_ins.StandIns.closed``): EEVEE's world must light nothing
#: (``eevee_setup.world_shut_out``).
CLOSED_KEY = "vplace_closed"
#: The VPL collection's custom property holding the distance within which EEVEE's fast GI
#: gathers the light between nearby surfaces (``vplace.VplSet.near_field_distance``): what the
#: evaluator adds with ``near_field=True`` (``eevee_setup.set_up``). Absent for points.
NEAR_FIELD_KEY = "vplace_near_field_distance"
#: The VPL collection's custom property naming the user's lamps that the planes of surfaces the
#: cameras see pass through (``Prepared.cut_lamps``, given to the write-back): what the panel
#: and ``eevee_setup.lamp_notes`` note.
CUT_LAMPS_KEY = "vplace_cut_lamps"
#: EEVEE renders 8,192 lights; beyond 65,536 it drops them (DESIGN). We refuse more than this.
MAX_VPLS = 8192
#: The custom cutoff distance of every VPL light, in scene diagonals (see the module docs).
CUTOFF_DIAGONALS = 5.0
#: The diameter written for a VPL of near-field radius 0 (a point), in scene diagonals.
POINT_DISK_DIAGONALS = 1e-4
#: EEVEE shadow settings of every VPL light: the evaluator's shadow ray goes from the light's
#: centre, so the shadow map is not jittered over the disk.
SHADOW_SETTINGS: dict[str, object] = {"use_shadow_jitter": False}
#: EEVEE shadow settings of the emitter lights: their soft shadows are the scene's direct light,
#: which Cycles traces over the whole emitter. Without jitter EEVEE blurs one shadow map per light
#: with a noisy filter: the panel room's direct light scored SSIM 0.945 and brightness 0.972
#: against Cycles' at 16 samples, with jitter 0.963 and 0.998, for a few lights re-rendering their
#: maps at every sample. The VPL lights stay unjittered (above), and so does the world's sun: its
#: half-degree penumbra gained nothing (the sky room: SSIM 0.603 -> 0.604, RMSE 0.118 both,
#: brightness 0.965 -> 0.959), and a sun's maps are the costliest to re-render.
STAND_IN_SHADOW_SETTINGS: dict[str, object] = {"use_shadow_jitter": True}
#: The sky portals' (``portals``): unjittered. On the sky-lit room's five views their direct
#: light scored a lower RMSE against Cycles' without jitter (0.0724-0.1223 against
#: 0.0735-0.1229; SSIM within -.017..+.015), and jitter made its render with 256 VPLs 19 %
#: slower than with the world's volume, against 6 % without (``docs/EEVEE_NOTES.md`` Q7).
PORTAL_SHADOW_SETTINGS: dict[str, object] = {"use_shadow_jitter": False}
#: Every VPL light's ``shadow_maximum_resolution``, in scene diagonals: coarser than a 256-texel
#: cube face at one diagonal's distance (1 / 128), so EEVEE makes its coarsest maps.
SHADOW_TEXEL_DIAGONALS = 0.01
#: Shadow pool pages one VPL light takes at the coarsest level (measured on Sponza: 1,195 pages
#: for 256 AREA lights, about 4.7; a POINT light has 6 cube faces).
SHADOW_PAGES = {"AREA": 5, "POINT": 6}
#: ... and a SUN light's (its cascade).
SUN_PAGES = 16
#: Pages per MB of ``scene.eevee.shadow_pool_size``, and the largest pool (EEVEE's
#: ``SHADOW_MAX_PAGE``: 4,096 pages).
POOL_PAGES_PER_MB = 4
MAX_POOL_PAGES = 4096
#: The name of the VPL lights' receiver collection is the VPL collection's plus this.
UNLIT_SUFFIX = " (not lit by VPLs)"
#: The most VPL lights written with a shadow (the brightest): what the largest pool holds, with
#: room for the user's own lights (fewer where they take more: :func:`shadowed_vpls`).
MAX_SHADOWED_VPLS = 768
#: Of the largest pool's pages, the share vplace plans to fill (the user's lights take pages
#: too): what "Set up EEVEE for vplace" sizes the pool by (``eevee_setup``).
POOL_SHARE = 0.9


def shadowed_vpls(profile: str, other_pages: int) -> int:
    """How many VPL lights of ``profile`` cast a shadow: :data:`MAX_SHADOWED_VPLS`, or fewer
    where their pages (:data:`SHADOW_PAGES`) and ``other_pages`` (the scene's other shadowed
    lights: the user's, vplace's stand-ins) would not fit in :data:`POOL_SHARE` of the largest
    pool. 768 POINT lights take 4,608 pages of 4,096: "Set up EEVEE" could not make room."""
    per = SHADOW_PAGES["AREA" if profile == "cosine" else "POINT"]
    room = POOL_SHARE * MAX_POOL_PAGES - other_pages
    return max(0, min(MAX_SHADOWED_VPLS, int(room // per)))


def light_pages(light: bpy.types.Light) -> int:
    """Shadow pool pages a shadowed light takes at its coarsest level (an estimate)."""
    return SUN_PAGES if light.type == "SUN" else SHADOW_PAGES.get(light.type, 6)


def shadow_cap(scene: bpy.types.Scene, profile: str, emitters: int, sun: bool) -> int:
    """:func:`shadowed_vpls` for VPL lights of ``profile`` written into ``scene`` beside
    ``emitters`` AREA stand-ins and, with ``sun``, a SUN light for the world's sun."""
    others = user_shadow_pages(scene) + SHADOW_PAGES["AREA"] * emitters + SUN_PAGES * sun
    return shadowed_vpls(profile, others)


def cutoff_loss(distance: float, cutoff: float) -> float:
    """The fraction of a light's contribution EEVEE's distance fade removes at ``distance``
    from it with a custom cutoff ``cutoff``: ``1 - (1 - (d / c)^4)^2`` (0 beyond the cutoff
    means all of it: 1)."""
    x = (distance / cutoff) ** 4
    return 1.0 - max(0.0, 1.0 - x) ** 2


def _role(coll: bpy.types.Collection) -> str:
    """The name a vplace collection was written under (:data:`ROLE_KEY`; a collection written
    before it was kept: its name without Blender's ``.001``)."""
    role = coll.get(ROLE_KEY)
    return str(role) if role is not None else base_name(coll.name)


def scene_collection(
    scene: bpy.types.Scene, name: str, marker: str = VPL_MARKER
) -> bpy.types.Collection | None:
    """The collection vplace marked (``marker``) and wrote as ``name`` in ``scene``'s
    hierarchy, whatever it is called now (:data:`ROLE_KEY`), or None: each scene's own, never
    another's."""
    for coll in scene.collection.children_recursive:
        if coll.get(marker, False) and _role(coll) == name:
            return coll
    return None


def find_collection(
    name: str = COLLECTION_NAME, scene: bpy.types.Scene | None = None
) -> bpy.types.Collection | None:
    """The VPL collection vplace wrote earlier in ``scene`` (default: the context's) as
    ``name``, if any: marked as vplace's, in the scene's hierarchy, whatever it is called now.
    A collection of the user's named ``name`` is refused (:class:`WriteBackError`)."""
    found = scene_collection(scene if scene is not None else bpy.context.scene, name)
    if found is not None:
        return found
    user = bpy.data.collections.get(name)
    if user is not None and not user.get(VPL_MARKER, False):
        raise WriteBackError(
            f"a collection named {name!r} exists but was not made by vplace; "
            "rename it so vplace can write its own"
        )
    return None


def _strays(scene: bpy.types.Scene) -> list[bpy.types.Object]:
    """vplace's lights in ``scene`` that no vplace collection holds (theirs deleted in the
    Outliner, which moves its objects to the collection above)."""
    held = {o.as_pointer() for c in bpy.data.collections if c.get(VPL_MARKER) for o in c.objects}
    return [
        o
        for o in scene.objects
        if o.type == "LIGHT" and o.get(VPL_MARKER, False) and o.as_pointer() not in held
    ]


def clear_vpls(name: str = COLLECTION_NAME, scene: bpy.types.Scene | None = None) -> int:
    """Removes ``scene``'s (default: the context's) VPL collection ``name``, its objects and
    their light data, and with the main collection vplace's stray lights in the scene (see the
    module docs). Returns how many lights."""
    scene = scene if scene is not None else bpy.context.scene
    coll = find_collection(name, scene)
    count = remove_collection(coll, scene) if coll is not None else 0
    if name == COLLECTION_NAME:
        count += _remove_objects(_strays(scene))
    return count


def remove_collection(coll: bpy.types.Collection, scene: bpy.types.Scene | None = None) -> int:
    """Removes a vplace collection with the objects and lights vplace made in it, and the
    receiver collection of its lights (:func:`exclude_receivers`; the objects in it stay). What
    the user put into it stays, in ``scene``'s (default: the context's) collection if it was
    their only one."""
    count = _empty(coll, scene if scene is not None else bpy.context.scene)
    bpy.data.collections.remove(coll)
    return count


def _empty(coll: bpy.types.Collection, scene: bpy.types.Scene | None = None) -> int:
    """Removes vplace's objects from ``coll`` (with their light data and actions) and the
    receiver collection of its lights; the user's objects leave it for ``scene``'s collection
    (without a scene they stay in it). Returns how many were removed."""
    receivers = _receivers(coll)
    ours = []
    for obj in list(coll.objects):
        if obj.get(VPL_MARKER, False):
            ours.append(obj)
        elif scene is not None:
            # Something the user put into our collection: keep it, in the scene's collection
            # if ours was its only one (an object in no collection would be lost on save).
            if len(obj.users_collection) == 1:
                scene.collection.objects.link(obj)
            coll.objects.unlink(obj)
    count = _remove_objects(ours)
    if receivers is not None:
        bpy.data.collections.remove(receivers)
    return count


def _vpl_action(block: bpy.types.ID | None) -> bpy.types.Action | None:
    """The action the keyed write-back (``keyed``) gave ``block``, marked as vplace's, or
    None."""
    anim = getattr(block, "animation_data", None) if block is not None else None
    action = anim.action if anim is not None else None
    return action if action is not None and action.get(VPL_MARKER) else None


def _remove_objects(objects: Sequence[bpy.types.Object]) -> int:
    """Removes vplace's ``objects`` with their light data and the keyed write-back's actions
    (``keyed``; the object and its light may share one) once nothing else uses them, each kind
    in one batch (one at a time, 8,000 lights took 82 s: each removal walks the file)."""
    lights, actions = [], []
    for obj in objects:
        actions += [a for a in (_vpl_action(obj), _vpl_action(obj.data)) if a is not None]
        if isinstance(obj.data, bpy.types.Light):
            lights.append(obj.data)
    count = len(objects)
    bpy.data.batch_remove(list(objects))
    bpy.data.batch_remove(list({d.name: d for d in lights if d.users == 0}.values()))
    bpy.data.batch_remove(list({a.name: a for a in actions if a.users == 0}.values()))
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
    radius: float,
    cutoff: float,
    shadows: bool,
    texel: float,
    specular: float,
) -> bpy.types.Object:
    """VPL ``i`` as a new light object in ``coll`` (see the module docs)."""
    energy = float(power.max())
    light = bpy.data.lights.new(f"vplace VPL {i:04d}", "AREA" if profile == "cosine" else "POINT")
    light.energy = energy
    light.color = tuple(float(c) / energy for c in power)
    light.use_custom_distance = True
    light.cutoff_distance = cutoff
    light.use_shadow = shadows
    light.diffuse_factor = 1.0
    light.specular_factor = specular
    light.transmission_factor = 0.0
    light.volume_factor = 0.0
    for attr, value in SHADOW_SETTINGS.items():
        setattr(light, attr, value)
    light.shadow_maximum_resolution = texel
    if profile == "cosine":
        light.shape = "DISK"
        light.size = 2.0 * radius
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


def emitter_rotation(normal: Sequence[float], tangent: Sequence[float]) -> Quaternion:
    """The rotation of an AREA light that emits along ``normal`` (its -Z) with its first side
    along ``tangent`` (its X; made orthogonal to ``normal``)."""
    z = -Vector(normal)
    y = z.cross(Vector(tangent)).normalized()
    return Matrix((y.cross(z), y, z)).transposed().to_quaternion()


def _new_emitter_object(
    coll: bpy.types.Collection, i: int, e: EmitterLight, cutoff: float, shadows: bool
) -> bpy.types.Object:
    """Emitter light ``i`` (``emitter_lights``' module docs) as a new AREA light in ``coll``."""
    energy = max(e.power)
    kind = "portal" if e.portal else "emitter"
    light = bpy.data.lights.new(f"vplace {kind} {i:03d} ({e.material})", "AREA")
    light.energy = energy
    light.color = tuple(c / energy for c in e.power)
    light.shape = e.shape
    light.size = e.size
    if e.shape == "RECTANGLE":
        light.size_y = e.size_y
    light.use_custom_distance = True
    light.cutoff_distance = cutoff
    light.use_shadow = shadows
    for attr, value in (PORTAL_SHADOW_SETTINGS if e.portal else STAND_IN_SHADOW_SETTINGS).items():
        setattr(light, attr, value)
    obj = bpy.data.objects.new(light.name, light)
    obj.location = e.position
    obj.rotation_mode = "QUATERNION"
    obj.rotation_quaternion = emitter_rotation(e.normal, e.tangent)
    obj[VPL_MARKER] = True
    obj["vplace_emitter"] = e.material
    if e.portal:
        obj["vplace_portal"] = True
    coll.objects.link(obj)
    return obj


#: The name of the SUN light that stands in for the world's sun (``emitter_lights.world_sun``).
SUN_NAME = "vplace sun (world)"


def new_sun_object(coll: bpy.types.Collection, sun: SunLight) -> bpy.types.Object:
    """The world's sun as a SUN light in ``coll``, shining along ``-sun.direction``."""
    strength = max(sun.irradiance)
    light = bpy.data.lights.new(SUN_NAME, "SUN")
    light.energy = strength
    light.color = tuple(c / strength for c in sun.irradiance)
    light.angle = sun.angle
    light.use_shadow = True
    obj = bpy.data.objects.new(SUN_NAME, light)
    obj.rotation_mode = "QUATERNION"
    obj.rotation_quaternion = Vector((0.0, 0.0, 1.0)).rotation_difference(Vector(sun.direction))
    obj[VPL_MARKER] = True
    obj["vplace_world_sun"] = True
    coll.objects.link(obj)
    return obj


def hide_vpl_lights(g: SettingsGuard, scene: bpy.types.Scene) -> None:
    """Hides the VPL lights written into ``scene`` (each keeps its ``vplace_index``) through
    ``g`` for its block: a render then shows the rest, vplace's stand-ins included."""
    for obj in scene.objects:
        if obj.get("vplace_index") is not None:
            g.set(obj, "hide_render", True)


def world_sun_light(scene: bpy.types.Scene) -> bpy.types.Object | None:
    """The SUN light vplace wrote for the world's sun into ``scene``, if any."""
    return next((o for o in scene.objects if o.get("vplace_world_sun", False)), None)


#: A box ``(min, max)`` of world-space corners (``vplace.Scene.region``).
Region = tuple[Sequence[float], Sequence[float]]


def new_collection(
    name: str, region: Region | None, closed: bool = False, near_field: float = 0.0
) -> bpy.types.Collection:
    """A new, unlinked VPL collection to write ``name`` into, marked as vplace's, with
    ``region`` under :data:`REGION_KEY` when given, ``closed`` under :data:`CLOSED_KEY` and a
    positive ``near_field`` under :data:`NEAR_FIELD_KEY`."""
    coll = bpy.data.collections.new(name + " (writing)")
    coll[VPL_MARKER] = True
    coll[ROLE_KEY] = name
    if region is not None:
        coll[REGION_KEY] = [float(v) for corner in region for v in corner]
    if closed:
        coll[CLOSED_KEY] = True
    if near_field > 0.0:
        coll[NEAR_FIELD_KEY] = float(near_field)
    return coll


def _stored(name: str, key: str, scene: bpy.types.Scene | None) -> Any:
    """The custom property ``key`` of ``scene``'s (default: the context's) VPL collection
    ``name``, or None."""
    coll = scene_collection(scene if scene is not None else bpy.context.scene, name)
    return coll.get(key) if coll is not None else None


def stored_near_field(name: str = COLLECTION_NAME, scene: bpy.types.Scene | None = None) -> float:
    """The near-field distance kept on ``scene``'s VPL collection ``name``
    (:data:`NEAR_FIELD_KEY`), 0 without one."""
    value = _stored(name, NEAR_FIELD_KEY, scene)
    return float(value) if value is not None else 0.0


def stored_region(
    name: str = COLLECTION_NAME, scene: bpy.types.Scene | None = None
) -> Region | None:
    """The region kept on ``scene``'s VPL collection ``name`` (:data:`REGION_KEY`), or None."""
    values = _stored(name, REGION_KEY, scene)
    if values is None or len(values) != 6:
        return None
    v = [float(x) for x in values]
    return (v[:3], v[3:])


def stored_cut_lamps(
    name: str = COLLECTION_NAME, scene: bpy.types.Scene | None = None
) -> list[str]:
    """The user's lamps that the planes of surfaces the cameras see pass through, as the
    write-back was given them (:data:`CUT_LAMPS_KEY`; ``Prepared.cut_lamps``): what the panel
    notes; empty without."""
    values = _stored(name, CUT_LAMPS_KEY, scene)
    return [str(v) for v in values] if values else []


def stored_closed(name: str = COLLECTION_NAME, scene: bpy.types.Scene | None = None) -> bool:
    """Whether ``scene``'s VPL collection ``name`` says its lights light a closed room
    (:data:`CLOSED_KEY`)."""
    return bool(_stored(name, CLOSED_KEY, scene))


def write_vpls(
    scene: bpy.types.Scene,
    vpls: vplace.VplSet,
    *,
    shadows: bool = True,
    scene_diagonal: float = 10.0,
    specular: float = 0.0,
    emitters: Sequence[EmitterLight] = (),
    sun: SunLight | None = None,
    region: Region | None = None,
    closed: bool = False,
    unlit: Sequence[str] = (),
    cut_lamps: Sequence[str] = (),
    name: str = COLLECTION_NAME,
) -> bpy.types.Collection:
    """Writes the VPLs of ``vpls`` that carry power as lights (by its profile and near-field
    radius) in a fresh VPL collection linked to ``scene``; with ``shadows``, the
    :data:`MAX_SHADOWED_VPLS` brightest cast shadows; ``specular`` is their specular factor
    (``Prepared.vpl_specular``) and ``unlit`` the objects they do not light
    (``Prepared.vpl_unlit``, :func:`exclude_receivers`); ``emitters`` are written beside them,
    lights that stand in for emissive meshes EEVEE does not light with (``emitter_lights``),
    and ``sun``, a SUN light for the world's sun (``emitter_lights.world_sun``). ``region``
    (``vplace.Scene.region``) is kept on the collection (:data:`REGION_KEY`), ``closed``, a
    closed room (``StandIns.closed``; :data:`CLOSED_KEY`), and ``cut_lamps``, the user's lamps
    EEVEE darkens on what the cameras see (``Prepared.cut_lamps``; :data:`CUT_LAMPS_KEY`). See
    the module docs."""
    n = len(vpls)
    if n > MAX_VPLS:
        raise WriteBackError(
            f"{n} VPLs is more than EEVEE can render ({MAX_VPLS}); lower the VPL budget"
        )
    find_collection(name, scene)  # refuses a foreign collection of that name before any change
    point = 0.5 * POINT_DISK_DIAGONALS * scene_diagonal
    radii = vpls.radii if vpls.radius > 0 else np.full(n, point, dtype=np.float32)
    position, normal, flux = vpls.position, vpls.normal, vpls.flux
    power = vpls.blender_power
    # Build the new collection unlinked; only a complete one replaces the old one.
    near = vpls.near_field_distance if vpls.near_field else 0.0
    coll = new_collection(name, region, closed, near)
    lum = power @ np.asarray(vplace.LUMINANCE, dtype=np.float64)
    lit = np.flatnonzero(power.max(axis=1) > 0)
    cap = shadow_cap(scene, vpls.profile, len(emitters), sun is not None)
    shadowed = set(lit[np.argsort(-lum[lit], kind="stable")[:cap]].tolist())
    try:
        for i in lit:
            _new_vpl_object(
                coll,
                int(i),
                position[i],
                normal[i],
                flux[i],
                power[i],
                vpls.profile,
                float(radii[i]),
                CUTOFF_DIAGONALS * scene_diagonal,
                shadows and int(i) in shadowed,
                SHADOW_TEXEL_DIAGONALS * scene_diagonal,
                specular,
            )
        for j, e in enumerate(emitters):
            _new_emitter_object(coll, j, e, CUTOFF_DIAGONALS * scene_diagonal, shadows)
        if sun is not None:
            new_sun_object(coll, sun)
        exclude_receivers(coll, unlit)
    except BaseException:
        remove_collection(coll)
        raise
    coll = replace_collection(scene, coll, name)
    coll[CUT_LAMPS_KEY] = list(cut_lamps)
    return coll


def user_shadow_pages(scene: bpy.types.Scene) -> int:
    """Shadow pool pages the scene's own shadowed lamps take (not vplace's lights)."""
    return sum(
        light_pages(o.data)
        for o in scene.objects
        if o.type == "LIGHT"
        and not o.hide_render
        and o.data.use_shadow
        and not o.get(VPL_MARKER, False)
    )


def exclude_receivers(coll: bpy.types.Collection, unlit: Sequence[str]) -> None:
    """Makes the VPL lights of ``coll`` (those with a ``vplace_index``) light every object
    but ``unlit`` (object names; those not in the file are skipped): a Light Linking receiver
    collection, new, unlinked and marked as vplace's, holds them excluded. No collection when
    nothing is left out."""
    objects = [bpy.data.objects[n] for n in unlit if n in bpy.data.objects]
    if not objects:
        return
    receivers = bpy.data.collections.new(coll.name + UNLIT_SUFFIX)
    receivers[VPL_MARKER] = True
    for obj in objects:
        receivers.objects.link(obj)
    for entry in receivers.collection_objects:
        entry.light_linking.link_state = "EXCLUDE"
    for obj in coll.objects:
        if obj.get("vplace_index") is not None:
            obj.light_linking.receiver_collection = receivers


#: The collection that shows the region the lights were laid out for (:func:`write_region`).
REGION_NAME = "vplace region"
#: The arrow of a coverage view, in radii of the region it stands in.
REGION_ARROW = 0.25


@dataclass(frozen=True)
class RegionMarks:
    """What :func:`write_region` draws: per user camera where it stands (``eyes``, world,
    scene units; ``vplace.coverage.camera_eye``) and the radius of its region (``radii``), and
    the coverage views chosen for the region (``poses``, ``vplace.coverage.Pose``)."""

    eyes: list[np.ndarray]
    radii: list[float]
    poses: list[vplace.coverage.Pose]

    @classmethod
    def of(cls, coverage: vplace.coverage.Coverage | None) -> RegionMarks | None:
        """The region a job laid its lights out for (``Prepared.coverage``): its cameras' eyes
        and radii and its coverage views' poses; None without coverage views."""
        if coverage is None or not coverage.poses:
            return None
        return cls(list(coverage.eyes), list(coverage.radius), list(coverage.poses))


def union_of_regions(marks: Sequence[RegionMarks | None]) -> RegionMarks | None:
    """One :class:`RegionMarks` for several runs' (an animated job's frames): each camera's
    eye and radius and each coverage view once, in order (a camera that stands still over the
    frames is one sphere); None where none has marks."""
    eyes: list[np.ndarray] = []
    radii: list[float] = []
    poses: list[vplace.coverage.Pose] = []
    for m in (m for m in marks if m is not None):
        for eye, radius in zip(m.eyes, m.radii, strict=True):
            seen = zip(eyes, radii, strict=True)
            if not any(np.array_equal(eye, e) and radius == r for e, r in seen):
                eyes.append(eye)
                radii.append(radius)
        for pose in m.poses:
            if not any(
                np.array_equal(pose.eye, p.eye) and np.array_equal(pose.forward, p.forward)
                for p in poses
            ):
                poses.append(pose)
    return RegionMarks(eyes, radii, poses) if eyes else None


def region_arrow_matrix(pose: vplace.coverage.Pose) -> Matrix:
    """The world matrix of an empty at ``pose``'s eye whose +Z axis (a single arrow empty's)
    points where the view looks (and whose +Y is the view's up)."""
    f, right, up = pose.basis()
    rot = Matrix((-right, up, f)).transposed()  # columns: x, y, z; a rotation (det +1)
    return Matrix.Translation(Vector(pose.eye.tolist())) @ rot.to_4x4()


def write_region(scene: bpy.types.Scene, marks: RegionMarks | None) -> bpy.types.Collection | None:
    """Shows the region in ``scene``'s viewport: a fresh :data:`REGION_NAME` collection (written
    unlinked, then in place of the last run's, as :func:`write_vpls` does) holding a sphere
    empty ``vplace region k`` per camera, at its eye with the region's radius, and an arrow
    empty ``vplace region view k`` per coverage view. Without marks (no coverage views: the
    lights were laid out for the cameras alone), the last run's region is removed and None
    returned. Nothing renders: the empties are hidden from renders too."""
    if marks is None or not marks.eyes:
        clear_vpls(REGION_NAME, scene)
        return None
    find_collection(REGION_NAME, scene)  # refuses a foreign collection of that name
    coll = new_collection(REGION_NAME, None)
    arrow = REGION_ARROW * float(np.median(marks.radii))
    try:
        for k, (eye, radius) in enumerate(zip(marks.eyes, marks.radii, strict=True), start=1):
            obj = _new_mark(coll, f"vplace region {k}", "SPHERE", float(radius))
            obj.location = Vector(np.asarray(eye, dtype=np.float64).tolist())
        for k, pose in enumerate(marks.poses, start=1):
            obj = _new_mark(coll, f"vplace region view {k}", "SINGLE_ARROW", arrow)
            obj.matrix_world = region_arrow_matrix(pose)
    except BaseException:
        remove_collection(coll)
        raise
    return replace_collection(scene, coll, REGION_NAME)


def _new_mark(coll: bpy.types.Collection, name: str, shape: str, size: float) -> bpy.types.Object:
    """A new empty of ``shape`` and ``size`` in ``coll``, marked as vplace's, not rendered."""
    obj = bpy.data.objects.new(name, None)
    obj.empty_display_type = shape
    obj.empty_display_size = size
    obj.hide_render = True
    obj[VPL_MARKER] = True
    coll.objects.link(obj)
    return obj


def unlit_objects(coll: bpy.types.Collection | None = None) -> list[str]:
    """The names of the objects the VPL lights of ``coll`` (default: the VPL collection, if
    vplace wrote it) do not light (:func:`exclude_receivers`)."""
    if coll is None:
        coll = scene_collection(bpy.context.scene, COLLECTION_NAME)
        if coll is None:
            return []
    receivers = _receivers(coll)
    return sorted(o.name for o in receivers.objects) if receivers is not None else []


def _receivers(coll: bpy.types.Collection) -> bpy.types.Collection | None:
    """The receiver collection vplace made for the VPL lights of ``coll``, if any."""
    for obj in coll.objects:
        linking = getattr(obj, "light_linking", None)
        found = linking.receiver_collection if linking is not None else None
        if found is not None and found.get(VPL_MARKER, False):
            return found
    return None


def replace_collection(
    scene: bpy.types.Scene, coll: bpy.types.Collection, name: str
) -> bpy.types.Collection:
    """Puts the lights of ``coll``, just written unlinked, in place of those of ``scene``'s VPL
    collection ``name`` and returns the collection that holds them: the earlier one where the
    scene has it (so its name, its place, its view layer's exclude and hide settings and the
    user's objects in it stay; ``coll`` is removed), else ``coll``, linked to the scene.
    vplace's stray lights in the scene go (see the module docs)."""
    old = find_collection(name, scene)
    if name == COLLECTION_NAME:
        _remove_objects(_strays(scene))
    if old is not None:
        _empty(old)
        for key in [k for k in old.keys() if k.startswith("vplace_")]:
            del old[key]
        for key, value in coll.items():
            old[key] = value.to_list() if hasattr(value, "to_list") else value
        for obj in list(coll.objects):
            old.objects.link(obj)
            coll.objects.unlink(obj)
        bpy.data.collections.remove(coll)
        coll = old
    else:
        coll.name = name
        scene.collection.children.link(coll)
    receivers = _receivers(coll)
    if receivers is not None:
        receivers.name = name + UNLIT_SUFFIX
    _own_names([o for o in coll.objects if o.get(VPL_MARKER, False)])
    return coll


def _own_names(objects: Sequence[bpy.types.Object]) -> None:
    """Written beside the old lights, the new ``objects`` and their lights took Blender's
    ".001" names; with the old gone, each takes its own name back where it is free, so that
    every run names its lights alike, and the keyed write-back's action, named by Blender after
    its light as it was ("vplace VPL slot 0000.001Action"), follows it.

    The names taken are looked up in sets: ``name in bpy.data.objects`` compares every name,
    and with one lookup per light the renames took 2.2 s of the 5.7 s that re-writing 4,000
    lights took (0.4 s with the sets)."""
    taken = {
        bpy.types.Object: {o.name for o in bpy.data.objects},
        bpy.types.Light: {d.name for d in bpy.data.lights},
        bpy.types.Action: {a.name for a in bpy.data.actions},
    }

    def rename(block: bpy.types.ID, name: str, names: set[str]) -> None:
        if name != block.name and name not in names:
            was = block.name
            block.name = name
            names.discard(was)
            names.add(block.name)

    for obj in objects:
        for block in (obj, obj.data) if obj.data is not None else (obj,):  # an empty: no data
            was = block.name
            kind = bpy.types.Object if isinstance(block, bpy.types.Object) else bpy.types.Light
            rename(block, base_name(was), taken[kind])
            action = _vpl_action(block)
            if action is not None and action.name.startswith(was):
                rename(action, block.name + action.name[len(was) :], taken[bpy.types.Action])
