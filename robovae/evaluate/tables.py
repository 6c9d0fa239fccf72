"""Plain-text tables for the command line and the reports.

:func:`format_table` lays out rows of dicts under a header line and a dashed rule, each column
as wide as its widest cell, cells left-aligned and separated by two spaces, trailing spaces
stripped.
"""

from __future__ import annotations

from collections.abc import Sequence

__all__ = ["format_table"]


def format_table(rows: list[dict], columns: Sequence[str]) -> str:
    """Plain-text table of ``rows`` (``str()`` of ``row.get(column, "")``) under a header line of
    the ``columns`` and a dashed rule; widths fit the content."""
    cells = [[str(r.get(c, "")) for c in columns] for r in rows]
    widths = [max([len(c)] + [len(row[i]) for row in cells]) for i, c in enumerate(columns)]
    line = lambda vals: "  ".join(v.ljust(w) for v, w in zip(vals, widths)).rstrip()  # noqa: E731
    return "\n".join([line(list(columns)), line(["-" * w for w in widths])]
                     + [line(row) for row in cells])
