"""Figures of ``drltg report``, sweeps and the bench: both learning curves with the transfer metrics drawn on
them, the transfer-matrix heatmap, performance profiles, a pair's curves per method. Rendered off-screen (Agg)
to the bytes of each format a :class:`~drltg.analysis.figure_style.FigureStyle` asks for."""
from __future__ import annotations

import functools
import io

import numpy as np

from drltg.analysis.figure_style import DEFAULT, FigureStyle
from drltg.analysis.stats import ASSUMES

RANGE_ONLY = ASSUMES["range"]
COLORS = {"baseline": "#0072B2", "transfer": "#D55E00"}  # colour-blind safe blue / vermillion


def _figure(style: FigureStyle, own: tuple[float, float], **kwargs):
    """A figure of ``own`` size (inches) unless ``style`` sets one; laid out inside its size where it does."""
    import matplotlib.pyplot as plt

    layout = "constrained" if style.page else None
    return plt, plt.subplots(figsize=style.size(own), layout=layout, **kwargs)


def _styled(draw):
    """Draw under the figure's style (:meth:`FigureStyle.drawing`), given as the ``style`` keyword."""

    @functools.wraps(draw)
    def drawn(*args, style: FigureStyle = DEFAULT, **kwargs):
        with style.drawing():
            return draw(*args, style=style, **kwargs)

    return drawn


def _pt(base: float) -> float:
    """``base`` points at matplotlib's 10-point default, scaled to the font size in use (a style's or a preset's)."""
    import matplotlib

    return base * float(matplotlib.rcParams["font.size"]) / 10.0


def _save(plt, fig, style: FigureStyle, vector: str | None = None) -> dict[str, bytes]:
    """The figure's files as ``{format: bytes}`` (:meth:`FigureStyle.formats`), the same bytes for the same figure:
    no date, and the SVG's element ids hashed with a fixed salt (matplotlib draws a random one per figure
    otherwise). A figure of a set size keeps it (a PDF's page is that size); others are cropped to what they draw."""
    out = {}
    for fmt in style.formats(vector):
        buf = io.BytesIO()
        metadata = {"Date": None} if fmt == "svg" else {"CreationDate": None} if fmt == "pdf" else None
        fig.savefig(buf, format=fmt, dpi=style.dpi, bbox_inches=None if style.page else "tight", metadata=metadata)
        out[fmt] = buf.getvalue()
    plt.close(fig)
    return out


def files(stem: str, drawn: dict[str, bytes]) -> dict[str, bytes]:
    """A figure's files named ``stem.<format>``."""
    return {f"{stem}.{fmt}": data for fmt, data in drawn.items()}


def _frames(x: float) -> str:
    x = float(x)
    for unit, div in (("M", 1e6), ("k", 1e3)):
        if abs(x) >= div:
            return f"{x / div:.3g}{unit}"
    return f"{x:.0f}"


def _signed(x) -> str:
    return "n/a" if x is None else f"{x:+.3g}"


@_styled
def plot_transfer(result: dict, *, style: FigureStyle = DEFAULT) -> dict[str, bytes]:
    """Mean curve per side (t-interval band over seeds where there are >= 3), faint raw runs, the
    threshold line with each run's crossing and the median crossing, jumpstart and asymptotic gaps as
    annotated segments, and a box of the differences with their intervals (mean return gain first).

    A figure of a set width (``style.page``, a paper's column) keeps the verdict and its test in the title, the
    legend under the axes in short words, and leaves the box out: the printed table and the JSON hold it."""
    st, curves = result["settings"], result["curves"]
    m = _as_shown(result["metrics"], curves)
    short = style.page
    plt, (fig, ax) = _figure(style, (7.0, 6.0) if short else (10, 5.5))
    moving = {side: v for side, v in st.get("convergence", {}).items() if v != "converged"}
    _curves(ax, curves, st, short)
    _asymptote(ax, m, st, moving, short)
    _jumpstart(ax, m, curves)
    if st["threshold"] is not None:
        _threshold_marks(ax, m, st, curves, short)
    if short:
        _page_axes(fig, ax, m, st, style.height)
    else:
        _summary_box(ax, m, st, moving)
        _axes(ax, m, st)
    return _save(plt, fig, style, vector="svg")


DIFFERENCES = ("jumpstart", "asymptotic_performance", "mean_return_gain", "mean_return_gain_with_source")


def _as_shown(m: dict, curves: dict) -> dict:
    """The metrics as drawn: a difference smaller than float32 can resolve at the curves' scale is drawn as 0.

    Curves are logged in float32, so two sides that start equal can differ by ``eps * |y|`` (a jumpstart of
    5e-06 between returns near 40); the kept metrics stay exact, the plot shows ``+0``."""
    scale = max((float(np.abs(values).max()) for c in curves.values() for _, values in c["runs"] if len(values)),
                default=0.0)
    resolution = 8 * float(np.finfo(np.float32).eps) * scale
    return {k: 0.0 if k in DIFFERENCES and v is not None and abs(v) <= resolution else v for k, v in m.items()}


def _curves(ax, curves: dict, st: dict, short: bool = False) -> None:
    """Each side's raw runs (faint), its mean and, with enough seeds, the band of the mean."""
    for side in ("baseline", "transfer"):
        c, color = curves[side], COLORS[side]
        n = len(c["runs"])
        for frames, values in c["runs"]:
            keep = frames <= st["budget"]
            ax.plot(frames[keep], values[keep], color=color, lw=0.6, alpha=0.18, zorder=1)
        smooth = f", moving average of {c['smooth']} evals" if c["smooth"] > 1 else ""
        what = f"mean of {n} seeds" if n > 1 else "1 seed"
        label = (f"{st[side + '_label']} ({n} seed{'s' if n > 1 else ''})" if short
                 else f"{st[side + '_label']} ({side}; {what}{smooth})")
        ax.plot(c["grid"], c["mean"], color=color, lw=1.5 if short else 2.0, zorder=3, label=label)
        if c["band"] is not None:
            band = f"{round(100 * st['confidence'])}% t-interval of the mean"
            ax.fill_between(c["grid"], *c["band"], color=color, alpha=0.2, lw=0, zorder=2,
                            label=f"{band} over seeds" if not short else band if side == "baseline" else None)
    ax.plot([], [], color="0.4", lw=0.6, alpha=0.4, label="one seed" if short else "raw evaluations, one line per seed")


def _asymptote(ax, m: dict, st: dict, moving: dict, short: bool = False) -> None:
    """The asymptote window (shaded), both sides' mean level over it, and the gap at its end."""
    lo_w, hi_w = st["asymptote_frames"]
    ax.axvspan(lo_w, hi_w, color="0.5", alpha=0.08, lw=0, zorder=0)
    ax.plot([], [], color="0.4", lw=2.2, ls=(0, (4, 2)),
            label=f"mean over the last {100 * st['asymptote_window']:g}%" if short
            else "mean over the asymptote window")
    fb, ft = m["final_performance_baseline"], m["final_performance_transfer"]
    for side, level in (("baseline", fb), ("transfer", ft)):
        ax.hlines(level, lo_w, hi_w, colors=COLORS[side], lw=2.2, linestyles=(0, (4, 2)), zorder=4)
    what_gap = "asymptotic" if not moving else "final" if short else "final performance\n(not converged)"
    _gap(ax, hi_w, fb, ft, f"{what_gap}\n{_signed(m['asymptotic_performance'])}", side="left")


def _jumpstart(ax, m: dict, curves: dict) -> None:
    """Both sides' initial performance at the first evaluation, and the gap between them."""
    x0 = min(min(r[0][0] for r in curves[s]["runs"]) for s in curves)
    ib, it = m["initial_performance_baseline"], m["initial_performance_transfer"]
    for side, level in (("baseline", ib), ("transfer", it)):
        ax.plot([x0], [level], "o", color=COLORS[side], ms=7, mec="white", mew=1.2, zorder=6)
    _gap(ax, x0, ib, it, f"jumpstart\n{_signed(m['jumpstart'])}", side="right")


def _quantity(st: dict) -> str:
    """What the curves measure, for the box's first line: "return" unless ``--tag`` picked another column."""
    tag = st.get("tag")
    return "return" if not tag or "return" in tag or "reward" in tag else tag


def _summary_box(ax, m: dict, st: dict, moving: dict) -> None:
    """:func:`summary_lines` beside the axes."""
    ax.text(1.02, 1.0, "\n".join(summary_lines(m, st, moving)), transform=ax.transAxes, ha="left", va="top",
            fontsize=_pt(9), family="monospace", zorder=8,
            bbox=dict(boxstyle="round,pad=0.4", fc="white", ec="0.7", alpha=0.9))


VERDICT_WORDS = {"higher": "higher with transfer", "lower": "lower with transfer", "undecided": "undecided",
                 "equivalent": "equivalent"}


def summary_lines(m: dict, st: dict, moving: dict) -> list[str]:
    """The box's text: the headline's verdict and the exact test that made it first (its p, pairs and, for
    ``--seeds auto``, the look and its share of the level), the magnitude intervals that go with it, then the
    other differences with each interval under its own name (the worst case over the declared range says so)."""
    lines = _verdict_lines(m, st)
    asym = "asymptotic" if not moving else "final perf. (not converged)"
    conf = round(100 * st["confidence"])
    worst = any(m.get(f"{n}_ci_assumes") == RANGE_ONLY for n in SHOWN)
    kind = f"worst case over the declared range, {conf}%" if worst else f"{conf}% CI"
    lines += [
        "transfer - baseline" + (f" [{kind}]" if _has_intervals(m) else " (no CI: < 3 seeds a side)")
        + (", paired" if st.get("paired") else ""),
        f"mean {_quantity(st)} gain {_signed(m.get('mean_return_gain'))}" + _ci(m, "mean_return_gain"),
        f"jumpstart {_signed(m['jumpstart'])}" + _ci(m, "jumpstart"),
        f"{asym} {_signed(m['asymptotic_performance'])}" + _ci(m, "asymptotic_performance"),
        f"transfer ratio {_signed(m['transfer_ratio'])}" + _ci(m, "transfer_ratio") + " (offset-dependent)",
        f"P(T > B) {m['probability_of_improvement']:.2f}" + _ci(m, "probability_of_improvement", sign=""),
    ]
    if "mean_return_gain_with_source" in m:
        lines.append(f"total time (source frames counted): gain {_signed(m['mean_return_gain_with_source'])}"
                     + _ci(m, "mean_return_gain_with_source"))
    for side, verdict in moving.items():
        said = "not shown to have converged" if verdict.startswith("undetermined") else verdict
        lines.append(f"warning: {side} {said} at the budget")
    return lines


def _verdict_lines(m: dict, st: dict) -> list[str]:
    """The mean gain's verdict as the report's headline gives it, with its test and its magnitude intervals;
    none where the report gives no verdict (fewer than 2 seeds a side)."""
    from drltg.analysis.claims import test_words

    name = "mean_return_gain"
    if f"{name}_verdict" not in m:
        return []
    p, n = m[f"{name}_verdict_p"], m["n_seeds_transfer"]
    pairs = f"{n} pairs" if st.get("paired") else f"{n} + {m['n_seeds_baseline']} runs"
    seq = st.get("sequential")
    if seq:
        last = seq["taken"][-1]
        test = (f"exact sign-flip test, look {len(seq['taken'])} of {len(seq['looks'])}, {last['pairs']} pairs: "
                f"p = {p:.3g} vs its share {last['alpha']:.3g}")
    else:
        test = f"{test_words(n, bool(st.get('paired')), m['n_seeds_baseline'])}, {pairs}: p = {p:.3g}"
        if m[f"{name}_verdict_test"] not in ("sign-flip", "permutation"):  # TOST, or a test named otherwise
            test = f"{m[f'{name}_verdict_test']}, {pairs}: p = {p:.3g}"
    lines = [f"verdict: mean {_quantity(st)} gain {_signed(m[name])}, {VERDICT_WORDS[m[f'{name}_verdict']]}",
             f"  {test}"]
    if m.get(f"{name}_t_interval"):
        lo, hi = m[f"{name}_t_interval"]
        t = "paired t" if st.get("paired") else "Welch t"
        lines.append(f"  mean [{lo:+.3g}, {hi:+.3g}] ({t}, {round(100 * st['confidence'])}%)")
    if m.get(f"{name}_median_interval"):
        lo, hi = m[f"{name}_median_interval"]
        lines.append(f"  median {m[f'{name}_median']:+.3g} [{lo:+.3g}, {hi:+.3g}] (order statistics, "
                     f"{100 * m[f'{name}_median_interval_level']:.1f}%)")
    return lines + [""]


def _frame_axes(ax, st: dict) -> None:
    """Frames from the start (or 0) to the budget on x, what the curves measure on y, a light grid."""
    from matplotlib.ticker import FuncFormatter

    start, budget = st["start"], st["budget"]
    pad = 0.015 * (budget - min(0, start))
    ax.set_xlim(min(0, start) - pad, budget + pad)
    ax.xaxis.set_major_formatter(FuncFormatter(lambda x, _: _frames(x)))
    ax.set_xlabel("environment frames")
    ax.set_ylabel(st["tag"] or "evaluation return")
    ax.grid(alpha=0.3)


def _axes(ax, m: dict, st: dict) -> None:
    _frame_axes(ax, st)
    budget = st["budget"]
    task = f" on {st['task']}" if st["task"] else ""
    verdict = _verdict_lines(m, st)
    said = f"{verdict[0].removeprefix('verdict: ')} ({verdict[1].strip()})\n" if verdict else ""
    ax.set_title(f"Transfer{task}: {st['transfer_label']} vs {st['baseline_label']}\n{said}"
                 f"budget {_frames(budget)} frames; asymptote = mean over the last "
                 f"{100 * st['asymptote_window']:g}% of it (shaded)", fontsize=_pt(11))
    ax.legend(loc="upper left", bbox_to_anchor=(0.0, -0.1), fontsize=_pt(8.5), frameon=False)


def _page_axes(fig, ax, m: dict, st: dict, style_height: float | None) -> None:
    """The axes of a figure of a set width: the comparison and its verdict with its test as the title, wrapped
    to the width, and the legend under the axes, inside the figure."""
    import textwrap

    import matplotlib

    _frame_axes(ax, st)
    verdict = _verdict_lines(m, st)
    said = f": {verdict[0].removeprefix('verdict: ')} ({verdict[1].strip()})" if verdict else ""
    size = float(matplotlib.rcParams["font.size"])
    width = fig.get_figwidth()
    chars = max(20, int(width * 72 / (0.6 * size)))  # a serif or sans letter is about 0.5 to 0.6 em wide
    title = textwrap.fill(f"{st['transfer_label']} vs {st['baseline_label']}{said}", chars)
    ax.set_title(title, fontsize=size)
    _page_legend(fig, ax, style_height, 1 if width < 5 else 2, title.count("\n") + 1)


def _page_legend(fig, ax, height: float | None, ncols: int, title_lines: int) -> None:
    """The legend of a figure of a set width under its axes, inside the figure; where no height is set, the
    figure as tall as its axes (0.6 of the width, 2.6 in at most), title, ticks and legend need. Under a set
    height the legend's type shrinks (to 5 pt at the least) until it takes at most a third of it."""
    import matplotlib

    handles, labels = ax.get_legend_handles_labels()
    size = float(matplotlib.rcParams["font.size"])
    legend = float(matplotlib.font_manager.FontProperties(size=matplotlib.rcParams["legend.fontsize"]).get_size())
    lines = -(-len(labels) // ncols)
    if height is not None:
        legend = max(5.0, min(legend, height / 3 * 72 / (1.45 * lines)))
    fig.legend(handles, labels, loc="outside lower center", ncols=ncols, frameon=False, handlelength=2.2,
               columnspacing=1.0, fontsize=legend)
    if height is None:
        text = 1.3 * size * (title_lines + 3) + 1.45 * legend * lines  # points
        fig.set_figheight(min(0.6 * fig.get_figwidth(), 2.6) + text / 72)


def _ci(m: dict, name: str, sign: str = "+") -> str:
    ci = m.get(f"{name}_ci")
    if ci:
        return f" [{ci[0]:{sign}.3g}, {ci[1]:{sign}.3g}]"
    return " [no CI]" if _has_intervals(m) else ""


SHOWN = ("mean_return_gain", "jumpstart", "asymptotic_performance", "transfer_ratio", "probability_of_improvement")


def _has_intervals(m: dict) -> bool:
    """Whether the report gave the comparisons the plot shows intervals (so that a missing one is said)."""
    return any(f"{name}_ci" in m for name in SHOWN)


def _threshold_marks(ax, m: dict, st: dict, curves: dict, short: bool = False) -> None:
    """The threshold line; on each run, a small marker where that run crosses (by the report's rule,
    so the run is at or above the threshold there); the median over seeds as a vertical line."""
    thr = st["threshold"]
    basis = st["threshold_basis"]
    if short and any(t is not None for side in ("baseline", "transfer") for t in curves[side]["times"]):
        ax.plot([], [], "v", ms=4.5, color="0.6", mec="black", mew=0.6, ls="none", label="a run's crossing")
    of_best = "" if basis == "absolute" else f" ({basis.split(' x ')[0]} x best baseline mean)"
    ax.axhline(thr, color="0.15", lw=1.1, ls="--", zorder=2, label=f"threshold {thr:.4g}{of_best}")
    rule = ("first crossing" if st.get("crossing") == "first" else
            f"stays above for {st['sustain']} evals" if st.get("sustain") else "stays above from here")
    for side in ("baseline", "transfer"):
        c, color = curves[side], COLORS[side]
        xs, ys = [], []
        for (frames, values), t in zip(c["runs"], c["times"]):
            if t is not None:
                xs.append(t)
                ys.append(float(np.interp(t, frames, values)))
        ms = 4.5 if short else 7
        if xs:
            ax.plot(xs, ys, "v", ms=ms, color=color, mec="black", mew=0.6, zorder=7,
                    label=None if short else f"{side}: where each run crosses ({rule})")
        t = m[f"time_to_threshold_{side}"]
        n, reached = len(c["times"]), len(xs)
        if t is not None:
            ax.axvline(t, color=color, lw=1.2, ls=":", zorder=2,
                       label=f"{st[side + '_label']}: median crossing {_frames(t)} ({reached} of {n})" if short else
                       f"{side}: upper median crossing, {_frames(t)} frames ({reached} of {n} runs cross)")
        else:
            ax.plot([], [], ls="none", color=color,  # a statement, drawn nowhere: no marker beside it
                    label=f"{st[side + '_label']}: no majority crosses ({reached} of {n})" if short else
                    f"{side}: no majority of runs crosses within the budget ({reached} of {n} do)")


def _legend_columns(fig) -> int:
    """Columns of a page figure's legend of short labels (method names): one per 1.6 in of width."""
    return max(1, int(fig.get_figwidth() / 1.6))


def _gap(ax, x, y_from, y_to, text, side):
    """A vertical arrow from ``y_from`` (baseline) to ``y_to`` (transfer) at ``x`` with a label."""
    ax.annotate("", xy=(x, y_to), xytext=(x, y_from), zorder=6,
                arrowprops=dict(arrowstyle="<|-|>", color="black", lw=1.4, shrinkA=0, shrinkB=0))
    dx = 8 if side == "right" else -8
    ax.annotate(text, xy=(x, (y_from + y_to) / 2), xytext=(dx, 0), textcoords="offset points",
                ha="left" if side == "right" else "right", va="center", fontsize=_pt(9), zorder=8,
                bbox=dict(boxstyle="round,pad=0.25", fc="white", ec="0.6", alpha=0.9))


@_styled
def plot_matrix(
    table: np.ndarray,
    sources,
    targets,
    metric: str,
    *,
    text: np.ndarray | None = None,
    axis_labels: tuple[str, str] = ("source task", "target task"),
    title: str | None = None,
    vector: str | None = "svg",
    style: FigureStyle = DEFAULT,
) -> dict[str, bytes]:
    """Heatmap of ``metric`` over source (rows) x target (columns); empty cells are grey. ``text``
    replaces each cell's printed value (e.g. with its confidence interval)."""
    from matplotlib.colors import TwoSlopeNorm

    plt, (fig, ax) = _figure(style, (1.6 * len(targets) + 3, 1.1 * len(sources) + 2))
    data = np.ma.masked_invalid(table)
    finite = table[np.isfinite(table)]
    span = float(np.abs(finite).max()) if finite.size else 1.0
    diverging = not metric.startswith(("total_reward", "time_to", "probability"))
    center = 0.5 if metric.startswith("probability") else 0.0
    if diverging or metric.startswith("probability"):
        half = max(span - center, center - float(finite.min()) if finite.size else 0, 1e-12)
        norm = TwoSlopeNorm(vcenter=center, vmin=center - half, vmax=center + half)
        cmap = plt.get_cmap("RdBu")
    else:
        norm, cmap = None, plt.get_cmap("viridis")
    cmap = cmap.with_extremes(bad="0.85")
    im = ax.imshow(data, cmap=cmap, norm=norm, aspect="auto")
    for i in range(len(sources)):
        for j in range(len(targets)):
            v = table[i, j]
            label = text[i, j] if text is not None else "n/a" if not np.isfinite(v) else f"{v:.3g}"
            ax.text(j, i, label, ha="center", va="center",
                    fontsize=_pt(10), color="black",
                    bbox=dict(boxstyle="round,pad=0.2", fc="white", ec="none", alpha=0.85))
    ax.set_xticks(range(len(targets)), targets, rotation=30, ha="right")
    ax.set_yticks(range(len(sources)), sources)
    ax.set_ylabel(axis_labels[0])
    ax.set_xlabel(axis_labels[1])
    ax.set_title(title or f"Transfer matrix: {metric}", wrap=style.page)
    fig.colorbar(im, ax=ax, label=metric)
    return _save(plt, fig, style, vector)


@_styled
def plot_profiles(entries: list[dict], over: str = "the sweep's pairs", *,
                  style: FigureStyle = DEFAULT) -> dict[str, bytes]:
    """Performance profiles of a sweep (:func:`drltg.analysis.aggregate.sweep_aggregates`) or a leaderboard: per
    algo and method, the share of runs whose normalised score exceeds tau, with its stratified-bootstrap band;
    the baseline of each algo drawn once, dashed."""
    plt, (fig, ax) = _figure(style, (7, 4.5))
    drawn = set()
    for e in entries:
        p, tau = e["profile"], e["profile"]["tau"]
        if e["algo"] not in drawn:
            drawn.add(e["algo"])
            ax.plot(tau, p["baseline"]["share"], "--", color="0.3", label=f"no transfer ({e['algo']})")
        label = " ".join(x for x in (e["method"], e["variant"], f"({e['algo']})") if x)
        line, = ax.plot(tau, p["transfer"]["share"], label=label)
        ax.fill_between(tau, p["transfer"]["low"], p["transfer"]["high"], color=line.get_color(), alpha=0.15)
    ax.set_xlabel("normalised score tau" if all(e["normalised"] for e in entries) else "score tau")
    ax.set_ylabel("share of runs with score > tau")
    ax.set_ylim(-0.02, 1.02)
    ax.set_title(f"Performance profiles over {over} (95% stratified-bootstrap bands)", wrap=style.page)
    return _grid_and_legend(plt, fig, ax, style, title_lines=2, size=8, loc="lower left")


def _grid_and_legend(plt, fig, ax, style: FigureStyle, *, title_lines: int, size: float, loc: str) -> dict[str, bytes]:
    """A figure's grid and its legend (under the axes on a page, inside them at ``loc`` otherwise), saved."""
    ax.grid(alpha=0.3)
    if style.page:
        _page_legend(fig, ax, style.height, _legend_columns(fig), title_lines)
    else:
        ax.legend(fontsize=_pt(size), loc=loc)
    return _save(plt, fig, style)


@_styled
def plot_method_curves(title: str, curves: dict[str, tuple], baseline: tuple | None, *,
                       style: FigureStyle = DEFAULT) -> dict[str, bytes]:
    """One pair's learning curves, a line per method: ``label -> (frames, runs x evaluations)`` of normalised
    returns, the mean over runs with the band between the 25th and 75th percentile; no transfer dashed."""
    plt, (fig, ax) = _figure(style, (7, 4.2))
    for label, (frames, values) in ([("no transfer", baseline)] if baseline else []) + list(curves.items()):
        look = dict(color="0.3", linestyle="--") if label == "no transfer" else {}
        line, = ax.plot(frames, values.mean(axis=0), label=label, **look)
        lo, hi = np.percentile(values, [25, 75], axis=0)
        ax.fill_between(frames, lo, hi, color=line.get_color(), alpha=0.12)
    ax.set_xlabel("frames")
    ax.xaxis.set_major_formatter(lambda x, _: _frames(x))
    ax.set_ylabel("normalised return" if style.page else "normalised return (mean; band: 25th-75th percentile of runs)")
    ax.set_title(title, wrap=style.page)
    return _grid_and_legend(plt, fig, ax, style, title_lines=1, size=7, loc="lower right")
