"""Benchmark of the scene export on a procedural textured scene of about a million triangles.

Builds a fresh file holding a wavy terrain of ``(n - 1)^2 * 2`` triangles with a UV map and a
Principled material whose base colour is a ``tex`` x ``tex`` image texture, plus a sun and a
camera, then times :func:`export.export_scene` (the render depsgraph, triangles, UVs, the
texture) and :func:`scene.convert.build_scene` (the core scene with its BVH), and reports the peak
memory of the process (``ru_maxrss``) and the Python-side peak of the export (``tracemalloc``,
which sees numpy's buffers). The export target of issue 14: under 3 s and within 2 GB for a
million textured triangles.

    python -m addon.scene.bench_export [--grid 709] [--texture 2048] [--repeat 3]
"""

from __future__ import annotations

import argparse
import resource
import statistics
import time
import tracemalloc
from collections.abc import Callable
from typing import Any

import bpy
import numpy as np

from ..compat import new_material
from . import export
from .convert import build_scene


def grid_mesh(
    name: str, xs: np.ndarray, height: Callable[[np.ndarray, np.ndarray], np.ndarray]
) -> tuple[bpy.types.Mesh, np.ndarray, np.ndarray]:
    """A mesh of ``len(xs)^2`` vertices over the grid ``xs x xs`` at ``z = height(x, y)``, one
    quad per grid cell: the mesh, its (V, 3) vertices and (Q, 4) quads."""
    n = len(xs)
    gx, gy = np.meshgrid(xs, xs)
    verts = np.stack([gx.ravel(), gy.ravel(), height(gx.ravel(), gy.ravel())], 1)
    idx = np.arange(n * n).reshape(n, n)
    quads = np.stack([idx[:-1, :-1], idx[:-1, 1:], idx[1:, 1:], idx[1:, :-1]], -1).reshape(-1, 4)
    mesh = bpy.data.meshes.new(name)
    mesh.vertices.add(len(verts))
    mesh.vertices.foreach_set("co", verts.astype(np.float32).ravel())
    mesh.loops.add(quads.size)
    mesh.loops.foreach_set("vertex_index", quads.astype(np.int32).ravel())
    mesh.polygons.add(len(quads))
    mesh.polygons.foreach_set("loop_start", np.arange(0, quads.size, 4, dtype=np.int32))
    mesh.update()
    return mesh, verts, quads


def textured_terrain(n: int, tex: int) -> bpy.types.Scene:
    """A fresh file with an ``n`` x ``n`` vertex terrain (UV-mapped, image-textured), a sun
    and a camera looking at it."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    mesh, verts, quads = grid_mesh(
        "terrain", np.linspace(-10.0, 10.0, n), lambda x, y: 0.3 * np.sin(x) * np.cos(y)
    )
    uv = mesh.uv_layers.new(name="UVMap")
    uvs = verts[quads.ravel(), :2] / 20.0 + 0.5
    uv.data.foreach_set("uv", uvs.astype(np.float32).ravel())
    image = bpy.data.images.new("bench texture", tex, tex, float_buffer=False)
    rng = np.random.default_rng(0)
    pixels = rng.uniform(0.1, 0.9, (tex, tex, 4)).astype(np.float32)
    pixels[..., 3] = 1.0
    image.pixels.foreach_set(pixels.ravel())
    image.pack()
    mat = new_material("textured")
    tree = mat.node_tree
    bsdf = next(n for n in tree.nodes if n.type == "BSDF_PRINCIPLED")
    node = tree.nodes.new("ShaderNodeTexImage")
    node.image = image
    tree.links.new(node.outputs["Color"], bsdf.inputs["Base Color"])
    mesh.materials.append(mat)
    scene.collection.objects.link(bpy.data.objects.new("terrain", mesh))
    sun = bpy.data.objects.new("sun", bpy.data.lights.new("sun", "SUN"))
    sun.rotation_euler = (0.6, 0.2, 0.0)
    scene.collection.objects.link(sun)
    cam = bpy.data.objects.new("camera", bpy.data.cameras.new("camera"))
    cam.location = (0.0, -14.0, 8.0)
    cam.rotation_euler = (1.0, 0.0, 0.0)
    scene.collection.objects.link(cam)
    scene.camera = cam
    bpy.context.view_layer.update()
    return scene


def _median(fn: Callable[[], Any], repeat: int) -> tuple[float, Any]:
    times, out = [], None
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t)
    return statistics.median(times), out


def run(grid: int, texture: int, repeat: int, log: Callable[[str], None] = print) -> dict:
    """Builds the scene, times export and scene build, and prints the table; returns it."""
    scene = textured_terrain(grid, texture)
    t_export, exported = _median(lambda: export.export_scene(scene), repeat)
    tracemalloc.start()  # one more export for its memory only: tracing slows it several times
    export.export_scene(scene)
    _, traced_peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    t_build, _ = _median(lambda: build_scene(exported), repeat)
    rss_peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    out = {
        "triangles": len(exported.triangles),
        "textures": len(exported.textures),
        "texels": sum(int(t.shape[0] * t.shape[1]) for t in exported.textures),
        "export_seconds": t_export,
        "build_seconds": t_build,
        "export_peak_bytes": traced_peak,
        "process_peak_bytes": rss_peak,
    }
    log(
        f"vplace export benchmark: {out['triangles']} triangles, {out['textures']} texture(s) "
        f"of {out['texels']} texels, median of {repeat}"
    )
    log(f"{'step':<58} {'seconds':>8}")
    log(f"{'export_scene (render depsgraph, triangles, UVs, texture)':<58} {t_export:>8.3f}")
    log(f"{'build_scene (core scene and BVH)':<58} {t_build:>8.3f}")
    log(f"export peak (Python + numpy, tracemalloc): {traced_peak / 2**20:.0f} MB")
    log(f"process peak (ru_maxrss, Blender included): {rss_peak / 2**20:.0f} MB")
    return out


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--grid", type=int, default=709, help="vertices per side (709: 1,002,528 tris)")
    ap.add_argument("--texture", type=int, default=2048, help="texture size in texels")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args(argv)
    run(args.grid, args.texture, args.repeat)


if __name__ == "__main__":
    main()
