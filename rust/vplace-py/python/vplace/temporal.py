"""Lights over frames, without Blender (issue 23): the temporal error of an image sequence,
VPLs matched from frame to frame into *slots* (one Blender light each, keyed over the frames),
and the keyed lights at any frame between the captured ones, as Blender interpolates them.

- :func:`temporal_error`: the mean over frames ``t`` of the mean over pixels of
  ``|(E_t - E_{t-1}) - (T_t - T_{t-1})|`` (luminance of linear RGB), over the truth's mean
  luminance (all frames). A sequence that changes exactly as the truth does scores 0 whatever
  its per-frame error; a flicker the truth lacks scores its amplitude.
- :func:`track`: frame ``t``'s lit VPLs are matched to the slots greedily by cost: the
  position's move plus :data:`NORMAL_WEIGHT` scene diagonals times ``1 - cos`` of the normals'
  angle, in patch radii (the larger of the pair's: the radius of the surface patch each
  VPL stands for, its disk's ``VplSet.radii`` over ``sqrt(DISK_PATCHES)``). Cheapest pair
  first, each slot's last lit VPL standing for it; a pair dearer than :data:`MAX_MATCH_COST`
  (a move beyond the patch) is not matched: that VPL opens a new slot (0 W before) and the
  slot goes dark (0 W) on that frame. A dark slot keeps the position, normal, colour and disk
  of its nearest lit frame, so it fades in or out where it stands. Why the patch: a light that
  moves within its patch keeps lighting what it lit; one that moves farther sweeps its light,
  between the frames, over surfaces that neither frame's layout lights (measured: README,
  "Keyed lights that do not sweep").
- :func:`shared_layout`: one set of VPL *positions* for every captured frame, with each frame's
  *powers* refitted on that frame's captures. Each frame lays out ``n // F`` VPLs for its own
  light (``vplace.job.lay_out``: fit, layout, refit); the union of the F layouts is the set (so
  every frame's lit places have VPLs), each flux over F as the refit's prior (F layouts carry F
  times the light); then each frame refits every power on its own captures, as the still
  layout refits (``vplace.job.refit_powers``: at its stride; without the coverage views'
  penalty, which would hold VPLs at other frames' powers; README, "Each frame's refit is the
  still layout's"); frames whose light alone differs trace the refit's shadow rays once for
  all (``vplace.job.refit_frame_powers``). The keyed lights then stand still and only their
  powers change. Why: a frame's own layout differs from the next frame's in the places it
  picks, and that change is what flickers. Capturing more frames
  made the keyed lights flicker more, not less (evaluator temporal error, step 4 -> 2 -> 1:
  ``cornell_moving`` .0105 -> .0159 -> .0299, ``skyroom_afternoon`` .0332 -> .0440 -> .0664),
  while positions shared over the captured frames gave .0060 and .0230 at step 4 (README,
  "Keyed lights that stand still").
- :func:`at_frame`: the keyed lights at a frame, linear between the captured frames, as
  Blender evaluates linear keys: position, energy, colour and disk size each interpolated, the
  rotation's quaternion component by component (here its normal, interpolated and
  normalized). So a light that fades out beside one that fades in gives, half way, the mean
  of the two frames' light.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

import vplace
import vplace.job

#: The weight of ``1 - cos(angle between normals)`` in the matching cost, against the distance
#: in scene diagonals: a VPL turned by 90 degrees costs what one moved by half a diagonal does.
NORMAL_WEIGHT = 0.5
#: The dearest pair that is still matched, in patch radii (the move plus the normal term, over
#: the larger patch radius of the two, ``VplSet.radii`` over ``sqrt(DISK_PATCHES)``): a VPL
#: that moves within the patch it stands for keeps its light where it was; one that moves
#: farther would sweep its light over surfaces that neither frame lights, so it fades out where
#: it stands and another fades in.
MAX_MATCH_COST = 1.0
#: The smallest patch radius of the matching cost, in scene diagonals (omni VPLs are points).
MIN_PATCH_DIAGONALS = 0.01


def _luminance(image: np.ndarray) -> np.ndarray:
    return np.asarray(image, dtype=np.float64)[..., :3] @ np.asarray(vplace.LUMINANCE)


def temporal_error(
    images: Sequence[np.ndarray], truths: Sequence[np.ndarray], *, over: float | None = None
) -> float:
    """The temporal error of ``images`` against ``truths`` (see the module docs): two sequences
    of (H, W, 3) linear images of at least two frames, of one shape. ``over``: the luminance
    to divide by instead of the truths' mean (to compare a part of an image with the whole)."""
    return float(temporal_steps(images, truths, over=over).mean())


def temporal_steps(
    images: Sequence[np.ndarray], truths: Sequence[np.ndarray], *, over: float | None = None
) -> np.ndarray:
    """Each step's term of :func:`temporal_error` (F - 1 values: frame t against t - 1), each
    over the truth's mean luminance of all frames (or ``over``); their mean is the temporal
    error."""
    if len(images) != len(truths):
        raise ValueError(f"{len(images)} images against {len(truths)} truth frames")
    if len(images) < 2:
        raise ValueError("the temporal error needs at least two frames")
    e = np.stack([_luminance(i) for i in images])
    t = np.stack([_luminance(i) for i in truths])
    if e.shape != t.shape:
        raise ValueError(f"images of shape {e.shape[1:]} against truths of shape {t.shape[1:]}")
    mean_truth = max(float(t.mean()) if over is None else float(over), 1e-12)
    change = np.abs(np.diff(e, axis=0) - np.diff(t, axis=0))
    return change.mean(axis=(1, 2)) / mean_truth


@dataclass
class Keyed:
    """Slots over frames: arrays (F, S, ...) for F frames and S slots. ``power`` is the
    Blender power (W, RGB) a slot's light has on each frame (0 when dark), ``flux`` its VPL's
    flux; ``index`` the VPL of that frame's set in the slot (-1 when dark)."""

    position: np.ndarray
    normal: np.ndarray
    power: np.ndarray
    flux: np.ndarray
    index: np.ndarray
    #: (F, S, 3) the colour a slot keeps where it is dark: its nearest lit frame's.
    held_color: np.ndarray
    profile: str
    radius: float
    #: (F, S) each slot's near-field radius on each frame: its VPL's in that frame's set
    #: (``VplSet.radii``; a dark frame keeps its nearest lit frame's), keyed as the disk's size.
    radii: np.ndarray
    #: The frames' own sets: :func:`at_frame` at a captured frame is that frame's lights.
    sets: list[vplace.VplSet]

    @property
    def lit(self) -> np.ndarray:
        """(F, S) whether a slot's light gives anything on a frame."""
        return self.index >= 0

    @property
    def energy(self) -> np.ndarray:
        """(F, S) the light's keyed energy: the largest channel of its power."""
        return self.power.max(axis=2)

    @property
    def color(self) -> np.ndarray:
        """(F, S, 3) the light's keyed colour, ``power / energy``; a dark frame keeps the
        colour of its nearest lit frame."""
        e = self.energy[..., None]
        return np.where(e > 0, self.power / np.maximum(e, 1e-30), self.held_color)


def _cost(
    pos_a: np.ndarray,
    nrm_a: np.ndarray,
    rad_a: np.ndarray,
    pos_b: np.ndarray,
    nrm_b: np.ndarray,
    rad_b: np.ndarray,
    diagonal: float,
) -> np.ndarray:
    """(A, B) matching costs (see the module docs): the move plus the normal term, in patch
    radii (the larger of the pair's, at least :data:`MIN_PATCH_DIAGONALS` of the diagonal).
    ``rad_a`` and ``rad_b`` are the disks' radii (``VplSet.radii``); a disk covers
    ``vplace.DISK_PATCHES`` patches, so its patch's radius is that over their square root."""
    d = np.linalg.norm(pos_a[:, None, :] - pos_b[None, :, :], axis=2)
    turn = NORMAL_WEIGHT * diagonal * (1.0 - nrm_a @ nrm_b.T)
    disk = np.maximum(rad_a[:, None], rad_b[None, :])
    patch = np.maximum(disk / np.sqrt(vplace.DISK_PATCHES), MIN_PATCH_DIAGONALS * diagonal)
    return (d + turn) / np.maximum(patch, 1e-12)


def greedy_match(cost: np.ndarray, max_cost: float = MAX_MATCH_COST) -> np.ndarray:
    """For each column of ``cost`` (A, B), the row it is matched to or -1: pairs taken
    cheapest first (ties by row then column), each row and column once, none dearer than
    ``max_cost``."""
    rows, cols = cost.shape
    out = np.full(cols, -1, dtype=np.int64)
    if rows == 0 or cols == 0:
        return out
    flat = cost.ravel()
    order = np.argsort(flat, kind="stable")
    taken = np.zeros(rows, dtype=bool)
    left = min(rows, cols)
    for k in order:
        if flat[k] > max_cost or left == 0:
            break
        r, c = divmod(int(k), cols)
        if taken[r] or out[c] >= 0:
            continue
        taken[r] = True
        out[c] = r
        left -= 1
    return out


def track(sets: Sequence[vplace.VplSet], diagonal: float) -> Keyed:
    """The VPLs of ``sets`` (one set per frame, in frame order, one profile and radius) matched
    into slots (see the module docs); ``diagonal`` is the scene's size (its working scale,
    ``Scene.scale``). Deterministic: the same sets give the same slots. Sets that share their
    positions and normals (:func:`shared_layout`'s) are matched VPL by VPL: each light stands
    where it stands on every frame, whichever of its neighbours a frame's refit switched off."""
    if not sets:
        raise ValueError("no frames to track")
    profile, radius = sets[0].profile, sets[0].radius
    for f, vpls in enumerate(sets):
        if vpls.profile != profile:
            raise ValueError(f"frame {f}'s VPLs are {vpls.profile}, the first frame's {profile}")
    own = [np.asarray(v.radii, dtype=np.float64) for v in sets]
    lit_of = [np.flatnonzero(np.asarray(v.blender_power).max(axis=1) > 0) for v in sets]
    shared = all(
        len(v) == len(sets[0])
        and np.array_equal(v.position, sets[0].position)
        and np.array_equal(v.normal, sets[0].normal)
        for v in sets
    )
    # Per slot: frame -> VPL index.
    if shared:
        members: list[dict[int, int]] = []
        lit_sets = [set(lit.tolist()) for lit in lit_of]
        for i in range(len(sets[0])):
            got = {f: i for f, lit in enumerate(lit_sets) if i in lit}
            if got:
                members.append(got)
    else:
        members = _match_by_position(sets, lit_of, own, diagonal)
    frames, slots = len(sets), len(members)
    position = np.zeros((frames, slots, 3))
    normal = np.zeros((frames, slots, 3))
    normal[..., 2] = 1.0
    power = np.zeros((frames, slots, 3))
    flux = np.zeros((frames, slots, 3))
    index = np.full((frames, slots), -1, dtype=np.int64)
    held = np.ones((frames, slots, 3))
    radii = np.zeros((frames, slots))
    for s, got in enumerate(members):
        lit_frames = sorted(got)
        for f in range(frames):
            # The frame's own VPL, else the nearest lit frame's (the earlier on a tie).
            g = min(lit_frames, key=lambda k, f=f: (abs(k - f), k))
            vpls, i = sets[g], got[g]
            position[f, s] = vpls.position[i]
            normal[f, s] = vpls.normal[i]
            radii[f, s] = own[g][i]
            p = np.asarray(vpls.blender_power[i], dtype=np.float64)
            held[f, s] = p / max(float(p.max()), 1e-30)
            if g == f:
                power[f, s] = p
                flux[f, s] = vpls.flux[i]
                index[f, s] = i
    return Keyed(position, normal, power, flux, index, held, profile, radius, radii, list(sets))


def _match_by_position(
    sets: Sequence[vplace.VplSet],
    lit_of: Sequence[np.ndarray],
    own: Sequence[np.ndarray],
    diagonal: float,
) -> list[dict[int, int]]:
    """:func:`track`'s slots of sets laid out on their own: frame by frame, each lit VPL
    (``lit_of[f]``, radii ``own[f]``) matched to a slot where the slot's last VPL stood
    (:func:`greedy_match`), else a new slot. Per slot: frame -> VPL index."""
    members: list[dict[int, int]] = []
    slot_pos: list[np.ndarray] = []
    slot_nrm: list[np.ndarray] = []
    slot_rad: list[float] = []
    for f, vpls in enumerate(sets):
        lit = lit_of[f]
        pos = np.asarray(vpls.position, dtype=np.float64)[lit]
        nrm = np.asarray(vpls.normal, dtype=np.float64)[lit]
        rad = own[f][lit]
        if slot_pos:
            cost = _cost(
                np.array(slot_pos), np.array(slot_nrm), np.array(slot_rad), pos, nrm, rad, diagonal
            )
            match = greedy_match(cost)
        else:
            match = np.full(len(lit), -1, dtype=np.int64)
        for j, i in enumerate(lit):
            s = int(match[j])
            if s < 0:
                s = len(members)
                members.append({})
                slot_pos.append(pos[j])
                slot_nrm.append(nrm[j])
                slot_rad.append(float(rad[j]))
            members[s][f] = int(i)
            slot_pos[s], slot_nrm[s], slot_rad[s] = pos[j], nrm[j], float(rad[j])
    return members


def shared_layout(
    scenes: Sequence[vplace.Scene],
    views: Sequence[Sequence[vplace.View]],
    settings: vplace.job.LayoutSettings,
    *,
    progress: vplace.Progress | None = None,
) -> list[vplace.VplSet]:
    """One VPL set per captured frame, all at the same positions with each frame's powers (see
    the module docs): ``scenes[f]`` and ``views[f]`` are frame ``f``'s export and views (its
    captures, and coverage views the layout places for; the refit fits the captures).
    ``settings.method`` must refit (``vplace+refit``). Each frame adds ``n_vpls // F`` VPLs,
    at least one, so with more frames than ``n_vpls`` the set holds one VPL per frame."""
    if len(scenes) != len(views):
        raise ValueError(f"{len(scenes)} scenes for {len(views)} frames of views")
    if not scenes:
        raise ValueError("no frames to lay out")
    if settings.method != "vplace+refit":
        raise ValueError(
            f"a shared layout refits each frame's powers; {settings.method!r} does not"
        )
    frames = len(scenes)
    per_frame = replace(settings, n_vpls=max(settings.n_vpls // frames, 1))
    parts = [
        vplace.job.lay_out(
            scene, frame_views, per_frame, progress=progress, judge_near_field=False
        ).vpls
        for scene, frame_views in zip(scenes, views, strict=True)
    ]
    union = vplace.VplSet(
        np.concatenate([np.asarray(p.position) for p in parts]),
        np.concatenate([np.asarray(p.normal) for p in parts]),
        np.concatenate([np.asarray(p.flux) for p in parts]) / np.float32(frames),
        profile=parts[0].profile,
        radius=parts[0].radius,
    )
    # One scale per VPL (not power groups): the refit picks each frame's lights out of the
    # union, and a group would tie a light of this frame to its neighbour of another. Nothing
    # held at the union's powers: they are other frames' (refit_powers). Frames whose light
    # alone differs share their shadow rays (refit_frame_powers).
    refits = vplace.job.refit_frame_powers(scenes, views, union, group=1, progress=progress)
    return [r.vpls for r in refits]


def at_frame(keyed: Keyed, frames: Sequence[float], frame: float) -> vplace.VplSet:
    """The keyed lights at ``frame`` (linear between the captured ``frames``, held before the
    first and after the last) as a ``VplSet`` for the evaluator; dark slots are left out. At a
    captured frame it is that frame's own set. Between captured frames each light's near-field
    radius is its keyed disk size interpolated, as Blender interpolates it (``VplSet(...,
    radii=...)``), not the interpolated set's spacing: a light fading out beside one fading in
    keeps its own frame's disk."""
    f = np.asarray(frames, dtype=np.float64)
    if len(f) != keyed.position.shape[0]:
        raise ValueError(f"{len(f)} frames for {keyed.position.shape[0]} keyed frames")
    k = int(np.clip(np.searchsorted(f, frame, side="right") - 1, 0, len(f) - 1))
    k1 = min(k + 1, len(f) - 1)
    w = 0.0 if k1 == k else float(np.clip((frame - f[k]) / (f[k1] - f[k]), 0.0, 1.0))

    def lerp(a: np.ndarray) -> np.ndarray:
        return (1.0 - w) * a[k] + w * a[k1]

    energy = lerp(keyed.energy)
    color = lerp(keyed.color)
    power = energy[:, None] * color
    # blender_power = flux * (1 for cosine, 2 for omni): see ARCHITECTURE, Profiles.
    flux = power / (2.0 if keyed.profile == "omni" else 1.0)
    normal = lerp(keyed.normal)
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-12)
    if w == 0.0 and frame == f[k]:
        return keyed.sets[k]
    keep = energy > 0
    radii = None
    if keyed.profile == "cosine":  # the disk sizes as keyed: Blender interpolates them too
        radii = np.ascontiguousarray(lerp(keyed.radii)[keep], dtype=np.float32)
    return vplace.VplSet(
        np.ascontiguousarray(lerp(keyed.position)[keep], dtype=np.float32),
        np.ascontiguousarray(normal[keep], dtype=np.float32),
        np.ascontiguousarray(flux[keep], dtype=np.float32),
        profile=keyed.profile,
        radius=keyed.radius,
        radii=radii,
    )
