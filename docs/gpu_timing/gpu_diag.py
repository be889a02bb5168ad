"""On the device: EEVEE frame times at 1920x1080 of Sponza under other settings (samples,
transparent shadows, VPL shadows, EEVEE ray tracing). Run from the folder holding gpu/*.blend."""
import os
import time
import bpy
out = os.environ.get("OUT", "/tmp")
def load(name, novpl=False):
    bpy.ops.wm.open_mainfile(filepath=f"gpu/{name}.blend")
    s = bpy.context.scene
    s.render.engine = "BLENDER_EEVEE"
    s.render.resolution_x, s.render.resolution_y = 1920, 1080
    if novpl:
        for c in bpy.data.collections:
            if c.get("vplace_vpl", False):
                c.hide_render = True
    return s
def vpls(s):
    return [o for o in s.objects if o.get("vplace_index") is not None]
def opaque():
    n = 0
    for m in bpy.data.materials:
        if hasattr(m, "use_transparent_shadow") and m.use_transparent_shadow:
            m.use_transparent_shadow = False; n += 1
    return n
def go(tag, s, reps=2):
    for i in range(reps):
        t = time.perf_counter(); bpy.ops.render.render()
        print(f"ROW {tag} render {i}: {time.perf_counter() - t:.3f} s", flush=True)
s = load("sp256"); s.eevee.taa_render_samples = 1; go("sp256 1spp", s)
s = load("sp256"); s.eevee.taa_render_samples = 4; go("sp256 4spp", s)
s = load("sp256"); print("transparent-shadow materials:", opaque()); go("sp256 16spp opaque-shadows", s)
s = load("sp256")
for o in vpls(s): o.data.use_shadow = False
go("sp256 16spp vpl-shadows-off", s)
s = load("sp256", novpl=True); print("opaque", opaque()); go("sp0 16spp opaque-shadows", s)
s = load("sp256", novpl=True); s.eevee.use_raytracing = True; s.eevee.ray_tracing_method = "SCREEN"; go("sp0 rt 16spp", s)
s = load("sp800"); opaque(); go("sp800 16spp opaque-shadows", s, 1)
s = load("sp800"); s.eevee.taa_render_samples = 1; go("sp800 1spp", s, 1)
