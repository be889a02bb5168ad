"""Headless entry: ``python -m addon.cli demo`` (bpy module) or, with an installed Blender,
``blender --background --python addon/cli.py -- demo`` (arguments after ``--``).

A problem the user can fix (a bad scene, a bad option) prints one line, ``vplace: error: ...``,
and exits with status 2; ``--debug`` prints the traceback instead.
"""

from __future__ import annotations

import argparse
import sys
import time
import traceback
from pathlib import Path
from typing import TYPE_CHECKING

import bpy

if TYPE_CHECKING:
    from .capture.views import ViewSet

REPO = Path(__file__).resolve().parent.parent


def view_set(args: argparse.Namespace) -> ViewSet:
    """The views of the ``demo`` options (default: the scene camera)."""
    from .capture.views import ViewSet

    region = {
        "coverage": args.coverage,
        "region_radius": args.region_radius,
        "render_coverage": args.render_coverage,
    }
    if args.cameras:
        return ViewSet(mode="cameras", cameras=tuple(args.cameras), **region)
    if args.frames:
        start, end, step = args.frames
        return ViewSet(mode="frames", frame_start=start, frame_end=end, frame_step=step, **region)
    if args.orbit:
        count, radius, angle = args.orbit
        return ViewSet(
            mode="orbit", orbit_count=int(count), orbit_radius=radius, orbit_angle=angle, **region
        )
    return ViewSet(**region)


def add_region_arguments(parser: argparse.ArgumentParser) -> None:
    """``--coverage N``, ``--region-radius M`` and ``--render-coverage`` (``vplace.coverage``)."""
    from .capture.views import ViewSet

    parser.add_argument(
        "--coverage", type=int, default=ViewSet.coverage, metavar="N",
        help="add N coverage views of the region around the cameras, which the lights are "
        f"laid out for (0-16; default {ViewSet.coverage}; 0: the cameras' captures only)",
    )  # fmt: skip
    parser.add_argument(
        "--region-radius", type=float, default=0.0, metavar="M",
        help="metres a camera may move from the user's (default 0: the room it stands in)",
    )  # fmt: skip
    parser.add_argument(
        "--render-coverage", action=argparse.BooleanOptionalAction,
        default=ViewSet.render_coverage,
        help="render the coverage views with Cycles and fit them as captures (the default); "
        "--no-render-coverage: trace them, lit by light-path VPLs, with no render",
    )  # fmt: skip


def parse_args(argv: list[str]) -> argparse.Namespace:
    """The command line: ``demo``, ``report`` or ``par2d`` with their options."""
    p = argparse.ArgumentParser(prog="vplace", description=__doc__)
    p.add_argument("--debug", action="store_true", help="print tracebacks of errors")
    sub = p.add_subparsers(dest="command", required=True)
    _demo_options(sub)
    _report_options(sub)
    _par2d_options(sub)
    return p.parse_args(argv)


def _demo_options(sub: argparse._SubParsersAction) -> None:
    from .job import FEATURE_MODES, MATCH_EEVEE, Job
    from .scenes.registry import BUILTIN

    demo = sub.add_parser("demo", help="run the main job on a scene (default: the Cornell box)")
    demo.add_argument(
        "--scene",
        default="cornell",
        help=f"a built-in scene ({', '.join(BUILTIN)}; default cornell) or a .blend file",
    )
    demo.add_argument("--out", type=Path, default=Path("out/cornell"))
    demo.add_argument("--vpls", type=int, default=128, help="VPL budget")
    demo.add_argument(
        "--size",
        type=int,
        default=160,
        help="capture size: pixels on the long side, at the render's aspect ratio (default 160)",
    )
    views = demo.add_mutually_exclusive_group()
    views.add_argument(
        "--cameras", nargs="+", metavar="NAME", help="lay out for these scene cameras"
    )
    views.add_argument(
        "--frames",
        type=int,
        nargs=3,
        metavar=("START", "END", "STEP"),
        help="lay out for the scene camera at these frames (an animated camera)",
    )
    views.add_argument(
        "--orbit",
        type=float,
        nargs=3,
        metavar=("COUNT", "RADIUS", "ANGLE"),
        help="lay out for COUNT views around the scene camera: turned about a pivot RADIUS m in "
        "front of it (0: the scene's centre) by up to ANGLE degrees",
    )
    views.add_argument(
        "--animate", type=int, nargs=3, metavar=("START", "END", "STEP"),
        help="capture the scene camera at frames START, START+STEP, ..., END, lay out each with "
        "the same random numbers and write one set of lights keyed over them (linear keys); "
        "scores every frame against a Cycles truth of it",
    )  # fmt: skip
    demo.add_argument(
        "--score-between", action="store_true",
        help="with --animate: also capture and score the frames between the captured ones "
        "(the keyed lights interpolated there, against a still layout of that frame)",
    )  # fmt: skip
    demo.add_argument(
        "--cycles-samples", type=int, nargs="*", default=[],
        help="with --animate: also score Cycles + OpenImageDenoise at these samples per frame",
    )  # fmt: skip
    demo.add_argument(
        "--eevee-still", action="store_true",
        help="with --animate: also render EEVEE with a still layout of each scored frame "
        "(the keyed lights are written back after)",
    )  # fmt: skip
    demo.add_argument(
        "--volume-once", action="store_true",
        help="with --animate: also score EEVEE ray tracing with a light probe volume baked once "
        "at the first frame",
    )  # fmt: skip
    demo.add_argument(
        "--volume-per-frame", action="store_true",
        help="with --animate: also score EEVEE ray tracing with a light probe volume baked again "
        "at every scored frame",
    )  # fmt: skip
    demo.add_argument(
        "--truth-noise", action="store_true",
        help="with --animate: render every scored frame's truth again with another seed, to "
        "score the truth's own noise and each image against the noise-free truth",
    )  # fmt: skip
    demo.add_argument(
        "--samples", type=int, default=Job.samples, help="Cycles samples of each capture"
    )
    add_region_arguments(demo)
    demo.add_argument(
        "--truth-samples", type=int, default=256,
        help="score against a Cycles render of the scene camera at these samples (default 256; "
        "0: against the first view's own capture, as noisy as it is)",
    )  # fmt: skip
    demo.add_argument("--seed", type=int, default=0)
    demo.add_argument("--cell-px", type=int, default=16, help="regression grid cell, pixels")
    demo.add_argument("--method", choices=("uniform", "vplace", "rsm"), default="vplace")
    demo.add_argument("--alpha", type=float, default=1.0, help="0 uniform .. 1 regression-guided")
    demo.add_argument(
        "--no-refit", action="store_true", help="vplace: keep the layout's VPL powers"
    )
    demo.add_argument(
        "--match-eevee", nargs="?", choices=MATCH_EEVEE, default="auto", const="on",
        help="refit the powers so that EEVEE's direct light plus the VPLs' light matches the "
        "captures, where that helps (an EEVEE render per captured view first; not with "
        "--animate): on (the flag alone), off, or auto (the default: on only where a surface the "
        "cameras see cuts one of your lamps, which EEVEE darkens)",
    )  # fmt: skip
    demo.add_argument(
        "--no-near-field", action="store_true",
        help="never add the light between nearby surfaces (the near-field gather, EEVEE's "
        "global-illumination fast GI within the lights' distance); by default the captures decide",
    )  # fmt: skip
    demo.add_argument("--iterations", type=int, default=3, help="layout iterations (cap)")
    demo.add_argument(
        "--feature-mode",
        choices=FEATURE_MODES,
        default="auto",
        help="auto: the surface's features, cross-validated; view: also the view's; all: every "
        "feature, no selection",
    )
    demo.add_argument("--profile", choices=("cosine", "omni"), default="cosine")
    demo.add_argument(
        "--radius",
        type=float,
        default=None,
        help="near-field radius of the VPLs, m (default: 1%% of the scene's diagonal)",
    )
    demo.add_argument("--no-eevee", action="store_true", help="skip the EEVEE preview render")


def _report_options(sub: argparse._SubParsersAction) -> None:
    from .job import FEATURE_MODES, MATCH_EEVEE
    from .report.config import PRESETS, ReportConfig

    rep = sub.add_parser(
        "report",
        help="speed against error: scenes x views x methods x VPL budgets, with Cycles",
    )
    rep.add_argument(
        "--scenes", nargs="+", default=list(ReportConfig.scenes),
        help=f"built-in scenes, of {', '.join(PRESETS)} (default: all)",
    )  # fmt: skip
    rep.add_argument("--blend", type=Path, default=None, help="any .blend instead of --scenes")
    rep.add_argument(
        "--fit-cameras", nargs="+", default=[], metavar="NAME",
        help="with --blend: the cameras the lights are laid out for",
    )  # fmt: skip
    rep.add_argument(
        "--held-out-cameras", nargs="+", default=[], metavar="NAME",
        help="with --blend: cameras scored with the same lights, never laid out for",
    )  # fmt: skip
    rep.add_argument(
        "--generated-views", type=int, default=None, metavar="N",
        help="held-out views to make in the region around the first fit camera (0-8; default: "
        "2 where the scene names no held-out camera, else 0)",
    )  # fmt: skip
    rep.add_argument("--budgets", type=int, nargs="+", default=[16, 64, 256, 1024])
    rep.add_argument("--methods", nargs="+", default=["uniform", "rsm", "vplace", "vplace+refit"])
    rep.add_argument("--out", type=Path, default=Path("out/report"))
    rep.add_argument(
        "--resolution", type=int, nargs=2, default=None, metavar=("W", "H"),
        help="override every view's size (default: each scene's preset; a .blend's render "
        "shape at 320 px on the long side)",
    )  # fmt: skip
    rep.add_argument("--capture-samples", type=int, default=None, help="the user's capture, spp")
    rep.add_argument(
        "--capture-curve", type=int, nargs="+", default=[],
        help="also lay out vplace+refit from captures at these spp and score every view",
    )  # fmt: skip
    rep.add_argument("--truth-samples", type=int, default=None, help="the ground truth, spp")
    rep.add_argument(
        "--cycles-samples", type=int, nargs="+", default=[1, 4, 16, 64],
        help="Cycles + OpenImageDenoise at these samples, the user's alternative",
    )  # fmt: skip
    rep.add_argument("--alpha", type=float, default=1.0, help="0 uniform .. 1 regression-guided")
    rep.add_argument("--iterations", type=int, default=3)
    rep.add_argument(
        "--seeds", type=int, nargs="+", default=[0, 1, 2],
        help="seeds of the stochastic layouts; tables show their mean",
    )  # fmt: skip
    rep.add_argument("--cache", type=Path, default=None, help="render cache (default OUT/cache)")
    rep.add_argument("--no-eevee", action="store_true", help="score with the evaluator only")
    rep.add_argument(
        "--single-truth", action="store_true",
        help="render each view's truth once: no second render with another seed, so no SSIM "
        "against the noise-free truth and no ceiling from the truth's noise",
    )  # fmt: skip
    rep.add_argument(
        "--eevee-methods", nargs="+", default=["uniform", "rsm", "vplace+refit"],
        help="methods whose lights EEVEE renders on every view (of --eevee-views)",
    )  # fmt: skip
    rep.add_argument(
        "--alternatives", nargs="*", default=["plain", "rt", "rt+volume", "vpl+rt", "cycles+oidn"],
        help="what a Blender user would pick instead, rendered on every view (of --eevee-views; "
        "none: only vplace)",
    )  # fmt: skip
    rep.add_argument("--eevee-samples", type=int, default=None, help="EEVEE's render samples")
    rep.add_argument(
        "--eevee-views", nargs="+", default=[], metavar="NAME",
        help="render EEVEE (the lights and the alternatives) only on these views, named as the "
        "report names them (default: every view)",
    )  # fmt: skip
    rep.add_argument("--feature-mode", choices=FEATURE_MODES, default="auto")
    rep.add_argument(
        "--no-near-field", action="store_true",
        help="never add the light between nearby surfaces (by default the captures decide)",
    )  # fmt: skip
    rep.add_argument(
        "--match-eevee", nargs="?", choices=MATCH_EEVEE, default="auto", const="on",
        help="lay out vplace+refit as the demo's --match-eevee does (default auto; the flag "
        "alone: on): the refit fits each fit view's indirect light plus what EEVEE's direct "
        "light lacks (an EEVEE render per captured view first, counted in the one-time cost)",
    )  # fmt: skip
    rep.add_argument(
        "--radius", type=float, default=None,
        help="near-field radius of the VPLs, m (default: 1%% of the scene's diagonal)",
    )  # fmt: skip
    rep.add_argument("--no-par2d", action="store_true", help="skip the PAR 2D plot")
    rep.add_argument(
        "--animate", type=int, nargs=3, default=None, metavar=("START", "END", "STEP"),
        help="with --blend: lights keyed over these frames (as demo --animate), every frame "
        "from START to END scored against a Cycles truth with the alternatives, plotted",
    )  # fmt: skip
    rep.add_argument(
        "--volume-per-frame", action="store_true",
        help="with --animate: also EEVEE ray tracing with a light probe volume baked again at "
        "every frame (slow: one bake a frame)",
    )  # fmt: skip
    add_region_arguments(rep)


def _par2d_options(sub: argparse._SubParsersAction) -> None:
    par = sub.add_parser("par2d", help="bake the PAR 2D demo scene and render it with EEVEE")
    par.add_argument("--out", type=Path, default=Path("out/par2d"))
    par.add_argument("--size", type=int, default=256, help="light map side, pixels")
    par.add_argument("--method", choices=("exact", "par", "monte_carlo"), default="exact")


def run_par2d_demo(out: Path, size: int, method: str) -> None:
    """Builds the PAR demo scene, bakes its light map, renders it with EEVEE, saves both."""
    from .errors import AddonError, output_folder, run_operator
    from .job import render_eevee_preview
    from .scenes import registry as default_scene
    from .writeback import par2d_bake

    if size < 1:
        raise AddonError(f"the light map size must be at least 1 pixel, got {size}")
    output_folder(out)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    source = default_scene.build_par2d_demo(scene)
    start = time.perf_counter()
    par2d_bake.bake_to_scene(scene, source, size, size, method)
    print(
        f"[vplace] baked a {size}x{size} {method} light map in {time.perf_counter() - start:.2f} s"
    )
    blend = out / "par2d_demo.blend"
    run_operator("wm.save_as_mainfile", f"cannot save {blend}", filepath=str(blend), copy=True)
    seconds = render_eevee_preview(scene, out / "eevee.png", (size, size))
    print(f"[vplace] EEVEE render {seconds:.1f} s -> {out / 'eevee.png'}")


def run(args: argparse.Namespace) -> None:
    """Runs the chosen command."""
    if args.command == "par2d":
        run_par2d_demo(args.out, args.size, args.method)
        return
    if args.command == "report" and args.animate:
        if args.eevee_views:
            from .errors import ReportError

            raise ReportError(
                "--eevee-views names views of the still report; with --animate EEVEE renders "
                "the scene camera's frames"
            )
        run_animated_report(args)
        return
    if args.command == "report" and args.volume_per_frame:
        from .errors import ReportError

        raise ReportError("--volume-per-frame goes with --animate")
    if args.command == "report":
        from .report.config import ReportConfig
        from .report.runs import run_report

        config = ReportConfig(
            scenes=args.scenes,
            blend=args.blend,
            fit_cameras=args.fit_cameras,
            held_out_cameras=args.held_out_cameras,
            budgets=args.budgets,
            methods=args.methods,
            resolution=tuple(args.resolution) if args.resolution else None,
            capture_samples=args.capture_samples,
            truth_samples=args.truth_samples,
            cycles_samples=args.cycles_samples,
            alpha=args.alpha,
            iterations=args.iterations,
            seeds=args.seeds,
            with_eevee=not args.no_eevee,
            eevee_methods=args.eevee_methods,
            alternatives=args.alternatives,
            eevee_views=args.eevee_views,
            feature_mode=args.feature_mode,
            near_field=not args.no_near_field,
            capture_curve=args.capture_curve,
            par2d=not args.no_par2d,
            cache_dir=args.cache,
            coverage=args.coverage,
            region_radius=args.region_radius,
            render_coverage=args.render_coverage,
            generated_views=args.generated_views,
            truth_noise=not args.single_truth,
            radius=args.radius,
            match_eevee=args.match_eevee,
        )
        if args.eevee_samples is not None:
            config.eevee_samples = args.eevee_samples
        run_report(config, args.out)
        return
    from .job import Job, method_name, run_main_job
    from .scenes.registry import builtin_scene, open_blend

    if args.scene.endswith(".blend") or Path(args.scene).is_file():
        blend = Path(args.scene)
    else:
        blend = builtin_scene(args.scene)
    open_blend(blend)
    from .scene.export import unit_scale

    job = Job(
        n_vpls=args.vpls,
        size=args.size,
        views=view_set(args),
        samples=args.samples,
        seed=args.seed,
        profile=args.profile,
        radius=args.radius,
        cell_px=args.cell_px,
        method=method_name(args.method, not args.no_refit),
        alpha=args.alpha,
        iterations=args.iterations,
        feature_mode=args.feature_mode,
        match_eevee=args.match_eevee,
        near_field=not args.no_near_field,
    ).in_scene_units(unit_scale(bpy.context.scene))
    extra = (
        args.score_between,
        args.cycles_samples,
        args.volume_once,
        args.volume_per_frame,
        args.eevee_still,
        args.truth_noise,
    )
    if not args.animate and any(extra):
        from .errors import AddonError

        raise AddonError(
            "--score-between, --cycles-samples, --eevee-still, --volume-once, "
            "--volume-per-frame and --truth-noise go with --animate"
        )
    if args.match_eevee == "on" and (args.animate or job.method != "vplace+refit"):
        from .errors import AddonError

        raise AddonError(
            "--match-eevee refits a still layout's powers: leave out --animate, --no-refit "
            "and --method uniform|rsm"
        )
    if args.animate:
        from .animation import run_animated_job

        done = run_animated_job(
            bpy.context.scene,
            args.out,
            tuple(args.animate),
            job=job,
            truth_samples=args.truth_samples or None,
            score_between=args.score_between,
            cycles_samples=args.cycles_samples,
            eevee=not args.no_eevee,
            eevee_still=args.eevee_still,
            volume_once=args.volume_once,
            volume_per_frame=args.volume_per_frame,
            truth_noise=args.truth_noise,
        )
        print(vplace_md(args.out))
        print(f"[vplace] {done.slots} keyed lights; results in {args.out}")
        return
    run_main_job(
        bpy.context.scene,
        args.out,
        job=job,
        eevee=not args.no_eevee,
        truth_samples=args.truth_samples or None,
    )
    print(f"[vplace] results in {args.out}")


#: The VPL budget of ``report --animate`` when ``--budgets`` holds it (the report's headline
#: figures are at 256); else the first budget given.
ANIMATED_REPORT_BUDGET = 256


def run_animated_report(args: argparse.Namespace) -> None:
    """``report --blend F --animate START END STEP``: the animated job (``addon.animation``) on
    the scene camera with the report's settings: one budget (:data:`ANIMATED_REPORT_BUDGET`),
    the first seed, every frame scored against a Cycles truth (``--truth-samples``, default
    1024), Cycles + OIDN at ``--cycles-samples``, EEVEE with the keyed lights and (``rt+volume``
    among ``--alternatives``) a volume baked once (``--volume-per-frame``: and one baked again
    at every frame), unless ``--no-eevee``; then the plot ``animation.png``."""
    from .animation import plot_animation, run_animated_job
    from .errors import ReportError
    from .job import Job, method_name
    from .scenes.registry import open_blend

    if args.blend is None:
        raise ReportError("report --animate needs --blend (the animated .blend)")
    if not args.budgets or min(args.budgets) < 1:
        raise ReportError(f"budgets must be positive VPL counts, got {list(args.budgets)}")
    open_blend(args.blend)
    budget = ANIMATED_REPORT_BUDGET if ANIMATED_REPORT_BUDGET in args.budgets else args.budgets[0]
    job = Job(
        n_vpls=budget,
        seed=args.seeds[0] if args.seeds else 0,
        method=method_name("vplace", True),
        alpha=args.alpha,
        iterations=args.iterations,
        feature_mode=args.feature_mode,
        resolution=tuple(args.resolution) if args.resolution else None,
        cache_dir=args.cache,
    )
    if args.capture_samples is not None:
        job.samples = args.capture_samples
    done = run_animated_job(
        bpy.context.scene,
        args.out,
        tuple(args.animate),
        job=job,
        truth_samples=args.truth_samples or 1024,
        score_between=True,
        cycles_samples=args.cycles_samples,
        eevee=not args.no_eevee,
        volume_once=not args.no_eevee and "rt+volume" in args.alternatives,
        volume_per_frame=not args.no_eevee and args.volume_per_frame,
        truth_noise=not args.single_truth,
    )
    plot_animation(done, args.out / "animation.png")
    print(vplace_md(args.out))
    print(f"[vplace] {done.slots} keyed lights; results in {args.out}")


def vplace_md(out: Path) -> str:
    """The animated run's Markdown report (``animation.md`` in ``out``)."""
    return (out / "animation.md").read_text()


def main(argv: list[str] | None = None) -> int:
    if argv is None:
        argv = sys.argv[sys.argv.index("--") + 1 :] if "--" in sys.argv else sys.argv[1:]
    args = parse_args(argv)
    from .errors import os_error_message
    from .native import vplace

    try:
        run(args)
    except (vplace.VplaceError, OSError) as exc:
        # A problem the user can fix: the input, the options, or the disk (a folder that cannot
        # be written, a full disk). Anything else is a bug and keeps its traceback.
        if args.debug:
            traceback.print_exc()
        else:
            message = os_error_message(exc, args.out) if isinstance(exc, OSError) else str(exc)
            print(f"vplace: error: {' '.join(message.split())}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    if not __package__:  # run as a file: blender --background --python addon/cli.py -- ...
        sys.path.insert(0, str(REPO))
        from addon.cli import main as package_main

        sys.exit(package_main())
    sys.exit(main())
