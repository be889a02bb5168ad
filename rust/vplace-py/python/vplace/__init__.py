"""vplace: regression-guided virtual point light layout, at the numpy level.

Usable without Blender. The native classes and functions come from ``vplace._native`` (Rust);
this package re-exports them and adds the Python-level API.
"""

from vplace import par2d as par2d
from vplace._native import (
    MAX_BOUNCES,
    CancelledError,
    InputError,
    InternalError,
    Light,
    Progress,
    Scene,
    VplaceError,
    __version__,
    evaluate,
    relative_mse,
    rmse,
    rsm_vpls,
    ssim,
    uniform_vpls,
)
from vplace.fit import FitResult, extract_features, fit, fit_design
from vplace.layout import Layout, layout
from vplace.refit import Refit, refit

__all__ = [
    "MAX_BOUNCES",
    "CancelledError",
    "FitResult",
    "InputError",
    "InternalError",
    "Layout",
    "Light",
    "Progress",
    "Refit",
    "Scene",
    "VplaceError",
    "__version__",
    "evaluate",
    "extract_features",
    "fit",
    "fit_design",
    "layout",
    "refit",
    "relative_mse",
    "rmse",
    "rsm_vpls",
    "ssim",
    "uniform_vpls",
]
