"""On the device: what a finite reach of the VPLs (their custom cutoff distance), and EEVEE's
shadow-tracing settings, save in an EEVEE frame.

python reach_time.py -- NAME VARIANT [VARIANT ...]   (run from the folder holding gpu/NAME.blend)

vplace writes every VPL with a cutoff of several scene diagonals, so EEVEE's light culling keeps
every VPL in every tile (``docs/EEVEE_NOTES.md``, Q8). This renders NAME as written, then each
VARIANT: ``+``-joined changes from the written file, ``reach=M`` (every VPL's cutoff M metres),
``reachp=M`` (each VPL's cutoff M metres times the square root of its power over the median
power: the distance at which every VPL's light falls to the same irradiance), ``noshadow``
(the VPLs' shadows off), ``steps=N`` and ``rays=N`` (``scene.eevee``'s ``shadow_step_count``,
``shadow_ray_count``), ``samples=N``, ``novpl`` (every collection vplace wrote hidden). At
1920x1080, the written file twice (the first render compiles the shaders), each variant once;
each also at 320x180 to ``$OUT/NAME_<variant>.exr``, so that the images can be compared where
Blender runs without a GPU. ``BIG=0``: the 320x180 renders alone; ``WRITTEN=0``: the written
file at 320x180 alone.
"""

import os
import sys
import time

import bpy

args = sys.argv[sys.argv.index("--") + 1 :]
name, variants = args[0], args[1:]
out = os.environ.get("OUT", "/tmp")
bpy.ops.wm.open_mainfile(filepath=f"gpu/{name}.blend")
scene = bpy.context.scene
scene.render.engine = "BLENDER_EEVEE"
e = scene.eevee
vpls = [o for o in scene.objects if o.get("vplace_index") is not None]
written = {o.name: (o.data.cutoff_distance, o.data.use_shadow) for o in vpls}
median = sorted(o.data.energy for o in vpls)[len(vpls) // 2]
base = (e.shadow_step_count, e.shadow_ray_count, e.taa_render_samples)
print(f"{len(vpls)} VPLs, cutoff {vpls[0].data.cutoff_distance:.1f} m, steps/rays/samples {base}")


def render(tag: str, w: int, h: int, reps: int, exr: bool) -> None:
    scene.render.resolution_x, scene.render.resolution_y = w, h
    scene.render.image_settings.file_format = "OPEN_EXR" if exr else "PNG"
    scene.render.filepath = f"{out}/{name}_{tag}.exr" if exr else "/tmp/frame.png"
    for i in range(reps):
        start = time.perf_counter()
        bpy.ops.render.render(write_still=exr)
        print(
            f"ROW {name} {tag} {w}x{h} render {i}: {time.perf_counter() - start:.3f} s", flush=True
        )


render("written", 320, 180, 1, True)
big = os.environ.get("BIG", "1") == "1"  # BIG=0: the 320x180 images alone
if big and os.environ.get("WRITTEN", "1") == "1":  # WRITTEN=0: not the written one
    render("written", 1920, 1080, 2, False)
for spec in variants:
    change = dict(p.partition("=")[::2] for p in spec.split("+"))
    for o in vpls:
        o.data.cutoff_distance = float(change.get("reach", written[o.name][0]))
        if "reachp" in change:
            o.data.cutoff_distance = float(change["reachp"]) * (o.data.energy / median) ** 0.5
        o.data.use_shadow = written[o.name][1] and "noshadow" not in change
    for c in bpy.data.collections:
        if c.get("vplace_vpl", False):
            c.hide_render = "novpl" in change
    e.shadow_step_count = int(change.get("steps", base[0]))
    e.shadow_ray_count = int(change.get("rays", base[1]))
    e.taa_render_samples = int(change.get("samples", base[2]))
    tag = spec.replace("=", "").replace("+", "_")
    if big:
        render(tag, 1920, 1080, 1, False)
    render(tag, 320, 180, 1, True)
