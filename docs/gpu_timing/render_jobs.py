"""On the GPU machine: render every ``.blend`` that ``eevee_jobs.py collect`` saved, to EXR.

Usage (the bundle's bpy): ``python render_jobs.py JOBS OUT SECONDS``. Renders the jobs in the
order of ``JOBS/jobs.jsonl``, grouped by scene so that its shaders compile once, until SECONDS
have passed; writes ``OUT/<key>.exr`` and a line per render in ``OUT/times.jsonl`` (the render's
seconds and the GPU's name; the first render of each group is rendered twice and timed the second
time, so that no time holds shader compilation).
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import bpy


def _gpu() -> str:
    import gpu

    p = gpu.platform
    return f"{p.backend_type_get()} {p.vendor_get()} {p.renderer_get()} {p.version_get()}"


def main() -> int:
    jobs_dir, out, budget = Path(sys.argv[-3]), Path(sys.argv[-2]), float(sys.argv[-1])
    out.mkdir(parents=True, exist_ok=True)
    jobs = [json.loads(line) for line in (jobs_dir / "jobs.jsonl").read_text().splitlines()]
    t0 = time.perf_counter()
    seen: set[str] = set()
    done = 0
    for job in jobs:
        if time.perf_counter() - t0 > budget:
            print(f"time is up after {done} of {len(jobs)} renders", flush=True)
            break
        key = job["key"]
        if (out / f"{key}.exr").exists():
            continue
        bpy.ops.wm.open_mainfile(filepath=str(jobs_dir / f"{key}.blend"), load_ui=False)
        scene = bpy.data.scenes[job["scene"]]
        scene.render.filepath = str(out / f"{key}.exr")
        scene.render.image_settings.exr_codec = "ZIP"
        group = job.get("group", job["scene"])
        reps = 1 if group in seen else 2
        seen.add(group)
        for _ in range(reps):
            start = time.perf_counter()
            bpy.ops.render.render(write_still=True, scene=scene.name)
            seconds = time.perf_counter() - start
        done += 1
        gpu = _gpu()
        with open(out / "times.jsonl", "a") as f:
            f.write(json.dumps({"key": key, "seconds": seconds, "reps": reps, "gpu": gpu}) + "\n")
        print(f"{done}/{len(jobs)} {job['setup']:<10} {group} {seconds:6.2f} s", flush=True)
    print(f"{done} renders in {time.perf_counter() - t0:.1f} s", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
