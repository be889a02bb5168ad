"""The four extension zips of ``make extension``, checked as far as this Linux machine can.

Each zip (``dist/vplace-<version>-<platform>.zip``) is opened and checked: Blender's own
validator accepts it; its manifest names its one platform and the wheels it holds; each wheel's
tags (abi3 for vplace, cp311 for OpenEXR, the platform) agree with its WHEEL file; each native
library is the right binary format and CPU, exports ``PyInit_<module>``, loads only the system's
libraries (and, on Windows, ``python3.dll``: the stable ABI), needs no newer glibc or macOS than
its wheel's tag and Blender 4.2 claim, and on arm64 macOS carries a valid ad-hoc signature; the
add-on's files are the same in all four and the same as ``addon/``. Where the Windows CPython
under Wine of ``tests/windows_under_wine.py`` is set up, the Windows zip's wheels are unpacked
into it and the native test suite (tests/native) runs against them.

The zips are built by ``make extension`` (cross compilation: minutes, not part of ``make test``);
without them, or when they are older than the sources, these tests skip and say so.
"""

from __future__ import annotations

import io
import re
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

import binformats
import pytest
import windows_under_wine as wine

ROOT = Path(__file__).resolve().parent.parent
DIST = ROOT / "dist"
sys.path.insert(0, str(ROOT / "addon/_build"))
import build_extension  # noqa: E402

PLATFORMS = list(build_extension.PLATFORMS)
VERSION = tomllib.loads((ROOT / "addon/blender_manifest.toml").read_text())["version"]
#: The oldest systems Blender 4.2 runs on: glibc 2.28, macOS 11.2.
GLIBC_MAX = (2, 28)
MACOS_MAX = (11, 2)
#: What each platform's native libraries are, and the system libraries they may load.
EXPECT = {
    "windows-x64": ("PE32+", "x86_64", r"win_amd64"),
    "macos-arm64": ("Mach-O", "arm64", r"macosx_(\d+)_(\d+)_arm64"),
    "macos-x64": ("Mach-O", "x86_64", r"macosx_(\d+)_(\d+)_x86_64"),
    "linux-x64": ("ELF64", "x86_64", r"manylinux_2_(\d+)_x86_64"),
}
WINDOWS_SYSTEM_DLLS = {
    "kernel32.dll", "ntdll.dll", "msvcrt.dll", "bcryptprimitives.dll", "advapi32.dll",
    "ws2_32.dll", "userenv.dll", "bcrypt.dll", "vcruntime140.dll", "vcruntime140_1.dll",
}  # fmt: skip
#: Where the sources of the zips are: a zip older than any of them is stale.
SOURCES = [ROOT / "addon", ROOT / "rust", ROOT / "Cargo.lock"]


def zip_path(platform: str) -> Path:
    return DIST / f"vplace-{VERSION}-{platform.replace('-', '_')}.zip"


def newest_source() -> float:
    files = [p for s in SOURCES for p in ([s] if s.is_file() else s.rglob("*"))]
    return max(p.stat().st_mtime for p in files if p.is_file() and "__pycache__" not in p.parts)


def _missing_or_stale() -> str | None:
    missing = [zip_path(p).name for p in PLATFORMS if not zip_path(p).exists()]
    if missing:
        return f"{', '.join(missing)} not in dist/: `make extension` builds and checks the zips"
    if min(zip_path(p).stat().st_mtime for p in PLATFORMS) < newest_source():
        return "dist/ zips are older than addon/ or rust/: `make extension` rebuilds them"
    return None


pytestmark = pytest.mark.skipif(bool(_missing_or_stale()), reason=_missing_or_stale() or "")


def manifest(zf: zipfile.ZipFile) -> dict:
    return tomllib.loads(zf.read("blender_manifest.toml").decode())


def wheels(zf: zipfile.ZipFile) -> dict[str, zipfile.ZipFile]:
    return {
        Path(n).name: zipfile.ZipFile(io.BytesIO(zf.read(n)))
        for n in zf.namelist()
        if n.startswith("wheels/") and n.endswith(".whl")
    }


def native_libs(wheel: zipfile.ZipFile) -> dict[str, binformats.NativeLib]:
    return {
        n: binformats.read(wheel.read(n))
        for n in wheel.namelist()
        if re.search(r"\.(pyd|so|dylib)$", n) and "/tests/" not in n
    }


@pytest.mark.parametrize("platform", PLATFORMS)
def test_blender_validates_and_manifest_names_the_platform(platform):
    path = zip_path(platform)
    check = subprocess.run(
        [sys.executable, str(build_extension.blender_ext_cli()), "validate", str(path)],
        capture_output=True,
        text=True,
    )
    assert check.returncode == 0 and "Success" in check.stdout, check.stdout + check.stderr
    zf = zipfile.ZipFile(path)
    m = manifest(zf)
    assert m["id"] == "vplace" and m["version"] == VERSION
    generated = m["build"]["generated"]  # what Blender reads when it installs the zip
    assert generated["platforms"] == [platform]
    in_zip = sorted(f"./wheels/{name}" for name in wheels(zf))
    assert sorted(generated["wheels"]) == in_zip, (generated["wheels"], in_zip)
    assert len(in_zip) == 1 + len(build_extension.PYTHON_VERSIONS), in_zip
    assert sorted(m["platforms"]) == sorted(PLATFORMS)  # the source manifest: all four


@pytest.mark.parametrize("platform", PLATFORMS)
def test_wheel_tags(platform):
    plat_re = EXPECT[platform][2]
    by_name = wheels(zipfile.ZipFile(zip_path(platform)))
    projects = sorted(n.split("-")[0].lower() for n in by_name)
    assert projects == ["openexr"] * len(build_extension.PYTHON_VERSIONS) + ["vplace"], projects
    pythons = {f"cp{v.replace('.', '')}" for v in build_extension.PYTHON_VERSIONS}
    for name, wheel in by_name.items():
        project, version, py_tag, abi_tag, plat_tag = name[: -len(".whl")].split("-")
        if project == "vplace":
            assert (py_tag, abi_tag, version) == ("cp311", "abi3", VERSION), name
        else:  # one OpenEXR wheel for each Python Blender has
            assert abi_tag == py_tag and py_tag in pythons, name
            pythons.discard(py_tag)
        assert re.fullmatch(plat_re, plat_tag), name
        # The same tag as the WHEEL file inside says, and a binary (not pure) wheel.
        (meta,) = [n for n in wheel.namelist() if n.endswith(".dist-info/WHEEL")]
        text = wheel.read(meta).decode()
        assert f"Tag: {py_tag}-{abi_tag}-{plat_tag}" in text, text
        assert "Root-Is-Purelib: false" in text, text
    assert not pythons, f"no OpenEXR wheel for {pythons}"


@pytest.mark.parametrize("platform", PLATFORMS)
def test_native_libraries(platform):
    fmt, machine, plat_re = EXPECT[platform]
    for name, wheel in wheels(zipfile.ZipFile(zip_path(platform))).items():
        plat_tag = name[: -len(".whl")].split("-")[-1]
        libs = native_libs(wheel)
        assert libs, f"{name} has no native library"
        if name.startswith("vplace-"):
            suffix = ".pyd" if platform.startswith("windows") else ".abi3.so"
            assert sorted(libs) == [f"vplace/_native{suffix}"], sorted(libs)
        for path, lib in libs.items():
            where = f"{name}:{path}"
            assert (lib.format, lib.machine, lib.shared_library) == (fmt, machine, True), where
            module = Path(path).name.split(".")[0]
            symbol = ("_" if fmt == "Mach-O" else "") + f"PyInit_{module}"
            if path.endswith((".pyd", ".so")) and "/.dylibs/" not in path:
                assert symbol in lib.exports, f"{where} does not export {symbol}"
            if fmt == "PE32+":
                dlls = {d.lower() for d in lib.needed}
                extra = {
                    d
                    for d in dlls - WINDOWS_SYSTEM_DLLS
                    if not d.startswith("api-ms-win-") and not re.fullmatch(r"python3\d*\.dll", d)
                    and not re.fullmatch(r"msvcp140[-_\w]*\.dll", d)
                }  # fmt: skip
                assert not extra, f"{where} loads DLLs Windows does not ship: {sorted(extra)}"
                if name.startswith("vplace-"):
                    # The stable ABI: python3.dll, never one Python's python3XY.dll.
                    assert "python3.dll" in dlls and not any(
                        re.fullmatch(r"python3\d+\.dll", d) for d in dlls
                    ), dlls
                    assert not any(d.startswith("lib") for d in dlls), dlls  # no MinGW runtime
            elif fmt == "Mach-O":
                foreign = [d for d in lib.needed if not d.startswith(("/usr/lib/", "/System/"))]
                assert not foreign, f"{where} loads libraries macOS does not ship: {foreign}"
                tag = tuple(int(x) for x in re.fullmatch(plat_re, plat_tag).groups())
                assert lib.macos_min is not None and lib.macos_min <= tag, (where, lib.macos_min)
                assert lib.macos_min <= MACOS_MAX, (where, lib.macos_min)
                if machine == "arm64":  # arm64 macOS kills unsigned code at load
                    assert lib.code_signature and lib.code_signature.startswith("valid"), where
            else:
                assert not any("libpython" in d for d in lib.needed), (where, lib.needed)
                tag_glibc = (2, int(re.fullmatch(plat_re, plat_tag).group(1)))
                assert lib.glibc_needed is not None and lib.glibc_needed <= tag_glibc, where
                assert lib.glibc_needed <= GLIBC_MAX, (where, lib.glibc_needed)


def test_addon_files_are_the_same_in_all_four_and_in_addon():
    def addon_files(zf: zipfile.ZipFile) -> dict[str, bytes]:
        return {
            n: zf.read(n)
            for n in zf.namelist()
            if not n.startswith("wheels/") and n != "blender_manifest.toml" and not n.endswith("/")
        }

    files = {p: addon_files(zipfile.ZipFile(zip_path(p))) for p in PLATFORMS}
    first = files[PLATFORMS[0]]
    for platform in PLATFORMS[1:]:
        assert files[platform] == first, platform
    sources = {
        str(p.relative_to(ROOT / "addon")): p.read_bytes()
        for p in (ROOT / "addon").rglob("*.py")
        if "_build" not in p.parts and "__pycache__" not in p.parts
    }
    assert first == sources, sorted(set(first) ^ set(sources))
    # The manifests differ only in the generated platform and wheels.
    heads = {
        zipfile.ZipFile(zip_path(p)).read("blender_manifest.toml").decode().split("# BEGIN GEN")[0]
        for p in PLATFORMS
    }
    assert len(heads) == 1, heads


WINE_SMOKE = """
import sys, tempfile, os
import numpy as np
import vplace, OpenEXR
assert vplace._native.__file__.startswith(sys.argv[1]), vplace._native.__file__
a = np.linspace(0, 1, 16 * 16 * 3, dtype=np.float32).reshape(16, 16, 3)
assert vplace.ssim(a, a) > 0.999 and vplace.rmse(a, a) == 0.0
path = os.path.join(tempfile.mkdtemp(), "t.exr")
OpenEXR.File({"type": OpenEXR.scanlineimage}, {"RGB": a}).write(path)
with OpenEXR.File(path) as f:
    assert np.array_equal(f.channels()["RGB"].pixels, a)
print("WINDOWS-OK", vplace._native.__file__, OpenEXR.__file__)
"""


#: Native tests that do not run on Windows, each with its reason.
WINDOWS_DESELECT = {
    # vplace.bench_layout reads its peak memory with the Unix-only `resource` module.
    "tests/native/test_bench_scripts.py::test_bench_layout_runs_for_several_views",
}


@pytest.mark.slow
@pytest.mark.skipif(
    not wine.ready(),
    reason="no Windows Python under Wine: `python tests/windows_under_wine.py` (make extension) "
    "sets it up",
)
def test_windows_wheels_load_and_pass_the_native_tests_under_wine(tmp_path):
    site = tmp_path / "site"
    for name, wheel in wheels(zipfile.ZipFile(zip_path("windows-x64"))).items():
        if "-cp311-" in name:  # the wheels for this Python (Blender 4.2 to 5.0's)
            wine.unpack_wheel(wheel, site)
    env = {"PYTHONPATH": f"{wine.windows_path(site)};{wine.windows_path(wine.SITE)}"}
    (tmp_path / "smoke.py").write_text(WINE_SMOKE)
    smoke = wine.run(env, str(tmp_path / "smoke.py"), wine.windows_path(site), timeout=300)
    assert "WINDOWS-OK" in smoke.stdout, smoke.stdout[-3000:] + smoke.stderr[-3000:]
    tests = wine.run(
        env,
        "-m", "pytest", "tests/native", "-q", "-p", "no:cacheprovider",
        "-o", "addopts=", "--basetemp", wine.windows_path(tmp_path / "pt"), "-rs",
        "--hypothesis-seed=0",  # reproducible: a failure here must be the Windows build's
        *(arg for test in WINDOWS_DESELECT for arg in ("--deselect", test)),
        cwd=ROOT,
    )  # fmt: skip
    tail = tests.stdout[-3000:] + tests.stderr[-3000:]
    assert tests.returncode == 0 and re.search(r"\d+ passed", tests.stdout), tail
    print(smoke.stdout, tests.stdout[-1500:])  # shown with -s or -rP
