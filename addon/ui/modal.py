"""The machinery of an operator whose long native part runs on a worker thread.

:class:`BackgroundOperator` is a mixin for ``bpy.types.Operator``: ``invoke`` runs the Blender
part on the main thread (:meth:`start`), the native part on a worker thread (:meth:`work`, which
must not touch ``bpy``) while the status bar and the window's progress indicator show how far it
is, Esc cancels it through a ``vplace.Progress``, and :meth:`finish` runs back on the main thread
with the result. A cancelled or failed run leaves the scene as it was: only :meth:`finish`
changes it, and Esc pressed at any time before it runs cancels the run, even where the worker
has already finished. One run at a time: while a worker runs, another start is refused
(:func:`running`). Headless (no window), ``execute`` runs the three steps in a row.
"""

from __future__ import annotations

import threading
from typing import Any

import bpy

from ..errors import AddonError
from ..native import vplace

#: The run whose worker was started last: its operator's label and its thread (running while
#: the thread is alive: :func:`running`).
_current: tuple[str, threading.Thread] | None = None


def running() -> str | None:
    """The label of the vplace operator whose worker thread runs now, or None. A second run
    started meanwhile would write its lights first and see them replaced by the older run's
    when that one finishes (or replace them the other way round): the last to finish would
    win, not the last asked for."""
    if _current is not None and _current[1].is_alive():
        return _current[0]
    return None


class BackgroundOperator:
    """Mixin: see the module docs. Subclasses implement ``start``, ``work`` and ``finish``."""

    #: What the status bar says while the worker runs.
    status_text = "working"

    _thread: threading.Thread | None = None
    _timer: Any = None

    def start(self, context: bpy.types.Context) -> None:
        """The Blender part before the work (main thread); raises ``vplace.VplaceError``."""
        raise NotImplementedError

    def work(self, progress: vplace.Progress | None) -> Any:
        """The native part (worker thread, no bpy); raises ``vplace.VplaceError``."""
        raise NotImplementedError

    def finish(self, context: bpy.types.Context, result: Any) -> set[str]:
        """Applies the result (main thread); raises ``vplace.VplaceError``."""
        raise NotImplementedError

    def _fail(self, exc: BaseException) -> set[str]:
        report = self.report  # type: ignore[attr-defined]  # bpy.types.Operator's
        if isinstance(exc, vplace.CancelledError):
            report({"WARNING"}, "vplace: cancelled; the scene is unchanged")
            return {"CANCELLED"}
        if isinstance(exc, vplace.VplaceError):
            report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        raise exc

    def _finish(self, context: bpy.types.Context, result: Any) -> set[str]:
        try:
            started = getattr(self, "_scene_name", None)
            if started is not None and _scene_name(context) != started:
                # Written into another scene, the lights would light what was not captured.
                raise AddonError(
                    f"the scene changed from {started!r} while vplace worked: nothing is "
                    "written; run it again in the scene to light"
                )
            return self.finish(context, result)
        except vplace.VplaceError as exc:
            return self._fail(exc)

    def _start(self, context: bpy.types.Context) -> None:
        """:meth:`start`, remembering the scene it ran in (:meth:`_finish` writes nowhere else);
        refused while another run's worker works (:func:`running`)."""
        busy = running()
        if busy is not None:
            raise AddonError(
                f"vplace is still running {busy!r}: wait for it to finish (Esc cancels it) "
                "and run this again"
            )
        self._scene_name = _scene_name(context)
        self.start(context)

    def execute(self, context: bpy.types.Context) -> set[str]:
        try:
            self._start(context)
            result = self.work(None)
        except vplace.VplaceError as exc:
            return self._fail(exc)
        return self._finish(context, result)

    def invoke(self, context: bpy.types.Context, _event: bpy.types.Event) -> set[str]:
        if context.window is None:  # headless: nothing to be modal in
            return self.execute(context)
        try:
            self._start(context)
        except vplace.VplaceError as exc:
            return self._fail(exc)
        self.progress = vplace.Progress()
        self.result: list[Any] = []

        def run() -> None:
            try:
                self.result.append(self.work(self.progress))
            except Exception as exc:  # handed to the main thread, reported or re-raised there
                self.result.append(exc)

        global _current
        self._thread = threading.Thread(target=run, daemon=True)
        self._thread.start()
        _current = (getattr(self, "bl_label", type(self).__name__), self._thread)
        wm = context.window_manager
        wm.progress_begin(0, 100)
        self._timer = wm.event_timer_add(0.1, window=context.window)
        wm.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def modal(self, context: bpy.types.Context, event: bpy.types.Event) -> set[str]:
        if event.type == "ESC":
            # Asked for, the cancel holds even where the worker has just finished: nothing is
            # written after the user pressed Esc.
            self._cancel_asked = True
            self.progress.cancel()
        if event.type != "TIMER":
            return {"RUNNING_MODAL"}
        total = max(self.progress.total, 1)
        context.window_manager.progress_update(int(100 * self.progress.done / total))
        if context.workspace is not None:
            context.workspace.status_text_set(
                f"vplace: {self.status_text} {self.progress.done}/{self.progress.total} "
                "(Esc to cancel)"
            )
        if self._thread is not None and self._thread.is_alive():
            return {"RUNNING_MODAL"}
        self._cleanup(context)
        outcome = self.result[0]
        bug = isinstance(outcome, BaseException) and not isinstance(outcome, vplace.VplaceError)
        if getattr(self, "_cancel_asked", False) and not bug:
            return self._fail(vplace.CancelledError("cancelled"))
        if isinstance(outcome, BaseException):
            return self._fail(outcome)
        return self._finish(context, outcome)

    def _cleanup(self, context: bpy.types.Context) -> None:
        wm = context.window_manager
        wm.event_timer_remove(self._timer)
        wm.progress_end()
        if context.workspace is not None:
            context.workspace.status_text_set(None)


def _scene_name(context: bpy.types.Context) -> str | None:
    """The name of ``context``'s scene, or None without one."""
    scene = getattr(context, "scene", None)
    return scene.name if scene is not None else None
