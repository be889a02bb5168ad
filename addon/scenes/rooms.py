"""Two built-in rooms built from code alone (no asset files, so no licence): ``skyroom``, lit
only by a sky through its windows, and ``panelroom``, lit only by emissive meshes.

Both are closed rooms at metre scale whose walls, floor and ceiling are solid boxes
:data:`WALL` thick, never single planes (no renderer leaks light at the edges), with no lamp
objects, 16:9 cameras inside (:data:`SKYROOM_FIT` and :data:`PANELROOM_FIT` to lay out for,
:data:`SKYROOM_HELD_OUT` and :data:`PANELROOM_HELD_OUT` to score with the same lights) and
Cycles' light-path settings at Blender's defaults. Every texture is made with numpy (fixed
seeds), written to an 8-bit sRGB image packed into the .blend, and read through each mesh's
``UVMap`` the way :mod:`.materials` reads exactly (Image Texture -> Base Color, Image Alpha ->
Alpha).

- **skyroom** (6 x 4 x 3 m): a Sky Texture world (Blender's multiple-scattering sky with its sun
  disc, :data:`SKY_STRENGTH`), which vplace's export bakes to an equirectangular map with a
  warning. Two windows in the south wall and one in the west wall (real holes) let the sun in
  as patches on the rug, the floor, the sofa, the table and the terracotta north wall. Wooden
  planks on the floor, a terracotta and a sage-green wall (coloured bounce light), a rug and a
  painting, a table, a sofa, a bookcase with book spines, a cabinet, and a potted plant of leaf
  cards cut out by their texture's alpha, standing in the sun.
- **panelroom** (6 x 4 x 2.8 m, no openings): a black world; three ceiling light panels (an
  Emission shader on their lower face) and a TV whose screen is a Principled BSDF with a pale
  blue Emission Color. A lattice louvre under the third panel lets its light through the holes
  its texture's alpha cuts. Tiled floor, a deep blue wall, a bookcase with book spines, a
  painting, a sofa, a coffee table, a TV stand and a plant of leaf cards beside the TV.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import bpy
import numpy as np

from ..compat import new_material, new_world

__all__ = [
    "PANELROOM_BLEND",
    "PANELROOM_FIT",
    "PANELROOM_HELD_OUT",
    "PANELROOM_INTERIOR",
    "SKYROOM_BLEND",
    "SKYROOM_FIT",
    "SKYROOM_HELD_OUT",
    "SKYROOM_INTERIOR",
    "build_panelroom",
    "build_skyroom",
    "write_panelroom_blend",
    "write_skyroom_blend",
]

REPO = Path(__file__).resolve().parents[2]
SKYROOM_BLEND = REPO / "blend_scenes" / "skyroom" / "skyroom.blend"
PANELROOM_BLEND = REPO / "blend_scenes" / "panelroom" / "panelroom.blend"

#: Thickness of walls, floor and ceiling, m.
WALL = 0.2
#: The rooms' insides, ``(min corner, max corner)`` in metres (Blender axes, Z up).
SKYROOM_INTERIOR = ((-3.0, -2.0, 0.0), (3.0, 2.0, 3.0))
PANELROOM_INTERIOR = ((-3.0, -2.0, 0.0), (3.0, 2.0, 2.8))
#: Render size (16:9); the report's presets set their own.
RESOLUTION = (320, 180)

#: The sky: the sun's elevation and rotation (radians; at this rotation the sun stands in the
#: south-west, towards -x -y), and the Background strength that keeps a Standard-view render
#: of the room in range (mean pixel 0.29-0.48 over the five cameras, the windows clipped).
SKY_SUN_ELEVATION = math.radians(35.0)
SKY_SUN_ROTATION = math.radians(217.0)
SKY_STRENGTH = 0.3

#: Radiance of the ceiling panels (Emission strength, warm white) and of the TV screen (mean
#: pixel of a Standard-view render 0.35-0.50 over the five cameras).
PANEL_STRENGTH = 8.0
PANEL_COLOR = (1.0, 0.88, 0.72)
SCREEN_STRENGTH = 1.2
SCREEN_COLOR = (0.55, 0.75, 1.0)

#: Cameras, ``name -> (location, target, lens mm)`` on a 36 mm sensor: the views each report
#: lays out for (the first is the scene camera) and the views it holds out.
SKYROOM_FIT = {
    "Skyroom camera": ((-2.6, -1.6, 1.6), (1.6, 1.4, 0.5), 18.0),
    "Skyroom camera east": ((2.8, -1.0, 2.0), (-2.0, 1.0, 0.5), 18.0),
    "Skyroom camera high": ((0.0, -1.75, 2.75), (0.0, 1.4, 0.2), 18.0),
}
SKYROOM_HELD_OUT = {
    "Skyroom camera (held out, windows)": ((-0.6, 1.5, 1.5), (0.2, -2.0, 1.3), 18.0),
    "Skyroom camera (held out, ceiling)": ((0.2, 1.2, 0.5), (-2.0, -1.5, 2.9), 16.0),
}
PANELROOM_FIT = {
    "Panelroom camera": ((2.6, -1.6, 1.7), (-2.6, 0.7, 0.9), 18.0),
    "Panelroom camera north": ((-1.9, 1.45, 2.2), (2.0, -1.4, 0.5), 18.0),
    "Panelroom camera high": ((0.0, -1.75, 2.55), (0.0, 1.5, 0.6), 18.0),
}
PANELROOM_HELD_OUT = {
    "Panelroom camera (held out, ceiling)": ((0.5, 1.6, 0.6), (-1.0, -1.5, 2.8), 16.0),
    "Panelroom camera (held out, south)": ((0.8, 1.4, 1.5), (-0.5, -2.0, 0.8), 18.0),
}

# Textures: (H, W, 4) float arrays, linear RGB and alpha, row 0 at the bottom (v = 0) as
# Blender stores pixels.


def _srgb(linear: np.ndarray) -> np.ndarray:
    """Linear to sRGB-encoded values in [0, 1]."""
    c = np.clip(linear, 0.0, 1.0)
    return np.where(c <= 0.0031308, 12.92 * c, 1.055 * c ** (1.0 / 2.4) - 0.055)


def _grid(h: int, w: int) -> tuple[np.ndarray, np.ndarray]:
    """Texel centres as (u, v) in [0, 1), each (h, w)."""
    v, u = np.mgrid[0:h, 0:w].astype(np.float64)
    return (u + 0.5) / w, (v + 0.5) / h


def _rgba(rgb: np.ndarray, alpha: np.ndarray | None = None) -> np.ndarray:
    a = np.ones(rgb.shape[:2]) if alpha is None else alpha
    return np.dstack([rgb, a])


def plank_texture(size: int = 512, rows: int = 8, seed: int = 1) -> np.ndarray:
    """Wooden planks running along u, ``rows`` of them across v, joints staggered, grain and
    dark gaps; tiles seamlessly."""
    rng = np.random.default_rng(seed)
    u, v = _grid(size, size)
    row = np.minimum((v * rows).astype(int), rows - 1)
    local_v = v * rows - row
    rgb = np.zeros((size, size, 3))
    gap = np.zeros((size, size), bool)
    base = np.array([0.32, 0.17, 0.075])
    for r in range(rows):
        joints = np.sort(rng.uniform(0.0, 1.0, rng.integers(1, 3)))
        in_row = row == r
        ur = u[in_row]
        # Plank index along the row; the piece after the last joint wraps into the first.
        idx = np.searchsorted(joints, ur) % len(joints)
        tint = rng.uniform(0.75, 1.25, (len(joints), 1)) * base
        tint = tint * rng.uniform(0.92, 1.08, (len(joints), 3))
        phase = rng.uniform(0.0, 2.0 * math.pi, len(joints))
        lv = local_v[in_row]
        grain = 0.85 + 0.15 * np.sin(
            2.0 * math.pi * (9.0 * lv + 0.35 * np.sin(2.0 * math.pi * 3.0 * ur + phase[idx]))
            + phase[idx]
        )
        rgb[in_row] = tint[idx] * grain[:, None]
        dist = np.abs(ur[:, None] - joints[None, :])
        dist = np.minimum(dist, 1.0 - dist).min(axis=1)
        gap[in_row] = dist * size < 1.0
    gap |= (local_v * size / rows < 1.0) | (local_v * size / rows > size / rows - 1.0)
    rgb[gap] = base * 0.25
    return _rgba(rgb)


def tile_texture(size: int = 512, tiles: int = 4, seed: int = 2) -> np.ndarray:
    """Square floor tiles, ``tiles`` x ``tiles``, in two tones with grout lines; tiles."""
    rng = np.random.default_rng(seed)
    u, v = _grid(size, size)
    iu, iv = (u * tiles).astype(int), (v * tiles).astype(int)
    fu, fv = u * tiles - iu, v * tiles - iv
    tones = np.array([[0.42, 0.40, 0.36], [0.30, 0.31, 0.32]])
    jitter = rng.uniform(0.9, 1.1, (tiles, tiles))
    rgb = tones[(iu + iv) % 2] * jitter[iv, iu][..., None]
    grout = np.minimum(np.minimum(fu, 1 - fu), np.minimum(fv, 1 - fv)) * size / tiles < 2.0
    rgb[grout] = (0.65, 0.63, 0.6)
    return _rgba(rgb)


def rug_texture(size: int = 256) -> np.ndarray:
    """A rug over the whole face: a dark red border, a blue field and gold diamonds."""
    u, v = _grid(size, size)
    rgb = np.empty((size, size, 3))
    rgb[:] = (0.02, 0.05, 0.25)
    diamond = (np.abs((u * 6) % 1 - 0.5) + np.abs((v * 4) % 1 - 0.5)) < 0.3
    rgb[diamond] = (0.7, 0.45, 0.08)
    border = np.minimum(np.minimum(u, 1 - u), np.minimum(v, 1 - v)) < 0.08
    rgb[border] = (0.35, 0.02, 0.02)
    return _rgba(rgb)


def painting_texture(size: int = 256) -> np.ndarray:
    """An abstract painting over the whole face: coloured fields between black lines."""
    u, v = _grid(size, size)
    rgb = np.empty((size, size, 3))
    rgb[:] = (0.8, 0.78, 0.7)
    rgb[(u < 0.4) & (v > 0.55)] = (0.7, 0.05, 0.03)
    rgb[(u > 0.7) & (v < 0.3)] = (0.02, 0.08, 0.5)
    rgb[(u > 0.4) & (u < 0.7) & (v < 0.55)] = (0.85, 0.65, 0.02)
    for line in (0.4, 0.7):
        rgb[np.abs(u - line) < 0.012] = 0.01
    for line in (0.3, 0.55):
        rgb[np.abs(v - line) < 0.018] = 0.01
    return _rgba(rgb)


def leaf_texture(size: int = 256, seed: int = 3) -> np.ndarray:
    """A sprig over the whole face: pointed leaves on stems fanning out from the bottom
    centre, alpha 1 on them and 0 elsewhere."""
    rng = np.random.default_rng(seed)
    u, v = _grid(size, size)
    rgb = np.empty((size, size, 3))
    rgb[:] = (0.05, 0.2, 0.03)
    alpha = np.zeros((size, size))
    for k in range(7):
        angle = math.radians(-60.0 + 20.0 * k + rng.uniform(-6.0, 6.0))
        d = np.array([math.sin(angle), math.cos(angle)])
        length = rng.uniform(0.55, 0.85)
        # Stem from (0.5, 0) along d; the leaf along its outer 55 %.
        px, py = u - 0.5, v - 0.02
        along = px * d[0] + py * d[1]
        across = -px * d[1] + py * d[0]
        t = (along - 0.45 * length) / (0.55 * length)
        width = 0.09 * np.sqrt(np.clip(1.0 - (2.0 * t - 1.0) ** 2, 0.0, None))
        leaf = (t > 0.0) & (t < 1.0) & (np.abs(across) < width)
        stem = (along > 0.0) & (along < 0.5 * length) & (np.abs(across) < 0.006)
        shade = rng.uniform(0.7, 1.2)
        rgb[leaf] = np.array([0.06, 0.28, 0.04]) * shade
        rgb[leaf & (np.abs(across) < 0.006)] = (0.12, 0.35, 0.06)
        rgb[stem] = (0.1, 0.18, 0.04)
        alpha[leaf | stem] = 1.0
    return _rgba(rgb, alpha)


def grille_texture(size: int = 256, cells: int = 6) -> np.ndarray:
    """A diagonal wooden lattice in a frame: alpha 1 on the bars, 0 in the holes."""
    u, v = _grid(size, size)
    a = ((u + v) * cells) % 1.0
    b = ((u - v) * cells) % 1.0
    bars = (np.minimum(a, 1 - a) < 0.12) | (np.minimum(b, 1 - b) < 0.12)
    bars |= np.minimum(np.minimum(u, 1 - u), np.minimum(v, 1 - v)) < 0.04
    rgb = np.empty((size, size, 3))
    rgb[:] = (0.35, 0.2, 0.09)
    return _rgba(rgb, bars.astype(np.float64))


def books_texture(
    width: int = 512, height: int = 256, shelves: int = 4, seed: int = 4
) -> np.ndarray:
    """A bookcase front over the whole face: shelf boards, and books of random widths,
    heights and colours standing on each shelf against a dark back."""
    rng = np.random.default_rng(seed)
    u, v = _grid(height, width)
    rgb = np.empty((height, width, 3))
    rgb[:] = (0.03, 0.02, 0.015)
    board = 0.06
    palette = np.array(
        [[0.5, 0.05, 0.04], [0.05, 0.15, 0.45], [0.06, 0.3, 0.08], [0.6, 0.45, 0.1],
         [0.55, 0.5, 0.42], [0.25, 0.06, 0.3], [0.04, 0.04, 0.04], [0.6, 0.25, 0.05]]
    )  # fmt: skip
    for s in range(shelves):
        lo = s / shelves + board / shelves
        hi = (s + 1) / shelves
        x = 0.03
        while x < 0.97:
            w = rng.uniform(0.012, 0.03)
            top = lo + (hi - lo) * rng.uniform(0.6, 0.9)
            book = (u >= x) & (u < min(x + w, 0.97)) & (v >= lo) & (v < top)
            rgb[book] = palette[rng.integers(len(palette))] * rng.uniform(0.7, 1.1)
            x += w + (rng.uniform(0.0, 0.06) if rng.random() < 0.1 else 0.002)
    shelf = ((v * shelves) % 1.0) < board
    shelf |= (u < 0.03) | (u > 0.97) | (v > 1.0 - board / shelves)
    rgb[shelf] = (0.3, 0.17, 0.08)
    return _rgba(rgb)


def packed_image(name: str, rgba: np.ndarray) -> bpy.types.Image:
    """An 8-bit sRGB image of the linear ``rgba`` (row 0 at the bottom), packed into the file."""
    h, w = rgba.shape[:2]
    img = bpy.data.images.new(name, w, h, alpha=True)
    px = np.array(rgba, dtype=np.float64)
    px[..., :3] = _srgb(px[..., :3])
    img.pixels.foreach_set(px.astype(np.float32).ravel())
    img.pack()
    return img


# Materials.


def _principled(
    name: str,
    color: Sequence[float],
    roughness: float = 0.8,
    *,
    image: bpy.types.Image | None = None,
    alpha: bool = False,
) -> bpy.types.Material:
    """A Principled BSDF of base ``color``, or of ``image`` through the UVs (its alpha the
    cut-out with ``alpha``)."""
    mat = new_material(name)
    tree = mat.node_tree
    bsdf = tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (*color[:3], 1.0)
    bsdf.inputs["Roughness"].default_value = roughness
    mat.diffuse_color = (*color[:3], 1.0)
    if image is not None:
        tex = tree.nodes.new("ShaderNodeTexImage")
        tex.image = image
        tex.location = (-400.0, 200.0)
        tree.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
        if alpha:
            tree.links.new(tex.outputs["Alpha"], bsdf.inputs["Alpha"])
    return mat


def _emission(name: str, color: Sequence[float], strength: float) -> bpy.types.Material:
    """A pure emitter: an Emission shader of ``color`` x ``strength`` (reflects nothing)."""
    mat = new_material(name)
    tree = mat.node_tree
    tree.nodes.remove(tree.nodes["Principled BSDF"])
    em = tree.nodes.new("ShaderNodeEmission")
    em.inputs["Color"].default_value = (*color[:3], 1.0)
    em.inputs["Strength"].default_value = strength
    tree.links.new(em.outputs["Emission"], tree.nodes["Material Output"].inputs["Surface"])
    mat.diffuse_color = (*color[:3], 1.0)
    return mat


def _screen(name: str, color: Sequence[float], strength: float) -> bpy.types.Material:
    """A glossy dark screen glowing ``color`` x ``strength``: Principled BSDF emission."""
    mat = new_material(name)
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (0.02, 0.02, 0.02, 1.0)
    bsdf.inputs["Roughness"].default_value = 0.2
    bsdf.inputs["Emission Color"].default_value = (*color[:3], 1.0)
    bsdf.inputs["Emission Strength"].default_value = strength
    mat.diffuse_color = (*color[:3], 1.0)
    return mat


# Meshes.

Vec3 = tuple[float, float, float]
#: Box faces by outward normal: (axis, side).
FACES = {"-x": (0, -1), "+x": (0, 1), "-y": (1, -1), "+y": (1, 1), "-z": (2, -1), "+z": (2, 1)}


@dataclass
class MeshParts:
    """Boxes and quads gathered into one mesh with UVs and per-face material slots."""

    verts: list[Vec3] = field(default_factory=list)
    faces: list[tuple[int, ...]] = field(default_factory=list)
    slots: list[int] = field(default_factory=list)
    uvs: list[tuple[float, float]] = field(default_factory=list)

    def quad(
        self, corners: Sequence[Vec3], uvs: Sequence[tuple[float, float]], slot: int = 0
    ) -> None:
        """A quad of four ``corners`` (its normal by the right-hand rule) and their ``uvs``."""
        n = len(self.verts)
        self.verts.extend(corners)
        self.faces.append(tuple(range(n, n + 4)))
        self.slots.append(slot)
        self.uvs.extend(uvs)

    def box(
        self,
        lo: Vec3,
        hi: Vec3,
        tile: float | None = 1.0,
        slot: int = 0,
        face_slots: dict[str, int] | None = None,
    ) -> None:
        """An axis-aligned box, normals out. UVs per face: world metres / ``tile`` (textures
        run on across boxes), or the face's own 0..1 with ``tile=None``; the u axis runs to
        the right as seen from outside on the walls. ``face_slots``: other material slots by
        face (keys of :data:`FACES`)."""
        lo_a, hi_a = np.asarray(lo, float), np.asarray(hi, float)
        for key, (axis, side) in FACES.items():
            ua, va = {0: (1, 2), 1: (0, 2), 2: (0, 1)}[axis]
            flip = (axis == 1 and side > 0) or (axis == 0 and side < 0)
            corners, uvs = [], []
            for a, b in ((0, 0), (1, 0), (1, 1), (0, 1)):
                p = np.where(side > 0, hi_a, lo_a).copy()
                p[ua] = (lo_a, hi_a)[a][ua]
                p[va] = (lo_a, hi_a)[b][va]
                corners.append(p)
                if tile is None:
                    uv = [float(a), float(b)]
                else:
                    uv = [p[ua] / tile, p[va] / tile]
                if flip:
                    uv[0] = (1.0 - uv[0]) if tile is None else -uv[0]
                uvs.append((uv[0], uv[1]))
            normal = np.cross(corners[1] - corners[0], corners[2] - corners[0])
            if normal[axis] * side < 0:
                corners, uvs = corners[::-1], uvs[::-1]
            self.quad(
                [(float(c[0]), float(c[1]), float(c[2])) for c in corners],
                uvs,
                (face_slots or {}).get(key, slot),
            )

    def build(
        self,
        name: str,
        materials: Sequence[bpy.types.Material],
        collection: bpy.types.Collection,
    ) -> bpy.types.Object:
        """The mesh object ``name`` with ``materials`` in its slots, linked to ``collection``."""
        mesh = bpy.data.meshes.new(name)
        mesh.from_pydata(self.verts, [], self.faces)
        uv = mesh.uv_layers.new(name="UVMap")
        uv.data.foreach_set("uv", np.array(self.uvs, dtype=np.float32).ravel())
        mesh.polygons.foreach_set("material_index", np.array(self.slots, dtype=np.int32))
        for mat in materials:
            mesh.materials.append(mat)
        mesh.update()
        obj = bpy.data.objects.new(name, mesh)
        collection.objects.link(obj)
        return obj


def _boxes(
    name: str,
    boxes: Sequence[tuple[Vec3, Vec3]],
    material: bpy.types.Material,
    collection: bpy.types.Collection,
    tile: float | None = 1.0,
) -> bpy.types.Object:
    """One object of several boxes of one material."""
    parts = MeshParts()
    for lo, hi in boxes:
        parts.box(lo, hi, tile)
    return parts.build(name, [material], collection)


#: A window: (centre along the wall, width, sill height, height), metres.
Window = tuple[float, float, float, float]


def wall_boxes(lo: Vec3, hi: Vec3, axis: int, windows: Sequence[Window]) -> list[tuple[Vec3, Vec3]]:
    """The wall box ``lo``..``hi`` running along ``axis`` (0: x, 1: y) as boxes around its
    ``windows``: piers between them, a sill box below and a lintel box above each."""

    def span(a0: float, a1: float, z0: float, z1: float) -> tuple[Vec3, Vec3]:
        b_lo, b_hi = list(lo), list(hi)
        b_lo[axis], b_hi[axis] = a0, a1
        b_lo[2], b_hi[2] = z0, z1
        return (b_lo[0], b_lo[1], b_lo[2]), (b_hi[0], b_hi[1], b_hi[2])

    out = []
    start = lo[axis]
    for centre, width, sill, height in sorted(windows):
        a0, a1 = centre - width / 2.0, centre + width / 2.0
        if a0 > start:
            out.append(span(start, a0, lo[2], hi[2]))
        out.append(span(a0, a1, lo[2], sill))
        out.append(span(a0, a1, sill + height, hi[2]))
        start = a1
    if start < hi[axis]:
        out.append(span(start, hi[axis], lo[2], hi[2]))
    return out


def room_shell(
    collection: bpy.types.Collection,
    interior: tuple[Vec3, Vec3],
    floor: bpy.types.Material,
    ceiling: bpy.types.Material,
    walls: dict[str, bpy.types.Material],
    windows: dict[str, Sequence[Window]] | None = None,
    floor_tile: float = 2.0,
) -> None:
    """Floor, ceiling and the four walls (``walls`` by "north" +y, "south", "east" +x,
    "west") as boxes :data:`WALL` thick around ``interior``, with ``windows`` cut into
    walls. The floor and ceiling reach under and over the walls; the walls along x span the
    corners, so no seam opens onto the outside."""
    (x0, y0, z0), (x1, y1, z1) = interior
    t = WALL
    windows = windows or {}
    _boxes(
        "Floor", [((x0 - t, y0 - t, z0 - t), (x1 + t, y1 + t, z0))], floor, collection, floor_tile
    )
    _boxes("Ceiling", [((x0 - t, y0 - t, z1), (x1 + t, y1 + t, z1 + t))], ceiling, collection)
    boxes = {
        "north": ((x0 - t, y1, z0), (x1 + t, y1 + t, z1), 0),
        "south": ((x0 - t, y0 - t, z0), (x1 + t, y0, z1), 0),
        "east": ((x1, y0, z0), (x1 + t, y1, z1), 1),
        "west": ((x0 - t, y0, z0), (x0, y1, z1), 1),
    }
    for side, (lo, hi, axis) in boxes.items():
        holes = windows.get(side, ())
        name = f"Wall {side}" + (f" ({len(holes)} windows)" if len(holes) > 1 else "")
        if len(holes) == 1:
            name = f"Wall {side} (window)"
        _boxes(name, wall_boxes(lo, hi, axis, holes), walls[side], collection)


def plastered_shell(
    collection: bpy.types.Collection,
    interior: tuple[Vec3, Vec3],
    windows: dict[str, Sequence[Window]],
) -> None:
    """:func:`room_shell` with a textured wooden floor, a white ceiling, a terracotta north
    wall, a sage-green east wall and white plaster south and west (the sky room's and the
    L-shaped room's walls)."""
    white = _principled("Plaster white", (0.75, 0.74, 0.7))
    floor = _principled(
        "Wooden floor", (0.3, 0.16, 0.07), 0.6, image=packed_image("Wooden planks", plank_texture())
    )
    room_shell(
        collection,
        interior,
        floor,
        _principled("Ceiling white", (0.8, 0.8, 0.78)),
        {
            "north": _principled("Terracotta wall", (0.7, 0.22, 0.08)),
            "south": white,
            "east": _principled("Sage green wall", (0.2, 0.45, 0.22)),
            "west": white,
        },
        windows=windows,
    )


def table(
    name: str,
    centre: tuple[float, float],
    size: Vec3,
    material: bpy.types.Material,
    collection: bpy.types.Collection,
) -> bpy.types.Object:
    """A table ``size`` (x, y, height) with a 4 cm top and four 5 cm legs."""
    cx, cy = centre
    hx, hy, h = size[0] / 2.0, size[1] / 2.0, size[2]
    boxes = [((cx - hx, cy - hy, h - 0.04), (cx + hx, cy + hy, h))]
    for dx in (-1, 1):
        for dy in (-1, 1):
            lx, ly = cx + dx * (hx - 0.06), cy + dy * (hy - 0.06)
            boxes.append(((lx - 0.025, ly - 0.025, 0.0), (lx + 0.025, ly + 0.025, h - 0.04)))
    return _boxes(name, boxes, material, collection)


def sofa(
    name: str,
    lo: tuple[float, float],
    hi: tuple[float, float],
    back: str,
    material: bpy.types.Material,
    collection: bpy.types.Collection,
) -> bpy.types.Object:
    """A sofa on the floor over ``lo``..``hi`` (x, y) with its back on side ``back`` ("+x",
    "-x", "+y" or "-y"): seat, backrest and two arms. The arms end at the backrest: boxes that
    overlap show two faces in one plane, which Cycles renders black (a ray leaving one face
    meets the other at once) where vplace and EEVEE light them (0.14 % of the L room's wing
    view, every pixel of its hot spots)."""
    (x0, y0), (x1, y1) = lo, hi
    axis, side = FACES[back][0], FACES[back][1]
    boxes: list[tuple[Vec3, Vec3]] = [((x0, y0, 0.0), (x1, y1, 0.42))]
    if axis == 0:
        bx = (x1 - 0.2, x1) if side > 0 else (x0, x0 + 0.2)
        ax = (x0, bx[0]) if side > 0 else (bx[1], x1)
        boxes.append(((bx[0], y0, 0.42), (bx[1], y1, 0.85)))
        boxes += [
            ((ax[0], y0, 0.42), (ax[1], y0 + 0.18, 0.62)),
            ((ax[0], y1 - 0.18, 0.42), (ax[1], y1, 0.62)),
        ]
    else:
        by = (y1 - 0.2, y1) if side > 0 else (y0, y0 + 0.2)
        ay = (y0, by[0]) if side > 0 else (by[1], y1)
        boxes.append(((x0, by[0], 0.42), (x1, by[1], 0.85)))
        boxes += [
            ((x0, ay[0], 0.42), (x0 + 0.18, ay[1], 0.62)),
            ((x1 - 0.18, ay[0], 0.42), (x1, ay[1], 0.62)),
        ]
    return _boxes(name, boxes, material, collection)


def painting(collection: bpy.types.Collection, lo: Vec3, hi: Vec3) -> bpy.types.Object:
    """A thin box hung on a wall, the painting texture over each of its faces."""
    canvas = _principled(
        "Painting", (0.6, 0.4, 0.3), 0.5, image=packed_image("Painting canvas", painting_texture())
    )
    return _boxes("Painting", [(lo, hi)], canvas, collection, tile=None)


def bookcase(collection: bpy.types.Collection, lo: Vec3, hi: Vec3, front: str) -> bpy.types.Object:
    """A bookcase box whose ``front`` face (a key of :data:`FACES`) shows the book spines
    texture over its whole area."""
    parts = MeshParts()
    parts.box(lo, hi, tile=None, face_slots={front: 1})
    books = _principled(
        "Books", (0.3, 0.15, 0.1), 0.7, image=packed_image("Book spines", books_texture())
    )
    wood = _principled("Bookcase wood", (0.3, 0.17, 0.08))
    return parts.build("Bookcase", [wood, books], collection)


def plant(
    name: str,
    centre: tuple[float, float],
    height: float,
    pot: bpy.types.Material,
    leaves: bpy.types.Material,
    collection: bpy.types.Collection,
    cards: int = 3,
) -> tuple[bpy.types.Object, bpy.types.Object]:
    """A potted plant: a 0.4 m pot and ``cards`` vertical leaf cards crossing over it (the leaf
    texture's alpha cuts them out), ``height`` m tall in all."""
    cx, cy = centre
    pot_obj = _boxes(
        f"{name} pot", [((cx - 0.2, cy - 0.2, 0.0), (cx + 0.2, cy + 0.2, 0.4))], pot, collection
    )
    parts = MeshParts()
    half = 0.45 * height
    for k in range(cards):
        a = math.pi * k / cards + 0.3
        dx, dy = half * math.cos(a), half * math.sin(a)
        z0, z1 = 0.3, height
        parts.quad(
            [
                (cx - dx, cy - dy, z0),
                (cx + dx, cy + dy, z0),
                (cx + dx, cy + dy, z1),
                (cx - dx, cy - dy, z1),
            ],
            [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)],
        )
    return pot_obj, parts.build(f"{name} leaves", [leaves], collection)


def _camera(
    scene: bpy.types.Scene, name: str, location: Vec3, target: Vec3, lens_mm: float
) -> bpy.types.Object:
    """A perspective camera at ``location`` aimed at ``target``, 36 mm sensor."""
    from mathutils import Vector

    data = bpy.data.cameras.new(name)
    data.lens = lens_mm
    data.sensor_width = 36.0
    data.clip_start = 0.05
    cam = bpy.data.objects.new(name, data)
    cam.location = location
    cam.rotation_euler = (Vector(target) - Vector(location)).to_track_quat("-Z", "Y").to_euler()
    scene.collection.objects.link(cam)
    return cam


def _cameras(scene: bpy.types.Scene, *views: dict[str, tuple[Vec3, Vec3, float]]) -> None:
    """The cameras of ``views``; the first one is the scene camera."""
    for group in views:
        for name, (location, target, lens) in group.items():
            cam = _camera(scene, name, location, target, lens)
            if scene.camera is None:
                scene.camera = cam


def _render_settings(scene: bpy.types.Scene) -> None:
    """Cycles on the CPU at :data:`RESOLUTION`, Blender's default light paths, Standard view."""
    r = scene.render
    r.engine = "CYCLES"
    r.resolution_x, r.resolution_y = RESOLUTION
    r.resolution_percentage = 100
    c = scene.cycles
    c.device = "CPU"
    c.samples = 64
    # Blender's defaults, set explicitly: the renders and the report assume them.
    c.max_bounces = 12
    c.diffuse_bounces = 4
    c.glossy_bounces = 4
    c.transmission_bounces = 12
    c.volume_bounces = 0
    c.transparent_max_bounces = 8
    c.sample_clamp_direct = 0.0
    c.sample_clamp_indirect = 10.0
    c.blur_glossy = 1.0
    c.caustics_reflective = True
    c.caustics_refractive = True
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    scene.eevee.taa_render_samples = 16


def _leaves() -> bpy.types.Material:
    """The alpha-cut leaf material both rooms' plants use."""
    return _principled(
        "Leaves",
        (0.06, 0.28, 0.04),
        0.6,
        image=packed_image("Leaf sprig", leaf_texture()),
        alpha=True,
    )


def build_skyroom(scene: bpy.types.Scene | None = None) -> bpy.types.Scene:
    """Adds the sky-lit room (see the module docs) to ``scene``."""
    scene = scene or bpy.context.scene
    coll = scene.collection
    plastered_shell(
        coll,
        SKYROOM_INTERIOR,
        {
            "south": [(-1.5, 1.2, 0.8, 1.5), (1.2, 1.2, 0.8, 1.5)],
            "west": [(0.6, 1.0, 0.9, 1.4)],
        },
    )
    rug = _principled(
        "Rug", (0.1, 0.08, 0.2), 1.0, image=packed_image("Rug pattern", rug_texture())
    )
    _boxes("Rug", [((-1.3, -0.9, 0.0), (1.1, 0.7, 0.012))], rug, coll, tile=None)
    painting(coll, (2.97, -0.9, 1.1), (3.0, 0.5, 2.0))
    wood = _principled("Dark wood", (0.12, 0.06, 0.03), 0.5)
    table("Table", (-1.6, 1.1), (1.4, 0.8, 0.75), wood, coll)
    sofa(
        "Sofa", (2.1, -1.0), (2.95, 1.0), "+x", _principled("Sofa fabric", (0.08, 0.12, 0.35)), coll
    )
    bookcase(coll, (0.3, 1.62, 0.0), (1.9, 2.0, 1.9), "-y")
    _boxes(
        "Side cabinet",
        [((-2.95, -1.6, 0.0), (-2.45, -0.6, 0.7))],
        _principled("Cabinet white", (0.6, 0.6, 0.58), 0.4),
        coll,
    )
    leaves = _leaves()
    plant("Plant", (1.2, -1.45), 1.6, _principled("Clay pot", (0.45, 0.15, 0.06)), leaves, coll)

    world = new_world("Sky")
    tree = world.node_tree
    sky = tree.nodes.new("ShaderNodeTexSky")
    # Blender before 5.0 has no MULTIPLE_SCATTERING; its Nishita sky is the single-scattering one.
    kinds = sky.bl_rna.properties["sky_type"].enum_items.keys()
    sky.sky_type = "MULTIPLE_SCATTERING" if "MULTIPLE_SCATTERING" in kinds else "NISHITA"
    sky.sun_elevation = SKY_SUN_ELEVATION
    sky.sun_rotation = SKY_SUN_ROTATION
    sky.location = (-300.0, 300.0)
    bg = tree.nodes["Background"]
    bg.inputs["Strength"].default_value = SKY_STRENGTH
    tree.links.new(sky.outputs["Color"], bg.inputs["Color"])
    world.color = (0.3, 0.45, 0.7)
    scene.world = world

    _cameras(scene, SKYROOM_FIT, SKYROOM_HELD_OUT)
    _render_settings(scene)
    return scene


def build_panelroom(scene: bpy.types.Scene | None = None) -> bpy.types.Scene:
    """Adds the room lit by emissive panels and a screen (see the module docs) to ``scene``."""
    scene = scene or bpy.context.scene
    coll = scene.collection
    white = _principled("Plaster white", (0.75, 0.74, 0.7))
    floor = _principled(
        "Tiled floor", (0.35, 0.34, 0.33), 0.5, image=packed_image("Floor tiles", tile_texture())
    )
    room_shell(
        coll,
        PANELROOM_INTERIOR,
        floor,
        _principled("Ceiling white", (0.8, 0.8, 0.78)),
        {
            "north": white,
            "south": white,
            "east": _principled("Deep blue wall", (0.05, 0.12, 0.4)),
            "west": white,
        },
        floor_tile=1.2,
    )
    top = PANELROOM_INTERIOR[1][2]
    frame = _principled("Panel frame", (0.8, 0.8, 0.8), 0.4)
    glow = _emission("Panel light", PANEL_COLOR, PANEL_STRENGTH)
    for k, x in enumerate((-1.8, 0.0, 1.8)):
        parts = MeshParts()
        parts.box((x - 0.6, -0.3, top - 0.04), (x + 0.6, 0.3, top), slot=0, face_slots={"-z": 1})
        parts.build(f"Ceiling panel {k + 1}", [frame, glow], coll)
    # The TV on the west wall, its screen (the +x face) glowing; a stand below it.
    parts = MeshParts()
    parts.box((-2.98, -0.7, 0.95), (-2.92, 0.7, 1.75), face_slots={"+x": 1})
    parts.build(
        "TV",
        [
            _principled("TV body", (0.02, 0.02, 0.02), 0.3),
            _screen("TV screen", SCREEN_COLOR, SCREEN_STRENGTH),
        ],
        coll,
    )
    wood = _principled("Dark wood", (0.12, 0.06, 0.03), 0.5)
    _boxes("TV stand", [((-2.98, -0.9, 0.0), (-2.55, 0.9, 0.5))], wood, coll)
    sofa("Sofa", (1.2, -1.1), (2.1, 1.1), "+x", _principled("Sofa fabric", (0.5, 0.3, 0.1)), coll)
    table("Coffee table", (-0.2, 0.0), (1.1, 0.6, 0.42), wood, coll)
    bookcase(coll, (-1.6, 1.6, 0.0), (0.6, 2.0, 2.0), "-y")
    painting(coll, (-0.9, -2.0, 1.1), (0.5, -1.97, 1.9))
    leaves = _leaves()
    plant("Plant", (-2.6, 1.3), 1.4, _principled("Clay pot", (0.45, 0.15, 0.06)), leaves, coll)
    # A lattice louvre 12 cm under the third panel: that panel lights the room only through
    # the holes the texture's alpha cuts.
    grille = _principled(
        "Lattice",
        (0.35, 0.2, 0.09),
        0.7,
        image=packed_image("Lattice", grille_texture()),
        alpha=True,
    )
    parts = MeshParts()
    z = top - 0.12
    parts.quad(
        [(1.1, -0.4, z), (2.5, -0.4, z), (2.5, 0.4, z), (1.1, 0.4, z)],
        [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)],
    )
    parts.build("Lattice louvre", [grille], coll)

    world = new_world("Black")
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
    world.color = (0.0, 0.0, 0.0)
    scene.world = world

    _cameras(scene, PANELROOM_FIT, PANELROOM_HELD_OUT)
    _render_settings(scene)
    return scene


def _write(build: Callable[[bpy.types.Scene], bpy.types.Scene], blend_path: Path) -> Path:
    """Builds a room with ``build`` in a fresh file and saves it to ``blend_path``."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    build(bpy.context.scene)
    blend_path.parent.mkdir(parents=True, exist_ok=True)
    bpy.ops.wm.save_as_mainfile(filepath=str(blend_path), compress=True)
    return blend_path


def write_skyroom_blend(blend_path: Path = SKYROOM_BLEND) -> Path:
    """Builds the sky-lit room in a fresh file and saves it to ``blend_path``."""
    return _write(build_skyroom, blend_path)


def write_panelroom_blend(blend_path: Path = PANELROOM_BLEND) -> Path:
    """Builds the panel-lit room in a fresh file and saves it to ``blend_path``."""
    return _write(build_panelroom, blend_path)
