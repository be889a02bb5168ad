"""Builds the installable extension zips, one per platform: the add-on, its manifest and the wheels.

Run with the project's Python (``make extension``). For each platform it builds the ``vplace``
abi3 wheel with maturin (release; cross-compiled for Windows and macOS), downloads the OpenEXR
wheel the capture reads passes with, stages the add-on with ``platforms`` and ``wheels`` filled
in, and packs it with Blender's own extension CLI (shipped in the bpy wheel) with
``--split-platforms``, which writes one zip per platform holding only that platform's wheels.
Prints each zip's path, one a line.

The cross toolchains are installed here, from the registries, when missing: the Rust targets
(``rustup target add``), the MinGW-w64 linker for Windows (Debian's ``gcc-mingw-w64-x86-64``;
needs root for apt-get) and zig (PyPI ``ziglang``), which maturin uses as the linker for macOS
and for a Linux wheel that runs on glibc 2.28, the oldest Blender 4.2 supports.
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

ADDON = Path(__file__).resolve().parent.parent
REPO = ADDON.parent
#: Wheels the add-on needs beyond what Blender ships (numpy comes with Blender).
EXTRA_WHEELS = ["OpenEXR==3.5.3"]
#: The Pythons of the Blenders the manifest names: 3.11 (4.2 to 5.0) and 3.13 (5.1 on). The vplace
#: wheel is abi3 (any of them); OpenEXR's are per Python, and Blender installs the one for its own.
PYTHON_VERSIONS = ("3.11", "3.13")
ZIGLANG = "ziglang==0.17.1"


@dataclass(frozen=True)
class Platform:
    blender: str  # Blender's platform name, as in the manifest
    rust_target: str
    maturin_args: tuple[str, ...]
    pip_platforms: tuple[str, ...]  # for `pip download --platform`, any of them


PLATFORMS = {
    p.blender: p
    for p in (
        Platform(
            "windows-x64",
            "x86_64-pc-windows-gnu",
            (),
            ("win_amd64",),
        ),
        Platform(
            "macos-arm64",
            "aarch64-apple-darwin",
            ("--zig",),
            ("macosx_11_0_arm64",),
        ),
        Platform(
            "macos-x64",
            "x86_64-apple-darwin",
            ("--zig",),
            ("macosx_10_9_x86_64", "macosx_10_15_x86_64", "macosx_11_0_x86_64"),
        ),
        Platform(
            "linux-x64",
            "x86_64-unknown-linux-gnu",
            ("--zig", "--compatibility", "manylinux_2_28"),
            ("manylinux_2_28_x86_64", "manylinux_2_17_x86_64", "manylinux2014_x86_64"),
        ),
    )
}


def blender_ext_cli() -> Path:
    import bpy  # the bpy wheel carries Blender's scripts, among them the extension CLI

    for parent in Path(bpy.__file__).parents:
        found = sorted(parent.glob("scripts/addons_core/bl_pkg/cli/blender_ext.py"))
        if found:
            return found[-1]
    raise SystemExit(f"Blender's extension CLI was not found above {bpy.__file__}")


def step(msg: str) -> None:
    print(f"[extension] {msg}", file=sys.stderr, flush=True)


def install_toolchains(platforms: list[Platform]) -> None:
    """Installs what the cross builds need and is missing: Rust targets, MinGW, zig."""
    targets = [p.rust_target for p in platforms]
    if shutil.which("rustup"):
        installed = subprocess.run(
            ["rustup", "target", "list", "--installed"], capture_output=True, text=True, check=True
        ).stdout.split()
    else:  # a Rust without rustup builds for its host only
        host = re.search(
            r"^host: (\S+)", subprocess.check_output(["rustc", "-vV"], text=True), re.M
        )
        installed = [host.group(1)] if host else []
    missing = [t for t in targets if t not in installed]
    if missing and not shutil.which("rustup"):
        raise SystemExit(f"building for {', '.join(missing)} needs rustup (rustup target add)")
    if missing:
        step(f"rustup target add {' '.join(missing)}")
        subprocess.run(["rustup", "target", "add", *missing], check=True)
    if "x86_64-pc-windows-gnu" in targets and not shutil.which("x86_64-w64-mingw32-gcc"):
        cmd = ["apt-get", "install", "-y", "-q", "gcc-mingw-w64-x86-64"]
        if os.geteuid() != 0:
            raise SystemExit(
                "the Windows build links with MinGW-w64's x86_64-w64-mingw32-gcc, not found: "
                f"install it as root ({' '.join(cmd)}) or build without windows-x64 (--platforms)"
            )
        step(" ".join(cmd))
        if subprocess.run(cmd).returncode != 0:
            subprocess.run(["apt-get", "update", "-q"], check=True)
            subprocess.run(cmd, check=True)
    if any("--zig" in p.maturin_args for p in platforms):
        have_zig = subprocess.run(
            [sys.executable, "-m", "ziglang", "version"], capture_output=True
        ).returncode
        if have_zig != 0:
            step(f"pip install {ZIGLANG}")
            subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", ZIGLANG], check=True)


def build_vplace_wheel(platform: Platform, wheels: Path) -> Path:
    step(f"maturin build --target {platform.rust_target}")
    before = set(wheels.glob("vplace-*.whl"))
    # maturin finds zig through the `ziglang` module of the Python on PATH: this venv's.
    env = dict(os.environ, PATH=f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}")
    subprocess.run(
        [
            sys.executable, "-m", "maturin", "build", "--release", "--quiet",
            "-m", str(REPO / "rust/vplace-py/Cargo.toml"),
            "--target", platform.rust_target, *platform.maturin_args,
            "-o", str(wheels),
        ],
        check=True,
        env=env,
    )  # fmt: skip
    built = sorted(set(wheels.glob("vplace-*.whl")) - before)
    if len(built) != 1:
        raise SystemExit(f"maturin for {platform.blender} wrote {built}, expected one wheel")
    return built[0]


def download_wheels(platform: Platform, wheels: Path) -> None:
    platform_args = [arg for tag in platform.pip_platforms for arg in ("--platform", tag)]
    for python in PYTHON_VERSIONS:
        step(f"pip download {' '.join(EXTRA_WHEELS)} for {platform.blender}, Python {python}")
        subprocess.run(
            [
                sys.executable, "-m", "pip", "download", "--quiet", "--no-deps",
                "--only-binary=:all:", "--python-version", python, *platform_args,
                "-d", str(wheels), *EXTRA_WHEELS,
            ],
            check=True,
        )  # fmt: skip


def stage_addon(stage: Path, platforms: list[Platform], wheel_names: list[str]) -> str:
    for src in ADDON.rglob("*.py"):
        rel = src.relative_to(ADDON)
        if rel.parts[0] == "_build":
            continue
        (stage / rel).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(src, stage / rel)
    manifest = (ADDON / "blender_manifest.toml").read_text()
    listed = ", ".join(f'"./wheels/{n}"' for n in wheel_names)
    manifest = re.sub(r"^wheels = \[.*?\]", f"wheels = [{listed}]", manifest, flags=re.M)
    names = ", ".join(f'"{p.blender}"' for p in platforms)
    manifest = re.sub(r"^platforms = \[.*?\]", f"platforms = [{names}]", manifest, flags=re.M)
    (stage / "blender_manifest.toml").write_text(manifest)
    return manifest


def build(out_dir: Path, platforms: list[Platform]) -> list[Path]:
    install_toolchains(platforms)
    out_dir.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="vplace-ext-") as tmp:
        stage = Path(tmp) / "vplace"
        wheels = stage / "wheels"
        wheels.mkdir(parents=True)
        for platform in platforms:
            build_vplace_wheel(platform, wheels)
            download_wheels(platform, wheels)
        names = sorted(p.name for p in wheels.glob("*.whl"))
        manifest = stage_addon(stage, platforms, names)
        version = re.search(r'^version = "(.*)"', manifest, flags=re.M)
        zips = [
            out_dir
            / f"vplace-{version.group(1) if version else '0'}-{p.blender.replace('-', '_')}.zip"
            for p in platforms
        ]
        for old in zips:
            old.unlink(missing_ok=True)
        step("blender_ext.py build --split-platforms")
        subprocess.run(
            [
                sys.executable, str(blender_ext_cli()), "build", "--split-platforms",
                "--source-dir", str(stage), "--output-dir", str(out_dir),
            ],
            check=True,
            stdout=sys.stderr,
        )  # fmt: skip
    missing = [z for z in zips if not z.exists()]
    if missing:
        raise SystemExit(f"the extension CLI did not write {', '.join(map(str, missing))}")
    return zips


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--out", type=Path, default=REPO / "dist")
    p.add_argument(
        "--platforms",
        nargs="+",
        choices=list(PLATFORMS),
        default=list(PLATFORMS),
        help="Blender platforms to build zips for (default: all four)",
    )
    args = p.parse_args()
    for zip_path in build(args.out, [PLATFORMS[name] for name in args.platforms]):
        print(zip_path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
