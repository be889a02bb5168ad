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


def percent(share: float, *, signed: bool = False, digits: int = 0) -> str:
    """``share`` (a fraction) as a percentage with ``digits`` decimals (default a whole one):
    ``"12%"``, or ``"+12%"`` with ``signed``. A share that rounds to zero is written ``"0%"``
    (``"+0%"``, ``"+0.0%"``), never with a minus; one that is not finite is ``"-"``."""
    if not math.isfinite(share):
        return "-"
    value = round(100.0 * share, digits) + 0.0  # + 0.0: no negative zero
    text = f"{value:+.{digits}f}" if signed else f"{value:.{digits}f}"
    return text + "%"
