"""Shared test set-up: the repository root on sys.path (for the ``addon`` package) and markers."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
for path in (ROOT, Path(__file__).resolve().parent):
    if str(path) not in sys.path:
        sys.path.insert(0, str(path))


def pytest_configure(config: pytest.Config) -> None:
    # Filters, each with its reason (every other warning still shows):
    # - blender_util reads every RNA property of the file for the "file unchanged" checks,
    #   deprecated ones included, to tell that vplace changed none of them.
    config.addinivalue_line("filterwarnings", "ignore::DeprecationWarning:blender_util")
    # - matplotlib 3.9.4 (pinned in tests/requirements.txt) calls pyparsing's camelCase names,
    #   which pyparsing 3.3 deprecates: matplotlib's code, not ours.
    #   (pyparsing.util warns about the parseAll argument matplotlib passes.)
    for module in ("matplotlib._fontconfig_pattern", "matplotlib._mathtext", "pyparsing.util"):
        config.addinivalue_line("filterwarnings", f"ignore::DeprecationWarning:{module}")
    config.addinivalue_line("markers", "slow: renders with Cycles or EEVEE for more than a few s")
