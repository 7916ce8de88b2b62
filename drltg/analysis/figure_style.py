"""How a command's figures are drawn for the page they go on: size, matplotlib style, font size, DPI, format.

One :class:`FigureStyle` travels from the command line (``--figure one-column``, ``--figure-size``,
``--figure-style``, ``--figure-dpi``, ``--figure-format``) to every plot a command draws, checked once. The
default draws each figure as it always was; a set width makes the figure exactly that wide on the page (a
PDF's MediaBox is ``width x 72`` points), laid out to fit inside it."""
from __future__ import annotations

import argparse
import contextlib
import math
import re
from dataclasses import dataclass, replace
from pathlib import Path

from drltg.errors import UsageError

FORMATS = ("png", "pdf", "svg")
LARGEST_INCHES = 40.0
DPI_RANGE = (20, 1200)
PAGE_FONT = (8.0, 9.0, 5.0)
"""The type of a figure of a set width where no preset or style sets it: 8 pt below 5 in wide, 9 pt above."""

PRESETS: dict[str, dict] = {
    "default": {},
    # a column of a two-column paper (IEEE, ACM, ICML: 3.25 to 3.5 in), 8 pt type as in a caption
    "one-column": {"width": 3.3, "font_size": 8.0, "serif": True, "format": "pdf", "dpi": 300},
    # both columns of a two-column paper (a figure* in LaTeX)
    "two-column": {"width": 7.0, "font_size": 9.0, "serif": True, "format": "pdf", "dpi": 300},
}


@dataclass(frozen=True)
class FigureStyle:
    """Every choice of how figures are drawn; checked at construction (one sentence naming the option).

    ``width``/``height`` are inches (``height`` ``None``: what the figure needs, its axes at its own aspect
    ratio or, with a legend under them, at 0.6 of the width and 2.6 in at most; ``width``
    ``None``: each figure's own size, cropped to what it draws); ``style`` a matplotlib style name or a
    ``.mplstyle`` file; ``font_size`` the base size in points (``None``: the style's, else matplotlib's 10 pt, or
    :data:`PAGE_FONT` for a figure of a set width); ``serif`` draws text in a
    serif face, as a paper's body; ``dpi`` the PNG's pixels per inch; ``format`` the file written beside the
    PNG (``None``: each figure's own, SVG for a report's; ``"png"``: the PNG alone)."""

    width: float | None = None
    height: float | None = None
    style: str | None = None
    font_size: float | None = None
    serif: bool = False
    dpi: int = 130
    format: str | None = None

    def __post_init__(self):
        for name in ("width", "height"):
            value = getattr(self, name)
            if value is not None and not (isinstance(value, (int, float)) and 1.0 <= value <= LARGEST_INCHES):
                raise UsageError(f"--figure-size: a figure's {name} must lie between 1 and {LARGEST_INCHES:g} "
                                 f"inches, got {value!r}.")
        if self.height is not None and self.width is None:
            raise UsageError("--figure-size: a height needs a width (WIDTH,HEIGHT in inches).")
        if self.font_size is not None and not (isinstance(self.font_size, (int, float)) and 4 <= self.font_size <= 40):
            raise UsageError(f"a figure's font size must lie between 4 and 40 points, got {self.font_size!r}.")
        lo, hi = DPI_RANGE
        if isinstance(self.dpi, bool) or not isinstance(self.dpi, int) or not lo <= self.dpi <= hi:
            raise UsageError(f"--figure-dpi must be a whole number from {lo} to {hi}, got {self.dpi!r}.")
        if self.format is not None and self.format not in FORMATS:
            raise UsageError(f"unknown --figure-format '{self.format}'; choose one of {', '.join(FORMATS)}.")
        if self.style is not None:
            check_style(self.style)

    @classmethod
    def preset(cls, name: str = "default", **changes) -> "FigureStyle":
        """The preset ``name`` (:data:`PRESETS`) with ``changes`` (the options given besides it) on top."""
        if name not in PRESETS:
            raise UsageError(f"unknown --figure '{name}'; choose one of {', '.join(PRESETS)}.")
        return cls(**{**PRESETS[name], **{k: v for k, v in changes.items() if v is not None}})

    def formats(self, vector: str | None = None) -> tuple[str, ...]:
        """The files each figure is written as: the PNG always (what summaries embed and a quick look opens),
        and beside it the asked format, else the figure's own ``vector`` one."""
        second = self.format if self.format is not None else vector
        return ("png",) if second in (None, "png") else ("png", second)

    def size(self, own: tuple[float, float]) -> tuple[float, float]:
        """The figure's size in inches: its ``own`` unless a width is set, then that width and the height given
        or ``own``'s aspect ratio."""
        if self.width is None:
            return own
        return self.width, self.height if self.height is not None else self.width * own[1] / own[0]

    @property
    def page(self) -> bool:
        """Whether the figure is laid out for a set page width (inside its size) rather than cropped to its
        content."""
        return self.width is not None

    @contextlib.contextmanager
    def drawing(self):
        """matplotlib's settings while a figure is drawn and saved: the style, then the font, and every label
        as plain text (run names and labels are the user's, and matplotlib would read a pair of ``$`` in them as
        mathematics); the user's own settings are back afterwards."""
        import matplotlib

        matplotlib.use("Agg", force=True)
        import matplotlib.pyplot as plt

        rc = {"text.parse_math": False, "svg.hashsalt": "drltg", "pdf.fonttype": 42, "ps.fonttype": 42}
        size = self.font_size
        if size is None and self.page and "font.size" not in style_settings(self.style):  # type as a paper's
            size = PAGE_FONT[0] if self.width < PAGE_FONT[2] else PAGE_FONT[1]
        if size is not None:
            rc.update({"font.size": size, "axes.titlesize": size, "axes.labelsize": size,
                       "legend.fontsize": 0.85 * size, "xtick.labelsize": 0.9 * size, "ytick.labelsize": 0.9 * size})
        if self.serif:
            rc["font.family"] = "serif"
        with plt.style.context(self.style or []), matplotlib.rc_context(rc):
            yield


DEFAULT = FigureStyle()


def style_settings(style: str | None) -> dict:
    """What a style sets (a name matplotlib ships, or a ``.mplstyle`` file); nothing for ``None``."""
    import matplotlib
    import matplotlib.pyplot as plt

    if style is None:
        return {}
    if style in plt.style.library:
        return dict(plt.style.library[style])
    return dict(matplotlib.rc_params_from_file(style, use_default_template=False))


def check_style(style: str) -> None:
    """A style must be one matplotlib ships or a ``.mplstyle`` file (settings only: nothing in it runs)."""
    import matplotlib.pyplot as plt

    if style in plt.style.available:
        return
    path = Path(style)
    if path.suffix == ".mplstyle":
        if not path.is_file():
            raise UsageError(f"--figure-style '{style}' is no file.")
        return
    raise UsageError(f"unknown --figure-style '{style}'; choose a matplotlib style ({', '.join(plt.style.available)}) "
                     "or a .mplstyle file.")


def parse_size(text: str | None) -> tuple[float | None, float | None]:
    """``"3.3"`` -> (3.3, None); ``"3.3,2.4"`` or ``"3.3x2.4"`` -> (3.3, 2.4); inches."""
    if text is None:
        return None, None
    parts = re.split(r"[,x]", str(text).strip())
    try:
        values = [float(p) for p in parts]
    except ValueError:
        values = []
    if len(values) not in (1, 2) or not all(math.isfinite(v) for v in values):
        raise UsageError(f"--figure-size '{text}' is not WIDTH or WIDTH,HEIGHT in inches (e.g. 3.3 or 3.3,2.5).")
    return values[0], values[1] if len(values) == 2 else None


def parse_dpi(text: str | None) -> int | None:
    if text is None:
        return None
    try:
        return int(str(text).strip())
    except ValueError:
        raise UsageError(f"--figure-dpi '{text}' is not a whole number of pixels per inch (e.g. 300).") from None


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The figure options of a command that draws figures (``drltg report``, ``experiment``, ``sweep``,
    ``bench report``)."""
    g = parser.add_argument_group("figures")
    g.add_argument("--figure", metavar="PRESET", default=None,
                   help=f"a page preset: {', '.join(PRESETS)} (one-column: 3.3 in wide, 8 pt serif type, PDF "
                        "at 300 dpi; two-column: 7 in wide, 9 pt); the options below change it")
    g.add_argument("--figure-size", metavar="W[,H]", default=None,
                   help="figure size in inches (the height, left out, is what the figure needs)")
    g.add_argument("--figure-style", metavar="STYLE", default=None,
                   help="a matplotlib style (e.g. seaborn-v0_8-paper, ggplot) or a .mplstyle file")
    g.add_argument("--figure-dpi", metavar="DPI", default=None, help="PNG resolution (default 130)")
    g.add_argument("--figure-format", metavar="FORMAT", default=None,
                   help=f"written beside each PNG: {', '.join(FORMATS)} (png: the PNG alone; default: SVG "
                        "beside a report's plot, nothing beside the others)")


def from_args(args: argparse.Namespace) -> FigureStyle:
    """The :class:`FigureStyle` the command line names (its preset, then each option given)."""
    width, height = parse_size(args.figure_size)
    style = FigureStyle.preset(args.figure or "default", style=args.figure_style, dpi=parse_dpi(args.figure_dpi),
                               format=args.figure_format)
    return replace(style, width=width, height=height) if width is not None else style

