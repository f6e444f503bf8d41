"""Numbers and tables as the reports print them, written once for every study."""

from __future__ import annotations

from collections.abc import Iterable, Sequence


def percent(value: float | None, spec: str = "+.2f", space: str = " ",
            missing: str = "-") -> str:
    """``value``, a fraction, as a percentage: ``100 value`` formatted by ``spec``, then
    ``space`` and "%" (``percent(0.0123)`` is "+1.23 %"); ``missing`` where it is None."""
    return missing if value is None else f"{100 * value:{spec}}{space}%"


def number(value: float | None, spec: str, suffix: str = "", missing: str = "-") -> str:
    """``value`` formatted by ``spec``, then ``suffix``; ``missing`` where it is None."""
    return missing if value is None else f"{value:{spec}}{suffix}"


def aligned(rows: Iterable[Sequence]) -> list[str]:
    """A plain-text table: every cell (``str`` of it) left-aligned in a column as wide as its
    widest cell, columns two spaces apart, trailing blanks stripped; one line per row."""
    cells = [[str(v) for v in row] for row in rows]
    widths = [max(len(row[i]) for row in cells) for i in range(len(cells[0]))] if cells else []
    return ["  ".join(v.ljust(w) for v, w in zip(row, widths)).rstrip() for row in cells]


def markdown_table(head: Sequence[str], body: Iterable[Sequence[str]] = ()) -> list[str]:
    """A Markdown table's lines: the header ``head``, its rule, then one line per row of
    ``body``."""
    return ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)] + \
        ["| " + " | ".join(cells) + " |" for cells in body]
