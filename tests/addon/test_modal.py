"""ui/modal.py: the worker-thread mixin of long operators, without a window (the headless path
and the modal loop driven by hand)."""

from __future__ import annotations

import threading
from types import SimpleNamespace

import pytest

from addon.native import vplace
from addon.ui import modal
from addon.ui.modal import BackgroundOperator


class Fake(BackgroundOperator):
    """An operator whose stages record what ran and may raise."""

    def __init__(self, fail_in: str | None = None, exc: BaseException | None = None) -> None:
        self.fail_in, self.exc = fail_in, exc
        self.ran: list[str] = []
        self.reports: list[tuple[set[str], str]] = []

    def report(self, kind: set[str], text: str) -> None:
        self.reports.append((kind, text))

    def _step(self, name: str) -> None:
        self.ran.append(name)
        if self.fail_in == name:
            raise self.exc

    def start(self, context):
        self._step("start")

    def work(self, progress):
        self._step("work")
        return 42

    def finish(self, context, result):
        self._step("finish")
        assert result == 42
        return {"FINISHED"}


def headless():
    return SimpleNamespace(window=None)


def test_headless_invoke_runs_every_stage_in_order():
    op = Fake()
    assert op.invoke(headless(), None) == {"FINISHED"}
    assert op.ran == ["start", "work", "finish"] and op.reports == []


@pytest.mark.parametrize("stage", ["start", "work", "finish"])
def test_a_user_error_in_any_stage_is_reported_and_cancels(stage):
    op = Fake(stage, vplace.InputError("bad budget"))
    assert op.execute(headless()) == {"CANCELLED"}
    assert op.reports == [({"ERROR"}, "bad budget")]
    assert op.ran[-1] == stage  # nothing after the failing stage ran


def test_cancel_is_a_warning_and_a_bug_keeps_its_traceback():
    op = Fake("work", vplace.CancelledError("cancelled"))
    assert op.execute(headless()) == {"CANCELLED"}
    assert op.reports[0][0] == {"WARNING"} and "unchanged" in op.reports[0][1]
    with pytest.raises(ZeroDivisionError):
        Fake("work", ZeroDivisionError()).execute(headless())


def _modal_context(calls):
    wm = SimpleNamespace(
        progress_update=lambda v: calls.append(("progress", v)),
        event_timer_remove=lambda t: calls.append(("timer removed", t)),
        progress_end=lambda: calls.append(("end", None)),
    )
    return SimpleNamespace(window_manager=wm, workspace=None)


def test_the_modal_loop_waits_for_the_worker_then_finishes_or_fails():
    calls: list = []
    op = Fake()
    op.progress = vplace.Progress()
    gate = threading.Event()
    op._thread = threading.Thread(target=gate.wait, daemon=True)
    op._thread.start()
    op._timer = "t"
    op.result = [7]
    timer = SimpleNamespace(type="TIMER")
    assert op.modal(_modal_context(calls), timer) == {"RUNNING_MODAL"}  # still working
    assert ("timer removed", "t") not in calls
    gate.set()
    op._thread.join()
    op.result = [42]
    assert op.modal(_modal_context(calls), timer) == {"FINISHED"}
    assert ("timer removed", "t") in calls and ("end", None) in calls
    assert op.ran == ["finish"]
    failed = Fake()
    failed.progress, failed._thread, failed._timer = vplace.Progress(), None, "t"
    failed.result = [vplace.InputError("no lights")]
    assert failed.modal(_modal_context([]), timer) == {"CANCELLED"}
    assert failed.reports == [({"ERROR"}, "no lights")]


def test_esc_cancels_the_progress_the_worker_polls():
    op = Fake()
    op.progress = vplace.Progress()
    assert op.modal(_modal_context([]), SimpleNamespace(type="ESC")) == {"RUNNING_MODAL"}
    assert op.progress.cancelled


def _window_context(calls):
    """A context with a window: ``invoke`` runs the worker on a thread and goes modal."""
    wm = SimpleNamespace(
        progress_begin=lambda a, b: calls.append(("begin", b)),
        progress_update=lambda v: calls.append(("progress", v)),
        event_timer_add=lambda dt, window=None: "t",
        event_timer_remove=lambda t: calls.append(("timer removed", t)),
        modal_handler_add=lambda op: calls.append(("modal", op)),
        progress_end=lambda: calls.append(("end", None)),
    )
    return SimpleNamespace(window=object(), window_manager=wm, workspace=None)


class Gated(Fake):
    """A :class:`Fake` whose worker waits for ``gate``."""

    bl_label = "Gated run"

    def __init__(self, gate: threading.Event) -> None:
        super().__init__()
        self.gate = gate

    def work(self, progress):
        self.gate.wait(10)
        return super().work(progress)


def _drive(op, context, *events):
    """Sends ``events`` to ``op``'s modal, then TIMER events until it returns."""
    for event in events:
        op.modal(context, SimpleNamespace(type=event))
    op._thread.join(10)
    return op.modal(context, SimpleNamespace(type="TIMER"))


def test_a_second_run_is_refused_while_a_worker_runs():
    gate = threading.Event()
    first = Gated(gate)
    context = _window_context([])
    assert first.invoke(context, None) == {"RUNNING_MODAL"}
    try:
        assert modal.running() == "Gated run"
        second = Fake()
        assert second.invoke(context, None) == {"CANCELLED"}
        assert second.ran == []  # refused before its start: nothing captured, nothing written
        assert "still running 'Gated run'" in second.reports[0][1]
        assert second.execute(headless()) == {"CANCELLED"}  # a script's call too
    finally:
        gate.set()
    assert _drive(first, context) == {"FINISHED"} and first.ran == ["start", "work", "finish"]
    assert modal.running() is None
    third = Fake()
    assert third.execute(headless()) == {"FINISHED"}


def test_esc_after_the_worker_finished_still_cancels():
    gate = threading.Event()
    gate.set()  # the worker finishes before the Esc is seen
    op = Gated(gate)
    context = _window_context([])
    assert op.invoke(context, None) == {"RUNNING_MODAL"}
    op._thread.join(10)
    assert op.result == [42]
    assert _drive(op, context, "ESC") == {"CANCELLED"}
    assert op.ran == ["start", "work"]  # finish, which writes, never ran
    assert op.reports[0][0] == {"WARNING"} and "unchanged" in op.reports[0][1]


def test_esc_does_not_hide_a_bug_in_the_worker():
    op = Fake()
    op.progress, op._thread, op._timer = vplace.Progress(), None, "t"
    op.result = [ZeroDivisionError()]
    op.modal(_modal_context([]), SimpleNamespace(type="ESC"))
    with pytest.raises(ZeroDivisionError):
        op.modal(_modal_context([]), SimpleNamespace(type="TIMER"))
