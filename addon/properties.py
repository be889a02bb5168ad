"""Settings and last results, stored in the .blend as ``Scene.vplace``."""

from __future__ import annotations

import json
from typing import Any

import bpy
from bpy.props import (
    BoolProperty,
    EnumProperty,
    FloatProperty,
    IntProperty,
    PointerProperty,
    StringProperty,
)

from .pipeline import Job

#: The job's defaults: the panel starts where the command line does.
_DEFAULT = Job()

PROFILE_ITEMS = [
    ("cosine", "Cosine (area disk)", "Lambertian VPLs as small AREA disk lights (exact)"),
    ("omni", "Omni (point)", "VPLs as POINT lights of twice the flux (cheaper in EEVEE)"),
]
METHOD_ITEMS = [
    ("vplace", "Regression-guided", "The paper's layout: more VPLs where indirect light is strong"),
    ("uniform", "Uniform", "Keller's instant radiosity: light paths, every bounce"),
    ("rsm", "RSM", "A regular grid over each light's view (reflective shadow maps)"),
]
FEATURE_MODE_ITEMS = [
    ("auto", "Auto", "Drop constant, collinear and unhelpful features (cross-validated)"),
    ("all", "All", "Every feature of the registry that is not constant or collinear"),
]


class VPLACE_PG_settings(bpy.types.PropertyGroup):
    """vplace settings of a scene and the results of its last run."""

    vpl_budget: IntProperty(  # type: ignore[valid-type]
        name="VPL budget",
        description="Number of VPLs to place",
        default=_DEFAULT.n_vpls,
        min=1,
        max=8192,
    )
    cell_px: IntProperty(  # type: ignore[valid-type]
        name="Cell size",
        description="Grid cell side, pixels",
        default=_DEFAULT.cell_px,
        min=1,
        max=256,
    )
    alpha: FloatProperty(  # type: ignore[valid-type]
        name="Alpha",
        description="0: uniform layout, 1: fully regression-guided",
        default=_DEFAULT.alpha,
        min=0.0,
        max=1.0,
    )
    iterations: IntProperty(  # type: ignore[valid-type]
        name="Iterations",
        description="Cap on layout iterations",
        default=_DEFAULT.iterations,
        min=0,
        max=32,
    )
    resolution_x: IntProperty(  # type: ignore[valid-type]
        name="Capture width", default=_DEFAULT.resolution[0], min=8, max=4096, subtype="PIXEL"
    )
    resolution_y: IntProperty(  # type: ignore[valid-type]
        name="Capture height", default=_DEFAULT.resolution[1], min=8, max=4096, subtype="PIXEL"
    )
    samples: IntProperty(  # type: ignore[valid-type]
        name="Capture samples",
        description="Cycles samples of the capture",
        default=_DEFAULT.samples,
        min=1,
    )
    profile: EnumProperty(  # type: ignore[valid-type]
        name="Emission profile", items=PROFILE_ITEMS, default="cosine"
    )
    feature_mode: EnumProperty(  # type: ignore[valid-type]
        name="Features", items=FEATURE_MODE_ITEMS, default="auto"
    )
    method: EnumProperty(name="Layout", items=METHOD_ITEMS, default="vplace")  # type: ignore[valid-type]
    refit: BoolProperty(  # type: ignore[valid-type]
        name="Refit powers",
        description="Regression-guided layout: fit the VPL powers to the captured indirect light "
        "(non-negative least squares)",
        default=True,
    )
    seed: IntProperty(name="Seed", default=0, min=0)  # type: ignore[valid-type]
    # Results of the last run, as JSON (kept in the .blend).
    last_report: StringProperty(name="Last report", default="")  # type: ignore[valid-type]
    model_json: StringProperty(name="Fitted model", default="")  # type: ignore[valid-type]
    #: What the stored model was fitted on (capture keys and fit settings): "Lay out and apply"
    #: uses the model while they match, and fits again when they do not.
    model_key: StringProperty(name="Fitted on", default="")  # type: ignore[valid-type]

    def report(self) -> dict[str, Any]:
        """The last run's report, or an empty dict."""
        return json.loads(self.last_report) if self.last_report else {}


CLASSES = (VPLACE_PG_settings,)


def register() -> None:
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    bpy.types.Scene.vplace = PointerProperty(type=VPLACE_PG_settings)


def unregister() -> None:
    del bpy.types.Scene.vplace
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
