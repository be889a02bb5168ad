"""Writes the .blend files the GPU timing opens: each demo's ``scene.blend`` with the scored EEVEE
set-up (``eevee_render.SETUPS["vpl"]``) applied and saved, 1920x1080, 16 samples, EEVEE.

python docs/gpu_timing/prep_gpu.py OUTDIR NAME=DEMO_OUT [NAME=DEMO_OUT ...]
(each DEMO_OUT from ``python -m addon.cli demo --scene sponza --vpls N --no-eevee --out DEMO_OUT``)
"""

import sys
from pathlib import Path

import bpy

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
from addon.compat import eevee_engine  # noqa: E402
from addon.settings import override  # noqa: E402
from addon.writeback import eevee_render as eevee  # noqa: E402

out = Path(sys.argv[1])
out.mkdir(parents=True, exist_ok=True)
for arg in sys.argv[2:]:
    name, _, src = arg.partition("=")
    bpy.ops.wm.open_mainfile(filepath=str(Path(src) / "scene.blend"))
    scene = bpy.context.scene
    with override() as g:
        eevee.SETUPS["vpl"].configure(g, scene)
        r = scene.render
        r.engine = eevee_engine()
        r.resolution_x, r.resolution_y, r.resolution_percentage = 1920, 1080, 100
        r.image_settings.file_format = "PNG"
        r.use_compositing = r.use_sequencer = False
        scene.eevee.taa_render_samples = 16
        vpls = [o for o in scene.objects if o.get("vplace_index") is not None]
        shadowed = sum(1 for o in vpls if o.data.use_shadow)
        print(f"{name}: {len(vpls)} VPLs, {shadowed} shadowed")
        bpy.ops.wm.save_as_mainfile(filepath=str(out / f"{name}.blend"), copy=True, compress=True)
