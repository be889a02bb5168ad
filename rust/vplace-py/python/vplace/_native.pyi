# Type stubs for the Rust extension module vplace._native, checked by mypy.stubtest in the tests.
# Each section belongs to one part of the library; keep sections in this order.

from typing import Any, TypeAlias, final

import numpy as np
import numpy.typing as npt

__version__: str
VPL_SURFACE_OFFSET: float

# --- errors -------------------------------------------------------------------------------
class VplaceError(Exception): ...
class InputError(VplaceError): ...
class CancelledError(VplaceError): ...
class InternalError(VplaceError): ...

# --- scene, VPLs, evaluator, metrics ------------------------------------------------------
_Vec3: TypeAlias = tuple[float, float, float] | list[float]

@final
class Light:
    @staticmethod
    def point(position: _Vec3, power: _Vec3) -> Light: ...
    @staticmethod
    def spot(position: _Vec3, direction: _Vec3, half_angle: float, power: _Vec3) -> Light: ...
    @staticmethod
    def area(
        position: _Vec3,
        direction: _Vec3,
        tangent: _Vec3,
        disk: bool,
        size_x: float,
        size_y: float,
        power: _Vec3,
    ) -> Light: ...
    @staticmethod
    def sun(direction: _Vec3, irradiance: _Vec3) -> Light: ...
    @property
    def kind(self) -> str: ...
    @property
    def power(self) -> list[float]: ...

@final
class Scene:
    def __new__(
        cls,
        vertices: npt.NDArray[np.float32],
        triangles: npt.NDArray[np.uint32],
        material_ids: npt.NDArray[np.uint32],
        albedo: npt.NDArray[np.float32],
        lights: list[Light],
    ) -> Scene: ...
    @property
    def triangle_count(self) -> int: ...
    @property
    def light_count(self) -> int: ...
    @property
    def degenerate_triangles(self) -> int: ...
    @property
    def bounds(self) -> tuple[list[float], list[float]]: ...
    @property
    def diagonal(self) -> float: ...

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

def uniform_vpls(
    scene: Scene, n: int, seed: int = 0, bounces: int = 1
) -> dict[str, npt.NDArray[np.float32]]: ...

MAX_BOUNCES: int

def evaluate(
    scene: Scene,
    position: npt.NDArray[np.float32],
    normal: npt.NDArray[np.float32],
    albedo: npt.NDArray[np.float32],
    covered: npt.NDArray[np.bool_],
    vpl_position: npt.NDArray[np.float32],
    vpl_normal: npt.NDArray[np.float32],
    vpl_flux: npt.NDArray[np.float32],
    profile: str = "cosine",
    r_min: float = 0.01,
    tile: int = 16,
    progress: Progress | None = None,
    brute_force: bool = False,
) -> tuple[npt.NDArray[np.float32], dict[str, Any]]: ...
def rmse(image: npt.NDArray[np.float32], reference: npt.NDArray[np.float32]) -> float: ...
def relative_mse(image: npt.NDArray[np.float32], reference: npt.NDArray[np.float32]) -> float: ...

# --- features and regression (fit.rs) -----------------------------------------------------
def feature_registry() -> list[tuple[str, str, str]]: ...
def extract_features(
    position: npt.NDArray[np.float32],
    normal: npt.NDArray[np.float32],
    albedo: npt.NDArray[np.float32],
    depth: npt.NDArray[np.float32],
    direct: npt.NDArray[np.float32],
    covered: npt.NDArray[np.bool_],
    *,
    gi: npt.NDArray[np.float32] | None = None,
    specular: npt.NDArray[np.float32] | None = None,
    light_position: _Vec3 | None = None,
    light_direction: _Vec3 | None = None,
    cell_px: int = 16,
) -> dict[str, Any]: ...
def fit_capture(
    position: npt.NDArray[np.float32],
    normal: npt.NDArray[np.float32],
    albedo: npt.NDArray[np.float32],
    depth: npt.NDArray[np.float32],
    direct: npt.NDArray[np.float32],
    covered: npt.NDArray[np.bool_],
    gi: npt.NDArray[np.float32],
    *,
    specular: npt.NDArray[np.float32] | None = None,
    light_position: _Vec3 | None = None,
    light_direction: _Vec3 | None = None,
    cell_px: int = 16,
    folds: int = 5,
    select: bool = True,
    min_cv_gain: float = 1e-3,
    collinear_rtol: float = 1e-6,
    rank_rtol: float | None = None,
    ridge_above: float = 1e6,
    seed: int = 0x5EED,
) -> tuple[dict[str, Any], dict[str, Any], npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...
def fit_design(
    x: npt.NDArray[np.float64],
    y: npt.NDArray[np.float64],
    *,
    folds: int = 5,
    select: bool = True,
    min_cv_gain: float = 1e-3,
    collinear_rtol: float = 1e-6,
    rank_rtol: float | None = None,
    ridge_above: float = 1e6,
    seed: int = 0x5EED,
) -> dict[str, Any]: ...

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

# --- layout, RSM baseline, SSIM (layout.rs) -----------------------------------------------
def layout(
    scene: Scene,
    position: npt.NDArray[np.float32],
    normal: npt.NDArray[np.float32],
    albedo: npt.NDArray[np.float32],
    covered: npt.NDArray[np.bool_],
    diffuse_direct: npt.NDArray[np.float32],
    camera_position: _Vec3,
    world_to_clip: Any,
    *,
    indirect: npt.NDArray[np.float32] | None = None,
    predicted: npt.NDArray[np.float64] | None = None,
    budget: int = 256,
    alpha: float = 1.0,
    cell_px: int = 16,
    light_rays: int = 4096,
    bounces: int = ...,
    seed: int = 0,
    stride: int = 4,
    iterations: int = 3,
    tolerance: float = 0.01,
    step: float = 0.5,
    profile: str = "cosine",
    r_min: float = 0.01,
    tile: int = 16,
    progress: Progress | None = None,
) -> dict[str, Any]: ...
def rsm_vpls(scene: Scene, n: int) -> dict[str, npt.NDArray[np.float32]]: ...
def ssim(image: npt.NDArray[np.float32], reference: npt.NDArray[np.float32]) -> float: ...

# --- refit of VPL powers (refit.rs) -------------------------------------------------------
def refit(
    scene: Scene,
    position: npt.NDArray[np.float32],
    normal: npt.NDArray[np.float32],
    albedo: npt.NDArray[np.float32],
    covered: npt.NDArray[np.bool_],
    vpl_position: npt.NDArray[np.float32],
    vpl_normal: npt.NDArray[np.float32],
    vpl_flux: npt.NDArray[np.float32],
    indirect: npt.NDArray[np.float32],
    *,
    stride: int = 4,
    ridge: float = 0.1,
    profile: str = "cosine",
    r_min: float = 0.01,
    progress: Progress | None = None,
) -> dict[str, Any]: ...
