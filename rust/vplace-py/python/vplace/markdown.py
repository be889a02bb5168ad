"""Markdown for the reports: the one table writer, and shares written as percentages.

The full report (the add-on's ``report`` package) writes its tables with :func:`table` too, so
every Markdown table of vplace is written here.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence


def table(header: Sequence[str], rows: Iterable[Sequence[object]]) -> list[str]:
    """The lines of a Markdown table: the header, the rule, one line per row (cells already
    formatted; any object is written with ``str``)."""
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return lines


def percent(share: float, *, signed: bool = False) -> str:
    """``share`` (a fraction) as a whole percentage: ``"12%"``, or ``"+12%"`` with ``signed``.
    A share that rounds to zero is written ``"0%"`` (``"+0%"``), never ``"-0%"``; one that is
    not finite is ``"-"``."""
    if not math.isfinite(share):
        return "-"
    whole = round(100.0 * share)
    return f"{whole:+d}%" if signed else f"{whole:d}%"
