"""Builds the installable extension zip: the add-on, its manifest and the bundled wheels.

Run with the project's Python (``make extension``): builds the ``vplace`` abi3 wheel with
maturin (release), fetches the OpenEXR wheel the capture reads passes with, stages the add-on
with ``wheels = [...]`` filled in, and packs it with Blender's own extension CLI (shipped in the
bpy wheel). Prints the zip's path.
"""

from __future__ import annotations

import argparse
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ADDON = Path(__file__).resolve().parent.parent
REPO = ADDON.parent
#: Wheels the add-on needs beyond what Blender ships (numpy comes with Blender).
EXTRA_WHEELS = ["OpenEXR==3.5.3"]


def blender_ext_cli() -> Path:
    import bpy  # the bpy wheel carries Blender's scripts, among them the extension CLI

    for parent in Path(bpy.__file__).parents:
        found = sorted(parent.glob("scripts/addons_core/bl_pkg/cli/blender_ext.py"))
        if found:
            return found[-1]
    raise SystemExit(f"Blender's extension CLI was not found above {bpy.__file__}")


def build(out_dir: Path) -> Path:
    out_dir.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="vplace-ext-") as tmp:
        stage = Path(tmp) / "vplace"
        wheels = stage / "wheels"
        wheels.mkdir(parents=True)
        subprocess.run(
            [sys.executable, "-m", "maturin", "build", "--release", "--quiet",
             "-m", str(REPO / "rust/vplace-py/Cargo.toml"), "-o", str(wheels)],
            check=True,
        )
        subprocess.run(
            [sys.executable, "-m", "pip", "download", "--quiet", "--no-deps",
             "--only-binary=:all:", "-d", str(wheels), *EXTRA_WHEELS],
            check=True,
        )
        for src in ADDON.rglob("*.py"):
            rel = src.relative_to(ADDON)
            if rel.parts[0] == "_build":
                continue
            (stage / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, stage / rel)
        names = sorted(p.name for p in wheels.glob("*.whl"))
        manifest = (ADDON / "blender_manifest.toml").read_text()
        listed = ", ".join(f'"./wheels/{n}"' for n in names)
        manifest = re.sub(r"^wheels = \[.*?\]", f"wheels = [{listed}]", manifest, flags=re.M)
        (stage / "blender_manifest.toml").write_text(manifest)
        subprocess.run(
            [sys.executable, str(blender_ext_cli()), "build",
             "--source-dir", str(stage), "--output-dir", str(out_dir)],
            check=True,
        )
    version = re.search(r'^version = "(.*)"', manifest, flags=re.M)
    zip_path = out_dir / f"vplace-{version.group(1) if version else '0'}.zip"
    if not zip_path.exists():
        raise SystemExit(f"the extension CLI did not write {zip_path}")
    return zip_path


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--out", type=Path, default=REPO / "dist")
    print(build(p.parse_args().out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
