"""Headless entry: ``python -m addon.cli demo`` (bpy module) or, with an installed Blender,
``blender --background --python addon/cli.py -- demo`` (arguments after ``--``).
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from pathlib import Path

import bpy

REPO = Path(__file__).resolve().parent.parent
CORNELL_OBJ = REPO / "blend_scenes" / "cornell_box" / "CornellBox-Original.obj"
CORNELL_BLEND = REPO / "blend_scenes" / "cornell_box" / "cornell_box.blend"
SPONZA_GLTF = REPO / "blend_scenes" / "sponza" / "Sponza.gltf"
SPONZA_BLEND = REPO / "blend_scenes" / "sponza" / "sponza.blend"


def _ensure_blend(blend: Path, sources: list[Path], build: Callable[[], Path]) -> Path:
    """``blend``, rebuilt by ``build`` when missing or older than any of ``sources``."""
    if not blend.exists() or any(src.stat().st_mtime > blend.stat().st_mtime for src in sources):
        print(f"[vplace] building {blend.relative_to(REPO)}")
        build()
    return blend


def builtin_scene(name: str) -> Path:
    """The .blend of a built-in scene (``cornell`` or ``sponza``), built on first use."""
    from . import default_scene

    script = Path(default_scene.__file__)
    if name == "cornell":
        return _ensure_blend(
            CORNELL_BLEND,
            [CORNELL_OBJ, script],
            lambda: default_scene.write_cornell_blend(CORNELL_OBJ, CORNELL_BLEND),
        )
    if name == "sponza":
        return _ensure_blend(
            SPONZA_BLEND,
            [SPONZA_GLTF, script],
            lambda: default_scene.write_sponza_blend(SPONZA_GLTF, SPONZA_BLEND),
        )
    raise SystemExit(f"unknown built-in scene {name!r}: use cornell, sponza or a .blend path")


def output_size(scene: bpy.types.Scene) -> tuple[int, int]:
    """The scene's render size in pixels."""
    pct = scene.render.resolution_percentage / 100.0
    return (int(scene.render.resolution_x * pct), int(scene.render.resolution_y * pct))


def parse_args(argv: list[str]) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog="vplace", description=__doc__)
    sub = p.add_subparsers(dest="command", required=True)
    demo = sub.add_parser("demo", help="run the main job on a scene (default: the Cornell box)")
    demo.add_argument(
        "--scene", default="cornell", help="cornell (default), sponza, or a .blend file"
    )
    demo.add_argument("--out", type=Path, default=Path("out/cornell"))
    demo.add_argument("--vpls", type=int, default=128, help="VPL budget")
    demo.add_argument(
        "--resolution",
        type=int,
        nargs=2,
        default=None,
        metavar=("W", "H"),
        help="capture size (default: the scene's output size)",
    )
    demo.add_argument("--samples", type=int, default=256, help="Cycles samples of the capture")
    demo.add_argument("--seed", type=int, default=0)
    demo.add_argument("--cell-px", type=int, default=16, help="regression grid cell, pixels")
    demo.add_argument("--method", choices=("uniform", "vplace", "rsm"), default="vplace")
    demo.add_argument("--alpha", type=float, default=1.0, help="0 uniform .. 1 regression-guided")
    demo.add_argument(
        "--no-refit", action="store_true", help="vplace: keep the layout's VPL powers"
    )
    demo.add_argument("--iterations", type=int, default=3, help="layout iterations (cap)")
    demo.add_argument("--feature-mode", choices=("auto", "all"), default="auto")
    demo.add_argument("--profile", choices=("cosine", "omni"), default="cosine")
    demo.add_argument(
        "--r-min", type=float, default=None, help="distance clamp, m (default: 1%% of the scene)"
    )
    demo.add_argument("--no-eevee", action="store_true", help="skip the EEVEE preview render")
    rep = sub.add_parser(
        "report",
        help="speed against error: scenes x views x methods x VPL budgets, with Cycles",
    )
    rep.add_argument("--scenes", nargs="+", default=["cornell", "sponza"])
    rep.add_argument("--budgets", type=int, nargs="+", default=[16, 64, 256, 1024])
    rep.add_argument("--methods", nargs="+", default=["uniform", "rsm", "vplace", "vplace+refit"])
    rep.add_argument("--out", type=Path, default=Path("out/report"))
    rep.add_argument(
        "--resolution", type=int, nargs=2, default=None, metavar=("W", "H"),
        help="override every view's size (default: each scene's preset)",
    )  # fmt: skip
    rep.add_argument("--capture-samples", type=int, default=None, help="the user's capture, spp")
    rep.add_argument("--truth-samples", type=int, default=None, help="the ground truth, spp")
    rep.add_argument(
        "--cycles-samples", type=int, nargs="+", default=[16, 64, 256],
        help="Cycles' own speed-against-error curve, spp",
    )  # fmt: skip
    rep.add_argument("--alpha", type=float, default=1.0, help="0 uniform .. 1 regression-guided")
    rep.add_argument("--iterations", type=int, default=3)
    rep.add_argument(
        "--seeds", type=int, nargs="+", default=[0, 1, 2],
        help="seeds of the stochastic layouts; tables show their mean",
    )  # fmt: skip
    rep.add_argument("--cache", type=Path, default=None, help="render cache (default OUT/cache)")
    rep.add_argument("--no-eevee", action="store_true", help="skip the EEVEE preview renders")
    rep.add_argument("--no-par2d", action="store_true", help="skip the PAR 2D plot")
    par = sub.add_parser("par2d", help="bake the PAR 2D demo scene and render it with EEVEE")
    par.add_argument("--out", type=Path, default=Path("out/par2d"))
    par.add_argument("--size", type=int, default=256, help="light map side, pixels")
    par.add_argument("--method", choices=("exact", "par", "monte_carlo"), default="exact")
    return p.parse_args(argv)


def run_par2d_demo(out: Path, size: int, method: str) -> None:
    """Builds the PAR demo scene, bakes its light map, renders it with EEVEE, saves both."""
    from . import default_scene, par2d_bake
    from .pipeline import render_eevee_preview

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    source = default_scene.build_par2d_demo(scene)
    out.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    par2d_bake.bake_to_scene(scene, source, size, size, method)
    print(
        f"[vplace] baked a {size}x{size} {method} light map in {time.perf_counter() - start:.2f} s"
    )
    bpy.ops.wm.save_as_mainfile(filepath=str(out / "par2d_demo.blend"), copy=True)
    seconds = render_eevee_preview(scene, out / "eevee.png", (size, size))
    print(f"[vplace] EEVEE render {seconds:.1f} s -> {out / 'eevee.png'}")


def main(argv: list[str] | None = None) -> int:
    if argv is None:
        argv = sys.argv[sys.argv.index("--") + 1 :] if "--" in sys.argv else sys.argv[1:]
    args = parse_args(argv)
    if args.command == "par2d":
        run_par2d_demo(args.out, args.size, args.method)
        return 0
    if args.command == "report":
        from .report import ReportConfig, run_report

        config = ReportConfig(
            scenes=args.scenes,
            budgets=args.budgets,
            methods=args.methods,
            resolution=tuple(args.resolution) if args.resolution else None,
            capture_samples=args.capture_samples,
            truth_samples=args.truth_samples,
            cycles_samples=args.cycles_samples,
            alpha=args.alpha,
            iterations=args.iterations,
            seeds=args.seeds,
            eevee=not args.no_eevee,
            par2d=not args.no_par2d,
            cache_dir=args.cache,
        )
        run_report(config, args.out)
        return 0
    from .pipeline import Job, run_main_job

    blend = Path(args.scene) if args.scene.endswith(".blend") else builtin_scene(args.scene)
    bpy.ops.wm.open_mainfile(filepath=str(blend))
    job = Job(
        n_vpls=args.vpls,
        resolution=tuple(args.resolution) if args.resolution else output_size(bpy.context.scene),
        samples=args.samples,
        seed=args.seed,
        profile=args.profile,
        r_min=args.r_min,
        cell_px=args.cell_px,
        method=args.method,
        alpha=args.alpha,
        refit=not args.no_refit,
        iterations=args.iterations,
        feature_mode=args.feature_mode,
    )
    run_main_job(bpy.context.scene, args.out, job=job, eevee=not args.no_eevee)
    print(f"[vplace] results in {args.out}")
    return 0


if __name__ == "__main__":
    if not __package__:  # run as a file: blender --background --python addon/cli.py -- ...
        sys.path.insert(0, str(REPO))
        from addon.cli import main as package_main

        sys.exit(package_main())
    sys.exit(main())
