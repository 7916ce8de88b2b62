"""The one table formatter of the report, the sweep summary and results/summarize.py."""
import contextlib
import io
import json
import runpy
import sys
from pathlib import Path

import pytest

from drltg.analysis import tables

RESULTS = Path(__file__).resolve().parents[1] / "results"


def test_text_markdown_and_csv():
    rows = [("metric", "value", "note"), ("jumpstart", "1.5", ""), ("n", "12", "a, b")]
    assert tables.render(rows, "text", align="lr") == (
        "metric     value  note\n"
        "----------------------\n"
        "jumpstart    1.5\n"
        "n             12  a, b\n")
    assert tables.render(rows, "markdown") == (
        "| metric | value | note |\n|---|---|---|\n| jumpstart | 1.5 |  |\n| n | 12 | a, b |\n")
    assert tables.render([("a", "b"), (None, 1.5), ("x,y", 'say "hi"')], "csv") == (
        'a,b\n,1.5\n"x,y","say ""hi"""\n')
    with pytest.raises(ValueError, match="unknown table style 'html'"):
        tables.render(rows, "html")


def test_numbers_and_estimates():
    assert tables.number(1322500) == "1,322,500"  # frames in full
    assert tables.number(0.123456) == "0.1235"
    assert tables.number(1.983e8 + 0.5) == "1.983e+08"
    assert tables.estimate(0.5, [0.25, 0.75], ".2f") == "0.50 [0.25, 0.75]"
    assert tables.estimate(0.5, [0.5, 0.5], ".2f") == "0.50"  # a zero-width interval is no interval
    assert tables.estimate(None, [0.1, 0.2]) == "n/a"
    assert tables.estimate(16000, fmt=lambda x: f"{x / 1000:.3g}k", missing="not reached") == "16k"
    assert tables.interval(None) == tables.interval([None, None]) == ""


def test_summarize_prints_the_committed_reports():
    root = RESULTS / "sweep-fourrooms-graded"
    argv, sys.argv = sys.argv, ["summarize.py", str(root)]
    try:
        with contextlib.redirect_stdout(io.StringIO()) as out:
            runpy.run_path(str(RESULTS / "summarize.py"), run_name="__main__")
    finally:
        sys.argv = argv
    lines = out.getvalue().splitlines()
    reports = sorted(root.glob("*/*/*/report/transfer_metrics.json"))
    assert len(lines) == 2 + len(reports) and lines[1] == "|---" * 9 + "|"  # with the Holm p column
    near = next(line for line in lines if line.startswith("| fourrooms-near | model-reuse |"))
    m = json.loads((root / "fourrooms-near/sac/model-reuse/report/transfer_metrics.json").read_text())["metrics"]
    lo, hi = m["mean_return_gain_ci"]
    assert f"| {m['mean_return_gain']:+.2f} [{lo:+.2f}, {hi:+.2f}] |" in near
