"""The vplace panel, in Properties > Render: where artists already set up how a scene renders
(engine, samples, light paths), and where Cycles and EEVEE keep their own panels."""

from __future__ import annotations

import bpy


class VPLACE_PT_main(bpy.types.Panel):
    """Regression-placed virtual point lights for EEVEE"""

    bl_label = "vplace: bounce light for EEVEE"
    bl_idname = "VPLACE_PT_main"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "render"

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        return context.scene is not None and hasattr(context.scene, "vplace")

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
        col.prop(settings, "iterations")
        col.prop(settings, "feature_mode")
        col = layout.column(align=True)
        col.prop(settings, "resolution_x")
        col.prop(settings, "resolution_y")
        col.prop(settings, "samples")
        row = layout.row(align=True)
        row.operator("vplace.capture", icon="RENDER_STILL")
        row.operator("vplace.fit", icon="GRAPH")
        row = layout.row(align=True)
        row.operator("vplace.apply", icon="LIGHT")
        row.operator("vplace.clear_vpls", icon="X")
        layout.operator("vplace.report", icon="TEXT")
        layout.operator("vplace.bake_par2d", icon="IMAGE_DATA")
        report = settings.report()
        if not report:
            return
        box = layout.box()
        m = report.get("metrics", {})
        box.label(text=f"{report.get('n_vpls', 0)} VPLs, {report.get('profile', '')} profile")
        if m:
            box.label(
                text=f"RMSE vs Cycles GI: {m['rmse']:.4f} (direct only {m['rmse_direct_only']:.4f})"
            )
        fit = report.get("fit")
        if fit:
            box.label(text=f"R² {fit['r2']:.3f}, kept {len(fit['kept'])} features")
            grid = box.grid_flow(columns=2, even_columns=True)
            for name, weight in sorted(fit["weights"].items(), key=lambda kv: -kv[1]):
                grid.label(text=name)
                grid.label(text=f"{weight:.3f}")
            if fit.get("dropped"):
                box.label(text="dropped: " + ", ".join(sorted(fit["dropped"])))
        for stage, seconds in report.get("stage_seconds", {}).items():
            box.label(text=f"{stage}: {seconds:.2f} s")


CLASSES = (VPLACE_PT_main,)


def register() -> None:
    for cls in CLASSES:
        bpy.utils.register_class(cls)


def unregister() -> None:
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
