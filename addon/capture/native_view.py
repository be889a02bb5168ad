"""A capture as a ``vplace.View``, the mask of the pixels whose glossy layer vplace models, and
whether it models them at all (the written VPLs' specular factor)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from ..native import vplace

if TYPE_CHECKING:
    from ..scene.export import ExportedScene
    from .passes import Capture


def gloss_mask(scene: vplace.Scene, exported: ExportedScene, cap: Capture) -> np.ndarray | None:
    """(H, W) float32: 1 where the pixel's surface has a glossy layer vplace models (rough:
    ``export.ROUGH_GLOSS``), 0 where it is left to EEVEE's ray tracing; None when no material
    has a rough glossy layer. A surface without a glossy layer has a black Glossy Color pass, so
    only a scene with sharp layers needs to know which surface each pixel sees: a short ray
    along the view direction finds it in ``scene``."""
    rough, sharp = exported.rough_gloss, exported.sharp_gloss
    if not rough.any():
        return None
    mask = cap.covered.astype(np.float32)
    if not sharp.any():
        return mask
    ys, xs = np.nonzero(cap.covered)
    target = cap.position[ys, xs].astype(np.float32)
    look = target - np.asarray(cap.camera_position, dtype=np.float32)
    look /= np.maximum(np.linalg.norm(look, axis=1, keepdims=True), 1e-12)
    back = np.float32(1e-3 * scene.scale)
    _, tri, _ = scene.intersect(
        np.ascontiguousarray(target - back * look), np.ascontiguousarray(look)
    )
    hit = tri >= 0
    mat = exported.material_ids[np.where(hit, tri, 0)]
    mask[ys, xs] = np.where(hit & sharp[mat], 0.0, 1.0)
    return mask


def vpl_specular(
    exported: ExportedScene,
    captures: Sequence[Capture],
    masks: Sequence[np.ndarray | None],
) -> float:
    """The written VPLs' specular factor, 1 or 0, from the captures and their
    :func:`gloss_mask`; with 0 vplace models no glossy layer (the callers then pass no mask),
    so the evaluator shows what EEVEE does.

    EEVEE gives a light's specular to every surface alike. On a rough glossy layer
    (``export.ROUGH_GLOSS``) it is the broad glossy bounce the evaluator counts. On a sharp one,
    left to EEVEE's ray tracing (which already reflects the lit room), each VPL's disk shows as
    a mirrored spot: on a floor of roughness 0.15 seen at a grazing angle, 0.42 % of the pixels
    hot (ARCHITECTURE.md, "Glossy light"). So the factor is 1 when some material has a rough
    glossy layer and the captured views show at least as much glossy indirect light (Cycles'
    Glossy Indirect x Glossy Color, luminance) on rough layers as on sharp ones; else 0."""
    if not exported.rough_gloss.any():
        return 0.0
    if not exported.sharp_gloss.any():
        return 1.0
    lum = np.asarray(vplace.LUMINANCE, dtype=np.float32)
    rough = sharp = 0.0
    for cap, mask in zip(captures, masks, strict=True):
        assert mask is not None  # some layer is rough
        glossy = (cap.glossy_indirect * cap.glossy_color)[..., :3] @ lum
        rough += float(glossy[cap.covered & (mask > 0)].sum())
        sharp += float(glossy[cap.covered & (mask == 0)].sum())
    return 1.0 if rough >= sharp else 0.0


def view_of(
    cap: Capture,
    *,
    held_out: bool = False,
    gloss: np.ndarray | None = None,
    offset: np.ndarray | None = None,
) -> vplace.View:
    """The ``vplace.View`` of a capture; ``held_out`` leaves out its global-illumination passes
    (what a view the model has not seen provides). ``gloss`` (:func:`gloss_mask`) adds the
    rough glossy layers to the receivers' reflectance and to the indirect light to match.
    ``offset`` ((H, W, 3)) is added to the indirect light the VPLs are fitted to (EEVEE's
    direct-light deficit: ``writeback.match_eevee``)."""
    indirect = None
    if not held_out:
        indirect = cap.modelled_indirect(gloss)
        if offset is not None:
            indirect = np.ascontiguousarray(indirect + offset, dtype=np.float32)
    return vplace.View(
        position=cap.position,
        normal=cap.normal,
        albedo=cap.reflectance(gloss),
        covered=cap.covered,
        depth=cap.depth,
        direct=cap.direct,
        diffuse_direct=cap.diffuse_direct,
        diffuse_indirect=None if held_out else cap.diffuse_indirect,
        indirect=indirect,
        specular=cap.glossy_color,
        camera_position=cap.camera_position,
        world_to_clip=cap.world_to_clip,
        name=cap.camera,
    )
