"""Materials as vplace shades them: the diffuse albedo of a node tree, its base-colour texture and
its alpha cut-out (the material rule).

vplace's light paths and shadow rays need, per material, the albedo of the *diffuse bounce* (the
light a surface scatters diffusely, what Cycles' Diffuse Color pass shows), the reflectance of
its glossy layer (the light paths go on off it) and where the surface is cut away. Every value
is kept in the form ``constant + coefficient * texture``, with at most one image texture per
value; the core looks the texture up at each ray hit (the base colour at the hit's UV,
bilinear) and tests the alpha against a cutoff. The rule, from the active Cycles
material output's Surface input:

- **Principled BSDF**: albedo = Base Color x (1 - Metallic) x (1 - Transmission Weight) x
  Weight x (1 - E): metal and glass are not diffuse bounce sources, and the dielectric specular
  layer over the diffuse part takes off what it reflects, ``E`` (:func:`dielectric_reflectance`,
  0.092 at IOR 1.5 and the default level). Cycles takes off the layer's reflection at the view
  angle (the Diffuse Color pass of a 0.5 base: 0.481 head-on, 0.468 at 60 degrees, 0.430 at
  80); vplace its mean over the hemisphere. Its Alpha is the cut-out (below).
- **Diffuse BSDF**, **Subsurface Scattering**: albedo = Color x Weight.
- **Emission**, **Glossy**, **Metallic**, **Glass**, **Refraction**, **Holdout**: albedo 0 (no
  diffuse bounce; their emission is the lights' business).
- **Transparent BSDF**: albedo 0 and alpha 0 (fully cut away).
- **Mix Shader**: ``(1 - f) a + f b`` of the two sides' albedo and alpha, ``f`` the Factor: a
  constant, or the mean of the texture that drives it. Mixed with a **Transparent BSDF**, the
  factor (texture-driven or not) becomes the other side's alpha and its albedo is kept as it is.
- **Add Shader**: the sum of the albedos (the core clamps to 1); alpha ``a + b - 1``.
- **Node groups** are followed to the group's output; reroutes and muted nodes pass through.
- **Colour inputs**: a constant; an RGB node; an **Image Texture** (Color output) read through
  its UVs: the active render UV map, a UV Map node's map, the Texture Coordinate node's UV, each
  optionally through **Mapping** nodes without rotation (a plain scale and offset); other
  vectors, box/sphere/tube projection, UDIM tiles and movies give the image's *mean* colour and
  a warning. The lookup is always bilinear on linear values: an image's Closest or Cubic
  interpolation is read as bilinear, and Cycles, which interpolates 8-bit sRGB images before it
  linearizes them, gives darker blends where two very different texels meet (measured in
  ``tests/render/test_textures.py``: 1.5 % on a 256-texel checker, 7 % on a 64-texel one).
  **Mix** (colour) nodes with blend Mix or Multiply and a constant factor combine
  their inputs (two different textures: the second one's mean). An image that cannot be loaded
  is magenta (1, 0, 1), as Cycles renders it.
- **Float inputs** (Metallic, Transmission Weight, factors, Alpha): a constant; a Value node; an
  image's Alpha output, or its colour's luminance; Math Add, Subtract, Multiply with a constant.
  Metallic and Transmission use their mean. The Alpha may end in a Math Greater Than (cutoff
  = its threshold), Less Than (inverted) or Round (cutoff 0.5); otherwise the cutoff is 0.5.
- **Alpha**: where it is below the cutoff, rays pass through the surface. (Cycles lets a
  fraction ``1 - alpha`` of the light through; the test rounds that to all or nothing, exact for
  the binary masks of leaves and fences.)
- **The glossy layer**: a Principled BSDF with a specular level or metallic above 0, a Glossy,
  Anisotropic or Metallic BSDF has one, of its Roughness (the mean when a texture drives it);
  mixed or added shaders keep the sharpest of their sides'. Where it is rough (see
  ``export.ROUGH_GLOSS``) vplace models the light it shows a view as a broad lobe; a sharp one
  is left to EEVEE's ray tracing.
- **The glossy layer's reflectance** (its mean over incident directions): a Principled BSDF's
  ``E x Weight x (1 - Metallic)`` plus, for the metal, Base Color x 20/21 + 1/21 (Schlick's
  mean with the base colour as F0) x Weight x Metallic; a Glossy, Anisotropic or Metallic BSDF's
  Color x Weight; Mix and Add Shaders combine it as the albedo. A light path that reaches the
  surface leaves its VPL with the diffuse part and goes on off the layer in a mirror direction
  (GGX), as Cycles' light does. Without it, a metal reflected nothing and a dark dielectric a
  third too little: Sponza's light paths lit the views at 0.66-0.82 of Cycles' indirect light.
- **Anything else** (other shader nodes, procedural colour nodes, vertex colours): the
  material's viewport colour (Viewport Display > Color) with a warning naming the material; a
  float input fed by an unsupported node keeps its own value, with a warning.

A material whose Surface is unlinked renders black; one with only a Volume is a volume
container (left out by the export, with a warning); true displacement (Settings > Displacement
"Displacement Only" or "Both") is flagged: the export keeps the undisplaced surface and warns.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import bpy
import numpy as np

from ..native import vplace

__all__ = [
    "ImageCache",
    "ImageData",
    "Lin",
    "Surface",
    "TextureUse",
    "surface_of",
]

#: Rec. 709 luminance weights (the core's; Blender's colour-to-float conversion in linear).
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])
#: The colour Cycles renders for an image it cannot load.
MISSING_IMAGE = (1.0, 0.0, 1.0)
#: Shader nodes that reflect no diffuse light.
NON_DIFFUSE = {
    "EMISSION",
    "BSDF_GLOSSY",
    "BSDF_ANISOTROPIC",
    "BSDF_METALLIC",
    "BSDF_GLASS",
    "BSDF_REFRACTION",
    "HOLDOUT",
}
#: Shader nodes that let light through (a window's glass: ``Surface.transmits``).
TRANSMITTING = {"BSDF_GLASS", "BSDF_REFRACTION"}
#: Shader nodes whose only layer is glossy (their Roughness input is the layer's).
GLOSSY = {"BSDF_GLOSSY", "BSDF_ANISOTROPIC", "BSDF_METALLIC"}
#: Image Texture extension -> the core's wrap mode (Clip reads like Extend inside [0, 1]).
WRAP = {"REPEAT": "repeat", "EXTEND": "extend", "CLIP": "extend", "MIRROR": "mirror"}
#: Colour spaces of 8-bit images stored as linear values.
LINEAR_SPACES = ("Linear", "ACEScg", "ACES2065", "scene_linear", "Non-Color")


class Unsupported(Exception):
    """A node the rule does not cover; the message says which."""


@dataclass(frozen=True)
class TextureUse:
    """One image read through UVs: ``uv' = uv * uv_scale + uv_offset``, then ``channel``."""

    image: str  # Image.name_full
    uv_map: str  # "" = the active render UV map
    uv_scale: tuple[float, float] = (1.0, 1.0)
    uv_offset: tuple[float, float] = (0.0, 0.0)
    wrap: str = "repeat"
    channel: str = "rgb"  # "rgb", "alpha" or "luminance"

    def with_channel(self, channel: str) -> TextureUse:
        return TextureUse(
            self.image, self.uv_map, self.uv_scale, self.uv_offset, self.wrap, channel
        )


@dataclass
class ImageData:
    """An image's linear RGBA pixels, (H, W, 4) float32, row 0 at the top."""

    pixels: np.ndarray
    mean: np.ndarray  # (4,) float64

    @property
    def nbytes(self) -> int:
        return int(self.pixels.nbytes)


def _srgb_lut() -> np.ndarray:
    c = np.arange(256, dtype=np.float64) / 255.0
    lin = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    return lin.astype(np.float32)


SRGB_TO_LINEAR = _srgb_lut()


class ImageCache:
    """Reads each image once (``foreach_get`` into numpy) and shares it between materials."""

    def __init__(self) -> None:
        self._data: dict[str, ImageData | None] = {}
        self._images: dict[str, bpy.types.Image] = {}
        self.warnings: list[str] = []

    def register(self, image: bpy.types.Image) -> str:
        """Remembers ``image`` and returns its key."""
        key = image.name_full
        self._images[key] = image
        return key

    def get(self, key: str) -> ImageData | None:
        """The image's pixels, or None when it has none (missing file)."""
        if key not in self._data:
            self._data[key] = self._read(self._images[key])
        return self._data[key]

    def mean(self, use: TextureUse) -> np.ndarray:
        """The mean (3,) of what ``use`` reads (magenta for a missing image)."""
        data = self.get(use.image)
        if data is None:
            rgba = np.array([*MISSING_IMAGE, 1.0])
        else:
            rgba = data.mean
        if use.channel == "alpha":
            return np.full(3, rgba[3])
        if use.channel == "luminance":
            return np.full(3, float(LUMINANCE @ rgba[:3]))
        return np.asarray(rgba[:3], dtype=np.float64)

    def _read(self, image: bpy.types.Image) -> ImageData | None:
        w, h = image.size
        if w == 0 or h == 0:
            self.warnings.append(
                f"image {image.name!r} has no pixels (missing file?): it is read as magenta, "
                "as Cycles renders it"
            )
            return None
        channels = image.channels
        flat = np.empty(w * h * channels, dtype=np.float32)
        image.pixels.foreach_get(flat)
        space = image.colorspace_settings
        decode = (
            not image.is_float
            and not space.is_data
            and not any(space.name.startswith(s) for s in LINEAR_SPACES)
        )
        if decode and "sRGB" not in space.name:
            self.warnings.append(
                f"image {image.name!r} is in colour space {space.name!r}: read as sRGB"
            )
        # Flipped (bpy rows are bottom-first), decoded through the table and averaged natively:
        # numpy took 0.34 s for Sponza's 24 textures.
        out, mean = vplace.linear_image(
            flat.reshape(h, w, channels),
            table=SRGB_TO_LINEAR if decode else None,
            alpha=image.alpha_mode != "NONE",
            name=f"image {image.name!r}",
        )
        return ImageData(out, np.asarray(mean, dtype=np.float64))


@dataclass
class Lin:
    """``const + coef * value(tex)`` per RGB channel (a float is the same in all three)."""

    const: np.ndarray
    coef: np.ndarray = field(default_factory=lambda: np.zeros(3))
    tex: TextureUse | None = None

    @staticmethod
    def constant(value: Any) -> Lin:
        return Lin(np.broadcast_to(np.asarray(value, dtype=np.float64), (3,)).copy())

    @staticmethod
    def texture(use: TextureUse) -> Lin:
        return Lin(np.zeros(3), np.ones(3), use)

    @property
    def is_constant(self) -> bool:
        return self.tex is None or not self.coef.any()

    def mean(self, images: ImageCache) -> np.ndarray:
        if self.tex is None:
            return self.const.copy()
        return self.const + self.coef * images.mean(self.tex)

    def scaled(self, k: Any) -> Lin:
        k = np.asarray(k, dtype=np.float64)
        return Lin(self.const * k, self.coef * k, self.tex)

    def plus(self, other: Lin, images: ImageCache, warn: list[str]) -> Lin:
        if other.tex is None or not other.coef.any():
            return Lin(self.const + other.const, self.coef, self.tex)
        if self.tex is None or not self.coef.any():
            return Lin(self.const + other.const, other.coef, other.tex)
        if self.tex == other.tex:
            return Lin(self.const + other.const, self.coef + other.coef, self.tex)
        warn.append(
            f"two textures combined ({self.tex.image!r}, {other.tex.image!r}): the second is "
            "used as its mean colour"
        )
        return Lin(self.const + other.mean(images), self.coef, self.tex)

    def times(self, other: Lin, images: ImageCache, warn: list[str]) -> Lin:
        if other.is_constant:
            return self.scaled(other.const)
        if self.is_constant:
            return other.scaled(self.const)
        warn.append(
            f"two textures multiplied ({self.tex.image!r}, {other.tex.image!r}): the second "  # type: ignore[union-attr]
            "is used as its mean colour"
        )
        return self.scaled(other.mean(images))

    def luminance(self) -> Lin:
        """The float a colour gives a float input (Rec. 709 luminance)."""
        const = np.full(3, float(LUMINANCE @ self.const))
        if self.tex is None:
            return Lin(const)
        if self.tex.channel != "rgb":
            return Lin(const, np.full(3, float(LUMINANCE @ self.coef)), self.tex)
        if np.ptp(self.coef) == 0.0:
            return Lin(const, np.full(3, self.coef[0]), self.tex.with_channel("luminance"))
        raise Unsupported("a tinted texture used as a float")


@dataclass
class Surface:
    """What the core needs of a material: diffuse albedo and alpha as :class:`Lin` values."""

    albedo: Lin
    alpha: Lin
    cutoff: float = 0.5
    #: A bare Transparent BSDF (mixing with it sets the other side's alpha).
    transparent: bool = False
    #: The material only has a volume (its surface renders nothing).
    volume_only: bool = False
    #: The material displaces its geometry (displacement method Displacement or Both).
    displaced: bool = False
    #: The whole surface fell back to the viewport colour.
    fallback: bool = False
    #: The roughness of its glossy layer (the sharpest when there are several); None without
    #: one (see :data:`export.ROUGH_GLOSS`).
    gloss_roughness: float | None = None
    #: The glossy layers' reflectance (their mean over incident directions; see the module's
    #: rule), which the light paths reflect off besides the albedo; None: no layer.
    gloss: Lin | None = None
    #: Light passes through it (a Glass or Refraction BSDF, a Principled BSDF's transmission):
    #: the sky seen through a glass window still lights the room in Cycles.
    transmits: bool = False
    warnings: list[str] = field(default_factory=list)

    @property
    def alpha_tested(self) -> bool:
        return self.alpha.tex is not None or float(self.alpha.const[0]) < 1.0

    def textures(self) -> list[TextureUse]:
        """The textures the albedo and the alpha read."""
        return [lin.tex for lin in (self.albedo, self.alpha) if lin.tex is not None]


def _links(sock: bpy.types.NodeSocket) -> list[bpy.types.NodeLink]:
    return [link for link in sock.links if link.is_valid and not link.is_muted]


def _named_input(node: bpy.types.Node, *identifiers: str) -> bpy.types.NodeSocket | None:
    for ident in identifiers:
        for sock in node.inputs:
            if sock.identifier == ident and sock.enabled:
                return sock
    for ident in identifiers:
        for sock in node.inputs:
            if sock.identifier == ident:
                return sock
    return None


class _Evaluator:
    """Evaluates one material's node tree by the rule (see the module docs)."""

    def __init__(self, mat: bpy.types.Material, images: ImageCache) -> None:
        self.mat = mat
        self.images = images
        self.warnings: list[str] = []

    def warn(self, text: str) -> None:
        self.warnings.append(f"material {self.mat.name!r}: {text}")

    # --- following links through reroutes, muted nodes and groups -----------------------------
    def source(
        self, sock: bpy.types.NodeSocket, stack: tuple[bpy.types.Node, ...]
    ) -> tuple[bpy.types.Node, bpy.types.NodeSocket, tuple[bpy.types.Node, ...]] | None:
        """The node output that feeds ``sock`` after reroutes, muted nodes and group borders;
        None when nothing does (the socket's own value applies)."""
        for _ in range(256):
            links = _links(sock)
            if not links:
                return None
            node, out = links[0].from_node, links[0].from_socket
            if node.type == "REROUTE":
                sock = node.inputs[0]
            elif node.mute:
                through = [lk for lk in node.internal_links if lk.to_socket == out]
                if not through:
                    return None
                sock = through[0].from_socket
            elif node.type == "GROUP":
                tree = node.node_tree
                output = None
                if tree is not None:
                    outputs = [n for n in tree.nodes if n.type == "GROUP_OUTPUT"]
                    output = next((n for n in outputs if n.is_active_output), None) or (
                        outputs[0] if outputs else None
                    )
                inner = (
                    next((s for s in output.inputs if s.identifier == out.identifier), None)
                    if output is not None
                    else None
                )
                if inner is None:
                    return None
                stack = (*stack, node)
                sock = inner
            elif node.type == "GROUP_INPUT":
                if not stack:
                    return None
                group, stack = stack[-1], stack[:-1]
                outer = next((s for s in group.inputs if s.identifier == out.identifier), None)
                if outer is None:
                    return None
                sock = outer
            else:
                return node, out, stack
        raise Unsupported("a node loop")

    @staticmethod
    def default(sock: bpy.types.NodeSocket) -> Lin:
        v = getattr(sock, "default_value", 0.0)
        try:
            values = [float(x) for x in v]
        except TypeError:
            return Lin.constant(float(v))
        return Lin.constant(values[:3] if len(values) >= 3 else values[0])

    # --- colours and floats ------------------------------------------------------------------
    def color(self, sock: bpy.types.NodeSocket, stack: tuple[bpy.types.Node, ...] = ()) -> Lin:
        """A colour input (raises :class:`Unsupported`)."""
        src = self.source(sock, stack)
        if src is None:
            return self.default(sock)
        node, out, stack = src
        if node.type == "TEX_IMAGE":
            return self.image(node, stack, "alpha" if out.identifier == "Alpha" else "rgb")
        if node.type == "RGB":
            return Lin.constant(list(out.default_value)[:3])
        if node.type == "VALUE":
            return Lin.constant(float(out.default_value))
        if node.type in {"MIX", "MIX_RGB"}:
            return self.mix(node, stack)
        if node.type == "MATH":
            return self.math(node, stack)
        raise Unsupported(f"node {node.name!r} ({node.type}) feeds a colour")

    def value(self, sock: bpy.types.NodeSocket, stack: tuple[bpy.types.Node, ...] = ()) -> Lin:
        """A float input (raises :class:`Unsupported`)."""
        src = self.source(sock, stack)
        if src is None:
            return self.default(sock)
        node, out, stack = src
        if node.type == "TEX_IMAGE":
            return self.image(node, stack, "alpha" if out.identifier == "Alpha" else "luminance")
        if node.type == "VALUE":
            return Lin.constant(float(out.default_value))
        if node.type == "MATH":
            return self.math(node, stack)
        if node.type == "RGB":
            return Lin.constant(list(out.default_value)[:3]).luminance()
        if node.type in {"MIX", "MIX_RGB"}:
            mixed = self.mix(node, stack)
            return mixed if node.type == "MIX" and node.data_type == "FLOAT" else mixed.luminance()
        raise Unsupported(f"node {node.name!r} ({node.type}) feeds a value")

    def value_or_default(self, sock: bpy.types.NodeSocket | None, default: float, what: str) -> Lin:
        """A float input, or its own value (with a warning) when an unsupported node feeds it."""
        if sock is None:
            return Lin.constant(default)
        try:
            return self.value(sock)
        except Unsupported as exc:
            own = self.default(sock)
            self.warn(f"{what}: {exc}; its own value {float(own.const[0]):g} is used")
            return own

    def mean_value(self, sock: bpy.types.NodeSocket | None, default: float, what: str) -> float:
        return float(self.value_or_default(sock, default, what).mean(self.images)[0])

    def image(self, node: bpy.types.Node, stack: tuple[bpy.types.Node, ...], channel: str) -> Lin:
        """What an Image Texture node gives (``channel`` "rgb", "alpha" or "luminance"), read
        through its UVs, or its mean."""
        image = node.image
        if image is None:  # Cycles renders an Image Texture node without an image magenta
            rgba = np.array([*MISSING_IMAGE, 1.0])
            if channel == "rgb":
                return Lin.constant(rgba[:3])
            return Lin.constant(rgba[3] if channel == "alpha" else LUMINANCE @ rgba[:3])
        key = self.images.register(image)
        uv = self.uv_source(node.inputs["Vector"], stack)
        reason = None
        if uv is None:
            reason = "its vector is not a UV map (through Mapping without rotation)"
        elif node.projection != "FLAT":
            reason = f"{node.projection.lower()} projection"
        elif image.source not in {"FILE", "GENERATED"}:
            reason = f"image source {image.source}"
        wrap = WRAP.get(node.extension, "repeat")
        if reason is not None or uv is None:
            self.warn(f"image {image.name!r}: {reason}: its mean is used")
            return Lin.constant(self.images.mean(TextureUse(key, "", wrap=wrap, channel=channel)))
        uv_map, scale, offset = uv
        return Lin.texture(TextureUse(key, uv_map, scale, offset, wrap, channel))

    def uv_source(
        self, sock: bpy.types.NodeSocket, stack: tuple[bpy.types.Node, ...]
    ) -> tuple[str, tuple[float, float], tuple[float, float]] | None:
        """``(uv map, scale, offset)`` of an image's vector input; None when it is not UVs."""
        src = self.source(sock, stack)
        if src is None:
            return ("", (1.0, 1.0), (0.0, 0.0))  # unlinked: the active render UV map
        node, out, stack = src
        if node.type == "UVMAP" and not node.from_instancer:
            return (node.uv_map, (1.0, 1.0), (0.0, 0.0))
        if node.type == "TEX_COORD" and out.identifier == "UV" and not node.from_instancer:
            return ("", (1.0, 1.0), (0.0, 0.0))
        if node.type != "MAPPING" or node.vector_type == "NORMAL":
            return None
        params: dict[str, np.ndarray] = {}
        for name in ("Location", "Rotation", "Scale"):
            s = node.inputs.get(name)
            if s is None or not s.enabled:
                params[name] = np.zeros(3) if name != "Scale" else np.ones(3)
                continue
            if _links(s):
                return None
            params[name] = np.array(s.default_value[:3], dtype=np.float64)
        if np.any(params["Rotation"] != 0.0):
            return None
        inner = self.uv_source(node.inputs["Vector"], stack)
        if inner is None:
            return None
        uv_map, (s0u, s0v), (o0u, o0v) = inner
        sc, loc = params["Scale"], params["Location"]
        if node.vector_type == "POINT":
            k, b = sc[:2], loc[:2]  # v * S + L
        elif node.vector_type == "TEXTURE":
            if np.any(sc[:2] == 0.0):
                return None
            k, b = 1.0 / sc[:2], -loc[:2] / sc[:2]  # (v - L) / S
        else:  # VECTOR: no translation
            k, b = sc[:2], np.zeros(2)
        return (
            uv_map,
            (float(s0u * k[0]), float(s0v * k[1])),
            (float(o0u * k[0] + b[0]), float(o0v * k[1] + b[1])),
        )

    def mix(self, node: bpy.types.Node, stack: tuple[bpy.types.Node, ...]) -> Lin:
        """A Mix node (colour with blend Mix or Multiply, or float) or a legacy MixRGB."""
        floats = node.type == "MIX" and node.data_type == "FLOAT"
        if node.type == "MIX":
            if node.data_type not in {"RGBA", "FLOAT"}:
                raise Unsupported(f"Mix node {node.name!r} of type {node.data_type}")
            kind = "Float" if floats else "Color"
            fac_sock = _named_input(node, "Factor_Float")
            a_sock, b_sock = _named_input(node, f"A_{kind}"), _named_input(node, f"B_{kind}")
        else:
            fac_sock, a_sock, b_sock = node.inputs[0], node.inputs[1], node.inputs[2]
        blend = "MIX" if floats else node.blend_type
        if blend not in {"MIX", "MULTIPLY"}:
            raise Unsupported(f"Mix node {node.name!r} with blend {blend}")
        if fac_sock is None or a_sock is None or b_sock is None:
            raise Unsupported(f"Mix node {node.name!r} without its inputs")
        f = float(self.value(fac_sock, stack).mean(self.images)[0])
        f = min(max(f, 0.0), 1.0)
        read = self.value if floats else self.color
        a, b = read(a_sock, stack), read(b_sock, stack)
        if blend == "MIX":
            return a.scaled(1.0 - f).plus(b.scaled(f), self.images, self.warnings)
        # Multiply: lerp(A, A * B, f) = A * lerp(1, B, f)
        return a.times(
            Lin.constant(1.0 - f).plus(b.scaled(f), self.images, self.warnings),
            self.images,
            self.warnings,
        )

    def math(self, node: bpy.types.Node, stack: tuple[bpy.types.Node, ...]) -> Lin:
        op = node.operation
        if op not in {"ADD", "SUBTRACT", "MULTIPLY"}:
            raise Unsupported(f"Math node {node.name!r} ({op})")
        a, b = self.value(node.inputs[0], stack), self.value(node.inputs[1], stack)
        if op == "ADD":
            out = a.plus(b, self.images, self.warnings)
        elif op == "SUBTRACT":
            out = a.plus(b.scaled(-1.0), self.images, self.warnings)
        else:
            out = a.times(b, self.images, self.warnings)
        if node.use_clamp:
            if not out.is_constant:
                raise Unsupported(f"Math node {node.name!r} with clamp on a texture")
            out = Lin.constant(np.clip(out.const, 0.0, 1.0))
        return out

    def alpha(self, sock: bpy.types.NodeSocket | None) -> tuple[Lin, float]:
        """An Alpha input and its cutoff (Math Greater Than / Less Than / Round at the end)."""
        if sock is None:
            return Lin.constant(1.0), 0.5
        try:
            src = self.source(sock, ())
            if src is not None and src[0].type == "MATH":
                node, _, stack = src
                op = node.operation
                if op == "ROUND":
                    return self.value(node.inputs[0], stack), 0.5
                if op in {"GREATER_THAN", "LESS_THAN"}:
                    x = self.value(node.inputs[0], stack)
                    threshold = self.value(node.inputs[1], stack)
                    if not threshold.is_constant:
                        raise Unsupported(f"Math node {node.name!r} with a textured threshold")
                    th = float(threshold.const[0])
                    if op == "GREATER_THAN":
                        return x, th
                    return Lin.constant(1.0).plus(x.scaled(-1.0), self.images, []), 1.0 - th
            return self.value(sock), 0.5
        except Unsupported as exc:
            own = self.default(sock)
            self.warn(f"Alpha: {exc}; its own value {float(own.const[0]):g} is used")
            return own, 0.5

    # --- shaders -----------------------------------------------------------------------------
    def shader(self, sock: bpy.types.NodeSocket) -> Surface:
        """The surface of a shader socket (raises :class:`Unsupported`)."""
        src = self.source(sock, ())
        if src is None:
            return Surface(Lin.constant(0.0), Lin.constant(1.0))  # renders black
        node, _, stack = src
        return self.shader_node(node, stack)

    def shader_node(self, node: bpy.types.Node, stack: tuple[bpy.types.Node, ...]) -> Surface:
        kind = node.type
        weight = node.inputs.get("Weight")
        w = self.mean_value(weight, 1.0, "Weight") if weight is not None else 1.0
        if kind == "BSDF_PRINCIPLED":
            base = self.color(node.inputs["Base Color"], stack)
            metallic = self.mean_value(node.inputs.get("Metallic"), 0.0, "Metallic")
            trans = self.mean_value(
                _named_input(node, "Transmission Weight", "Transmission"), 0.0, "Transmission"
            )
            k = w * (1.0 - min(max(metallic, 0.0), 1.0)) * (1.0 - min(max(trans, 0.0), 1.0))
            alpha, cutoff = self.alpha(node.inputs.get("Alpha"))
            level = self.mean_value(node.inputs.get("Specular IOR Level"), 0.5, "Specular")
            rough = None
            layer = None
            e = 0.0
            if w > 0.0 and (level > 0.0 or metallic > 0.0):
                rough = self.mean_value(node.inputs.get("Roughness"), 0.5, "Roughness")
                ior = self.mean_value(node.inputs.get("IOR"), 1.5, "IOR")
                m = min(max(metallic, 0.0), 1.0)
                e = dielectric_reflectance(ior, level)
                # The metal's layer (Schlick's mean, F0 = the base colour) and the dielectric
                # layer over the rest.
                layer = base.scaled(w * m * 20.0 / 21.0).plus(
                    Lin.constant(w * (1.0 - m) * e + w * m / 21.0), self.images, self.warnings
                )
            albedo = base.scaled(k * (1.0 - e))
            transmits = w > 0.0 and trans > 0.0 and metallic < 1.0
            return Surface(
                albedo, alpha, cutoff, gloss_roughness=rough, gloss=layer, transmits=transmits
            )
        if kind in {"BSDF_DIFFUSE", "SUBSURFACE_SCATTERING"}:
            return Surface(self.color(node.inputs["Color"], stack).scaled(w), Lin.constant(1.0))
        if kind in NON_DIFFUSE:
            rough = None
            layer = None
            if kind in GLOSSY and w > 0.0:
                rough = self.mean_value(node.inputs.get("Roughness"), 0.5, "Roughness")
                col = _named_input(node, "Color", "Base Color")
                if col is not None:
                    layer = self.color(col, stack).scaled(w)
            return Surface(
                Lin.constant(0.0),
                Lin.constant(1.0),
                gloss_roughness=rough,
                gloss=layer,
                transmits=kind in TRANSMITTING and w > 0.0,
            )
        if kind == "BSDF_TRANSPARENT":
            return Surface(Lin.constant(0.0), Lin.constant(0.0), transparent=True)
        if kind == "MIX_SHADER":
            return self.mix_shader(node, stack)
        if kind == "ADD_SHADER":
            a = self.shader_input(node.inputs[0], stack)
            b = self.shader_input(node.inputs[1], stack)
            return Surface(
                a.albedo.plus(b.albedo, self.images, self.warnings),
                a.alpha.plus(b.alpha, self.images, self.warnings).plus(
                    Lin.constant(-1.0), self.images, self.warnings
                ),
                min(a.cutoff, b.cutoff),
                gloss_roughness=_sharpest(a, b),
                gloss=self.mixed_gloss(a, b, 1.0, 1.0),
                transmits=a.transmits or b.transmits,
            )
        raise Unsupported(f"shader node {node.name!r} ({kind})")

    def shader_input(
        self, sock: bpy.types.NodeSocket, stack: tuple[bpy.types.Node, ...]
    ) -> Surface:
        src = self.source(sock, stack)
        if src is None:
            return Surface(Lin.constant(0.0), Lin.constant(1.0))
        return self.shader_node(src[0], src[2])

    def mix_shader(self, node: bpy.types.Node, stack: tuple[bpy.types.Node, ...]) -> Surface:
        fac = self.value_or_default(node.inputs[0], 0.5, "Mix Shader factor")
        a = self.shader_input(node.inputs[1], stack)
        b = self.shader_input(node.inputs[2], stack)
        if a.transparent and b.transparent:
            return a
        if a.transparent or b.transparent:
            keep = b if a.transparent else a
            # alpha of the kept side times the share it gets: f for the second input,
            # 1 - f for the first.
            share = (
                fac if a.transparent else Lin.constant(1.0).plus(fac.scaled(-1.0), self.images, [])
            )
            if keep.alpha.is_constant:
                alpha = share.scaled(keep.alpha.const)
            else:
                alpha = keep.alpha.times(share, self.images, self.warnings)
            return Surface(
                keep.albedo,
                alpha,
                keep.cutoff,
                gloss_roughness=keep.gloss_roughness,
                gloss=keep.gloss,
                transmits=keep.transmits,
            )
        f = min(max(float(fac.mean(self.images)[0]), 0.0), 1.0)
        return Surface(
            a.albedo.scaled(1.0 - f).plus(b.albedo.scaled(f), self.images, self.warnings),
            a.alpha.scaled(1.0 - f).plus(b.alpha.scaled(f), self.images, self.warnings),
            min(a.cutoff, b.cutoff),
            gloss_roughness=_sharpest(a if f < 1.0 else None, b if f > 0.0 else None),
            gloss=self.mixed_gloss(a, b, 1.0 - f, f),
            transmits=(a.transmits and f < 1.0) or (b.transmits and f > 0.0),
        )

    def mixed_gloss(self, a: Surface, b: Surface, ka: float, kb: float) -> Lin | None:
        """``ka a + kb b`` of two sides' glossy reflectance; None when neither side has a
        layer."""
        if a.gloss is None and b.gloss is None:
            return None
        zero = Lin.constant(0.0)
        sides = [(s.gloss or zero).scaled(k) for s, k in ((a, ka), (b, kb))]
        return sides[0].plus(sides[1], self.images, self.warnings)


def dielectric_reflectance(ior: float, level: float = 0.5) -> float:
    """The cosine-weighted mean over incident directions of the Fresnel reflectance of a
    Principled BSDF's dielectric layer: ``F0 = ((ior - 1) / (ior + 1))^2 * 2 level`` (Blender's
    Specular IOR Level), turned back into the index it stands for and integrated with the exact
    unpolarized Fresnel term (0.092 at IOR 1.5, level 0.5; 0 at level 0)."""
    f0 = min(max(((ior - 1.0) / (ior + 1.0)) ** 2 * 2.0 * level, 0.0), 0.999)
    if f0 <= 0.0:
        return 0.0
    eta = (1.0 + f0**0.5) / (1.0 - f0**0.5)
    mu = (np.arange(512) + 0.5) / 512.0
    g = np.sqrt(eta * eta - 1.0 + mu * mu)
    fr = (
        0.5
        * ((g - mu) / (g + mu)) ** 2
        * (1.0 + ((mu * (g + mu) - 1.0) / (mu * (g - mu) + 1.0)) ** 2)
    )
    return float(2.0 * np.mean(fr * mu))


def _sharpest(*sides: Surface | None) -> float | None:
    """The lowest glossy roughness of the sides that have a glossy layer (None: no side has)."""
    found = [s.gloss_roughness for s in sides if s is not None and s.gloss_roughness is not None]
    return min(found) if found else None


def surface_of(mat: bpy.types.Material | None, images: ImageCache) -> Surface:
    """The material rule (module docs) applied to ``mat``; None is Blender's default grey."""
    if mat is None:
        return Surface(Lin.constant(0.8), Lin.constant(1.0))
    viewport = Lin.constant(list(mat.diffuse_color)[:3])
    tree = mat.node_tree
    if tree is None:
        return Surface(viewport, Lin.constant(1.0))
    out = tree.get_output_node("CYCLES")
    if out is None:
        return Surface(viewport, Lin.constant(1.0))
    ev = _Evaluator(mat, images)
    surface_sock, volume_sock = out.inputs["Surface"], out.inputs.get("Volume")
    has_surface = bool(_links(surface_sock))
    has_volume = volume_sock is not None and bool(_links(volume_sock))
    if not has_surface and has_volume:
        s = Surface(Lin.constant(0.0), Lin.constant(0.0), volume_only=True)
    else:
        try:
            s = ev.shader(surface_sock)
        except Unsupported as exc:
            ev.warn(f"{exc}: the viewport colour is used")
            s = Surface(viewport, Lin.constant(1.0), fallback=True)
    disp = out.inputs.get("Displacement")
    s.displaced = disp is not None and bool(_links(disp)) and mat.displacement_method != "BUMP"
    s.warnings = ev.warnings + s.warnings
    return s
