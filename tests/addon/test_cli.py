"""The headless command line: ``python -m addon.cli`` and the file form used by
``blender --background --python addon/cli.py -- ...``: the main job, and how errors print."""

import json
import subprocess
import sys
from pathlib import Path

import bpy
from blender_util import cornell

ROOT = Path(__file__).resolve().parents[2]
ARGS = ["--size", "16", "--samples", "4", "--vpls", "8", "--no-eevee"]


def saved_cornell(tmp_path):
    cornell()
    path = tmp_path / "in.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    return path


def run(cmd, cwd):
    return subprocess.run(cmd, capture_output=True, text=True, timeout=600, cwd=cwd)


def test_python_m_vplace_runs_the_main_job(tmp_path):
    blend = saved_cornell(tmp_path)
    out = tmp_path / "out"
    r = run(
        [
            sys.executable,
            "-m",
            "addon.cli",
            "demo",
            "--scene",
            str(blend),
            "--out",
            str(out),
            "--cell-px",
            "8",
            *ARGS,
        ],
        cwd=ROOT,
    )
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    report = json.loads((out / "report.json").read_text())
    assert report["n_vpls"] == 8 and (out / "scene.blend").exists()
    # Named after its file, not Blender's default scene name.
    assert report["scene"] == "in" and "# vplace report: in" in (out / "report.md").read_text()
    assert "fitted model (cells of 8 px)" in r.stdout
    # Scored against a 256 spp render of the scene camera, not the 4 spp capture.
    assert report["reference"]["samples"] == 256 and "ground truth" in report["reference"]["label"]


def test_cli_as_a_file_with_blender_style_arguments(tmp_path):
    blend = saved_cornell(tmp_path)
    out = tmp_path / "out"
    r = run(
        [
            sys.executable,
            str(ROOT / "addon/cli.py"),
            "--",
            "demo",
            "--scene",
            str(blend),
            "--out",
            str(out),
            *ARGS,
            "--truth-samples",
            "0",
        ],
        cwd=tmp_path,
    )
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    assert (out / "vpls.csv").exists()
    # --truth-samples 0: scored against the capture itself, and said so.
    assert json.loads((out / "report.json").read_text())["reference"]["samples"] == 4


def test_bad_arguments_exit_with_a_message(tmp_path):
    r = run([sys.executable, "-m", "addon.cli", "demo", "--profile", "phong"], cwd=ROOT)
    assert r.returncode == 2 and "invalid choice: 'phong'" in r.stderr


def test_user_errors_are_one_line_and_tracebacks_only_with_debug(tmp_path):
    cmd = [sys.executable, "-m", "addon.cli", "demo", "--scene", str(tmp_path / "nope.blend")]
    r = run(cmd, cwd=ROOT)
    assert r.returncode == 2
    assert (
        r.stderr.strip().splitlines()[-1]
        == f"vplace: error: no such .blend file: {tmp_path}/nope.blend"
    )
    assert "Traceback" not in r.stderr
    r = run([*cmd[:3], "--debug", *cmd[3:]], cwd=ROOT)
    assert r.returncode == 2 and "Traceback" in r.stderr and "AddonError" in r.stderr
