"""The house: layers and stages import one way, with no circle (issue 19).

Read from the sources as text (no Blender, no native module): the add-on and the ``vplace``
package by their Python imports, the core by its ``crate::`` paths.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
ADDON = ROOT / "addon"
VPLACE = ROOT / "rust" / "vplace-py" / "python" / "vplace"
CORE = ROOT / "rust" / "vplace-core" / "src"


def _modules(package: str, root: Path) -> dict[str, Path]:
    found = {}
    for path in root.rglob("*.py"):
        parts = [p for p in path.relative_to(root).with_suffix("").parts if p != "__init__"]
        found[".".join([package, *parts])] = path
    return found


MODULES = {**_modules("addon", ADDON), **_modules("vplace", VPLACE)}


def imports_of(name: str) -> set[str]:
    """The project modules ``name`` imports, type-checking imports included."""
    path = MODULES[name]
    base = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            stem = base[: len(base) - node.level + 1] if node.level else []
            module = ".".join(stem + ([node.module] if node.module else []))
            for alias in node.names:
                for candidate in (module, f"{module}.{alias.name}"):
                    if candidate in MODULES and candidate != name:
                        found.add(candidate)
        elif isinstance(node, ast.Import):
            found.update(a.name for a in node.names if a.name in MODULES and a.name != name)
    return found


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Every strongly connected group of more than one node (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    groups: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            group = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                group.append(w)
                if w == v:
                    break
            if len(group) > 1:
                groups.append(sorted(group))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return groups


def test_no_import_circle_in_the_addon_or_the_vplace_package():
    graph = {name: imports_of(name) for name in MODULES}
    assert cycles(graph) == []


def test_the_vplace_package_knows_nothing_of_blender():
    for name, path in MODULES.items():
        if not name.startswith("vplace"):
            continue
        tree = ast.parse(path.read_text())
        roots = set()
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                roots.update(a.name.split(".")[0] for a in node.names)
            elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
                roots.add(node.module.split(".")[0])
        assert not roots & {"bpy", "mathutils", "addon"}, name


def _crate_uses(path: Path) -> set[str]:
    text = re.sub(r"//[^\n]*", "", path.read_text())
    # `#[cfg(test)] mod tests` may reach anywhere: tests are not part of the house.
    text = text.split("#[cfg(test)]\nmod tests")[0]
    return set(re.findall(r"crate::(\w+)", text))


#: The add-on's stages in the order the main job meets them; a package may import its own
#: stage and earlier ones only. ``native`` (the one door to ``vplace``), ``errors``,
#: ``settings`` and ``compat`` serve every stage; the built-in scenes are builders the command
#: line and the report open.
ADDON_STAGES = (
    ("addon.native", "addon.errors", "addon.settings", "addon.compat"),
    ("addon.scene", "addon.scenes"),
    ("addon.capture",),
    ("addon.writeback",),
    ("addon.job",),
    ("addon.animation",),
    ("addon.report",),
    ("addon.ui",),
    ("addon.cli",),
)

#: The core's stages, foundations first (DESIGN: scene -> view -> VPLs -> shading -> fit ->
#: layout); ``test_util`` and the crate root see everything and are left out.
CORE_STAGES = (
    ("error", "color", "rng", "progress", "metrics", "par2d"),
    ("scene",),
    ("view",),
    ("vpl",),
    ("shade",),
    ("fit",),
    ("layout",),
)


def _rank(stages: tuple[tuple[str, ...], ...], name: str) -> int | None:
    for rank, group in enumerate(stages):
        if any(name == s or name.startswith(s + ".") for s in group):
            return rank
    return None


def test_every_addon_module_has_a_stage():
    for name in MODULES:
        if name.startswith("addon.") and not name.startswith("addon._build"):
            assert _rank(ADDON_STAGES, name) is not None, name


def test_addon_stages_import_only_their_own_and_earlier_stages():
    back_up = []
    for name in MODULES:
        here = _rank(ADDON_STAGES, name)
        if here is None:
            continue
        for dep in imports_of(name):
            there = _rank(ADDON_STAGES, dep)
            if there is not None and there > here:
                back_up.append(f"{name} -> {dep}")
    assert back_up == []


def test_one_addon_module_imports_vplace():
    importers = {
        name
        for name in MODULES
        if name.startswith("addon.") and any(d.startswith("vplace") for d in imports_of(name))
    }
    assert importers == {"addon.native"}


def _core_stage(path: Path) -> str:
    return path.relative_to(CORE).with_suffix("").parts[0]


def test_core_files_belong_to_a_stage():
    for path in CORE.rglob("*.rs"):
        stage = _core_stage(path)
        if stage not in ("lib", "test_util"):
            assert _rank(CORE_STAGES, stage) is not None, path


@pytest.mark.parametrize("path", sorted(CORE.rglob("*.rs")), ids=lambda p: str(p.relative_to(CORE)))
def test_core_stages_use_only_their_own_and_earlier_stages(path: Path):
    stage = _core_stage(path)
    here = _rank(CORE_STAGES, stage)
    if here is None:
        return
    later = sorted(u for u in _crate_uses(path) if (_rank(CORE_STAGES, u) or 0) > here)
    assert later == [], f"{stage} uses {later}"


def test_the_core_stages_have_no_cycle():
    graph: dict[str, set[str]] = {}
    for path in CORE.rglob("*.rs"):
        stage = _core_stage(path)
        if _rank(CORE_STAGES, stage) is None:
            continue
        uses = {u for u in _crate_uses(path) if u != stage and _rank(CORE_STAGES, u) is not None}
        graph.setdefault(stage, set()).update(uses)
    assert cycles(graph) == []
