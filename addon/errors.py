"""The add-on's one error family.

Every problem a user can fix (the scene, the settings, a missing file) is an :class:`AddonError`,
itself a ``vplace.VplaceError``: an operator or the command line catches ``vplace.VplaceError``
alone and reports its message; anything else is a bug and keeps its traceback.
"""

from __future__ import annotations

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
