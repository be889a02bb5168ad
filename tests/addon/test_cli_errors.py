"""Every subcommand's bad inputs, one row each: the command line answers with exactly one line,
``vplace: error: ...`` naming the input, exit status 2, and no traceback (``--debug`` shows it).

The rows run in-process (``addon.cli.main``) on a tiny saved Cornell box and stop before any
long render; a full disk and a render Blender aborts are injected (``np.savez`` raising
``ENOSPC``, Blender's operator seam ``errors._call_operator`` cancelling or raising). Two rows
also run as a separate process, as a user would start it."""

from __future__ import annotations

import errno
import subprocess
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import bpy
import numpy as np
import pytest
from blender_util import cornell

from addon import cli, errors

ROOT = Path(__file__).resolve().parents[2]
#: A demo that would run in seconds: a 16 px capture at 1 spp, 8 VPLs, scored on the capture.
QUICK = {"--size": "16", "--samples": "1", "--vpls": "8", "--truth-samples": "0"}


@dataclass
class Case:
    """One bad input: the arguments (``{blend}``, ``{random}``, ``{text}``, ``{file}``,
    ``{tmp}`` filled in), what the message must say, and a fault to inject."""

    argv: list[str]
    says: str
    inject: Callable[[pytest.MonkeyPatch], None] | None = None
    #: The arguments of a quick demo on the saved Cornell box, after ``argv``.
    quick_demo: bool = False


def _disk_full(monkeypatch: pytest.MonkeyPatch) -> None:
    def savez(file: object, *args: object, **kwargs: object) -> None:
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(np, "savez", savez)


def _blender_fails(result: set[str] | None, what: str = "render.render") -> Callable:
    def inject(monkeypatch: pytest.MonkeyPatch) -> None:
        real = errors._call_operator

        def call(name: str, kwargs: dict) -> set[str]:
            if name != what:
                return real(name, kwargs)
            if result is None:
                raise RuntimeError("Error: Render error (Out of memory) aborted\n")
            return result

        monkeypatch.setattr(errors, "_call_operator", call)

    return inject


CASES = [
    # demo: the scene
    Case(["demo", "--scene", "{tmp}/nope.blend"], "no such .blend file: {tmp}/nope.blend"),
    Case(["demo", "--scene", "{random}"], "not a .blend file: {random}"),
    Case(["demo", "--scene", "{text}"], "not a .blend file: {text}"),
    Case(["demo", "--scene", "{folder}"], "{folder} is a folder, not a .blend file"),
    Case(["demo", "--scene", "{tmp}"], "unknown built-in scene"),
    Case(["demo", "--scene", "atrium"], "unknown built-in scene 'atrium'"),
    # demo: the options
    Case(["demo", "--vpls", "0"], "the VPL budget must be 1 to", quick_demo=True),
    Case(["demo", "--vpls", "-5"], "the VPL budget must be 1 to 8192, got -5", quick_demo=True),
    Case(["demo", "--vpls", "99999999"], "the VPL budget must be 1 to", quick_demo=True),
    Case(["demo", "--samples", "0"], "samples must be at least 1, got 0", quick_demo=True),
    Case(["demo", "--size", "0"], "capture size must be at least 8 pixels, got 0", quick_demo=True),
    Case(["demo", "--cameras", "Nope"], "no camera object named 'Nope'", quick_demo=True),
    Case(["demo", "--frames", "5", "1", "1"], "frames 5..1 step 1", quick_demo=True),
    Case(["demo", "--orbit", "0", "1", "10"], "an orbit needs at least one view", quick_demo=True),
    Case(["demo", "--orbit", "500", "0", "30"], "500 views is more than the 64", quick_demo=True),
    Case(
        ["demo", "--orbit", "3", "1", "400"], "an orbit turns by 0 to 180 degrees", quick_demo=True
    ),
    Case(["demo", "--frames", "1", "5000", "1"], "5000 views is more than the 64", quick_demo=True),
    # demo --animate (issue 23)
    Case(["demo", "--animate", "5", "1", "1"], "the frame range 5..1 is empty", quick_demo=True),
    Case(
        ["demo", "--animate", "1", "5", "0"],
        "animation step must be at least 1 frame, got 0",
        quick_demo=True,
    ),
    Case(
        ["demo", "--animate", "1", "500", "1"], "are 500 frames, more than the 120", quick_demo=True
    ),
    Case(
        ["demo", "--animate", "1", "2", "1", "--cycles-samples", "0"],
        "Cycles sample counts must be at least 1, got 0",
        quick_demo=True,
    ),
    Case(
        ["demo", "--score-between"],
        "--cycles-samples, --eevee-still, --volume-once, --volume-per-frame and --truth-noise go "
        "with --animate",
        quick_demo=True,
    ),
    Case(
        ["demo", "--volume-per-frame"],
        "--volume-per-frame and --truth-noise go with --animate",
        quick_demo=True,
    ),
    Case(
        ["demo", "--truth-noise"],
        "--truth-noise go with --animate",
        quick_demo=True,
    ),
    Case(
        ["demo", "--animate", "1", "2", "1", "--truth-noise", "--truth-samples", "0"],
        "the truth's noise needs a truth: give truth samples",
        quick_demo=True,
    ),
    Case(["demo", "--cell-px", "0"], "cell_px = 0 is out of range", quick_demo=True),
    Case(["demo", "--coverage", "-1"], "coverage views must be 0 to 16", quick_demo=True),
    Case(["demo", "--region-radius", "-2"], "region radius", quick_demo=True),
    Case(
        ["demo", "--alpha", "2"],
        "alpha must be 0 (uniform) to 1 (regression-guided), got 2",
        quick_demo=True,
    ),
    Case(["demo", "--radius", "-1"], "the near-field radius must be 0 or more, got -1"),
    Case(["demo", "--iterations", "-1"], "layout iterations must be 0", quick_demo=True),
    Case(["demo", "--match-eevee", "--no-refit"], "--match-eevee refits a still layout's"),
    Case(["demo", "--match-eevee", "--animate", "1", "2", "1"], "leave out --animate"),
    Case(["demo", "--truth-samples", "-1"], "truth samples must be at least 1", quick_demo=True),
    # demo: the output and the machine
    Case(["demo", "--out", "{file}/out"], "cannot write the output folder {file}/out: Not a dir"),
    Case(["demo", "--out", "/proc/vplace-out"], "cannot write the output folder /proc/vplace-out"),
    Case(["demo", "--out", "{tmp}/out"], "writing into {tmp}/out: the disk is full", _disk_full),
    Case(
        ["demo", "--out", "{tmp}/out"],
        "Cycles did not finish the capture of scene 'Scene': Blender did not finish it (CANCELLED)",
        _blender_fails({"CANCELLED"}),
    ),
    Case(
        ["demo", "--out", "{tmp}/out"],
        "Cycles did not finish the capture of scene 'Scene': Render error (Out of memory) aborted",
        _blender_fails(None),
    ),
    Case(
        ["demo", "--out", "{tmp}/out"],
        "cannot save a copy of the file to {tmp}/out/scene.blend: Blender did not finish it",
        _blender_fails({"CANCELLED"}, "wm.save_as_mainfile"),
    ),
    # report
    Case(["report", "--blend", "{tmp}/nope.blend", "--fit-cameras", "A"], "no such .blend file"),
    Case(["report", "--blend", "{random}", "--fit-cameras", "A"], "not a .blend file: {random}"),
    Case(["report", "--blend", "{blend}"], "a report on a .blend needs --fit-cameras"),
    Case(
        ["report", "--blend", "{blend}", "--fit-cameras", "Nope", "--no-eevee", "--no-par2d"],
        "no camera object named 'Nope'",
    ),
    Case(["report", "--scenes", "atrium"], "unknown scenes ['atrium']"),
    Case(["report", "--volume-per-frame"], "--volume-per-frame goes with --animate"),
    Case(
        ["report", "--blend", "{blend}", "--animate", "1", "2", "1", "--eevee-views", "A"],
        "--eevee-views names views of the still report",
    ),
    Case(["report", "--animate", "1", "5", "1"], "report --animate needs --blend"),
    Case(["report", "--blend", "{blend}", "--animate", "5", "1", "1"], "frame range 5..1 is empty"),
    Case(["report", "--blend", "{blend}", "--animate", "1", "5", "0"], "step must be at least 1"),
    Case(["report", "--budgets", "0"], "budgets must be positive VPL counts, got [0]"),
    Case(["report", "--budgets", "16", "-5"], "budgets must be positive VPL counts, got [16, -5]"),
    Case(["report", "--methods", "magic"], "unknown methods ['magic']"),
    Case(["report", "--coverage", "99"], "coverage views must be 0 to 16, got 99"),
    Case(["report", "--generated-views", "9"], "generated views must be 0 to 8, got 9"),
    Case(["report", "--eevee-methods", "magic"], "unknown EEVEE methods ['magic']"),
    Case(["report", "--alternatives", "magic"], "unknown alternatives ['magic']"),
    Case(["report", "--capture-samples", "0"], "capture samples must be at least 1, got 0"),
    Case(["report", "--truth-samples", "0"], "truth samples must be at least 1, got 0"),
    Case(["report", "--eevee-samples", "0"], "EEVEE samples must be at least 1, got 0"),
    Case(["report", "--radius", "-1"], "the near-field radius must be 0 or more, got -1"),
    Case(["report", "--cycles-samples", "0"], "Cycles sample counts must be at least 1"),
    Case(["report", "--capture-curve", "0"], "Cycles sample counts must be at least 1"),
    Case(["report", "--resolution", "0", "0"], "the resolution must be at least 8 x 8"),
    Case(["report", "--alpha", "3"], "alpha must be 0 (uniform) to 1"),
    Case(["report", "--iterations", "-1"], "layout iterations must be 0 (off) or more"),
    Case(["report", "--out", "{file}/out"], "cannot write the output folder {file}/out"),
    # par2d
    Case(["par2d", "--size", "0"], "the light map size must be at least 1 pixel, got 0"),
    Case(["par2d", "--out", "{file}/out"], "cannot write the output folder {file}/out"),
]


def _id(case: Case) -> str:
    return " ".join(case.argv) + (
        " +" + case.inject.__qualname__.split(".")[0] if case.inject else ""
    )


@pytest.fixture(scope="module")
def inputs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, str]:
    """The files the rows name: a saved Cornell box, random bytes as a .blend and as a .txt,
    and a plain file to put an output folder under."""
    tmp = tmp_path_factory.mktemp("inputs")
    cornell()
    blend = tmp / "in.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    noise = np.random.default_rng(0).bytes(4096)
    (tmp / "random.blend").write_bytes(noise)
    (tmp / "notes.txt").write_bytes(noise)
    (tmp / "a_file").write_text("not a folder")
    (tmp / "folder.blend").mkdir()
    return {
        "folder": str(tmp / "folder.blend"),
        "blend": str(blend),
        "random": str(tmp / "random.blend"),
        "text": str(tmp / "notes.txt"),
        "file": str(tmp / "a_file"),
    }


def _argv(case: Case, names: dict[str, str]) -> list[str]:
    argv = [a.format(**names) for a in case.argv]
    if case.quick_demo or (argv[0] == "demo" and "--scene" not in argv):
        argv += ["--scene", names["blend"]]
    if argv[0] == "demo":
        given = set(argv)
        for flag, value in QUICK.items():
            if flag not in given:
                argv += [flag, value]
        argv.append("--no-eevee")
    if "--out" not in argv:
        argv += ["--out", names["tmp"] + "/out"]
    return argv


@pytest.mark.parametrize("case", CASES, ids=_id)
def test_every_bad_input_is_one_line_naming_it(case, inputs, tmp_path, monkeypatch, capsys):
    names = {**inputs, "tmp": str(tmp_path)}
    argv = _argv(case, names)
    if case.inject is not None:
        case.inject(monkeypatch)
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.startswith("vplace: error:")]
    assert len(lines) == 1, err
    assert case.says.format(**names) in lines[0], err
    assert "Traceback" not in err


def test_debug_shows_the_traceback(inputs, tmp_path, capsys):
    assert cli.main(["--debug", "demo", "--scene", inputs["random"], "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "Traceback" in err and "AddonError: not a .blend file" in err


@pytest.mark.parametrize(
    "argv, says",
    [
        (
            ["demo", "--scene", "{random}"],
            "vplace: error: not a .blend file: {random} (it does not begin as one)",
        ),
        (
            ["par2d", "--out", "{file}/out"],
            "vplace: error: cannot write the output folder {file}/out: Not a directory",
        ),
    ],
)
def test_as_a_process_the_last_line_is_the_error(argv, says, inputs):
    cmd = [sys.executable, "-m", "addon.cli", *(a.format(**inputs) for a in argv)]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert r.returncode == 2, r.stderr
    assert r.stderr.strip().splitlines()[-1] == says.format(**inputs)
    assert "Traceback" not in r.stderr
