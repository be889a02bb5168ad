"""Measures how the main job travels through the add-on's and the vplace package's files.

A helper module, not a test: ``python tests/flow_trace.py`` runs the main job on the Cornell box
at a tiny size under ``sys.setprofile`` and prints the files it stays in, the number of stays (a
maximal run of consecutive calls in one file) and of returns (entering a file already left
before). ``tests/addon/test_flow.py`` holds the returns to a bound.

Calls are counted down to :data:`DEPTH` levels below the job (the job, its stages and the
helpers they call directly; a stage's own internals are its business), leaving out
comprehensions, generator expressions and lambdas (``<listcomp>``...), which are not calls a
reader follows. ``--depth N`` counts deeper (0: every level).
"""

from __future__ import annotations

import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from types import FrameType
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
#: How many levels below the traced function are counted (0: all).
DEPTH = 2
OWN = (ROOT / "addon", ROOT / "rust" / "vplace-py" / "python" / "vplace")
#: The add-on's foundations serve every stage (``tests/test_house.py``), as bpy and numpy do: a
#: call into them (an operator run through ``errors.run_operator``, the output folder checked)
#: neither starts nor ends a stay.
FOUNDATIONS = frozenset(
    ROOT / "addon" / f"{name}.py" for name in ("errors", "settings", "compat", "native")
)


@dataclass
class Flow:
    """The files, in the order of the calls, that the traced code entered."""

    stays: list[str] = field(default_factory=list)

    @property
    def returns(self) -> int:
        """Entries into a file that had already been left before."""
        seen: set[str] = set()
        count = 0
        for name in self.stays:
            count += name in seen
            seen.add(name)
        return count

    @property
    def files(self) -> int:
        """The distinct files entered."""
        return len(set(self.stays))

    def text(self) -> str:
        """The stays in order, then the totals."""
        lines = [f"  {i:3d} {name}" for i, name in enumerate(self.stays, 1)]
        lines.append(f"stays {len(self.stays)}, returns {self.returns}, files {self.files}")
        return "\n".join(lines)


def _own_file(filename: str) -> str | None:
    path = Path(filename)
    if path in FOUNDATIONS:
        return None
    for root in OWN:
        if path.is_relative_to(root):
            return str(path.relative_to(ROOT))
    return None


def _depth(frame: FrameType | None) -> int:
    depth = 0
    while frame is not None:
        depth += 1
        frame = frame.f_back
    return depth


def trace(fn: Any, *args: Any, depth: int = DEPTH, **kwargs: Any) -> tuple[Any, Flow]:
    """Runs ``fn(*args, **kwargs)`` and records the stays in the project's own files, counting
    calls down to ``depth`` levels below ``fn`` (0: all): a call from code outside them (bpy,
    numpy, the native module) does not end a stay."""
    flow = Flow()
    own: dict[str, str] = {}
    top = _depth(sys._getframe()) + 1  # fn's own frame

    def profile(frame: FrameType, event: str, _arg: Any) -> None:
        if event != "call" or frame.f_code.co_name.startswith("<"):
            return
        if depth and _depth(frame) - top > depth:
            return
        filename = frame.f_code.co_filename
        name = own.get(filename)
        if name is None:
            name = own[filename] = _own_file(filename) or ""
        if name and (not flow.stays or flow.stays[-1] != name):
            flow.stays.append(name)

    sys.setprofile(profile)
    try:
        result = fn(*args, **kwargs)
    finally:
        sys.setprofile(None)
    return result, flow


def main_job_flow(out_dir: Path, depth: int = DEPTH) -> Flow:
    """The flow of the main job on the Cornell box: 32 px, 4 spp, 16 VPLs, a 4 spp truth, no
    EEVEE (the file is opened first, outside the trace)."""
    import bpy

    from addon import job
    from addon.scenes.registry import builtin_scene

    bpy.ops.wm.open_mainfile(filepath=str(builtin_scene("cornell")))
    settings = job.Job(n_vpls=16, size=32, samples=4, cache_dir=out_dir / "cache")
    _, flow = trace(
        job.run_main_job,
        bpy.context.scene,
        out_dir,
        depth=depth,
        job=settings,
        eevee=False,
        truth_samples=4,
        log=lambda _: None,
    )
    return flow


if __name__ == "__main__":
    sys.path.insert(0, str(ROOT))
    levels = int(sys.argv[sys.argv.index("--depth") + 1]) if "--depth" in sys.argv else DEPTH
    with tempfile.TemporaryDirectory() as tmp:
        print(main_job_flow(Path(tmp), levels).text())
