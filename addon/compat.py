"""What differs between the Blenders the manifest names (4.2 LTS to 5.2 LTS), in one place.

- Before Blender 5.0 a new material or world has no node tree until ``use_nodes`` is set; from
  5.0 every one has its tree and ``use_nodes`` is deprecated (:func:`new_material`,
  :func:`new_world`).
- EEVEE's engine is ``BLENDER_EEVEE_NEXT`` in 4.2 to 4.5, ``BLENDER_EEVEE`` from 5.0
  (:func:`eevee_engine`).
- A multilayer EXR names its passes ``DiffDir``, ``Emit``, ... before 5.0 and ``Diffuse
  Direct``, ``Emission``, ... from 5.0 (:data:`PASS_NAMES`).
- An action keeps its F-curves in ``action.fcurves`` before 4.4 and in the channelbags of its
  layers' strips from 4.4 (layered actions; ``action.fcurves`` is gone in 5.0)
  (:func:`action_fcurves`).
"""

from __future__ import annotations

from typing import TypeVar

import bpy

T = TypeVar("T", bpy.types.Material, bpy.types.World)


def _with_nodes(idblock: T) -> T:
    if idblock.node_tree is None:  # Blender before 5.0
        idblock.use_nodes = True
    return idblock


def uses_nodes(idblock: bpy.types.ID) -> bool:
    """Whether a material or world renders its node tree (from Blender 5.0 always; before, when
    ``use_nodes`` is on)."""
    if idblock.node_tree is None:
        return False
    return bpy.app.version >= (5, 0, 0) or bool(idblock.use_nodes)


def new_material(name: str) -> bpy.types.Material:
    """A new material with Blender's default node tree (a Principled BSDF into the output)."""
    return _with_nodes(bpy.data.materials.new(name))


def new_world(name: str) -> bpy.types.World:
    """A new world with Blender's default node tree (a Background into the output)."""
    return _with_nodes(bpy.data.worlds.new(name))


#: The pass names of a multilayer EXR before Blender 5.0 -> from 5.0.
PASS_NAMES = {
    "DiffDir": "Diffuse Direct",
    "DiffInd": "Diffuse Indirect",
    "DiffCol": "Diffuse Color",
    "GlossDir": "Glossy Direct",
    "GlossInd": "Glossy Indirect",
    "GlossCol": "Glossy Color",
    "Emit": "Emission",
    "Env": "Environment",
}


def eevee_engine() -> str:
    """EEVEE's ``render.engine`` name in this Blender."""
    engines = bpy.types.RenderSettings.bl_rna.properties["engine"].enum_items.keys()
    return "BLENDER_EEVEE_NEXT" if "BLENDER_EEVEE_NEXT" in engines else "BLENDER_EEVEE"


def action_fcurves(action: bpy.types.Action) -> list[bpy.types.FCurve]:
    """Every F-curve of ``action``, in either layout (see the module docs)."""
    curves = list(getattr(action, "fcurves", None) or [])
    for layer in getattr(action, "layers", None) or []:
        for strip in layer.strips:
            for bag in getattr(strip, "channelbags", None) or []:
                curves.extend(bag.fcurves)
    return curves


def make_keys_linear(id_data: bpy.types.ID) -> int:
    """Makes every key of ``id_data``'s action linear; returns how many keys."""
    anim = id_data.animation_data
    if anim is None or anim.action is None:
        return 0
    count = 0
    for fcurve in action_fcurves(anim.action):
        for key in fcurve.keyframe_points:
            key.interpolation = "LINEAR"
            count += 1
    return count
