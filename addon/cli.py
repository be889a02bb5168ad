"""Headless entry: ``python -m addon.cli demo`` (bpy module) or, with an installed Blender,
``blender --background --python addon/cli.py -- demo`` (arguments after ``--``).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import bpy

REPO = Path(__file__).resolve().parent.parent
CORNELL_OBJ = REPO / "blend_scenes" / "cornell_box" / "CornellBox-Original.obj"
CORNELL_BLEND = REPO / "blend_scenes" / "cornell_box" / "cornell_box.blend"


def ensure_cornell_blend() -> Path:
    """The Cornell box .blend, built from the OBJ when missing or older than its sources."""
    from .default_scene import write_cornell_blend

    sources = [CORNELL_OBJ, Path(__file__).with_name("default_scene.py")]
    if not CORNELL_BLEND.exists() or any(
        s.stat().st_mtime > CORNELL_BLEND.stat().st_mtime for s in sources
    ):
        print(f"[vplace] building {CORNELL_BLEND.relative_to(REPO)} from the OBJ")
        write_cornell_blend(CORNELL_OBJ, CORNELL_BLEND)
    return CORNELL_BLEND


def parse_args(argv: list[str]) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog="vplace", description=__doc__)
    sub = p.add_subparsers(dest="command", required=True)
    demo = sub.add_parser("demo", help="run the main job on a scene (default: the Cornell box)")
    demo.add_argument("--scene", type=Path, default=None, help=".blend file (default: Cornell box)")
    demo.add_argument("--out", type=Path, default=Path("out/cornell"))
    demo.add_argument("--vpls", type=int, default=128, help="VPL budget")
    demo.add_argument("--resolution", type=int, nargs=2, default=(160, 160), metavar=("W", "H"))
    demo.add_argument("--samples", type=int, default=256, help="Cycles samples of the capture")
    demo.add_argument("--seed", type=int, default=0)
    demo.add_argument("--profile", choices=("cosine", "omni"), default="cosine")
    demo.add_argument("--r-min", type=float, default=0.01, help="distance clamp, metres")
    demo.add_argument("--no-eevee", action="store_true", help="skip the EEVEE preview render")
    return p.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    if argv is None:
        argv = sys.argv[sys.argv.index("--") + 1 :] if "--" in sys.argv else sys.argv[1:]
    args = parse_args(argv)
    from .pipeline import run_main_job

    blend = args.scene if args.scene is not None else ensure_cornell_blend()
    bpy.ops.wm.open_mainfile(filepath=str(blend))
    run_main_job(
        bpy.context.scene,
        args.out,
        n_vpls=args.vpls,
        resolution=tuple(args.resolution),
        samples=args.samples,
        seed=args.seed,
        profile=args.profile,
        r_min=args.r_min,
        eevee=not args.no_eevee,
    )
    print(f"[vplace] results in {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
