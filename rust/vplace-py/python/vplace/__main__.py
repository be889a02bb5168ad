"""``python -m vplace ...``: the headless command line of the Blender add-on.

Needs the ``bpy`` module. Finds the add-on in a development checkout (the ``addon`` package of
the current directory) or among the installed extensions, and runs its CLI with the same
arguments (``python -m vplace demo --help``).
"""

from __future__ import annotations

import importlib
import sys
from types import ModuleType


def _addon_cli() -> ModuleType:
    try:
        import bpy  # noqa: F401  (the add-on needs Blender)
    except ImportError as exc:
        raise SystemExit("python -m vplace needs the bpy module (pip install bpy==5.0.1)") from exc
    try:
        return importlib.import_module("addon.cli")
    except ImportError:
        pass
    import addon_utils

    for mod in addon_utils.modules():
        if mod.__name__.split(".")[-1] == "vplace" and mod.__name__.startswith("bl_ext."):
            return importlib.import_module(mod.__name__ + ".cli")
    raise SystemExit("the vplace add-on was not found: run from the repository or install it")


def main() -> int:
    return int(_addon_cli().main(sys.argv[1:]))


if __name__ == "__main__":
    sys.exit(main())
