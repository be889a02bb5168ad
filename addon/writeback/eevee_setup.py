"""EEVEE set up for vplace's lights, and what in the current settings would drop or dim them.

What EEVEE does with many small lights was measured (``docs/EEVEE_NOTES.md``): the VPL lights
carry every bounce; EEVEE renders the direct light
of the user's lamps; nothing may count a bounce twice. :func:`problems` names each setting that
breaks this, :func:`set_up` (the operator "Set up EEVEE for vplace", undoable) applies the
settings that fix it:

- **shadow pool**: each shadowed VPL light takes about :data:`apply.SHADOW_PAGES` pages at the
  coarsest level; a pool too small drops shadows silently and the light leaks through walls (the
  image brightens). The pool is raised to hold them (at most 1,024 MB);
- **shadows on** (``use_shadows``): without them VPL light leaks (Sponza 1.6x too bright);
- **no second bounce**: EEVEE's ray tracing with the "global illumination" fast GI, or a light
  probe volume that captures indirect light, adds the lamps' bounce again (x2 the direct light in
  a test room): ray tracing is kept for reflections with fast GI set to ambient occlusion only,
  and a volume vplace bakes captures no indirect light. Where the written lights' light
  includes the near-field gather (``vplace.VplSet.near_field``: the light between nearby
  surfaces, a room's corners, that no VPL carries; the VPL collection keeps its distance,
  ``apply.NEAR_FIELD_KEY``), the fast GI gathers global illumination within that distance and
  no further (:func:`fast_gi_for`): what the evaluator adds;
- **the world where it is partly kept out**: EEVEE lights surfaces with the world unoccluded
  (+10 % of the direct light in a closed room with the default grey world). When the world
  emits and neither portals nor a closed room (below) shut it out, a light probe volume
  enclosing the scene (:data:`VOLUME_MARGIN` times its bounds) is baked with
  ``capture_indirect`` off, so the world reaches only what sees it (4 % left in the test room
  of ``tests/render/test_world_room.py``, 2 % with ray-traced ambient occlusion; that room is
  closed, and is now shut out instead: EEVEE + VPLs 1.034x the truth's brightness, the
  evaluator 1.033x);
- **the sky through a room's openings**: where vplace wrote sky portals (``portals``: AREA
  lights in the windows that carry the sky's light in), the world must light nothing more, or
  its light would count twice: the world gets an EEVEE-only World Output (:func:`camera_only`,
  its nodes marked ``vplace_world``) that shows the world's own surface to camera rays and black
  to every other ray (EEVEE's probes), so the windows still show the sky and Cycles renders the
  world as before. No probe volume is needed then;
- **a closed room**: where no ray from the cameras' eyes or the surfaces they see leaves the
  scene, not even through glass (``stand_ins.sky_seen``; ``apply.CLOSED_KEY``), the world
  lights nothing they see directly in Cycles (its bounce is the light paths' VPLs); EEVEE's
  world gets the same EEVEE-only World Output as with portals (:func:`world_shut_out`). The volume
  does not stop the world where the walls are single faces: in a box room of my own (a default
  cube scaled up, a spot and an emissive panel inside, the world 0.02 grey) EEVEE lit the
  inside with the world at 0.55x Cycles' whole direct light with the volume baked (0.42x-0.53x
  with its validity threshold at 0, its faces turned inward or 24 probes a side; 0.81x with a
  volume inside the walls), 0.83x without;
- each VPL light keeps its custom distance (then ``light_threshold`` does not cut it) and its
  shadow (written by :mod:`apply`); a user's edit that removes either is named;
- **the user's own lamps fade out**: a lamp without a custom distance is faded by
  ``(1 - (d / R)^4)^2`` with ``R = sqrt(P / (100 * light_threshold))`` m for ``P`` W (measured;
  Cycles does not fade). The Cornell box's 9.5 W area light at the default threshold 0.01 reaches
  3.1 m, so its floor, 2 m below, gets 0.6-0.7 of Cycles' direct light. The threshold is lowered
  until every lamp reaches :data:`LAMP_REACH_DIAGONALS` scene diagonals (at most 0.8 % lost
  inside the scene);
- **soft shadows traced with :data:`SHADOW_RAYS` rays** (``shadow_ray_count``, never lowered):
  with Blender's one ray EEVEE's penumbrae are grain that its samples do not average out, in
  the user's lamps' shadows and the VPLs' alike;
- at most :data:`MAX_LIGHTS` lights (EEVEE drops the rest).

What is not vplace's and is the user's to change, :func:`lamp_notes` names: **an area light's
Spread**, which EEVEE ignores (:func:`spread_lamps`), **a lamp that the plane of a surface in
front of it cuts**, whose light EEVEE darkens on that surface (:mod:`.cut_lights`), and **the
user's lamps' soft shadows without jitter**. EEVEE then blurs one shadow map per lamp with a
noisy filter: on the Cornell box at 16 samples its direct light scored SSIM 0.978 and 0.941
against Cycles' (two cameras), 0.989 and 0.976 with the lamp's jitter on
(``docs/EEVEE_NOTES.md``, Q7). vplace turns jitter on for its own stand-ins
(``apply.STAND_IN_SHADOW_SETTINGS``), never on the user's lamps.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass

import bpy
from mathutils import Vector

from ..compat import eevee_engine, uses_nodes
from ..errors import AddonError
from ..scene.export import VPL_MARKER, unit_scale
from ..settings import SettingsGuard, override
from . import apply, cut_lights, keyed
from .stand_ins import SunLight

#: The shadow rays EEVEE traces per light and pixel for soft shadows (``shadow_ray_count``, 1 to
#: 4; Blender's default 1). EEVEE traces a soft shadow through the light's shadow map, and with
#: one ray its penumbrae are grain that 16 samples do not average out: on the Cornell box (the
#: lamp's shadows unjittered, 256 VPLs, 16 samples, llvmpipe; `/work/runs/s67/sweep.sh`) EEVEE
#: scored SSIM .9759 / .9589 on the left / high camera with 1 ray, .9805 / .9672 with 2, .9841 /
#: .9717 with 4 (the evaluator .9877 / .9805), a frame 1.15x as long. More steps per ray
#: (``shadow_step_count`` 16 instead of 6) made it worse (.9739 / .9539 with 1 ray) and darker.
SHADOW_RAYS = 4
#: EEVEE's hard limit on lights in a scene (measured: 65,536; the excess is dropped).
MAX_LIGHTS = 65536
#: Pool sizes (MB) EEVEE offers, smallest first.
POOL_SIZES = (16, 32, 64, 128, 256, 512, 1024)
#: Of the pool's pages, the share vplace plans to fill (``apply.POOL_SHARE``).
POOL_SHARE = apply.POOL_SHARE
#: The light probe volume encloses the scene's bounds times this (its walls inside it).
VOLUME_MARGIN = 1.15
#: Probes along the volume's longest side (the others in proportion, at least 2).
VOLUME_PROBES = 12
#: How far (in scene diagonals) EEVEE's automatic light distance must reach for every lamp.
LAMP_REACH_DIAGONALS = 4.0
#: The collection of the probes vplace adds (replaced on each set-up).
PROBE_COLLECTION = "vplace probes"
#: The collection of the sun lamp that EEVEE's own GI gets while it is scored
#: (:func:`users_sun`; removed after).
USERS_SUN_COLLECTION = "vplace: the user's sun (scoring EEVEE's GI)"


@dataclass(frozen=True)
class Problem:
    """A setting that drops, dims or double-counts light with vplace's VPLs."""

    setting: str
    message: str

    def __str__(self) -> str:
        return f"{self.setting}: {self.message}"

    @property
    def remedy(self) -> str:
        """What fixes it where the message does not say: "Set up EEVEE for vplace" for the
        EEVEE and world settings it applies, a new write for VPL lights that lost their
        shadow; empty where only the user can (the light count, their own probe volume: the
        message says how)."""
        if self.setting.startswith(("scene.eevee.", "world")):
            return "Set up EEVEE for vplace fixes it"
        if self.setting.startswith("Light."):
            return "Lay out and apply again writes them as vplace sets them"
        return ""

    def advice(self) -> str:
        """The problem with its :attr:`remedy`, one line."""
        return f"{self} ({self.remedy})" if self.remedy else str(self)


def vpl_lights(scene: bpy.types.Scene) -> list[bpy.types.Object]:
    """The light objects vplace wrote into ``scene``."""
    return [o for o in scene.objects if o.type == "LIGHT" and o.get(VPL_MARKER, False)]


def lamp_reach(light: bpy.types.Light, threshold: float) -> float:
    """How far (m) EEVEE's automatic light distance lets a lamp without a custom distance reach:
    ``sqrt(P / (100 * threshold))`` for ``P`` its power in W (``inf`` for suns and at threshold
    0)."""
    power = light.energy * max(light.color)
    if light.type == "SUN" or threshold <= 0.0:
        return math.inf
    return math.sqrt(max(power, 0.0) / (100.0 * threshold))


def _reach_needed(scene: bpy.types.Scene, collection: str = apply.COLLECTION_NAME) -> float | None:
    """How far every lamp must reach: :data:`LAMP_REACH_DIAGONALS` scene diagonals (None
    without a visible mesh); the scene's box as :func:`scene_bounds` finds it with the region
    kept on the VPL collection ``collection``."""
    try:
        lo, hi = scene_bounds(scene, collection=collection)
    except AddonError:
        return None
    return LAMP_REACH_DIAGONALS * (hi - lo).length


def _faded(scene: bpy.types.Scene, need: float | None) -> list[tuple[str, float]]:
    if need is None:
        return []
    threshold = scene.eevee.light_threshold
    out = []
    for obj in scene.objects:
        if obj.type != "LIGHT" or obj.hide_render or obj.get(VPL_MARKER, False):
            continue
        if obj.data.use_custom_distance or obj.data.energy <= 0.0:
            continue
        reach = lamp_reach(obj.data, threshold)
        if reach < need:
            out.append((obj.name, reach))
    return out


def faded_lamps(scene: bpy.types.Scene) -> list[tuple[str, float]]:
    """The user's lamps (not vplace's) that EEVEE fades out inside the scene at its current
    ``light_threshold``, with the distance each reaches."""
    return _faded(scene, _reach_needed(scene))


def threshold_for(scene: bpy.types.Scene, collection: str = apply.COLLECTION_NAME) -> float:
    """The largest ``light_threshold`` at which every lamp of ``scene`` reaches
    :data:`LAMP_REACH_DIAGONALS` scene diagonals (the current one when none falls short), the
    scene's box taken with the region kept on the VPL collection ``collection``.
    A lamp's reach goes as ``1 / sqrt(threshold)``, so the shortest reach sets it."""
    threshold = scene.eevee.light_threshold
    need = _reach_needed(scene, collection)
    faded = _faded(scene, need)
    if need is None or not faded:
        return threshold
    shortest = min(reach for _, reach in faded)
    return 0.99 * threshold * (shortest / need) ** 2  # 0.5 % beyond


def shadow_pages(scene: bpy.types.Scene) -> int:
    """Shadow pool pages the scene's shadowed lights take at the coarsest level (an estimate:
    vplace's lights make their coarsest maps; the user's lights may take more)."""
    if not scene.eevee.use_shadows:
        return 0
    pages = 0
    for obj in scene.objects:
        if obj.type != "LIGHT" or obj.hide_render or not obj.data.use_shadow:
            continue
        pages += apply.light_pages(obj.data)
    return pages


def pool_pages(scene: bpy.types.Scene) -> int:
    """Pages the scene's shadow pool holds."""
    return apply.POOL_PAGES_PER_MB * int(scene.eevee.shadow_pool_size)


def pool_for(pages: int) -> int:
    """The smallest pool size (MB) that holds ``pages`` within :data:`POOL_SHARE`, or the
    largest."""
    for mb in POOL_SIZES:
        if pages <= POOL_SHARE * apply.POOL_PAGES_PER_MB * mb:
            return mb
    return POOL_SIZES[-1]


def world_emits(scene: bpy.types.Scene) -> bool:
    """Whether the world sends light into the scene (a Background with colour and strength, or
    a texture on its colour)."""
    world = scene.world
    if world is None or world.node_tree is None:
        return world is not None and max(world.color) > 0.0
    for node in world.node_tree.nodes:
        if node.type != "BACKGROUND" or node.mute:
            continue
        color, strength = node.inputs["Color"], node.inputs["Strength"]
        if strength.is_linked or (strength.default_value > 0.0 and color.is_linked):
            return True
        if strength.default_value > 0.0 and max(color.default_value[:3]) > 0.0:
            return True
    return False


def portal_lights(scene: bpy.types.Scene) -> list[bpy.types.Object]:
    """The sky portals vplace wrote into ``scene`` (``portals``) that render."""
    return [o for o in scene.objects if o.get("vplace_portal", False) and not o.hide_render]


def world_shut_out(scene: bpy.types.Scene) -> bool:
    """Whether EEVEE's world must light nothing: vplace's sky portals carry its light in, or
    vplace's lights light a closed room, which none of it reaches (``apply.stored_closed``)."""
    return bool(portal_lights(scene)) or apply.stored_closed(scene=scene)


#: The custom property that marks the world nodes :func:`camera_only` adds.
WORLD_NODE_MARKER = "vplace_world"


def _outputs(world: bpy.types.World) -> list[bpy.types.Node]:
    return [n for n in world.node_tree.nodes if n.bl_idname == "ShaderNodeOutputWorld"]


def is_camera_only(world: bpy.types.World | None) -> bool:
    """Whether ``world`` has vplace's EEVEE-only output (:func:`camera_only`)."""
    if world is None or world.node_tree is None:
        return False
    return any(n.get(WORLD_NODE_MARKER, False) for n in _outputs(world))


def _source_output(world: bpy.types.World) -> bpy.types.Node | str:
    """The World Output whose surface :func:`camera_only` shows to the camera, or why there is
    none it may use."""
    if not uses_nodes(world):
        return "the world does not use nodes"
    outputs = [n for n in _outputs(world) if not n.mute]
    if any(n.target == "EEVEE" for n in outputs):
        return "the world has an EEVEE World Output of its own"
    source = next((n for n in outputs if n.target == "ALL" and n.is_active_output), None)
    source = source or next((n for n in outputs if n.target == "ALL"), None)
    return source if source is not None else "the world has no World Output that EEVEE renders"


def camera_only_blocker(world: bpy.types.World | None) -> str | None:
    """Why :func:`camera_only` cannot change ``world`` (None: it can, or it has)."""
    if world is None:
        return "the scene has no world"
    if is_camera_only(world):
        return None
    source = _source_output(world)
    return source if isinstance(source, str) else None


def camera_only(world: bpy.types.World) -> str | None:
    """Adds to ``world`` an EEVEE-only World Output that shows its own surface (and volume) to
    camera rays and black to every other ray (the module docs; nodes marked
    :data:`WORLD_NODE_MARKER`, :func:`remove_camera_only` takes them out). Returns why it
    cannot (no node tree, no output, an EEVEE output of the user's), else None."""
    if is_camera_only(world):
        return None
    source = _source_output(world)
    if isinstance(source, str):
        return source
    tree = world.node_tree
    nodes = {
        "out": tree.nodes.new("ShaderNodeOutputWorld"),
        "path": tree.nodes.new("ShaderNodeLightPath"),
        "mix": tree.nodes.new("ShaderNodeMixShader"),
        "black": tree.nodes.new("ShaderNodeBackground"),
    }
    for k, node in enumerate(nodes.values()):
        node[WORLD_NODE_MARKER] = True
        node.label = "vplace: the world for the camera only"
        node.location = (source.location.x - 200.0 * k, source.location.y - 300.0)
    nodes["out"].target = "EEVEE"
    nodes["black"].inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    nodes["black"].inputs["Strength"].default_value = 0.0
    links = tree.links
    links.new(nodes["path"].outputs["Is Camera Ray"], nodes["mix"].inputs[0])
    links.new(nodes["black"].outputs["Background"], nodes["mix"].inputs[1])
    surface = source.inputs["Surface"]
    if surface.is_linked:
        links.new(surface.links[0].from_socket, nodes["mix"].inputs[2])
    links.new(nodes["mix"].outputs["Shader"], nodes["out"].inputs["Surface"])
    volume = source.inputs["Volume"]
    if volume.is_linked:
        links.new(volume.links[0].from_socket, nodes["out"].inputs["Volume"])
    return None


#: Cycles' samples for the lights of :func:`cycles_as_eevee_lights` (the attribution's split
#: of EEVEE's direct light): their noise counts toward the stand-ins' share, as the truth's does.
STAND_IN_SAMPLES = 64


def cycles_as_eevee_lights(
    g: SettingsGuard, scene: bpy.types.Scene, emissive: Sequence[str]
) -> bool:
    """Sets ``scene`` up (through ``g``, for its block) so that Cycles lights it as EEVEE's
    direct light does: with the lamps and vplace's stand-ins, the emissive meshes (objects with
    a material named in ``emissive``) seen but lighting nothing (their ray visibility off but
    the camera's: Cycles samples no light its rays cannot see), and a world kept from lighting
    EEVEE (:func:`camera_only`) kept from lighting Cycles too (its output's target made Cycles'
    for the block). Returns False, setting nothing, where the world lights EEVEE (its probe
    volume): Cycles would light with it exactly and with the sun's stand-in as well."""
    world = scene.world
    if world_emits(scene) and not is_camera_only(world):
        return False
    if world is not None and world.node_tree is not None:
        for node in _outputs(world):
            if node.get(WORLD_NODE_MARKER, False):
                g.set(node, "target", "CYCLES")
    names = set(emissive)
    for obj in scene.objects:
        slots = getattr(obj, "material_slots", ())
        if any(s.material is not None and s.material.name in names for s in slots):
            for attr in ("visible_diffuse", "visible_glossy", "visible_transmission"):
                g.set(obj, attr, False)
            g.set(obj, "visible_volume_scatter", False)
    return True


def remove_camera_only(world: bpy.types.World | None) -> None:
    """Takes the nodes of :func:`camera_only` out of ``world`` again."""
    if world is None or world.node_tree is None:
        return
    tree = world.node_tree
    for node in [n for n in tree.nodes if n.get(WORLD_NODE_MARKER, False)]:
        tree.nodes.remove(node)


def vplace_volume(scene: bpy.types.Scene) -> bpy.types.Object | None:
    """The light probe volume :func:`set_up` added, if any."""
    coll = apply.scene_collection(scene, PROBE_COLLECTION)
    if coll is None:
        return None
    return next((o for o in coll.objects if o.type == "LIGHT_PROBE"), None)


def problems(scene: bpy.types.Scene) -> list[Problem]:
    """Every setting of ``scene`` that would drop, dim or double the light of vplace's VPLs in
    EEVEE (none when there are no VPL lights)."""
    vpls = vpl_lights(scene)
    if not vpls:
        return []
    e = scene.eevee
    found: list[Problem] = []
    lights = sum(1 for o in scene.objects if o.type == "LIGHT" and not o.hide_render)
    if lights > MAX_LIGHTS:
        found.append(
            Problem(
                "lights",
                f"{lights} lights: EEVEE renders at most {MAX_LIGHTS} and drops the rest; lower "
                "the VPL budget",
            )
        )
    if not e.use_shadows:
        found.append(
            Problem(
                "scene.eevee.use_shadows",
                "shadows are off: VPL light leaks through walls (the image comes out too bright)",
            )
        )
    else:
        need, have = shadow_pages(scene), pool_pages(scene)
        if need > POOL_SHARE * have:
            found.append(
                Problem(
                    "scene.eevee.shadow_pool_size",
                    f"the shadowed lights need about {need} shadow pages and the "
                    f"{e.shadow_pool_size} MB pool holds {have}: EEVEE drops the shadows it "
                    "cannot hold and their light leaks (the image comes out too bright)",
                )
            )
    unshadowed = [o.name for o in vpls if not o.data.use_shadow]
    # The VPL lights' own (their stand-ins' and the user's lamps' pages come first).
    own = [o for o in vpls if o.get("vplace_index") is not None]
    others = shadow_pages(scene) - sum(apply.light_pages(o.data) for o in own if o.data.use_shadow)
    profile = "cosine" if all(o.data.type == "AREA" for o in own) else "omni"
    if len(unshadowed) > max(0, len(vpls) - apply.shadowed_vpls(profile, others)):
        found.append(
            Problem(
                "Light.use_shadow",
                f"{len(unshadowed)} VPL lights cast no shadow (e.g. {unshadowed[0]!r}): their "
                "light leaks through walls",
            )
        )
    uncut = [o.name for o in vpls if o.data.type != "SUN" and not o.data.use_custom_distance]
    if uncut and e.light_threshold > 0:
        found.append(
            Problem(
                "Light.use_custom_distance",
                f"{len(uncut)} VPL lights have no custom distance (e.g. {uncut[0]!r}): EEVEE cuts "
                f"them where they fall below the light threshold {e.light_threshold:g}",
            )
        )
    faded = faded_lamps(scene)
    if faded:
        name, reach = faded[0]
        found.append(
            Problem(
                "scene.eevee.light_threshold",
                f"EEVEE fades {len(faded)} lamp(s) out within the scene (e.g. {name!r} "
                f"reaches {reach * unit_scale(scene):.3g} m; Cycles does not fade): their "
                "light comes out too dark away from them; a threshold of "
                f"{threshold_for(scene):.3g} lets them reach",
            )
        )
    # Blender 4.2 has no use_fast_gi switch: its fast GI is on whenever ray tracing is.
    near = apply.stored_near_field(scene=scene)
    gathers = (
        e.use_raytracing
        and getattr(e, "use_fast_gi", True)
        and e.fast_gi_method == "GLOBAL_ILLUMINATION"
    )
    if gathers and not (near > 0.0 and abs(e.fast_gi_distance - near) <= 0.01 * near):
        found.append(
            Problem(
                "scene.eevee.fast_gi_method",
                "ray tracing with the global-illumination fast GI adds the bounce light the VPLs "
                "already carry (counted twice): "
                + (
                    "gather only within the lights' near-field distance "
                    f"({near * unit_scale(scene):.3g} m)"
                    if near > 0.0
                    else "use ambient occlusion only"
                ),
            )
        )
    if near > 0.0 and not gathers:
        found.append(
            Problem(
                "scene.eevee.fast_gi_method",
                "the written lights leave the light between nearby surfaces to EEVEE's fast GI: "
                f"ray tracing on, global illumination within {near * unit_scale(scene):.3g} m",
            )
        )
    for obj in scene.objects:
        if obj.type == "LIGHT_PROBE" and obj.data.type == "VOLUME" and obj.data.capture_indirect:
            found.append(
                Problem(
                    f"{obj.name}.capture_indirect",
                    "this light probe volume bakes bounce light, which the VPLs already carry "
                    "(counted twice): turn Capture Indirect off and bake again",
                )
            )
    world = scene.world
    if world is not None and world.sun_threshold > 0.0 and apply.world_sun_light(scene):
        found.append(
            Problem(
                "world.sun_threshold",
                "vplace wrote the world's sun as a lamp, and EEVEE extracts the sun from the "
                f"world too above its sun threshold ({world.sun_threshold:g}): the sun would "
                "count twice; set the threshold to 0",
            )
        )
    if portal_lights(scene):
        if not is_camera_only(world):
            found.append(
                Problem(
                    "world",
                    "vplace wrote sky portals, which carry the sky's light through the "
                    "openings, and EEVEE lights with the world too (counted twice): the world "
                    "must light nothing but show to the camera",
                )
            )
    elif apply.stored_closed(scene=scene) and world_emits(scene):
        if not is_camera_only(world):
            found.append(
                Problem(
                    "world",
                    "the cameras are in a closed room, which the world does not light in "
                    "Cycles, and EEVEE lights it with the world through the walls: the world "
                    "must light nothing but show to the camera",
                )
            )
    elif is_camera_only(world):
        found.append(
            Problem(
                "world",
                "the world lights nothing in EEVEE (vplace's EEVEE World Output, for sky "
                "portals that are no longer there): the scene misses the sky's light",
            )
        )
    elif world_emits(scene) and vplace_volume(scene) is None:
        found.append(
            Problem(
                "world",
                "EEVEE lights surfaces with the world as if nothing were in the way (indoors, "
                "light through walls): a light probe volume baked without indirect light "
                "occludes it",
            )
        )
    return found


def unjittered_lamps(scene: bpy.types.Scene) -> list[str]:
    """The user's lamps (not vplace's) that cast soft shadows in EEVEE without jitter: shadowed,
    render-visible, with a soft radius (an area light's size, a point or spot light's radius)
    and ``use_shadow_jitter`` off. Suns are left out: on the sky-lit room a sun's jitter changed
    nothing measurable (``apply.STAND_IN_SHADOW_SETTINGS``)."""
    if not scene.eevee.use_shadows:
        return []
    out = []
    for obj in scene.objects:
        if obj.type != "LIGHT" or obj.hide_render or obj.get(VPL_MARKER, False):
            continue
        light = obj.data
        if not light.use_shadow or light.use_shadow_jitter:
            continue
        if light.type == "SUN":
            continue
        radius = light.size if light.type == "AREA" else light.shadow_soft_size
        if radius > 0.0:
            out.append(obj.name)
    return sorted(out)


def spread_lamps(scene: bpy.types.Scene) -> list[tuple[str, float]]:
    """The user's render-visible AREA lights whose Spread is under 180 degrees, with it
    (degrees). EEVEE renders an area light as if its spread were 180 degrees (measured on the
    attic of stop 45: a rectangle light of spread 60 degrees gave EEVEE's view the light it gives
    at 180, Cycles' none; ``tests/render/test_eevee.py``), so it lights wider than in Cycles."""
    out = []
    for obj in scene.objects:
        if obj.type != "LIGHT" or obj.hide_render or obj.get(VPL_MARKER, False):
            continue
        light = obj.data
        if light.type == "AREA" and light.spread < math.pi - 1e-4:
            out.append((obj.name, math.degrees(light.spread)))
    return sorted(out)


def still_cut(scene: bpy.types.Scene, cut_lamps: Sequence[str]) -> list[str]:
    """Those of ``cut_lamps`` (``Prepared.cut_lamps``, ``apply.stored_cut_lamps``) that are
    still the user's render-visible lamps casting shadows in ``scene``: a lamp whose shadow
    was turned off since is darkened no more."""
    shadowed = {o.name for o in cut_lights.scene_lights(scene, users_only=True)}
    return [n for n in cut_lamps if n in shadowed]


def lamp_notes(scene: bpy.types.Scene, cut_lamps: Sequence[str] = ()) -> list[str]:
    """One line each on what EEVEE shows of the user's own lamps differently from Cycles, that
    the user can change and vplace does not (the module docs); ``cut_lamps`` are those EEVEE
    darkens on the surfaces the cameras see (``Prepared.cut_lamps``)."""
    notes = []
    lamps = unjittered_lamps(scene)
    if lamps:
        notes.append(
            f"EEVEE's soft shadows of {len(lamps)} of your lamps (e.g. {lamps[0]!r}) are "
            "noisier than Cycles' without jitter (Light > Shadow > Jitter, slower to render); "
            "vplace jitters only its own stand-in lights"
        )
    spread = spread_lamps(scene)
    if spread:
        name, degrees = spread[0]
        notes.append(
            f"EEVEE ignores the Spread of {len(spread)} of your area lights (e.g. {name!r}, "
            f"{degrees:.0f} degrees): they light wider in EEVEE than in Cycles, whose light "
            "vplace's VPLs carry on"
        )
    cut = still_cut(scene, cut_lamps)
    if cut:
        notes.append(
            f"EEVEE darkens the surfaces whose plane passes through {len(cut)} of your lamps "
            f"(e.g. {cut[0]!r}): its soft shadows count the part of the lamp behind such a "
            "surface as shadowed (the Cornell box's tall block gets 0.80x Cycles' direct light); "
            "no EEVEE setting changes it but the lamp's shadow. vplace's 'Match EEVEE's direct "
            "light' (`--match-eevee`; 'Auto' by default: on where the cameras see such a "
            "surface) lets the VPL powers make up for it where that helps (on the Cornell box "
            "EEVEE's RMSE fell 21-22 % on the two views it darkens most)"
        )
    return notes


def scene_bounds(
    scene: bpy.types.Scene,
    region: apply.Region | None = None,
    *,
    collection: str = apply.COLLECTION_NAME,
) -> tuple[Vector, Vector]:
    """The box the EEVEE set-up works over: ``region``, else the region kept on the VPL
    collection ``collection`` (``apply.stored_region``: where the cameras see far less than the
    scene, as a room on a kilometre of ground), else the world-space bounds of the scene's
    render-visible meshes (vplace's lights excluded)."""
    region = region if region is not None else apply.stored_region(collection, scene)
    if region is not None:
        return Vector(region[0]), Vector(region[1])
    corners = [
        obj.matrix_world @ Vector(c)
        for obj in scene.objects
        if obj.type == "MESH" and not obj.hide_render and not obj.get(VPL_MARKER, False)
        for c in obj.bound_box
    ]
    if not corners:
        raise AddonError("the scene has no visible mesh to fit a light probe volume to")
    lo = Vector(tuple(min(c[i] for c in corners) for i in range(3)))
    hi = Vector(tuple(max(c[i] for c in corners) for i in range(3)))
    return lo, hi


def new_volume(
    scene: bpy.types.Scene,
    collection: bpy.types.Collection,
    *,
    margin: float = 1.0,
    probes: int = VOLUME_PROBES,
    capture_indirect: bool = True,
    region: apply.Region | None = None,
) -> bpy.types.Object:
    """A light probe volume over :func:`scene_bounds` (``region``) times ``margin``,
    ``probes`` along its longest side, linked to ``collection`` (not baked)."""
    lo, hi = scene_bounds(scene, region)
    size = (hi - lo) * margin
    longest = max(max(size), 1e-6)
    data = bpy.data.lightprobes.new("vplace volume", "VOLUME")
    res = [max(2, math.ceil(probes * s / longest)) for s in size]
    data.resolution_x, data.resolution_y, data.resolution_z = res
    data.capture_indirect = capture_indirect
    obj = bpy.data.objects.new("vplace volume", data)
    obj[VPL_MARKER] = True
    obj.location = (lo + hi) / 2
    obj.scale = [max(s / 2, 1e-4) for s in size]
    collection.objects.link(obj)
    return obj


def bake(scene: bpy.types.Scene, volume: bpy.types.Object) -> float:
    """Bakes ``volume`` with EEVEE (blocking); returns the seconds."""
    with override() as g:
        g.set(scene.render, "engine", eevee_engine())
        with bpy.context.temp_override(
            scene=scene, active_object=volume, object=volume, selected_objects=[volume]
        ):
            start = time.perf_counter()
            result = bpy.ops.object.lightprobe_cache_bake(subset="ACTIVE")
            seconds = time.perf_counter() - start
    if "FINISHED" not in result:
        raise AddonError(f"the light probe volume did not bake ({result})")
    return seconds


@contextmanager
def temporary_volume(
    scene: bpy.types.Scene,
    *,
    margin: float = VOLUME_MARGIN,
    probes: int = VOLUME_PROBES,
    capture_indirect: bool = True,
    region: apply.Region | None = None,
) -> Iterator[float]:
    """A light probe volume over the scene (see :func:`new_volume`), baked for the block;
    yields the bake's seconds and always removes the probe and its data again."""
    obj = new_volume(
        scene,
        scene.collection,
        margin=margin,
        probes=probes,
        capture_indirect=capture_indirect,
        region=region,
    )
    data = obj.data
    try:
        yield bake(scene, obj)
    finally:
        bpy.data.objects.remove(obj)
        if data.users == 0:
            bpy.data.lightprobes.remove(data)


@contextmanager
def users_sun(
    scene: bpy.types.Scene,
    suns: Sequence[SunLight | None],
    frames: Sequence[int] | None = None,
) -> Iterator[bool]:
    """For a render of EEVEE's own GI, the alternative a user would pick instead of vplace's
    lights: where the world has a sun (vplace's ``SunLight``, found in the world image), the SUN
    lamp a user adds, because EEVEE extracts next to nothing from such a sky (the sky-lit room,
    EEVEE ray tracing + volume: 0.035x Cycles' light at its default sun threshold, 0.063x at a
    threshold of 1, whose extracted sun peaks at 1.4 where Cycles' patches reach 7.2). The lamp
    is vplace's sun stand-in (its direction, irradiance and angle; with ``frames``, one sun per
    frame keyed over them as the keyed write-back keys it), written unmarked so the render and
    its cache key count it as the user's, with EEVEE's own extraction off, for the block; it is
    removed after. Bake a volume inside the block so it captures the sun's bounce. Yields
    whether a lamp was written (no sun: nothing changes)."""
    lit = [s for s in suns if s is not None]
    world = scene.world
    if not lit or world is None:
        yield False
        return
    coll = bpy.data.collections.new(USERS_SUN_COLLECTION)
    scene.collection.children.link(coll)
    try:
        if frames is None:
            apply.new_sun_object(coll, lit[0])
        else:
            keyed.write_keyed_sun(coll, frames, suns, lit[0])
        for obj in coll.objects:
            del obj[VPL_MARKER], obj["vplace_world_sun"]
        with override() as g:
            g.set(world, "sun_threshold", 0.0)
            yield True
    finally:
        for obj in coll.objects:
            obj[VPL_MARKER] = True  # what apply removes
        apply.remove_collection(coll)


@contextmanager
def world_for_render(
    scene: bpy.types.Scene,
    *,
    probes: int = VOLUME_PROBES,
    portals: bool | None = None,
    region: apply.Region | None = None,
) -> Iterator[float]:
    """For a render of the written lights as :func:`set_up` would leave the scene: with sky
    portals or in a closed room, the world for the camera only (:func:`camera_only`) for the
    block; else, when the world emits and vplace has baked no volume, a temporary one without
    indirect light (the world's light, occluded). ``portals``: whether the lights rendered in
    the block have sky portals or light a closed room (None: :func:`world_shut_out` of the
    scene now); the volume spans :func:`scene_bounds`
    (``region``). Yields the volume's bake seconds (0.0 when none is baked)."""
    world = scene.world
    if portals is None:
        portals = world_shut_out(scene)
    if portals and world is not None:
        if is_camera_only(world):
            yield 0.0
            return
        if camera_only(world) is None:
            try:
                yield 0.0
            finally:
                remove_camera_only(world)
            return
        # The world cannot be kept from lighting: the portals are left out, as before them.
        with override() as g:
            for obj in portal_lights(scene):
                g.set(obj, "hide_render", True)
            with world_for_render(scene, probes=probes, portals=False, region=region) as seconds:
                yield seconds
    elif world_emits(scene) and vplace_volume(scene) is None:
        with temporary_volume(
            scene, probes=probes, capture_indirect=False, region=region
        ) as seconds:
            yield seconds
    else:
        yield 0.0


def _probe_collection(scene: bpy.types.Scene) -> bpy.types.Collection:
    """A fresh, empty probe collection of vplace's, linked to ``scene`` in place of the one
    vplace made there before (never another scene's). Its caller, :func:`set_up`, has refused a
    collection of the user's of that name before changing anything."""
    old = apply.scene_collection(scene, PROBE_COLLECTION)
    if old is not None:
        for obj in list(old.objects):
            data = obj.data
            bpy.data.objects.remove(obj)
            if data is not None and data.users == 0:
                bpy.data.lightprobes.remove(data)
        bpy.data.collections.remove(old)
    coll = bpy.data.collections.new(PROBE_COLLECTION)
    coll[VPL_MARKER] = True
    coll[apply.ROLE_KEY] = PROBE_COLLECTION
    scene.collection.children.link(coll)
    return coll


def shadow_rays_for(scene: bpy.types.Scene) -> int | None:
    """The shadow rays EEVEE traces per light for ``scene``'s soft shadows once set up: at least
    :data:`SHADOW_RAYS`, more where the user chose more; None where this Blender has no such
    setting."""
    e = scene.eevee
    if not hasattr(e, "shadow_ray_count"):
        return None
    return max(int(e.shadow_ray_count), SHADOW_RAYS)


def fast_gi_for(
    scene: bpy.types.Scene, collection: str = apply.COLLECTION_NAME
) -> tuple[str, float]:
    """The fast GI that shows the written lights as the evaluator computes them: with the
    near-field distance the VPL collection ``collection`` keeps (``apply.stored_near_field``),
    global illumination within that distance (the light between nearby surfaces that no VPL
    carries, ``vplace.evaluate(..., near_field=True)``); without, ambient occlusion only.
    Either way no second bounce from beyond the distance, which the VPLs carry."""
    near = apply.stored_near_field(collection, scene)
    return ("GLOBAL_ILLUMINATION", near) if near > 0.0 else ("AMBIENT_OCCLUSION_ONLY", 0.0)


def set_up(scene: bpy.types.Scene, *, bake_volume: bool = True) -> list[str]:
    """Applies the settings of the module docs to ``scene`` (EEVEE settings; with sky portals
    or in a closed room an EEVEE-only World Output, :func:`camera_only`; else a probe volume in
    its own collection when the world emits, baked unless ``bake_volume`` is false) and returns
    what it changed, in words. The user's own objects are not touched."""
    e = scene.eevee
    changed: list[str] = []
    # What would stop it half-way, found before anything changes: a collection of the user's
    # with the probes' name; an emitting world with no mesh to fit a probe volume to.
    user = bpy.data.collections.get(PROBE_COLLECTION)
    if user is not None and not user.get(VPL_MARKER, False):
        raise AddonError(
            f"a collection named {PROBE_COLLECTION!r} exists but was not made by vplace; rename it"
        )
    if world_emits(scene):
        scene_bounds(scene)

    def put(struct: object, attr: str, value: object, label: str) -> None:
        if getattr(struct, attr) != value:
            setattr(struct, attr, value)
            changed.append(f"{label} = {value!r}")

    put(e, "use_shadows", True, "scene.eevee.use_shadows")
    put(e, "light_threshold", threshold_for(scene), "scene.eevee.light_threshold")
    mb = pool_for(shadow_pages(scene))
    if int(e.shadow_pool_size) < mb:
        put(e, "shadow_pool_size", str(mb), "scene.eevee.shadow_pool_size")
    rays = shadow_rays_for(scene)
    if rays is not None:
        put(e, "shadow_ray_count", rays, "scene.eevee.shadow_ray_count")
    put(e, "use_raytracing", True, "scene.eevee.use_raytracing")
    if hasattr(e, "use_fast_gi"):  # Blender 4.5 on
        put(e, "use_fast_gi", True, "scene.eevee.use_fast_gi")
    method, near = fast_gi_for(scene)
    put(e, "fast_gi_method", method, "scene.eevee.fast_gi_method")
    if near > 0.0:
        put(e, "fast_gi_distance", near, "scene.eevee.fast_gi_distance")
    if scene.world is not None and apply.world_sun_light(scene):
        put(scene.world, "sun_threshold", 0.0, "world.sun_threshold")
    shut = world_shut_out(scene)
    if not shut and is_camera_only(scene.world):
        remove_camera_only(scene.world)
        changed.append("the world lights EEVEE again (vplace wrote no sky portals)")
    if shut and scene.world is not None and not is_camera_only(scene.world):
        why = camera_only(scene.world)
        if why is None:
            changed.append(
                "the world lights EEVEE through vplace's sky portals only (an EEVEE World "
                "Output that shows it to the camera)"
                if portal_lights(scene)
                else "the world lights nothing in EEVEE, as in Cycles, since the cameras are "
                "in a closed room (an EEVEE World Output that shows it to the camera)"
            )
        else:  # as before the portals: they are hidden, the world's volume occludes it
            for obj in portal_lights(scene):
                obj.hide_render = True
            changed.append(f"hid the sky portals ({why}: the world would count twice)")
    portals = shut and is_camera_only(scene.world)
    if world_emits(scene) and not portals:
        coll = _probe_collection(scene)
        volume = new_volume(scene, coll, margin=VOLUME_MARGIN, capture_indirect=False)
        changed.append(f"added the light probe volume {volume.name!r} (world light, occluded)")
        if bake_volume:
            seconds = bake(scene, volume)
            changed.append(f"baked it in {seconds:.1f} s")
    return changed
