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
    config.addinivalue_line("filterwarnings", "ignore::DeprecationWarning:blender_util")
    config.addinivalue_line("markers", "slow: renders with Cycles or EEVEE for more than a few s")
