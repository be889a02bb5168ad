"""The add-on's one error family.

Every problem a user can fix (the scene, the settings, a missing file) is an :class:`AddonError`,
itself a ``vplace.VplaceError``: an operator or the command line catches ``vplace.VplaceError``
alone and reports its message; anything else is a bug and keeps its traceback.
"""

from __future__ import annotations

import errno
import tempfile
from pathlib import Path
from typing import Any

import bpy

from .native import vplace


class AddonError(vplace.VplaceError):
    """A problem with the Blender scene or the settings; the message says what to change."""


class ExportError(AddonError):
    """The scene cannot be exported as it is."""


class CaptureError(AddonError):
    """The capture could not be made."""


class WriteBackError(AddonError):
    """The VPLs cannot be written."""


class ReportError(AddonError):
    """The report cannot run as configured."""


def blender_message(exc: BaseException) -> str:
    """Blender's message of a failed operator, on one line (without its ``Error:`` prefix)."""
    text = " ".join(str(exc).split())
    return text.removeprefix("Error: ").removeprefix("Error:").strip() or type(exc).__name__


def _call_operator(name: str, kwargs: dict[str, Any]) -> set[str]:
    """Calls ``bpy.ops.<name>`` (a seam that tests replace to make Blender fail or cancel)."""
    group, op = name.split(".")
    return getattr(getattr(bpy.ops, group), op)(**kwargs)


def run_operator(
    name: str, what: str, error: type[AddonError] = AddonError, **kwargs: Any
) -> set[str]:
    """Runs the Blender operator ``name`` (``"render.render"``); an operator that raises or does
    not finish (a render Blender aborts, a file it cannot read or write) is ``error``, its
    message ``what`` and Blender's reason."""
    try:
        result = _call_operator(name, kwargs)
    except RuntimeError as exc:
        raise error(f"{what}: {blender_message(exc)}") from exc
    if "FINISHED" not in result:
        raise error(f"{what}: Blender did not finish it ({', '.join(sorted(result))})")
    return result


def os_error_message(exc: OSError, out: Path | None = None) -> str:
    """One line for a file the system refused: the file (when the error names one, else the
    output folder ``out``) and why; a full disk says so."""
    if exc.errno == errno.ENOSPC:
        reason = "the disk is full (no space left on the device)"
    else:
        reason = exc.strerror or str(exc) or type(exc).__name__
    if exc.filename is not None:
        return f"{exc.filename}: {reason}"
    if out is not None:
        return f"writing into {out}: {reason}"
    return f"a file could not be written or read: {reason}"


def output_folder(path: Path) -> Path:
    """``path`` created (with its parents) and checked writable, or an :class:`AddonError`
    naming it: a folder under a file, a read-only place, a full disk."""
    try:
        path.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=path):
            pass
    except OSError as exc:
        reason = exc.strerror or str(exc)
        raise AddonError(f"cannot write the output folder {path}: {reason}") from exc
    return path
