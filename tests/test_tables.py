"""The one table formatter of the report and the sweep summary."""

import pytest

from drltg.analysis import tables


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
