"""The hand-written _native.pyi matches the compiled module."""

import subprocess
import sys


def test_stubtest_passes():
    result = subprocess.run(
        [sys.executable, "-m", "mypy.stubtest", "vplace._native", "--ignore-missing-stub"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode == 0, result.stdout + result.stderr
