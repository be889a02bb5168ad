"""Settings and last results, stored in the .blend as ``Scene.vplace``."""

from __future__ import annotations

import json
from typing import Any

import bpy
from bpy.props import (
    BoolProperty,
    CollectionProperty,
    EnumProperty,
    FloatProperty,
    IntProperty,
    PointerProperty,
    StringProperty,
)

from ..capture.views import ViewSet
from ..job import Job

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
VIEW_MODE_ITEMS = [
    ("active", "Scene camera", "Lay out for the scene camera's view"),
    ("cameras", "Chosen cameras", "One set of lights for the views of the cameras listed below"),
    ("frames", "Camera animation", "One set of lights for the scene camera at several frames"),
    ("orbit", "Around the camera", "One set of lights for views turned about the scene camera"),
    (
        "animate",
        "Frames: animate",
        "Lights keyed over the frames: the scene camera captured and laid out at each frame "
        "(start, start + step, ..., end), the lights keyed linearly between them",
    ),
]
#: The view mode that animates the lights (``addon.animation``) rather than picking views.
ANIMATE = "animate"
#: "Match EEVEE's direct light" (``Job.match_eevee``). Numbered so that a .blend saved with
#: the earlier on/off box reads on as "on" (1) and off as "auto" (0), the new default.
MATCH_EEVEE_ITEMS = [
    (
        "auto",
        "Where a lamp is cut",
        "Only where a surface the cameras see passes through the plane of one of your lamps, "
        "which EEVEE's soft shadows darken there (0.8x Cycles' light on the Cornell box's "
        "blocks): the EEVEE renders are paid only where they can help",
        0,
    ),
    ("on", "Always", "On every still layout that refits its powers", 1),
    ("off", "Never", "Fit the powers to Cycles' light alone", 2),
]
FEATURE_MODE_ITEMS = [
    (
        "auto",
        "Surface",
        "Features of the surface only (the same from every view), dropping constant, collinear "
        "and unhelpful ones (cross-validated)",
    ),
    (
        "view",
        "Surface and view",
        "Also the features of the view (depth, coverage, normal and depth spread): may fit the "
        "captured views closer, and hold less from other views",
    ),
    ("all", "All", "Every feature of the registry that is not constant or collinear"),
]


def _is_camera(_self: Any, obj: bpy.types.Object) -> bool:
    return obj.type == "CAMERA"


class VPLACE_PG_camera(bpy.types.PropertyGroup):
    """A scene camera the lights are laid out for."""

    camera: PointerProperty(type=bpy.types.Object, poll=_is_camera)  # type: ignore[valid-type]


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
    capture_size: IntProperty(  # type: ignore[valid-type]
        name="Capture size",
        description="Pixels on the long side of each capture, at the render's aspect ratio",
        default=_DEFAULT.size,
        min=8,
        max=4096,
        subtype="PIXEL",
    )
    view_mode: EnumProperty(  # type: ignore[valid-type]
        name="Views", items=VIEW_MODE_ITEMS, default=_DEFAULT.views.mode
    )
    cameras: CollectionProperty(type=VPLACE_PG_camera)  # type: ignore[valid-type]
    camera_index: IntProperty(name="Active camera row", default=0)  # type: ignore[valid-type]
    frame_start: IntProperty(name="Start", default=1)  # type: ignore[valid-type]
    frame_end: IntProperty(name="End", default=250)  # type: ignore[valid-type]
    frame_step: IntProperty(name="Step", default=50, min=1)  # type: ignore[valid-type]
    orbit_count: IntProperty(  # type: ignore[valid-type]
        name="Count", description="Views, the scene camera's included", default=4, min=1, max=64
    )
    orbit_radius: FloatProperty(  # type: ignore[valid-type]
        name="Radius",
        description="Distance to the pivot the views turn about (0: the scene's centre)",
        default=0.0,
        min=0.0,
        unit="LENGTH",
    )
    orbit_angle: FloatProperty(  # type: ignore[valid-type]
        name="Angle",
        description="The views turn by up to this many degrees either way",
        default=30.0,
        min=0.0,
        max=180.0,
    )
    coverage: IntProperty(  # type: ignore[valid-type]
        name="Coverage views",
        description="Views added around the cameras, so the lights also hold where the camera "
        "moves next (0: the cameras' captures only)",
        default=ViewSet.coverage,
        min=0,
        max=16,
    )
    region_radius: FloatProperty(  # type: ignore[valid-type]
        name="Region radius",
        description="How far the camera may move from the chosen views (0: the room it stands in)",
        default=0.0,
        min=0.0,
        unit="LENGTH",
    )
    render_coverage: BoolProperty(  # type: ignore[valid-type]
        name="Render coverage views",
        description="Render the coverage views with Cycles and fit the lights to them as to the "
        "captures: a few small renders more, better from views far from the cameras (off: "
        "traced, lit by light-path VPLs, no render)",
        default=ViewSet.render_coverage,
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
    match_eevee: EnumProperty(  # type: ignore[valid-type]
        name="Match EEVEE's direct light",
        description="Refit the VPL powers so that EEVEE's own direct light plus the VPLs' light "
        "matches the captures, where that helps: EEVEE renders each captured view's direct "
        "light first (a second or two on a GPU, about 6 s a view at 192 px on 2 CPU cores). "
        "Needs Refit powers",
        items=MATCH_EEVEE_ITEMS,
        default="auto",
    )
    near_field: BoolProperty(  # type: ignore[valid-type]
        name="Light between nearby surfaces",
        description="Add the light a room's corners get from the walls beside them, which no VPL "
        "carries, where the captures show it helps: EEVEE's fast GI gathers it (global "
        "illumination within the lights' near-field distance, ray tracing on; Set up EEVEE for "
        "vplace sets it). Off: never, and EEVEE's fast GI stays ambient occlusion only",
        default=True,
    )
    check_eevee: BoolProperty(  # type: ignore[valid-type]
        name="Check in EEVEE",
        description="After Lay out and apply, render the lights with EEVEE from the scene camera "
        "at the capture size and compare with the capture (its noise included): EEVEE's score, "
        "and whose part its difference is (vplace's stand-ins, EEVEE's rendering of the lights, "
        "the VPLs). Two EEVEE renders and a Cycles one: seconds on a GPU, minutes without",
        default=False,
    )
    # Results of the last run, as JSON (kept in the .blend).
    last_report: StringProperty(name="Last report", default="")  # type: ignore[valid-type]
    model_json: StringProperty(name="Fitted model", default="")  # type: ignore[valid-type]
    #: What the stored model was fitted on (capture keys and fit settings): "Lay out and apply"
    #: uses the model while they match, and fits again when they do not.
    model_key: StringProperty(name="Fitted on", default="")  # type: ignore[valid-type]

    def report(self) -> dict[str, Any]:
        """The last run's report, or an empty dict."""
        return json.loads(self.last_report) if self.last_report else {}

    def animate_frames(self) -> tuple[int, int, int] | None:
        """``(start, end, step)`` when the lights are animated ("Frames: animate"), else None."""
        if self.view_mode != ANIMATE:
            return None
        return (self.frame_start, self.frame_end, self.frame_step)

    def view_set(self) -> ViewSet:
        """The views these settings choose."""
        return ViewSet(
            # Animated: the scene camera at each frame, one frame at a time (addon.animation).
            mode="active" if self.view_mode == ANIMATE else self.view_mode,
            cameras=tuple(c.camera.name for c in self.cameras if c.camera is not None),
            frame_start=self.frame_start,
            frame_end=self.frame_end,
            frame_step=self.frame_step,
            orbit_count=self.orbit_count,
            orbit_radius=self.orbit_radius,
            orbit_angle=self.orbit_angle,
            coverage=self.coverage,
            region_radius=self.region_radius,
            render_coverage=self.render_coverage,
        )


CLASSES = (VPLACE_PG_camera, VPLACE_PG_settings)


def register() -> None:
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    bpy.types.Scene.vplace = PointerProperty(type=VPLACE_PG_settings)


def unregister() -> None:
    del bpy.types.Scene.vplace
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
