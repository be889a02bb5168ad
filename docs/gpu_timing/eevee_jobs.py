"""The report's EEVEE renders done on a GPU machine, the rest here.

EEVEE on these 2 cores (software OpenGL) takes 40-560 s a frame with 256 VPLs, so the report's
EEVEE rows for the rooms were rarely rendered. This runs the report three times over:

1. ``collect JOBS -- REPORT ARGS``: the report as usual (captures, truths, Cycles + OIDN,
   layouts, the evaluator, all cached in its ``--cache``), but every EEVEE render the cache lacks
   is saved instead, as the ``.blend`` Blender would have rendered (the set-up's settings
   applied, as ``eevee_render.render`` applies them), to ``JOBS/<key>.blend`` with a line in
   ``JOBS/jobs.jsonl``. Its EEVEE rows are black images: ignore that report.
2. On the GPU machine, ``render_jobs.py`` (bpy alone) renders each file to an EXR.
3. ``ingest JOBS EXRS CACHE``: each EXR becomes the cache entry of its key (the GPU's seconds as
   the frame time); then ``strict JOBS -- REPORT ARGS`` runs the report again, every EEVEE
   render now a cache hit (a miss is an error, never a slow render here).

The cache keys an EEVEE render by the GPU that renders it (``eevee_render.gpu_renderer``), so
``collect`` and ``strict`` key theirs by ``--gpu LABEL`` (default ``gpu-job``) instead of this
machine's: the GPU's images never answer for this machine's own renders, nor the other way
round. ``render_jobs.py`` writes the GPU's own name beside each render's time. EEVEE renders the
add-on does not cache (the animation's volume rows) are cached for this in
``JOBS/uncached/NNNN``, one folder per such render in the order the run makes them: their key
does not hold the light probe's bake, so a volume baked once and one baked again at that frame
would share it. ``ingest`` puts those where the line of ``jobs.jsonl`` says.

Run with the repository's ``.venv/bin/python`` from the repository root. Not part of the
add-on; CI never runs it.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import bpy
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from addon import cli
from addon import errors as addon_errors
from addon.compat import eevee_engine
from addon.writeback import eevee_render as er


class Deferred(Exception):
    """Raised in place of the render operator: the scene is saved instead."""


def main() -> int:
    mode, jobs = sys.argv[1], Path(sys.argv[2])
    if mode == "ingest":
        return ingest(jobs, Path(sys.argv[3]), Path(sys.argv[4]))
    split = sys.argv.index("--")
    own, rest = sys.argv[3:split], sys.argv[split + 1 :]
    label = own[own.index("--gpu") + 1] if "--gpu" in own else "gpu-job"
    renderer = f"GPU job {label}"
    er.gpu_renderer = lambda: renderer
    jobs.mkdir(parents=True, exist_ok=True)
    original_render, original_op = er.render, er.run_operator
    current: dict = {}
    uncached = [0]

    def op(name: str, what: str, error: type = addon_errors.AddonError, **kw: Any) -> Any:
        if name != "render.render" or not current:
            return original_op(name, what, error, **kw)
        key = current["key"]
        blend = jobs / f"{key}.blend"
        bpy.ops.wm.save_as_mainfile(
            filepath=str(blend), copy=True, compress=False, relative_remap=False
        )
        scene = bpy.data.scenes[kw["scene"]]
        entry = dict(current, scene=scene.name, frame=scene.frame_current)
        entry["group"] = Path(bpy.data.filepath).stem
        with open(jobs / "jobs.jsonl", "a") as f:
            f.write(json.dumps(entry) + "\n")
        raise Deferred

    def render(
        scene: Any,
        *,
        resolution: tuple[int, int],
        camera: Any = None,
        samples: int | None = None,
        setup: Any = None,
        seed: int = 0,
        cache_dir: Path | None = None,
    ) -> er.EeveeImage:
        kw = dict(resolution=resolution, camera=camera, samples=samples, setup=setup, seed=seed)
        engine = setup.engine if setup is not None else eevee_engine()
        own_dir = None
        if cache_dir is None and engine != "CYCLES":  # an uncached render: cached here
            own_dir = f"uncached/{uncached[0]:04d}"
            uncached[0] += 1
            cache_dir = jobs / own_dir
            cache_dir.mkdir(parents=True, exist_ok=True)
        if engine == "CYCLES" or cache_dir is None:
            return original_render(scene, cache_dir=cache_dir, **kw)
        cam = camera if camera is not None else scene.camera
        key = er._key(scene, cam, resolution, samples, engine, setup, seed, renderer)
        if (Path(cache_dir) / f"render-{key}.npz").exists():
            return original_render(scene, cache_dir=cache_dir, **kw)
        if mode == "strict":
            raise RuntimeError(f"EEVEE render {key} ({setup and setup.name}) is not cached")
        current.update(key=key, setup=setup.name if setup else "scene", camera=cam.name)
        if own_dir is not None:  # its own file names: two such renders can share a key
            current.update(key=f"{key}-{own_dir[-4:]}", cache_key=key, cache_dir=own_dir)
        try:
            return original_render(scene, cache_dir=cache_dir, **kw)
        except Deferred:
            return er.EeveeImage(np.zeros((resolution[1], resolution[0], 3), np.float32), 0.0)
        finally:
            current.clear()

    er.render = render
    er.run_operator = op
    return cli.main(rest)


def ingest(jobs: Path, exrs: Path, cache: Path) -> int:
    """Each ``exrs/<name>.exr`` (with ``exrs/times.jsonl``) as the cache entry of its job:
    ``render-<key>`` in ``cache``, or, for a render the add-on does not cache, in the job's own
    folder under ``jobs`` that its line names (with the key it was made under)."""
    where = {}
    for line in (jobs / "jobs.jsonl").read_text().splitlines():
        d = json.loads(line)
        if "cache_dir" in d:
            where[d["key"]] = (jobs / d["cache_dir"], d["cache_key"])
    seconds, gpus = {}, set()
    for line in (exrs / "times.jsonl").read_text().splitlines():
        d = json.loads(line)
        seconds[d["key"]] = d["seconds"]
        gpus.add(d.get("gpu", "?"))
    n = 0
    for exr in sorted(exrs.glob("*.exr")):
        name = exr.stem
        if name not in seconds:
            continue
        folder, key = where.get(name, (cache, name))
        image = er.read_exr_rgb(exr)
        np.savez(folder / f"render-{key}.npz", image=image, seconds=seconds[name])
        n += 1
    print(f"ingested {n} of {len(list((jobs).glob('*.blend')))} jobs into {cache}")
    print(f"rendered on: {'; '.join(sorted(gpus))}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
