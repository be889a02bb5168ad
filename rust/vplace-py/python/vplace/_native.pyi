# Type stubs for the Rust extension module vplace._native, checked by mypy.stubtest in the tests.
# Each section belongs to one part of the library; keep sections in this order.

from collections.abc import Sequence
from typing import Any, TypeAlias, final

import numpy as np
import numpy.typing as npt

__version__: str
VPL_SURFACE_OFFSET: float
MAX_BOUNCES: int
LUMINANCE: list[float]
NEAR_FIELD_FRACTION: float

# --- errors -------------------------------------------------------------------------------
class VplaceError(Exception): ...
class InputError(VplaceError): ...
class CancelledError(VplaceError): ...
class InternalError(VplaceError): ...

# --- scene, metrics (scene.rs) ------------------------------------------------------------
_Vec3: TypeAlias = tuple[float, float, float] | list[float]
_F32: TypeAlias = npt.NDArray[np.float32]

@final
class Light:
    @staticmethod
    def point(
        position: _Vec3, power: _Vec3, radius: float = 0.0, soft_falloff: bool = True
    ) -> Light: ...
    @staticmethod
    def spot(
        position: _Vec3,
        direction: _Vec3,
        half_angle: float,
        power: _Vec3,
        blend: float = 0.0,
        radius: float = 0.0,
        soft_falloff: bool = True,
    ) -> Light: ...
    @staticmethod
    def area(
        position: _Vec3,
        direction: _Vec3,
        tangent: _Vec3,
        shape: bool | str,
        size_x: float,
        size_y: float,
        power: _Vec3,
        spread: float = ...,
    ) -> Light: ...
    @staticmethod
    def sun(direction: _Vec3, irradiance: _Vec3, angle: float = 0.0) -> Light: ...
    @staticmethod
    def world(
        color: _Vec3 = ...,
        strength: float = 1.0,
        image: _F32 | None = None,
        rotation: Sequence[Sequence[float]] | npt.NDArray[np.floating[Any]] | None = None,
    ) -> Light: ...
    @property
    def kind(self) -> str: ...
    @property
    def power(self) -> list[float]: ...

@final
class TextureMap:
    def __new__(
        cls,
        texture: int,
        *,
        uv_scale: tuple[float, float] = ...,
        uv_offset: tuple[float, float] = ...,
        wrap: str = "repeat",
    ) -> TextureMap: ...
    @property
    def texture(self) -> int: ...
    @property
    def uv_scale(self) -> tuple[float, float]: ...
    @property
    def uv_offset(self) -> tuple[float, float]: ...
    @property
    def wrap(self) -> str: ...

@final
class AlphaTest:
    def __new__(
        cls,
        offset: float,
        scale: float = 0.0,
        texture: TextureMap | None = None,
        *,
        source: str = "alpha",
        cutoff: float = 0.5,
    ) -> AlphaTest: ...
    @property
    def offset(self) -> float: ...
    @property
    def scale(self) -> float: ...
    @property
    def texture(self) -> TextureMap | None: ...
    @property
    def source(self) -> str: ...
    @property
    def cutoff(self) -> float: ...

@final
class Scene:
    def __new__(
        cls,
        vertices: _F32,
        triangles: npt.NDArray[np.uint32],
        material_ids: npt.NDArray[np.uint32],
        albedo: _F32,
        lights: list[Light],
        *,
        emission: _F32 | None = None,
        uvs: _F32 | None = None,
        textures: Sequence[_F32] | None = None,
        base_textures: Sequence[TextureMap | None] | None = None,
        texture_tint: _F32 | None = None,
        alpha_tests: Sequence[AlphaTest | None] | None = None,
    ) -> Scene: ...
    def intersect(
        self, origins: _F32, directions: _F32, tmin: float = 0.0
    ) -> tuple[_F32, npt.NDArray[np.int64], _F32]: ...
    def albedo_at(self, triangles: npt.NDArray[np.uint32], barycentrics: _F32) -> _F32: ...
    def occluded(self, origins: _F32, targets: _F32) -> npt.NDArray[np.bool_]: ...
    @property
    def texture_count(self) -> int: ...
    @property
    def has_alpha_tests(self) -> bool: ...
    @property
    def triangle_count(self) -> int: ...
    @property
    def light_count(self) -> int: ...
    @property
    def emissive_triangle_count(self) -> int: ...
    def emitted_powers(self) -> list[tuple[str, list[float]]]: ...
    @property
    def degenerate_triangles(self) -> int: ...
    @property
    def bounds(self) -> tuple[list[float], list[float]]: ...
    @property
    def diagonal(self) -> float: ...
    @property
    def near_field_radius(self) -> float: ...

@final
class Progress:
    def __new__(cls) -> Progress: ...
    @property
    def done(self) -> int: ...
    @property
    def total(self) -> int: ...
    @property
    def cancelled(self) -> bool: ...
    def cancel(self) -> None: ...

def rmse(image: _F32, reference: _F32) -> float: ...
def relative_mse(image: _F32, reference: _F32) -> float: ...
def ssim(image: _F32, reference: _F32) -> float: ...

# --- views (view.rs) ----------------------------------------------------------------------
@final
class View:
    def __new__(
        cls,
        *,
        position: _F32,
        normal: _F32,
        albedo: _F32,
        covered: npt.NDArray[np.bool_],
        depth: _F32,
        direct: _F32,
        diffuse_direct: _F32,
        camera_position: _Vec3,
        world_to_clip: Any,
        diffuse_indirect: _F32 | None = None,
        indirect: _F32 | None = None,
        specular: _F32 | None = None,
        name: str = "view",
    ) -> View: ...
    def without_indirect(self) -> View: ...
    @property
    def name(self) -> str: ...
    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...
    @property
    def masked_pixels(self) -> int: ...
    @property
    def has_indirect(self) -> bool: ...
    @property
    def camera_position(self) -> list[float]: ...
    @property
    def position(self) -> _F32: ...
    @property
    def normal(self) -> _F32: ...
    @property
    def albedo(self) -> _F32: ...
    @property
    def covered(self) -> npt.NDArray[np.bool_]: ...
    @property
    def indirect(self) -> _F32 | None: ...

# --- VPL sets, uniform and RSM layouts, the evaluator (vpls.rs) ---------------------------
@final
class VplSet:
    def __new__(
        cls,
        position: _F32,
        normal: _F32,
        flux: _F32,
        *,
        profile: str = "cosine",
        radius: float = 0.0,
    ) -> VplSet: ...
    def with_flux(self, flux: _F32) -> VplSet: ...
    def __len__(self) -> int: ...
    @property
    def position(self) -> _F32: ...
    @property
    def normal(self) -> _F32: ...
    @property
    def flux(self) -> _F32: ...
    @property
    def blender_power(self) -> _F32: ...
    @property
    def profile(self) -> str: ...
    @property
    def radius(self) -> float: ...

@final
class EvalStats:
    @property
    def shadow_rays(self) -> int: ...
    @property
    def pairs(self) -> int: ...
    @property
    def seconds(self) -> float: ...
    @property
    def rays_per_second(self) -> float: ...

def uniform_vpls(
    scene: Scene,
    n: int,
    *,
    seed: int = 0,
    bounces: int = 1,
    profile: str = "cosine",
    radius: float | None = None,
) -> VplSet: ...
def rsm_vpls(
    scene: Scene, n: int, *, profile: str = "cosine", radius: float | None = None
) -> VplSet: ...
def evaluate(
    scene: Scene,
    view: View,
    vpls: VplSet,
    *,
    tile: int = 16,
    progress: Progress | None = None,
    brute_force: bool = False,
) -> tuple[_F32, EvalStats]: ...

# --- features and regression (fit.rs) -----------------------------------------------------
@final
class Fit:
    @property
    def feature_names(self) -> list[str]: ...
    @property
    def kept(self) -> list[str]: ...
    @property
    def dropped(self) -> dict[str, str]: ...
    @property
    def intercept(self) -> float: ...
    @property
    def coefficients(self) -> dict[str, float]: ...
    @property
    def weights(self) -> dict[str, float]: ...
    @property
    def r2(self) -> float: ...
    @property
    def adjusted_r2(self) -> float | None: ...
    @property
    def cv_r2(self) -> float | None: ...
    @property
    def folds(self) -> int: ...
    @property
    def condition_number(self) -> float: ...
    @property
    def rank(self) -> int: ...
    @property
    def ridge_lambda(self) -> float: ...
    @property
    def n_cells(self) -> int: ...
    @property
    def fitted(self) -> npt.NDArray[np.float64]: ...
    @property
    def cell_px(self) -> int | None: ...
    @property
    def light(self) -> tuple[str, list[float]] | None: ...
    @property
    def view_names(self) -> list[str]: ...
    @property
    def view_r2(self) -> dict[str, float | None]: ...
    @property
    def empty_cells(self) -> int: ...
    @property
    def masked_pixels(self) -> int: ...
    @property
    def feature_min(self) -> list[float] | None: ...
    @property
    def feature_max(self) -> list[float] | None: ...
    def predict(self, view: View) -> npt.NDArray[np.float64]: ...
    def out_of_range(self, view: View) -> list[tuple[str, float]]: ...
    def predict_design(self, x: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]: ...
    def to_json(self) -> str: ...
    @staticmethod
    def from_json(text: str) -> Fit: ...

def feature_registry() -> list[tuple[str, str, str, bool]]: ...
def extract_features(scene: Scene, view: View, *, cell_px: int = 16) -> dict[str, Any]: ...
def fit(
    scene: Scene,
    views: Sequence[View],
    *,
    cell_px: int = 16,
    surface_only: bool = True,
    folds: int = 5,
    select: bool = True,
    min_cv_gain: float = 1e-3,
    collinear_rtol: float = 1e-6,
    rank_rtol: float | None = None,
    ridge_above: float = 1e6,
    seed: int = 0x5EED,
) -> Fit: ...
def fit_design(
    x: npt.NDArray[np.float64],
    y: npt.NDArray[np.float64],
    *,
    names: list[str] | None = None,
    folds: int = 5,
    select: bool = True,
    min_cv_gain: float = 1e-3,
    collinear_rtol: float = 1e-6,
    rank_rtol: float | None = None,
    ridge_above: float = 1e6,
    seed: int = 0x5EED,
) -> Fit: ...

# --- PAR 2D (par2d.rs) --------------------------------------------------------------------
@final
class Scene2D:
    def __new__(
        cls,
        vertices: npt.NDArray[np.float64],
        counts: list[int],
        emission: npt.NDArray[np.float64],
    ) -> Scene2D: ...
    @property
    def polygon_count(self) -> int: ...
    @property
    def light_count(self) -> int: ...
    def polygon(self, index: int) -> npt.NDArray[np.float64]: ...
    def irradiance(
        self,
        points: npt.NDArray[np.float64],
        method: str = "exact",
        rays: int = 1024,
        seed: int = 0,
        progress: Progress | None = None,
    ) -> npt.NDArray[np.float64]: ...
    def light_map(
        self,
        bounds: tuple[float, float, float, float] | list[float],
        width: int,
        height: int,
        method: str = "exact",
        rays: int = 1024,
        seed: int = 0,
        progress: Progress | None = None,
    ) -> npt.NDArray[np.float64]: ...
    def __len__(self) -> int: ...

# --- layout (layout.rs) -------------------------------------------------------------------
@final
class Layout:
    @property
    def vpls(self) -> VplSet: ...
    def __len__(self) -> int: ...
    @property
    def counts(self) -> list[npt.NDArray[np.int64]]: ...
    @property
    def strata_flux(self) -> list[_F32]: ...
    @property
    def offscreen_count(self) -> int: ...
    @property
    def pool_count(self) -> int: ...
    @property
    def errors(self) -> list[float]: ...
    @property
    def best(self) -> int | None: ...
    @property
    def error(self) -> float | None: ...
    @property
    def seconds(self) -> list[float]: ...
    @property
    def shadow_rays(self) -> list[int]: ...
    @property
    def reused_rays(self) -> list[int]: ...
    @property
    def offscreen_flux(self) -> list[float]: ...
    @property
    def offscreen_view_weight(self) -> list[float]: ...
    @property
    def candidates(self) -> int: ...
    @property
    def light_hits_on_screen(self) -> int: ...
    @property
    def shared_pixels(self) -> int: ...
    @property
    def indirect_source(self) -> list[str]: ...

def layout(
    scene: Scene,
    views: Sequence[View],
    *,
    fit: Fit | None = None,
    budget: int = 256,
    alpha: float = 1.0,
    cell_px: int | None = None,
    iterate: bool = True,
    light_rays: int = 4096,
    bounces: int | None = None,
    seed: int = 0,
    stride: int = 4,
    iterations: int = 3,
    tolerance: float = 0.01,
    step: float = 0.5,
    profile: str = "cosine",
    radius: float | None = None,
    multi_bounce: bool = True,
    tile: int = 16,
    progress: Progress | None = None,
) -> Layout: ...

# --- refit of VPL powers (refit.rs) -------------------------------------------------------
@final
class Refit:
    @property
    def vpls(self) -> VplSet: ...
    def __len__(self) -> int: ...
    @property
    def scales(self) -> npt.NDArray[np.float64]: ...
    @property
    def error_before(self) -> float: ...
    @property
    def error_after(self) -> float: ...
    @property
    def pixels(self) -> int: ...
    @property
    def shadow_rays(self) -> int: ...
    @property
    def exchanges(self) -> int: ...
    @property
    def seconds(self) -> float: ...

def refit(
    scene: Scene,
    views: Sequence[View],
    vpls: VplSet,
    *,
    stride: int = 4,
    ridge: float = 0.1,
    progress: Progress | None = None,
) -> Refit: ...

# --- the direct-light estimator (direct.rs) -----------------------------------------------
MAX_DIRECT_SAMPLES: int

def direct_light(
    scene: Scene,
    view: View,
    *,
    samples: int = 64,
    seed: int = 0,
    progress: Progress | None = None,
) -> _F32: ...
