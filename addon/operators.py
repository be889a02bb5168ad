"""Operators. Thin: poll guards the context, execute calls the pipeline and reports errors."""

from __future__ import annotations

import bpy

from . import apply
from .native import vplace


class VPLACE_OT_clear_vpls(bpy.types.Operator):
    """Remove the lights vplace wrote (the 'vplace VPLs' collection)"""

    bl_idname = "vplace.clear_vpls"
    bl_label = "Clear VPLs"
    bl_options = {"REGISTER", "UNDO"}  # noqa: RUF012 (Blender reads a plain set)

    def execute(self, context: bpy.types.Context) -> set[str]:
        try:
            n = apply.clear_vpls()
        except (apply.WriteBackError, vplace.VplaceError) as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        self.report({"INFO"}, f"removed {n} VPL lights")
        return {"FINISHED"}


CLASSES = (VPLACE_OT_clear_vpls,)


def register() -> None:
    for cls in CLASSES:
        bpy.utils.register_class(cls)


def unregister() -> None:
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
