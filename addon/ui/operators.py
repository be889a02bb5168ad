"""Operators. Thin: ``poll`` guards the context, ``execute`` calls the pipeline and reports
``vplace.VplaceError`` (the one error family: the add-on's own errors derive from it) with
``self.report``; anything else is a bug and keeps its traceback.

"Lay out and apply" runs as a modal operator (``modal.BackgroundOperator``): export and capture
on the main thread, the layout and evaluator on a worker thread with progress in the status bar,
Esc cancels it, and a cancelled run leaves the scene as it was.
"""

from __future__ import annotations

import json
import tempfile
from dataclasses import asdict
from pathlib import Path
from typing import Any, ClassVar

import bpy

from .. import animation
from .. import job as pipeline
from ..native import vplace
from ..writeback import apply, eevee_setup, par2d_bake
from ..writeback import stage as writeback_stage
from .modal import BackgroundOperator, running


def cache_dir() -> Path:
    """Where captures are cached between operator runs (keyed by content, so shared safely)."""
    return Path(tempfile.gettempdir()) / "vplace-cache"


def _job(scene: bpy.types.Scene) -> pipeline.Job:
    return pipeline.Job.from_settings(scene.vplace, cache_dir())


def _model_key(job: pipeline.Job, prepared: pipeline.Prepared) -> str:
    """What a stored model was fitted on: the captures and the fit's settings."""
    return json.dumps([[c.key for c in prepared.captures], job.cell_px, job.feature_mode])


def _stored_fit(scene: bpy.types.Scene, key: str) -> vplace.Fit | None:
    """The model the panel's Fit stored, if it was fitted on exactly these captures (a model an
    older vplace saved in another format is fitted again)."""
    settings = scene.vplace
    if settings.model_json and settings.model_key == key:
        try:
            return vplace.Fit.from_json(settings.model_json)
        except vplace.VplaceError:
            return None
    return None


def _store_fit(scene: bpy.types.Scene, fitted: vplace.Fit, key: str) -> None:
    scene.vplace.model_json = fitted.to_json()
    scene.vplace.model_key = key


def _has_camera(context: bpy.types.Context) -> bool:
    return context.scene is not None and context.scene.camera is not None


class VPLACE_OT_capture(bpy.types.Operator):
    """Render the G-buffer and lighting passes of the camera view with Cycles (cached)"""

    bl_idname = "vplace.capture"
    bl_label = "Capture"
    bl_options: ClassVar[set[str]] = {"REGISTER"}

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        return _has_camera(context)

    def execute(self, context: bpy.types.Context) -> set[str]:
        try:
            prepared = pipeline.prepare(context.scene, _job(context.scene), pipeline.quiet_timer())
        except vplace.VplaceError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        cap = prepared.capture
        self.report(
            {"INFO"},
            f"captured {cap.width}x{cap.height} at {cap.samples} spp "
            f"(render {cap.render_seconds:.1f} s; cached)",
        )
        return {"FINISHED"}


class VPLACE_OT_fit(bpy.types.Operator):
    """Fit the regression of indirect light on the view's features; the table shows in the panel
    and "Lay out and apply" uses this model while the captures it was fitted on are current"""

    bl_idname = "vplace.fit"
    bl_label = "Fit"
    bl_options: ClassVar[set[str]] = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        return _has_camera(context)

    def execute(self, context: bpy.types.Context) -> set[str]:
        scene = context.scene
        job = _job(scene)
        timer = pipeline.quiet_timer()
        try:
            prepared = pipeline.prepare(scene, job, timer)
            with timer.stage("fit regression"):
                fitted = pipeline.fit(prepared, job)
        except vplace.VplaceError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        _store_fit(scene, fitted, _model_key(job, prepared))
        report = scene.vplace.report()
        report["fit"] = asdict(vplace.job.FitSummary.of(fitted))
        report["stage_seconds"] = dict(timer.seconds)
        scene.vplace.last_report = json.dumps(report)
        self.report({"INFO"}, f"R² {fitted.r2:.3f} with {len(fitted.kept)} features")
        return {"FINISHED"}


class VPLACE_OT_report(bpy.types.Operator):
    """Write a report of the current settings (every layout method at the same VPL budget,
    metrics against Cycles, images, CSV and JSON) into a folder; the scene is not changed"""

    bl_idname = "vplace.report"
    bl_label = "Report"
    bl_options: ClassVar[set[str]] = {"REGISTER"}

    directory: bpy.props.StringProperty(  # type: ignore[valid-type]
        name="Folder", subtype="DIR_PATH", default=""
    )

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        return _has_camera(context)

    def execute(self, context: bpy.types.Context) -> set[str]:
        out = (
            Path(bpy.path.abspath(self.directory))
            if self.directory
            else (Path(tempfile.gettempdir()) / "vplace-report")
        )
        try:
            pipeline.run_main_job(
                context.scene,
                out,
                job=_job(context.scene),
                write_back=False,
                log=lambda _line: None,
            )
        except vplace.VplaceError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        self.report({"INFO"}, f"report written to {out}")
        return {"FINISHED"}


class VPLACE_OT_apply(BackgroundOperator, bpy.types.Operator):
    """Capture the view with Cycles, place VPLs and write them as lights for EEVEE"""

    bl_idname = "vplace.apply"
    bl_label = "Lay out and apply"
    bl_options: ClassVar[set[str]] = {"REGISTER", "UNDO"}
    status_text = "placing VPLs"

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        busy = running()
        if busy is not None:
            cls.poll_message_set(f"vplace is still running {busy!r} (Esc cancels it)")
            return False
        return _has_camera(context)

    def start(self, context: bpy.types.Context) -> None:
        scene = context.scene
        self.job = _job(scene)
        # Quiet, but a warning the stages log (an export's, "Match EEVEE's direct light" left
        # out where EEVEE cannot render) is the user's to see: reported when it finishes.
        self.warnings: list[str] = []
        self.timer = pipeline.StageTimer(log=self._keep_warning)
        animate = scene.vplace.animate_frames()
        self.frames = None if animate is None else animation.check_animation(self.job, animate)
        if self.frames is not None:
            # "Frames: animate": every frame captured here, laid out in work(), keyed in finish().
            self.frame_preps = animation.capture_frames(scene, self.frames, self.job, self.timer)
            return
        self.prepared = pipeline.prepare(scene, self.job, self.timer)
        self.key = _model_key(self.job, self.prepared)
        self.fitted = _stored_fit(scene, self.key)
        self.match, self.matched = pipeline.eevee_match(scene, self.prepared, self.job, self.timer)

    def _keep_warning(self, line: str) -> None:
        prefix = "[vplace] warning: "
        if line.startswith(prefix):
            self.warnings.append(line.removeprefix(prefix))

    def work(self, progress: vplace.Progress | None) -> Any:
        if self.frames is not None:
            return animation.lay_out_frames(self.frame_preps, self.job, progress)
        return pipeline.compute(
            self.prepared,
            self.job,
            self.timer,
            progress,
            self.fitted,
            match=self.match,
        )

    def finish(self, context: bpy.types.Context, result: Any) -> set[str]:
        for warning in self.warnings:
            self.report({"WARNING"}, warning)
        if self.frames is not None:
            return self._finish_animation(context, result)
        scene, computed = context.scene, result
        apply.write_vpls(
            scene,
            computed.vpls,
            scene_diagonal=self.prepared.scene.scale,
            region=self.prepared.scene.region,
            specular=self.prepared.vpl_specular,
            unlit=self.prepared.vpl_unlit,
            emitters=self.prepared.stand_ins.emitters,
            sun=self.prepared.stand_ins.sun,
            closed=self.prepared.stand_ins.closed,
            cut_lamps=self.prepared.cut_lamps,
        )
        apply.write_region(scene, apply.RegionMarks.of(self.prepared.coverage))
        try:
            summary = pipeline.summary(scene, self.job, self.prepared, computed, self.timer)
            summary.set_match(self.matched, computed.laid.match)
            if scene.vplace.check_eevee:
                summary.eevee = self._check_eevee(scene, computed)
            scene.vplace.last_report = json.dumps(summary.to_dict())
        except vplace.VplaceError as exc:
            # The lights are written, and undoable as one step: the run is done, its report is
            # not, and the panel shows no report rather than the last run's.
            scene.vplace.last_report = ""
            self.report({"WARNING"}, f"the lights are written; their report failed: {exc}")
            return {"FINISHED"}
        if computed.fit is not None:
            _store_fit(scene, computed.fit, self.key)
        emitters, portals = summary.emitter_lights_written, summary.portals_written
        extra = (
            f" and {emitters} light{'s' * (emitters != 1)} for emissive meshes" if emitters else ""
        )
        extra += f" and {portals} sky portal{'s' * (portals != 1)}" if portals else ""
        extra += " and a SUN light for the world's sun" if summary.sun_written else ""
        missing = vplace.job.unwritten_vpls(summary)
        note = f" ({missing} of {summary.n_vpls} carry no power)" if missing else ""
        self.report({"INFO"}, f"wrote {summary.lights_written} VPL lights{note}{extra}")
        for problem in eevee_setup.problems(scene):
            self.report({"WARNING"}, f"EEVEE: {problem.advice()}")
        return {"FINISHED"}

    def _check_eevee(
        self, scene: bpy.types.Scene, computed: vplace.job.Computed
    ) -> dict[str, float] | None:
        """ "Check in EEVEE": the lights just written, rendered by EEVEE from the scene camera
        and scored against the first view's capture, which the evaluator was scored on
        (``writeback.stage.score_eevee``: the attribution of EEVEE's difference and its split
        into vplace's stand-ins and EEVEE's rendering). Only where that view is the scene camera
        at the current frame; a failed check is a warning, the written lights stay."""
        first = self.prepared.capture
        if scene.camera is None or not first.camera == first.view == scene.camera.name:
            self.report(
                {"WARNING"},
                "Check in EEVEE: not done, the first view is not the scene camera at this frame",
            )
            return None
        reference = pipeline.capture_reference(self.prepared, self.job)
        try:
            scores = writeback_stage.score_eevee(
                scene,
                reference,
                cache_dir() / "eevee_check.png",
                self.job.cache_dir,
                computed.indirect,
                self.prepared.exported.emissive_materials,
            )
        except vplace.VplaceError as exc:
            self.report({"WARNING"}, f"Check in EEVEE failed: {exc}")
            return None
        for line in vplace.job.PanelReport(metrics=computed.metrics, eevee=scores).eevee_lines():
            self.report({"INFO"}, line.strip())
        return scores

    def _finish_animation(
        self, context: bpy.types.Context, vpl_sets: list[vplace.VplSet]
    ) -> set[str]:
        """Writes the lights keyed over the captured frames (``addon.animation.key_lights``)."""
        scene = context.scene
        assert self.frames is not None
        tracked = animation.key_lights(scene, self.frames, self.frame_preps, vpl_sets, self.timer)
        for on, what in (
            (scene.vplace.match_eevee == "on", "Match"),
            (scene.vplace.check_eevee, "Check in"),
        ):
            if on:
                self.report(
                    {"WARNING"}, f"{what} EEVEE: not done for keyed lights (a still run is)"
                )
        frames = f"{self.frames[0]}..{self.frames[-1]} ({len(self.frames)} captured)"
        self.report(
            {"INFO"},
            f"wrote {tracked.position.shape[1]} VPL lights keyed over frames {frames}",
        )
        for problem in eevee_setup.problems(scene):
            self.report({"WARNING"}, f"EEVEE: {problem.advice()}")
        return {"FINISHED"}


class VPLACE_OT_clear_vpls(bpy.types.Operator):
    """Remove the lights vplace wrote ('vplace VPLs') and the region drawn for them"""

    bl_idname = "vplace.clear_vpls"
    bl_label = "Clear VPLs"
    bl_options: ClassVar[set[str]] = {"REGISTER", "UNDO"}

    def execute(self, context: bpy.types.Context) -> set[str]:
        try:
            n = apply.clear_vpls(scene=context.scene)
            apply.clear_vpls(apply.REGION_NAME, context.scene)  # the region they were for
        except vplace.VplaceError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        # The last run's report was of the lights just removed.
        if hasattr(context.scene, "vplace"):
            context.scene.vplace.last_report = ""
        # Without the sky portals the world must light EEVEE again.
        world = context.scene.world
        if eevee_setup.is_camera_only(world):
            eevee_setup.remove_camera_only(world)
            self.report({"INFO"}, f"removed {n} VPL lights; the world lights EEVEE again")
        else:
            self.report({"INFO"}, f"removed {n} VPL lights")
        return {"FINISHED"}


class VPLACE_OT_camera_add(bpy.types.Operator):
    """Add the active camera object (or an empty row to pick one) to the views' cameras"""

    bl_idname = "vplace.camera_add"
    bl_label = "Add camera"
    bl_options: ClassVar[set[str]] = {"REGISTER", "UNDO"}

    def execute(self, context: bpy.types.Context) -> set[str]:
        settings = context.scene.vplace
        row = settings.cameras.add()
        active = context.active_object
        if active is not None and active.type == "CAMERA":
            row.camera = active
        settings.camera_index = len(settings.cameras) - 1
        return {"FINISHED"}


class VPLACE_OT_camera_remove(bpy.types.Operator):
    """Remove the selected camera from the views' cameras"""

    bl_idname = "vplace.camera_remove"
    bl_label = "Remove camera"
    bl_options: ClassVar[set[str]] = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        return context.scene is not None and len(context.scene.vplace.cameras) > 0

    def execute(self, context: bpy.types.Context) -> set[str]:
        settings = context.scene.vplace
        if not 0 <= settings.camera_index < len(settings.cameras):
            self.report({"ERROR"}, "select a camera row to remove")
            return {"CANCELLED"}
        settings.cameras.remove(settings.camera_index)
        settings.camera_index = max(0, min(settings.camera_index, len(settings.cameras) - 1))
        return {"FINISHED"}


class VPLACE_OT_bake_par2d(bpy.types.Operator):
    """Bake the 2D direct light (PAR) of the flat objects of a collection, seen from above,
    onto an image-textured plane; objects whose material emits are the lights"""

    bl_idname = "vplace.bake_par2d"
    bl_label = "Bake 2D light map (PAR)"
    bl_options: ClassVar[set[str]] = {"REGISTER", "UNDO"}

    collection: bpy.props.StringProperty(  # type: ignore[valid-type]
        name="Collection", description="Collection of flat objects (default: the active one)"
    )
    width: bpy.props.IntProperty(name="Width", default=256, min=8, max=8192)  # type: ignore[valid-type]
    height: bpy.props.IntProperty(name="Height", default=256, min=8, max=8192)  # type: ignore[valid-type]
    method: bpy.props.EnumProperty(  # type: ignore[valid-type]
        name="Method",
        items=[
            ("exact", "Exact sweep", "Exact for every layout"),
            ("par", "PAR (paper)", "The paper's interval method; wrong where shapes cross"),
            ("monte_carlo", "Monte Carlo", "Ray-marching baseline"),
        ],
        default="exact",
    )

    def execute(self, context: bpy.types.Context) -> set[str]:
        source = (
            bpy.data.collections.get(self.collection) if self.collection else context.collection
        )
        if source is None:
            self.report({"ERROR"}, f"no collection named {self.collection!r}")
            return {"CANCELLED"}
        try:
            par2d_bake.bake_to_scene(context.scene, source, self.width, self.height, self.method)
        except vplace.VplaceError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        self.report({"INFO"}, f"baked the PAR light map of {source.name!r}")
        return {"FINISHED"}


class VPLACE_OT_setup_eevee(bpy.types.Operator):
    """Set EEVEE up for vplace's lights: shadow pool, shadows, ray tracing without a second
    bounce, and a baked light probe volume that occludes the world"""

    bl_idname = "vplace.setup_eevee"
    bl_label = "Set up EEVEE for vplace"
    bl_options: ClassVar[set[str]] = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        return context.scene is not None

    def execute(self, context: bpy.types.Context) -> set[str]:
        try:
            changed = eevee_setup.set_up(context.scene)
        except vplace.VplaceError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        self.report({"INFO"}, "; ".join(changed) if changed else "EEVEE was already set up")
        return {"FINISHED"}


CLASSES = (
    VPLACE_OT_capture,
    VPLACE_OT_fit,
    VPLACE_OT_apply,
    VPLACE_OT_clear_vpls,
    VPLACE_OT_report,
    VPLACE_OT_camera_add,
    VPLACE_OT_camera_remove,
    VPLACE_OT_bake_par2d,
    VPLACE_OT_setup_eevee,
)


def register() -> None:
    for cls in CLASSES:
        bpy.utils.register_class(cls)


def unregister() -> None:
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
