"""EEVEE's samples against its score for the written lights (runs anywhere; slow on llvmpipe).

python docs/gpu_timing/samples_quality.py DEMO_OUT/scene.blend [WIDTH HEIGHT]
(DEMO_OUT from ``python -m addon.cli demo --scene cornell --vpls 256 --no-eevee --out DEMO_OUT``):
the scene camera's view, scored against a 512-spp Cycles truth, at 1, 2, 4 and 16 samples."""
import sys
from pathlib import Path
import numpy as np
sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
import bpy
from addon.native import vplace
from addon.report import runs, config as rc
from addon.writeback import eevee_setup, eevee_render as eevee

blend = Path(sys.argv[1])
CACHE = blend.parent / "cache"
bpy.ops.wm.open_mainfile(filepath=str(blend))
cam = bpy.context.scene.camera.name
res = tuple(int(x) for x in sys.argv[2:4]) if len(sys.argv) > 3 else (160, 160)
cfg = rc.ReportConfig(blend=blend, fit_cameras=[cam], held_out_cameras=[], resolution=res, truth_samples=512)
preset = cfg.presets()[0]
bpy.ops.wm.open_mainfile(filepath=str(preset.blend))
bl = bpy.context.scene
n = sum(1 for o in bl.objects if o.get("vplace_index") is not None)
print("VPLs in the file", n, flush=True)
data = runs.load_scene(bl, preset, cfg, CACHE, lambda s: None)
v = data.views[0]
with eevee_setup.world_for_render(bl) as bake:
    for spp in (1, 2, 4, 16):
        img = eevee.render(bl, resolution=data.resolution, camera=v.camera, samples=spp, setup=eevee.SETUPS["vpl"], seed=0, cache_dir=CACHE)
        s = vplace.job.score(img.image, v.truth.gi)
        print(f"{blend.parent.name} {v.name} EEVEE {spp:2d} samples: SSIM {s['ssim']:.4f} RMSE {s['rmse']:.4f} brightness {s.get('brightness', float('nan')):.3f} {img.seconds:.1f} s", flush=True)
