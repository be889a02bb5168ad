"""The packaged extension: build the Linux zip, install it with Blender's extensions API in an
isolated user directory, enable it, and run its main operator on the Cornell box. (The other
platforms' zips are checked by tests/test_extension_zips.py.)"""

import os
import subprocess
import sys
import textwrap
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

INSTALL_AND_RUN = textwrap.dedent(
    """
    import sys
    from pathlib import Path
    # Hide the development copy of vplace: the extension must bring its own wheel.
    sys.path[:] = [p for p in sys.path if "vplace-py" not in p]
    import bpy, addon_utils
    zip_path, obj_path = sys.argv[1], Path(sys.argv[2])
    result = bpy.ops.extensions.package_install_files(
        filepath=zip_path, repo="user_default", enable_on_install=True)
    assert result == {"FINISHED"}, result
    import vplace
    assert "extensions" in vplace.__file__, vplace.__file__
    mod = sys.modules["bl_ext.user_default.vplace"]
    bpy.ops.wm.read_factory_settings(use_empty=True)
    addon_utils.enable("bl_ext.user_default.vplace", default_set=True)
    from bl_ext.user_default.vplace.scenes import registry as default_scene
    from bl_ext.user_default.vplace.writeback import apply
    scene = default_scene.build_cornell_box(obj_path)
    s = scene.vplace
    s.capture_size = 16
    s.samples, s.vpl_budget = 4, 8
    assert bpy.ops.vplace.apply() == {"FINISHED"}
    assert 0 < len(apply.find_collection().objects) <= 8
    print("EXTENSION-OK", vplace.__file__)
    """
)


@pytest.mark.slow
def test_extension_zip_installs_and_runs(tmp_path):
    build = subprocess.run(
        [
            sys.executable,
            str(ROOT / "addon/_build/build_extension.py"),
            "--out",
            str(tmp_path),
            "--platforms",
            "linux-x64",
        ],
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert build.returncode == 0, build.stdout + build.stderr
    zip_path = Path(build.stdout.strip().splitlines()[-1])
    assert zip_path.name.endswith("-linux_x64.zip"), zip_path
    names = zipfile.ZipFile(zip_path).namelist()
    assert "blender_manifest.toml" in names and "__init__.py" in names
    assert {"ui/operators.py", "scene/export.py", "writeback/apply.py"} <= set(names), names
    assert any(n.startswith("wheels/vplace-") and "manylinux" in n for n in names), names
    assert not any("_build" in n or "__pycache__" in n for n in names)
    script = tmp_path / "install.py"
    script.write_text(INSTALL_AND_RUN)
    env = dict(os.environ, BLENDER_USER_RESOURCES=str(tmp_path / "user"))
    obj = ROOT / "blend_scenes/cornell_box/CornellBox-Original.obj"
    run = subprocess.run(
        [sys.executable, str(script), str(zip_path), str(obj)],
        capture_output=True,
        text=True,
        timeout=600,
        env=env,
        cwd=tmp_path,
    )
    assert "EXTENSION-OK" in run.stdout, run.stdout[-3000:] + run.stderr[-3000:]
