"""A capture as a ``vplace.View``, the mask of the pixels whose glossy layer vplace models,
whether it models them at all (the written VPLs' specular factor), and the objects the written
VPLs must not light."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from ..native import vplace
from ..scene.export import ROUGH_GLOSS

if TYPE_CHECKING:
    from ..scene.export import ExportedScene
    from .passes import Capture


def gloss_mask(scene: vplace.Scene, exported: ExportedScene, cap: Capture) -> np.ndarray | None:
    """(H, W) float32: 1 where the pixel's surface has a glossy layer vplace models (rough:
    ``export.ROUGH_GLOSS``), 0 where it is left to EEVEE's ray tracing; None when no material
    has a rough glossy layer. A surface without a glossy layer has a black Glossy Color pass, so
    only a scene with sharp layers needs to know which surface each pixel sees
    (:func:`pixel_materials`)."""
    rough, sharp = exported.rough_gloss, exported.sharp_gloss
    if not rough.any():
        return None
    mask = cap.covered.astype(np.float32)
    if not sharp.any():
        return mask
    mat = pixel_materials(scene, exported, cap)
    mask[cap.covered] = np.where((mat >= 0) & sharp[np.maximum(mat, 0)], 0.0, 1.0)[cap.covered]
    return mask


def pixel_materials(scene: vplace.Scene, exported: ExportedScene, cap: Capture) -> np.ndarray:
    """(H, W) int64: the index into ``exported.materials`` of the surface each covered pixel
    sees, -1 where none is found (and where the pixel is not covered): a short ray along the
    view direction from just in front of the pixel's position finds it in ``scene``."""
    out = np.full(cap.covered.shape, -1, dtype=np.int64)
    ys, xs = np.nonzero(cap.covered)
    target = cap.position[ys, xs].astype(np.float32)
    look = target - np.asarray(cap.camera_position, dtype=np.float32)
    look /= np.maximum(np.linalg.norm(look, axis=1, keepdims=True), 1e-12)
    back = np.float32(1e-3 * scene.scale)
    _, tri, _ = scene.intersect(
        np.ascontiguousarray(target - back * look), np.ascontiguousarray(look)
    )
    hit = tri >= 0
    out[ys, xs] = np.where(hit, exported.material_ids[np.where(hit, tri, 0)].astype(np.int64), -1)
    return out


def vpl_specular(
    scene: vplace.Scene,
    exported: ExportedScene,
    captures: Sequence[Capture],
    masks: Sequence[np.ndarray | None],
) -> float:
    """The written VPLs' specular factor, 1 or 0, from the captures and their
    :func:`gloss_mask`; with 0 vplace models no glossy layer (the callers then pass no mask),
    so the evaluator shows what EEVEE does.

    EEVEE gives a light's specular to every surface it lights alike. On a rough glossy layer
    (``export.ROUGH_GLOSS``) it is the broad glossy bounce the evaluator counts. On a sharp one,
    left to EEVEE's ray tracing (which already reflects the lit room), each VPL's disk shows as
    a mirrored spot: on a floor of roughness 0.15 seen at a grazing angle, 0.42 % of the pixels
    hot (ARCHITECTURE.md, "Glossy light"). So the factor is 1 when some material has a rough
    glossy layer and the captured views show at least as much glossy indirect light (Cycles'
    Glossy Indirect x Glossy Color, luminance) on rough layers as on the sharp ones the VPLs
    would light; else 0. The objects :func:`vpl_unlit` leaves out with the factor 1 (metal,
    glass) do not count: the VPLs light them not at all."""
    if not exported.rough_gloss.any():
        return 0.0
    if not exported.sharp_gloss.any():
        return 1.0
    spared = spared_materials(exported)
    lum = np.asarray(vplace.LUMINANCE, dtype=np.float32)
    rough = sharp = 0.0
    for cap, mask in zip(captures, masks, strict=True):
        assert mask is not None  # some layer is rough
        glossy = (cap.glossy_indirect * cap.glossy_color)[..., :3] @ lum
        rough += float(glossy[cap.covered & (mask > 0)].sum())
        lit = cap.covered & (mask == 0)
        if spared.any():
            mat = pixel_materials(scene, exported, cap)
            lit &= ~((mat >= 0) & spared[np.maximum(mat, 0)])
        sharp += float(glossy[lit].sum())
    return 1.0 if rough >= sharp else 0.0


#: A sharp glossy object is left unlit by the VPLs (:func:`vpl_unlit`) when its diffuse albedo
#: is at most this fraction of its glossy layer's reflectance (both their luminance): what the
#: object then loses of the VPLs' diffuse light, which the evaluator counts, is at most 2 % of
#: the highlights it is spared, which the evaluator does not count. Metal and glass have none.
UNLIT_DIFFUSE = 0.02


def _dark_sharp(exported: ExportedScene) -> np.ndarray:
    """(M,) bool: the materials with a sharp glossy layer and next to no diffuse albedo
    (:data:`UNLIT_DIFFUSE`)."""
    lum = np.asarray(vplace.LUMINANCE, dtype=np.float64)
    return np.array(
        [
            m.gloss_roughness is not None
            and m.gloss_roughness < ROUGH_GLOSS
            and m.gloss is not None
            and float(np.dot(m.albedo, lum)) <= UNLIT_DIFFUSE * float(np.dot(m.gloss, lum))
            for m in exported.materials
        ],
        dtype=bool,
    )


def _unlit(exported: ExportedScene, dark: np.ndarray) -> list[str]:
    """The objects whose every material is ``dark`` (:func:`_dark_sharp`)."""
    return sorted(
        name
        for name, mats in exported.object_materials.items()
        if mats and all(dark[m] for m in mats)
    )


def spared_materials(exported: ExportedScene) -> np.ndarray:
    """(M,) bool: the materials only :func:`_unlit` objects show (no other object, no
    instance)."""
    out = _dark_sharp(exported)
    unlit = set(_unlit(exported, out))
    for name, mats in exported.object_materials.items():
        if name not in unlit:
            out[list(mats)] = False
    out[list(exported.instanced_materials)] = False
    return out


def vpl_unlit(exported: ExportedScene, specular: float) -> list[str]:
    """The objects the written VPLs must not light (``apply.write_vpls``' ``unlit``: a Light
    Linking receiver collection that excludes them): with specular factor ``specular`` > 0,
    each object of ``exported.object_materials`` whose every material has a sharp glossy layer
    (``export.sharp_gloss``) and next to no diffuse albedo (:data:`UNLIT_DIFFUSE`): chrome,
    polished metal, glass.

    The evaluator counts no VPL light on such a surface (its reflectance is the Diffuse Color
    pass, black on a metal; the sharp layer is left to EEVEE's ray tracing). EEVEE gives it
    each VPL's specular all the same: a bright mirrored disk per VPL where the truth reflects
    the lit room (a metal cube of roughness 0.3 in a studio whose floor and walls are rough
    enough for specular 1: 1.02 % of a held-out view's pixels hot, 68 % of its squared error in
    EEVEE's VPL light). Unlit, it shows what the evaluator computed, and its reflection is
    EEVEE's ray tracing's (``eevee_setup.set_up``). Objects drawn as instances are lit as
    before (``export.ExportedScene.object_materials``)."""
    return _unlit(exported, _dark_sharp(exported)) if specular > 0.0 else []


#: Samples per pixel and emitter of :func:`metal_irradiance` (``vplace.direct_light``).
METAL_SAMPLES = 16


def metal_irradiance(
    scene: vplace.Scene, cap: Capture, gloss: np.ndarray | None
) -> np.ndarray | None:
    """(H, W, 3) vplace's own direct irradiance over pi (``vplace.direct_light``, with shadow
    rays) at the pixels where the diffuse passes do not measure it (``Capture.glossy_stand_in``:
    a rough metal's), 0 elsewhere; None where there are none. Cycles' ``GlossDir`` would stand
    in there too, but it depends on the view: on Sponza's curtains it read 1.5 times vplace's
    estimate, and the written lights lost .0075 SSIM on a held-out view."""
    stand_in = cap.glossy_stand_in(gloss)
    covered = cap.covered & (stand_in > 0.0)
    if not covered.any():
        return None
    zeros = np.zeros_like(cap.diffuse_direct)
    view = vplace.View(
        albedo=cap.albedo, covered=covered, direct=zeros, diffuse_direct=zeros, **_geometry(cap)
    )
    return vplace.direct_light(scene, view, samples=METAL_SAMPLES, seed=0)


def _geometry(cap: Capture) -> dict[str, Any]:
    """The ``vplace.View`` arguments every view of ``cap`` shares: its G-buffer's position,
    normal and depth, and its camera."""
    return {
        "position": cap.position,
        "normal": cap.normal,
        "depth": cap.depth,
        "camera_position": cap.camera_position,
        "world_to_clip": cap.world_to_clip,
        "name": cap.camera,
    }


def view_of(
    cap: Capture,
    *,
    held_out: bool = False,
    gloss: np.ndarray | None = None,
    offset: np.ndarray | None = None,
    scene: vplace.Scene | None = None,
) -> vplace.View:
    """The ``vplace.View`` of a capture; ``held_out`` leaves out its global-illumination passes
    (what a view the model has not seen provides). ``gloss`` (:func:`gloss_mask`) adds the
    rough glossy layers to the receivers' reflectance and to the indirect light to match, and
    takes the irradiance where a surface has next to no diffuse layer from vplace's own direct
    light in ``scene`` (:func:`metal_irradiance`; without ``scene``, the glossy passes) and the
    glossy indirect pass (:meth:`Capture.reflected_irradiance`). ``offset`` ((H, W, 3)) is
    added to the indirect light the VPLs are fitted to (EEVEE's direct-light deficit:
    ``writeback.match_eevee``)."""
    indirect = None
    direct = metal_irradiance(scene, cap, gloss) if scene is not None else None
    diffuse_direct, diffuse_indirect = cap.reflected_irradiance(gloss, direct)
    if not held_out:
        indirect = cap.modelled_indirect(gloss)
        if offset is not None:
            indirect = np.ascontiguousarray(indirect + offset, dtype=np.float32)
    return vplace.View(
        albedo=cap.reflectance(gloss),
        covered=cap.covered,
        direct=cap.direct,
        diffuse_direct=diffuse_direct,
        diffuse_indirect=None if held_out else diffuse_indirect,
        indirect=indirect,
        specular=cap.glossy_color,
        # The Diffuse Color where the reflectance adds a glossy layer to it; else it is the albedo.
        diffuse_color=None if gloss is None else cap.diffuse_color,
        **_geometry(cap),
    )
