"""Tables of transfer metrics as aligned text, Markdown or CSV.

The one formatter of ``drltg report`` (its table and ``transfer_metrics.csv``), ``drltg sweep`` (``summary.{csv,md}``,
``runs.csv``): each builds rows of cells and picks a style; a cell holding an estimate is written
``value [low, high]`` by :func:`estimate`.
"""
from __future__ import annotations

import csv
import io
from typing import Callable, Sequence

STYLES = ("text", "markdown", "csv")
Format = str | Callable[[float], str]


def number(x: float) -> str:
    """Four significant digits; a whole number from 1000 up (a frame count) in full, and any other from 1000
    to 10^6 rounded to a whole one, both with thousands separators (-2342.3 as -2,342 beside -2,453: one
    format in a table)."""
    x = float(x)
    if x.is_integer() and abs(x) >= 1000:
        return f"{int(x):,}"
    if 1000 <= abs(x) < 1e6:
        return f"{round(x):,}"
    return f"{x:.4g}"


def formatted(x: float, fmt: Format = number) -> str:
    """``x`` through a format spec (``".3g"``) or a function (:func:`number`)."""
    return fmt(x) if callable(fmt) else format(x, fmt)


def interval(ci: Sequence | None, fmt: Format = number) -> str:
    """``[low, high]``; empty where there is no interval (absent, or both ends equal)."""
    if not ci or ci[0] is None or ci[1] is None or ci[0] == ci[1]:
        return ""
    return f"[{formatted(ci[0], fmt)}, {formatted(ci[1], fmt)}]"


def estimate(value: float | None, ci: Sequence | None = None, fmt: Format = number, missing: str = "n/a") -> str:
    """``value [low, high]`` (``missing`` for no value; the interval only where there is one)."""
    if value is None:
        return missing
    text, bounds = formatted(value, fmt), interval(ci, fmt)
    return f"{text} {bounds}" if bounds else text


def render(rows: Sequence[Sequence], style: str = "text", align: str = "") -> str:
    """``rows[0]`` is the header; every style ends with a newline.

    ``text``: each column padded to its widest cell (``align`` gives ``l`` or ``r`` per column, left by
    default), two spaces apart, a rule under the header; ``markdown``: a GitHub table; ``csv``: comma-separated
    with quoting where a cell needs it, ``None`` as an empty cell."""
    if style == "csv":
        buf = io.StringIO()
        writer = csv.writer(buf, lineterminator="\n")
        writer.writerows(["" if v is None else v for v in row] for row in rows)
        return buf.getvalue()
    cells = [["" if v is None else str(v) for v in row] for row in rows]
    if style == "markdown":
        lines = ["| " + " | ".join(row) + " |" for row in cells]
        lines.insert(1, "|" + "---|" * len(cells[0]))
        return "\n".join(lines) + "\n"
    if style != "text":
        raise ValueError(f"unknown table style '{style}'; choose one of {', '.join(STYLES)}.")
    widths = [max(len(row[i]) for row in cells) for i in range(len(cells[0]))]

    def line(row):
        return "  ".join(c.rjust(w) if align[i:i + 1] == "r" else c.ljust(w)
                         for i, (c, w) in enumerate(zip(row, widths))).rstrip()

    lines = [line(row) for row in cells]
    lines.insert(1, "-" * len(lines[0]))
    return "\n".join(lines) + "\n"
