"""The vplace panel, in Properties > Render: where artists already set up how a scene renders
(engine, samples, light paths), and where Cycles and EEVEE keep their own panels."""

from __future__ import annotations

from typing import Any

import bpy

from ..native import vplace
from ..writeback import apply, eevee_setup


class _Panel:
    """Where vplace's panels live: Properties > Render."""

    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "render"

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        return context.scene is not None and hasattr(context.scene, "vplace")


class VPLACE_UL_cameras(bpy.types.UIList):
    """The cameras the lights are laid out for"""

    def draw_item(
        self,
        _context: bpy.types.Context,
        layout: bpy.types.UILayout,
        _data: Any,
        item: Any,
        _icon: int,
        _active_data: Any,
        _active_prop: str,
        _index: int = 0,
        _flt_flag: int = 0,
    ) -> None:
        layout.prop(item, "camera", text="", emboss=False, icon="CAMERA_DATA")


class VPLACE_PT_main(_Panel, bpy.types.Panel):
    """Regression-placed virtual point lights for EEVEE"""

    bl_label = "vplace: bounce light for EEVEE"
    bl_idname = "VPLACE_PT_main"

    def draw(self, context: bpy.types.Context) -> None:
        settings = context.scene.vplace
        layout = self.layout
        layout.use_property_split = True
        col = layout.column()
        col.prop(settings, "vpl_budget")
        col.prop(settings, "method")
        col.prop(settings, "profile")
        col.prop(settings, "cell_px")
        col.prop(settings, "alpha")
        col.prop(settings, "refit")
        sub = col.column(align=True)
        sub.active = settings.refit and settings.method == "vplace"
        sub.prop(settings, "match_eevee")
        sub = col.column(align=True)
        sub.active = settings.method == "vplace"
        sub.prop(settings, "near_field")
        col.prop(settings, "iterations")
        col.prop(settings, "feature_mode")
        col = layout.column(align=True)
        col.prop(settings, "capture_size")
        col.prop(settings, "samples")
        row = layout.row(align=True)
        row.operator("vplace.capture", icon="RENDER_STILL")
        row.operator("vplace.fit", icon="GRAPH")
        layout.prop(settings, "check_eevee")
        row = layout.row(align=True)
        row.operator("vplace.apply", icon="LIGHT")
        row.operator("vplace.clear_vpls", icon="X")
        layout.operator("vplace.setup_eevee", icon="SHADING_RENDERED")
        found = eevee_setup.problems(context.scene)
        if found:
            box = layout.box()
            box.label(text="EEVEE will not show these lights right:", icon="ERROR")
            for problem in found:
                box.label(text=problem.setting)
                box.label(text=f"  {problem.message}")
                if problem.remedy:
                    box.label(text=f"  {problem.remedy}")
        written = eevee_setup.vpl_lights(context.scene)
        notes = []  # eevee_setup.lamp_notes, in lines the panel does not cut
        lamps = eevee_setup.unjittered_lamps(context.scene) if written else []
        if lamps:
            notes.append(f"{len(lamps)} lamp(s) with soft shadows, no jitter (e.g. {lamps[0]!r}):")
            notes.append("  noisier than Cycles; Light > Shadow > Jitter (slower)")
        cut = (
            eevee_setup.still_cut(context.scene, apply.stored_cut_lamps(scene=context.scene))
            if written
            else []
        )
        if cut:
            notes.append(f"{len(cut)} lamp(s) a surface's plane passes through (e.g. {cut[0]!r}):")
            notes.append("  EEVEE's soft shadow darkens that surface (0.8x Cycles)")
            if settings.match_eevee == "off":
                notes.append("  'Match EEVEE's direct light' makes up for it")
        if notes:
            box = layout.box()
            box.label(text="EEVEE's own light, not vplace's:", icon="INFO")
            for line in notes:
                box.label(text=line)
        unlit = apply.unlit_objects() if written else []
        if unlit:  # native_view.vpl_unlit: sharp metal and glass
            box = layout.box()
            box.label(text="Not lit by the VPLs (Light Linking):", icon="INFO")
            more = f" and {len(unlit) - 1} more" if len(unlit) > 1 else ""
            box.label(text=f"  {unlit[0]!r}{more}: sharp metal or glass,")
            box.label(text="  reflecting the room through EEVEE's ray tracing")
        layout.operator("vplace.report", icon="TEXT")
        layout.operator("vplace.bake_par2d", icon="IMAGE_DATA")
        try:
            report = vplace.job.PanelReport.from_json(settings.last_report)
        except (ValueError, TypeError, KeyError, AttributeError):
            report, stored = None, True
        else:
            stored = report is not None
        if report is not None:
            box = layout.box()
            try:
                _draw_report(box, report)
                return
            except (ValueError, TypeError, KeyError, AttributeError):
                pass
        if stored:  # written by another version of vplace: said once, never raised each redraw
            layout.label(text="The last run's report is of another vplace: run again", icon="INFO")


def _draw_report(box: bpy.types.UILayout, report: vplace.job.PanelReport) -> None:
    """The last run's report in the main panel."""
    m = report.metrics
    box.label(text=f"{report.n_vpls} VPLs, {report.profile} profile")
    if m:
        box.label(
            text=f"RMSE vs Cycles GI: {m['rmse']:.4f} (direct only {m['rmse_direct_only']:.4f})"
        )
    for name, share in report.eevee_matched.items():
        box.label(
            text=f"Matched EEVEE's direct light: {name} "
            f"{vplace.markdown.percent(share, signed=True)}"
        )
    choice = report.eevee_match
    if choice is not None and not choice["kept"]:
        box.label(text="Match EEVEE's direct light left out: it would not help here")
        box.label(
            text=f"  EEVEE's RMSE {choice['with_match']:.4g} with it, "
            f"{choice['without']:.4g} without"
        )
    for line in report.region.lines() if report.region is not None else []:
        box.label(text=line)
    for line in report.eevee_lines():
        box.label(text=line)
    fit = report.fit
    if fit:
        box.label(text=f"R² {fit.r2:.3f}, kept {len(fit.kept)} features")
        grid = box.grid_flow(columns=2, even_columns=True)
        for name, weight in sorted(fit.weights.items(), key=lambda kv: -kv[1]):
            grid.label(text=name)
            grid.label(text=f"{weight:.3f}")
        if fit.dropped:
            box.label(text="dropped: " + ", ".join(sorted(fit.dropped)))
    for stage, seconds in report.stage_seconds.items():
        box.label(text=f"{stage}: {seconds:.2f} s")


class VPLACE_PT_views(_Panel, bpy.types.Panel):
    """The views one set of lights is laid out for"""

    bl_label = "Views"
    bl_idname = "VPLACE_PT_views"
    bl_parent_id = "VPLACE_PT_main"

    def draw(self, context: bpy.types.Context) -> None:
        settings = context.scene.vplace
        layout = self.layout
        layout.use_property_split = True
        layout.prop(settings, "view_mode")
        mode = settings.view_mode
        if mode == "cameras":
            row = layout.row()
            row.template_list(
                "VPLACE_UL_cameras", "", settings, "cameras", settings, "camera_index", rows=3
            )
            col = row.column(align=True)
            col.operator("vplace.camera_add", icon="ADD", text="")
            col.operator("vplace.camera_remove", icon="REMOVE", text="")
        elif mode in ("frames", "animate"):
            col = layout.column(align=True)
            col.prop(settings, "frame_start")
            col.prop(settings, "frame_end")
            col.prop(settings, "frame_step")
        elif mode == "orbit":
            col = layout.column(align=True)
            col.prop(settings, "orbit_count")
            col.prop(settings, "orbit_radius")
            col.prop(settings, "orbit_angle")
        col = layout.column(align=True)
        col.prop(settings, "coverage")
        sub = col.column(align=True)
        sub.active = settings.coverage > 0
        sub.prop(settings, "region_radius")
        sub.prop(settings, "render_coverage")


CLASSES = (VPLACE_UL_cameras, VPLACE_PT_main, VPLACE_PT_views)


def register() -> None:
    for cls in CLASSES:
        bpy.utils.register_class(cls)


def unregister() -> None:
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
