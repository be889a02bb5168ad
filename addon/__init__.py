"""vplace: Cycles-like bounce light in EEVEE with virtual point lights.

Registers the add-on's modules in order and unregisters them in reverse. No other logic.
"""

from __future__ import annotations

import importlib
from types import ModuleType

_MODULE_NAMES = ("ui.properties", "ui.operators", "ui.panels")


def _modules() -> list[ModuleType]:
    return [importlib.import_module(f"{__package__}.{name}") for name in _MODULE_NAMES]


def register() -> None:
    for module in _modules():
        module.register()


def unregister() -> None:
    for module in reversed(_modules()):
        module.unregister()
