"""Operators. Thin: ``poll`` guards the context, ``execute`` calls the pipeline and reports errors.

"Lay out and apply" runs interactively as a modal operator: the Blender side (export, capture)
runs on the main thread, the native side (VPLs, evaluator) on a worker thread whose progress
shows in the status bar and the window's progress indicator; Esc cancels it, and a cancelled
run leaves the scene as it was (the write-back only happens after success).
"""

from __future__ import annotations

import json
import tempfile
import threading
from pathlib import Path
from typing import Any, ClassVar

import bpy

from . import apply, capture, export, par2d_bake, pipeline
from .native import vplace

#: Errors an operator reports to the user instead of raising.
USER_ERRORS = (
    vplace.VplaceError,
    apply.WriteBackError,
    capture.CaptureError,
    export.ExportError,
)


def _store_report(scene: bpy.types.Scene, report: dict[str, Any]) -> None:
    scene.vplace.last_report = json.dumps(report)


def cache_dir() -> Path:
    """Where captures are cached between operator runs (keyed by content, so shared safely)."""
    return Path(tempfile.gettempdir()) / "vplace-cache"


def _job(scene: bpy.types.Scene) -> pipeline.Job:
    return pipeline.Job.from_settings(scene.vplace, cache_dir())


class VPLACE_OT_capture(bpy.types.Operator):
    """Render the G-buffer and lighting passes of the camera view with Cycles (cached)"""

    bl_idname = "vplace.capture"
    bl_label = "Capture"
    bl_options: ClassVar[set[str]] = {"REGISTER"}

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        return context.scene is not None and context.scene.camera is not None

    def execute(self, context: bpy.types.Context) -> set[str]:
        timer = pipeline.StageTimer(log=lambda _line: None)
        try:
            prepared = pipeline.prepare(context.scene, _job(context.scene), timer)
        except USER_ERRORS as exc:
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
    """Fit the regression of indirect light on the view's features; the table shows in the panel"""

    bl_idname = "vplace.fit"
    bl_label = "Fit"
    bl_options: ClassVar[set[str]] = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        return context.scene is not None and context.scene.camera is not None

    def execute(self, context: bpy.types.Context) -> set[str]:
        scene = context.scene
        job = _job(scene)
        timer = pipeline.StageTimer(log=lambda _line: None)
        try:
            prepared = pipeline.prepare(scene, job, timer)
            with timer.stage("fit regression"):
                fitted = vplace.fit(
                    pipeline.fit_input(prepared),
                    cell_px=job.cell_px,
                    select=job.feature_mode == "auto",
                )
        except USER_ERRORS as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        scene.vplace.model_json = fitted.to_json()
        report = scene.vplace.report()
        report["fit"] = pipeline.fit_summary(fitted)
        report["stage_seconds"] = dict(timer.seconds)
        _store_report(scene, report)
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
        return context.scene is not None and context.scene.camera is not None

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
        except USER_ERRORS as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        self.report({"INFO"}, f"report written to {out}")
        return {"FINISHED"}


class VPLACE_OT_apply(bpy.types.Operator):
    """Capture the view with Cycles, place VPLs and write them as lights for EEVEE"""

    bl_idname = "vplace.apply"
    bl_label = "Lay out and apply"
    bl_options: ClassVar[set[str]] = {"REGISTER", "UNDO"}

    _thread: threading.Thread | None = None
    _timer: Any = None

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        return context.scene is not None and context.scene.camera is not None

    def _start(self, context: bpy.types.Context) -> bool:
        scene = context.scene
        self.job = _job(scene)
        self.timer = pipeline.StageTimer(log=lambda _line: None)
        try:
            self.prepared = pipeline.prepare(scene, self.job, self.timer)
        except USER_ERRORS as exc:
            self.report({"ERROR"}, str(exc))
            return False
        return True

    def _finish(self, context: bpy.types.Context, computed: pipeline.Computed) -> set[str]:
        scene = context.scene
        try:
            apply.write_vpls(
                scene,
                computed.vpls,
                profile=self.job.profile,
                scene_diagonal=self.prepared.scene.diagonal,
            )
        except USER_ERRORS as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        _store_report(scene, pipeline.summary(scene, self.job, self.prepared, computed, self.timer))
        if computed.fit is not None:
            scene.vplace.model_json = computed.fit.to_json()
        self.report({"INFO"}, f"wrote {len(computed.vpls)} VPL lights")
        return {"FINISHED"}

    def execute(self, context: bpy.types.Context) -> set[str]:
        if not self._start(context):
            return {"CANCELLED"}
        try:
            computed = pipeline.compute(self.prepared, self.job, self.timer)
        except USER_ERRORS as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        return self._finish(context, computed)

    def invoke(self, context: bpy.types.Context, _event: bpy.types.Event) -> set[str]:
        if context.window is None:  # headless: nothing to be modal in
            return self.execute(context)
        if not self._start(context):
            return {"CANCELLED"}
        self.progress = vplace.Progress()
        self.result: list[Any] = []

        def work() -> None:
            try:
                self.result.append(
                    pipeline.compute(self.prepared, self.job, self.timer, self.progress)
                )
            except Exception as exc:  # handed to the main thread, re-raised or reported there
                self.result.append(exc)

        self._thread = threading.Thread(target=work, daemon=True)
        self._thread.start()
        wm = context.window_manager
        wm.progress_begin(0, 100)
        self._timer = wm.event_timer_add(0.1, window=context.window)
        wm.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def modal(self, context: bpy.types.Context, event: bpy.types.Event) -> set[str]:
        if event.type == "ESC":
            self.progress.cancel()
        if event.type != "TIMER":
            return {"RUNNING_MODAL"}
        total = max(self.progress.total, 1)
        context.window_manager.progress_update(int(100 * self.progress.done / total))
        if context.workspace is not None:
            context.workspace.status_text_set(
                f"vplace: evaluating VPLs {self.progress.done}/{self.progress.total} tiles "
                "(Esc to cancel)"
            )
        if self._thread is not None and self._thread.is_alive():
            return {"RUNNING_MODAL"}
        self._cleanup(context)
        outcome = self.result[0]
        if isinstance(outcome, vplace.CancelledError):
            self.report({"WARNING"}, "vplace: cancelled; the scene is unchanged")
            return {"CANCELLED"}
        if isinstance(outcome, USER_ERRORS):
            self.report({"ERROR"}, str(outcome))
            return {"CANCELLED"}
        if isinstance(outcome, BaseException):
            raise outcome
        return self._finish(context, outcome)

    def _cleanup(self, context: bpy.types.Context) -> None:
        wm = context.window_manager
        wm.event_timer_remove(self._timer)
        wm.progress_end()
        if context.workspace is not None:
            context.workspace.status_text_set(None)


class VPLACE_OT_clear_vpls(bpy.types.Operator):
    """Remove the lights vplace wrote (the 'vplace VPLs' collection)"""

    bl_idname = "vplace.clear_vpls"
    bl_label = "Clear VPLs"
    bl_options: ClassVar[set[str]] = {"REGISTER", "UNDO"}

    def execute(self, context: bpy.types.Context) -> set[str]:
        try:
            n = apply.clear_vpls()
        except USER_ERRORS as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        self.report({"INFO"}, f"removed {n} VPL lights")
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
        except USER_ERRORS as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        self.report({"INFO"}, f"baked the PAR light map of {source.name!r}")
        return {"FINISHED"}


CLASSES = (
    VPLACE_OT_capture,
    VPLACE_OT_fit,
    VPLACE_OT_apply,
    VPLACE_OT_clear_vpls,
    VPLACE_OT_report,
    VPLACE_OT_bake_par2d,
)


def register() -> None:
    for cls in CLASSES:
        bpy.utils.register_class(cls)


def unregister() -> None:
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
