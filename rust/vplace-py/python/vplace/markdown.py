"""Markdown for the reports: the one table writer.

The full report (the add-on's ``report`` package) writes its tables with :func:`table` too, so
every Markdown table of vplace is written here.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence


def table(header: Sequence[str], rows: Iterable[Sequence[object]]) -> list[str]:
    """The lines of a Markdown table: the header, the rule, one line per row (cells already
    formatted; any object is written with ``str``)."""
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return lines
