"""On the device: EEVEE frame times of the prepared files (one process, so shaders compile once).

SIZES="320x180 1920x1080" REPS=3 python gpu_time.py -- sp256:novpl sp256 sp800 sp256:rt
NAME reads gpu/NAME.blend; NAME:novpl hides every collection vplace wrote; NAME:rt also turns on
EEVEE's screen-space ray tracing with its global-illumination fast GI (EEVEE's own GI)."""
import sys, time, os
import bpy, gpu
names = sys.argv[sys.argv.index("--") + 1:]
out = os.environ.get("OUT", "/tmp")
rows = []

for spec in names:
    name, _, variant = spec.partition(":")
    bpy.ops.wm.open_mainfile(filepath=f"gpu/{name}.blend")
    s = bpy.context.scene
    s.render.engine = "BLENDER_EEVEE"
    if variant:
        # EEVEE without vplace: every collection vplace wrote hidden (as passes.hide_vpls does)
        for coll in bpy.data.collections:
            if coll.get("vplace_vpl", False):
                coll.hide_render = True
        name = f"{name}-{variant}"
    if variant == "rt":
        # EEVEE's own GI (eevee_render.SETUPS["rt"]): screen-space ray tracing, fast GI
        s.eevee.use_raytracing = True
        s.eevee.ray_tracing_method = "SCREEN"
        s.eevee.use_fast_gi = True
        s.eevee.fast_gi_method = "GLOBAL_ILLUMINATION"
    sizes = [tuple(map(int, x.split('x'))) for x in os.environ.get('SIZES', '320x180 1920x1080').split()]
    for (w, h) in sizes:
        s.render.resolution_x, s.render.resolution_y = w, h
        for i in range(int(os.environ.get('REPS', '3'))):
            s.render.filepath = f"{out}/{name}_{w}.png"
            t = time.perf_counter()
            bpy.ops.render.render(write_still=(i == 0 and w == sizes[-1][0] and name in ("sp0", "sp256", "sp800")))
            dt = time.perf_counter() - t
            rows.append((name, w, h, i, dt))
            print(f"ROW {name} {w}x{h} render {i}: {dt:.3f} s", flush=True)
print("SUMMARY")
for r in rows:
    print("%s\t%dx%d\t%d\t%.3f" % r)
