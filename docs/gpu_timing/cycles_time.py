"""On the device: Cycles + OIDN frame times of Sponza (VPLs hidden) on the GPU, per backend."""
import os, sys, time
import bpy
out = os.environ.get("OUT", "/tmp")
backend = sys.argv[sys.argv.index("--") + 1]
spps = [int(x) for x in sys.argv[sys.argv.index("--") + 2:]]
bpy.ops.wm.open_mainfile(filepath="gpu/sp256.blend")
s = bpy.context.scene
for coll in bpy.data.collections:
    if coll.get("vplace_vpl", False):
        coll.hide_render = True
prefs = bpy.context.preferences.addons["cycles"].preferences
prefs.compute_device_type = backend
prefs.get_devices()
devs = [d for d in prefs.devices if d.type == backend]
for d in prefs.devices:
    d.use = d.type == backend
print("devices:", [(d.name, d.type, d.use) for d in prefs.devices], flush=True)
if not devs:
    sys.exit(f"no {backend} device")
s.render.engine = "CYCLES"
s.cycles.device = "GPU"
s.cycles.use_adaptive_sampling = False
s.cycles.use_denoising = True
s.cycles.denoiser = "OPENIMAGEDENOISE"
s.cycles.denoising_use_gpu = True
for (w, h) in ((1920, 1080),):
    s.render.resolution_x, s.render.resolution_y = w, h
    for spp in spps:
        s.cycles.samples = spp
        for i in range(2):
            s.render.filepath = f"{out}/cycles_{backend}_{spp}.png"
            t = time.perf_counter()
            bpy.ops.render.render(write_still=(i == 1 and spp == spps[-1]))
            print(f"ROW cycles-{backend} {w}x{h} {spp}spp render {i}: {time.perf_counter() - t:.3f} s", flush=True)
