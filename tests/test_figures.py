"""Figures for papers: ``--figure`` presets, ``--figure-size``, ``-style``, ``-dpi`` and ``-format``, checked by
opening the files the commands write."""
import re
from pathlib import Path

import numpy as np
import pytest

from drltg.analysis.figure_style import FigureStyle
from drltg.cli import main
from drltg.errors import UsageError


def share(img, rgb: tuple[int, int, int]) -> float:
    """The share of an image's pixels of colour ``rgb``."""
    return float((np.asarray(img.convert("RGB")) == rgb).all(axis=-1).mean())


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Three paired seeds a side: the baseline learns slowly, the transfer runs quickly."""
    root = tmp_path_factory.mktemp("figures")
    frames = np.arange(0, 2001, 250)
    for side, rate in (("baseline", 2000.0), ("transfer", 700.0)):
        for seed in range(3):
            run = root / side / f"seed-{seed}"
            run.mkdir(parents=True)
            returns = 1 - np.exp(-frames / rate) + 0.02 * seed
            rows = "".join(f"{f},{r:.4f},0.0,4,{min(1.0, r):.4f}\n" for f, r in zip(frames, returns))
            (run / "eval.csv").write_text("frames,return_mean,return_std,episodes,success_rate\n" + rows)
            (run / "config.yaml").write_text(f"task: fourrooms/near\nseed: {seed}\n")
    return root


def report(runs: Path, out: Path, *options: str) -> int:
    return main(["report", "--baseline", str(runs / "baseline"), "--transfer", str(runs / "transfer"),
                 "--threshold", "0.5", "--out", str(out), *options])


def test_one_column_writes_a_pdf_one_column_wide(runs, tmp_path, capsys, page_size):
    import matplotlib.image as mpimg

    assert report(runs, tmp_path / "o", "--figure", "one-column") == 0
    assert "transfer_plot.{png,pdf}" in capsys.readouterr().out
    assert sorted(p.name for p in (tmp_path / "o").iterdir()) == [
        "transfer_metrics.csv", "transfer_metrics.json", "transfer_plot.pdf", "transfer_plot.png"]
    width, height = page_size(tmp_path / "o" / "transfer_plot.pdf")
    assert width == pytest.approx(3.3 * 72)  # 237.6 pt: the page is the figure, not cropped to its content
    assert 2.5 * 72 < height < 5 * 72
    png = mpimg.imread(tmp_path / "o" / "transfer_plot.png")
    assert png.shape[1] == 990 and abs(png.shape[0] - height / 72 * 300) < 1  # the same page at 300 dpi
    text = (tmp_path / "o" / "transfer_plot.pdf").read_bytes()
    assert b"/FontFile2" in text and b"/Type3" not in text  # fonts embedded as TrueType, as publishers ask


def test_size_dpi_style_and_format_each_have_their_option(runs, tmp_path):
    from PIL import Image

    assert report(runs, tmp_path / "o", "--figure-size", "4,3", "--figure-dpi", "200", "--figure-format", "png",
                  "--figure-style", "ggplot") == 0
    assert sorted(p.name for p in (tmp_path / "o").iterdir() if p.name.startswith("transfer_plot")) == [
        "transfer_plot.png"]
    with Image.open(tmp_path / "o" / "transfer_plot.png") as img:
        assert img.size == (800, 600)
        assert [round(d) for d in img.info["dpi"]] == [200, 200]
        assert share(img, (0xE5, 0xE5, 0xE5)) > 0.1  # ggplot's grey axes background (none in the default)


def test_a_preset_s_values_give_way_to_the_options_beside_it(runs, tmp_path):
    assert report(runs, tmp_path / "o", "--figure", "one-column", "--figure-size", "5,4", "--figure-format",
                  "svg") == 0
    svg = (tmp_path / "o" / "transfer_plot.svg").read_text()
    assert re.search(r'<svg[^>]* width="360pt" height="288pt"', svg)  # 5 x 4 in
    assert not (tmp_path / "o" / "transfer_plot.pdf").exists()


def test_the_default_figure_is_unchanged(runs, tmp_path):
    import matplotlib.image as mpimg

    assert report(runs, tmp_path / "o") == 0
    assert {p.name for p in (tmp_path / "o").iterdir()} >= {"transfer_plot.png", "transfer_plot.svg"}
    assert not (tmp_path / "o" / "transfer_plot.pdf").exists()
    height, width = mpimg.imread(tmp_path / "o" / "transfer_plot.png").shape[:2]
    assert width > 1300  # 10 in at 130 dpi and the box beside, cropped to what is drawn


@pytest.mark.parametrize("options, message", [
    (["--figure", "poster"], "unknown --figure 'poster'; choose one of default, one-column, two-column."),
    (["--figure-size", "wide"], "--figure-size 'wide' is not WIDTH or WIDTH,HEIGHT in inches (e.g. 3.3 or 3.3,2.5)."),
    (["--figure-size", "0.3"], "--figure-size: a figure's width must lie between 1 and 40 inches, got 0.3."),
    (["--figure-size", "3,400"], "--figure-size: a figure's height must lie between 1 and 40 inches, got 400.0."),
    (["--figure-dpi", "0"], "--figure-dpi must be a whole number from 20 to 1200, got 0."),
    (["--figure-dpi", "high"], "--figure-dpi 'high' is not a whole number of pixels per inch (e.g. 300)."),
    (["--figure-format", "jpg"], "unknown --figure-format 'jpg'; choose one of png, pdf, svg."),
    (["--figure-style", "missing.mplstyle"], "--figure-style 'missing.mplstyle' is no file."),
])
def test_bad_figure_options_are_one_sentence_and_write_nothing(runs, tmp_path, capsys, options, message):
    assert report(runs, tmp_path / "o", *options) == 2
    assert capsys.readouterr().err == f"drltg report: error: {message}\n"
    assert not (tmp_path / "o").exists()


def test_an_unknown_style_names_the_styles_there_are(runs, tmp_path, capsys):
    assert report(runs, tmp_path / "o", "--figure-style", "pastel-dreams") == 2
    err = capsys.readouterr().err
    assert err.startswith("drltg report: error: unknown --figure-style 'pastel-dreams'; choose a matplotlib style (")
    assert "ggplot" in err and err.endswith("or a .mplstyle file.\n")


def test_a_style_file_is_read_as_settings(runs, tmp_path):
    from PIL import Image

    (tmp_path / "mine.mplstyle").write_text("axes.facecolor: 00FF00\n")
    assert report(runs, tmp_path / "o", "--figure-style", str(tmp_path / "mine.mplstyle"), "--figure-size", "4,3",
                  "--figure-format", "png", "--figure-dpi", "100") == 0
    with Image.open(tmp_path / "o" / "transfer_plot.png") as img:
        assert share(img, (0, 255, 0)) > 0.1


def test_the_style_leaves_matplotlib_s_settings_as_they_were(runs, tmp_path):
    import matplotlib

    before = dict(matplotlib.rcParams)
    assert report(runs, tmp_path / "o", "--figure", "one-column", "--figure-style", "ggplot") == 0
    assert dict(matplotlib.rcParams) == before


def test_the_python_api_takes_the_same_object(runs, tmp_path):
    from drltg.report import transfer_report

    style = FigureStyle.preset("one-column", format="svg")
    assert style.formats("svg") == ("png", "svg") and FigureStyle().formats("svg") == ("png", "svg")
    assert FigureStyle(format="png").formats("svg") == ("png",) and FigureStyle().formats() == ("png",)
    transfer_report(runs / "baseline", runs / "transfer", tmp_path / "o", figure=style, threshold=0.5)
    assert re.search(r'<svg[^>]* width="237.6pt"', (tmp_path / "o" / "transfer_plot.svg").read_text())
    with pytest.raises(UsageError, match="--figure-dpi must be a whole number"):
        FigureStyle(dpi=72.5)
