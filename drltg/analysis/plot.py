"""Figures of ``drltg report``: both learning curves with the transfer metrics drawn on them, and the
transfer-matrix heatmap. Rendered off-screen (Agg) to PNG and SVG bytes."""
from __future__ import annotations

import functools
import io

import numpy as np

COLORS = {"baseline": "#0072B2", "transfer": "#D55E00"}  # colour-blind safe blue / vermillion


def _figure(*args, **kwargs):
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt, plt.subplots(*args, **kwargs)


def _plain_text(draw):
    """Draw with every label as plain text: run names and labels are the user's, and matplotlib would read
    a pair of ``$`` in them as mathematics (``cost$5 vs $10``), or fail on a lone one."""

    @functools.wraps(draw)
    def drawn(*args, **kwargs):
        import matplotlib

        with matplotlib.rc_context({"text.parse_math": False}):
            return draw(*args, **kwargs)

    return drawn


def _save(plt, fig) -> tuple[bytes, bytes]:
    """The figure as PNG and SVG bytes, the same bytes for the same figure: no date, and the SVG's element
    ids hashed with a fixed salt (matplotlib draws a random one per figure otherwise)."""
    import matplotlib

    out = []
    with matplotlib.rc_context({"svg.hashsalt": "drltg"}):
        for fmt in ("png", "svg"):
            buf = io.BytesIO()
            fig.savefig(buf, format=fmt, dpi=130, bbox_inches="tight",
                        metadata={"Date": None} if fmt == "svg" else None)
            out.append(buf.getvalue())
    plt.close(fig)
    return out[0], out[1]


def _frames(x: float) -> str:
    x = float(x)
    for unit, div in (("M", 1e6), ("k", 1e3)):
        if abs(x) >= div:
            return f"{x / div:.3g}{unit}"
    return f"{x:.0f}"


def _signed(x) -> str:
    return "n/a" if x is None else f"{x:+.3g}"


@_plain_text
def plot_transfer(result: dict) -> tuple[bytes, bytes]:
    """Mean curve per side (t-interval band over seeds where there are >= 3), faint raw runs, the
    threshold line with each run's crossing and the median crossing, jumpstart and asymptotic gaps as
    annotated segments, and a box of the differences with their intervals (mean return gain first)."""
    st, curves = result["settings"], result["curves"]
    m = _as_shown(result["metrics"], curves)
    plt, (fig, ax) = _figure(figsize=(10, 5.5))
    moving = {side: v for side, v in st.get("convergence", {}).items() if v != "converged"}
    _curves(ax, curves, st)
    _asymptote(ax, m, st, moving)
    _jumpstart(ax, m, curves)
    if st["threshold"] is not None:
        _threshold_marks(ax, m, st, curves)
    _summary_box(ax, m, st, moving)
    _axes(ax, st)
    return _save(plt, fig)


DIFFERENCES = ("jumpstart", "asymptotic_performance", "mean_return_gain", "mean_return_gain_with_source")


def _as_shown(m: dict, curves: dict) -> dict:
    """The metrics as drawn: a difference smaller than float32 can resolve at the curves' scale is drawn as 0.

    Curves are logged in float32, so two sides that start equal can differ by ``eps * |y|`` (a jumpstart of
    5e-06 between returns near 40); the kept metrics stay exact, the plot shows ``+0``."""
    scale = max((float(np.abs(values).max()) for c in curves.values() for _, values in c["runs"] if len(values)),
                default=0.0)
    resolution = 8 * float(np.finfo(np.float32).eps) * scale
    return {k: 0.0 if k in DIFFERENCES and v is not None and abs(v) <= resolution else v for k, v in m.items()}


def _curves(ax, curves: dict, st: dict) -> None:
    """Each side's raw runs (faint), its mean and, with enough seeds, the band of the mean."""
    for side in ("baseline", "transfer"):
        c, color = curves[side], COLORS[side]
        n = len(c["runs"])
        for frames, values in c["runs"]:
            keep = frames <= st["budget"]
            ax.plot(frames[keep], values[keep], color=color, lw=0.6, alpha=0.18, zorder=1)
        smooth = f", moving average of {c['smooth']} evals" if c["smooth"] > 1 else ""
        what = f"mean of {n} seeds" if n > 1 else "1 seed"
        ax.plot(c["grid"], c["mean"], color=color, lw=2.0, zorder=3,
                label=f"{st[side + '_label']} ({side}; {what}{smooth})")
        if c["band"] is not None:
            ax.fill_between(c["grid"], *c["band"], color=color, alpha=0.2, lw=0, zorder=2,
                            label=f"{round(100 * st['confidence'])}% t-interval of the mean over seeds")
    ax.plot([], [], color="0.4", lw=0.6, alpha=0.4, label="raw evaluations, one line per seed")


def _asymptote(ax, m: dict, st: dict, moving: dict) -> None:
    """The asymptote window (shaded), both sides' mean level over it, and the gap at its end."""
    lo_w, hi_w = st["asymptote_frames"]
    ax.axvspan(lo_w, hi_w, color="0.5", alpha=0.08, lw=0, zorder=0)
    ax.plot([], [], color="0.4", lw=2.2, ls=(0, (4, 2)), label="mean over the asymptote window")
    fb, ft = m["final_performance_baseline"], m["final_performance_transfer"]
    for side, level in (("baseline", fb), ("transfer", ft)):
        ax.hlines(level, lo_w, hi_w, colors=COLORS[side], lw=2.2, linestyles=(0, (4, 2)), zorder=4)
    what_gap = "asymptotic" if not moving else "final performance\n(not converged)"
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
    """The differences with their intervals, beside the axes (mean return gain first)."""
    asym = "asymptotic" if not moving else "final perf. (not converged)"
    conf = round(100 * st["confidence"])
    summary = [
        "transfer - baseline" + (f" [{conf}% CI]" if _has_intervals(m) else " (no CI: < 3 seeds a side)")
        + (", paired" if st.get("paired") else ""),
        f"mean {_quantity(st)} gain {_signed(m.get('mean_return_gain'))}" + _ci(m, "mean_return_gain"),
        f"jumpstart {_signed(m['jumpstart'])}" + _ci(m, "jumpstart"),
        f"{asym} {_signed(m['asymptotic_performance'])}" + _ci(m, "asymptotic_performance"),
        f"transfer ratio {_signed(m['transfer_ratio'])}" + _ci(m, "transfer_ratio") + " (offset-dependent)",
        f"P(T > B) {m['probability_of_improvement']:.2f}" + _ci(m, "probability_of_improvement", sign=""),
    ]
    if "mean_return_gain_with_source" in m:
        summary.append(f"total time (source frames counted): gain {_signed(m['mean_return_gain_with_source'])}"
                       + _ci(m, "mean_return_gain_with_source"))
    for side, verdict in moving.items():
        said = "not shown to have converged" if verdict.startswith("undetermined") else verdict
        summary.append(f"warning: {side} {said} at the budget")
    ax.text(1.02, 1.0, "\n".join(summary), transform=ax.transAxes, ha="left", va="top",
            fontsize=9, family="monospace", zorder=8,
            bbox=dict(boxstyle="round,pad=0.4", fc="white", ec="0.7", alpha=0.9))


def _axes(ax, st: dict) -> None:
    from matplotlib.ticker import FuncFormatter

    start, budget = st["start"], st["budget"]
    pad = 0.015 * (budget - min(0, start))
    ax.set_xlim(min(0, start) - pad, budget + pad)
    ax.xaxis.set_major_formatter(FuncFormatter(lambda x, _: _frames(x)))
    ax.set_xlabel("environment frames")
    ax.set_ylabel(st["tag"] or "evaluation return")
    task = f" on {st['task']}" if st["task"] else ""
    ax.set_title(f"Transfer{task}: {st['transfer_label']} vs {st['baseline_label']}\n"
                 f"budget {_frames(budget)} frames; asymptote = mean over the last "
                 f"{100 * st['asymptote_window']:g}% of it (shaded)", fontsize=11)
    ax.grid(alpha=0.3)
    ax.legend(loc="upper left", bbox_to_anchor=(0.0, -0.1), fontsize=8.5, frameon=False)


def _ci(m: dict, name: str, sign: str = "+") -> str:
    ci = m.get(f"{name}_ci")
    if ci:
        return f" [{ci[0]:{sign}.3g}, {ci[1]:{sign}.3g}]"
    return " [no CI]" if _has_intervals(m) else ""


SHOWN = ("mean_return_gain", "jumpstart", "asymptotic_performance", "transfer_ratio", "probability_of_improvement")


def _has_intervals(m: dict) -> bool:
    """Whether the report gave the comparisons the plot shows intervals (so that a missing one is said)."""
    return any(f"{name}_ci" in m for name in SHOWN)


def _threshold_marks(ax, m: dict, st: dict, curves: dict) -> None:
    """The threshold line; on each run, a small marker where that run crosses (by the report's rule,
    so the run is at or above the threshold there); the median over seeds as a vertical line."""
    thr = st["threshold"]
    basis = st["threshold_basis"]
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
        if xs:
            ax.plot(xs, ys, "v", ms=7, color=color, mec="black", mew=0.6, zorder=7,
                    label=f"{side}: where each run crosses ({rule})")
        t = m[f"time_to_threshold_{side}"]
        n, reached = len(c["times"]), len(xs)
        if t is not None:
            ax.axvline(t, color=color, lw=1.2, ls=":", zorder=2,
                       label=f"{side}: upper median crossing, {_frames(t)} frames ({reached} of {n} runs cross)")
        else:
            ax.plot([], [], marker="v", ls="", ms=7, color=color, mec="black", mew=0.6,
                    label=f"{side}: no majority of runs crosses within the budget ({reached} of {n} do)")


def _gap(ax, x, y_from, y_to, text, side):
    """A vertical arrow from ``y_from`` (baseline) to ``y_to`` (transfer) at ``x`` with a label."""
    ax.annotate("", xy=(x, y_to), xytext=(x, y_from), zorder=6,
                arrowprops=dict(arrowstyle="<|-|>", color="black", lw=1.4, shrinkA=0, shrinkB=0))
    dx = 8 if side == "right" else -8
    ax.annotate(text, xy=(x, (y_from + y_to) / 2), xytext=(dx, 0), textcoords="offset points",
                ha="left" if side == "right" else "right", va="center", fontsize=9, zorder=8,
                bbox=dict(boxstyle="round,pad=0.25", fc="white", ec="0.6", alpha=0.9))


@_plain_text
def plot_matrix(
    table: np.ndarray,
    sources,
    targets,
    metric: str,
    *,
    text: np.ndarray | None = None,
    axis_labels: tuple[str, str] = ("source task", "target task"),
    title: str | None = None,
) -> tuple[bytes, bytes]:
    """Heatmap of ``metric`` over source (rows) x target (columns); empty cells are grey. ``text``
    replaces each cell's printed value (e.g. with its confidence interval)."""
    from matplotlib.colors import TwoSlopeNorm

    plt, (fig, ax) = _figure(figsize=(1.6 * len(targets) + 3, 1.1 * len(sources) + 2))
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
                    fontsize=10, color="black",
                    bbox=dict(boxstyle="round,pad=0.2", fc="white", ec="none", alpha=0.85))
    ax.set_xticks(range(len(targets)), targets, rotation=30, ha="right")
    ax.set_yticks(range(len(sources)), sources)
    ax.set_ylabel(axis_labels[0])
    ax.set_xlabel(axis_labels[1])
    ax.set_title(title or f"Transfer matrix: {metric}")
    fig.colorbar(im, ax=ax, label=metric)
    return _save(plt, fig)


@_plain_text
def plot_profiles(entries: list[dict], over: str = "the sweep's pairs") -> tuple[bytes, bytes]:
    """Performance profiles of a sweep (:func:`drltg.analysis.aggregate.sweep_aggregates`) or a leaderboard: per
    algo and method, the share of runs whose normalised score exceeds tau, with its stratified-bootstrap band;
    the baseline of each algo drawn once, dashed."""
    plt, (fig, ax) = _figure(figsize=(7, 4.5))
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
    ax.set_title(f"Performance profiles over {over} (95% stratified-bootstrap bands)")
    ax.legend(fontsize=8, loc="lower left")
    ax.grid(alpha=0.3)
    return _save(plt, fig)


@_plain_text
def plot_method_curves(title: str, curves: dict[str, tuple], baseline: tuple | None) -> tuple[bytes, bytes]:
    """One pair's learning curves, a line per method: ``label -> (frames, runs x evaluations)`` of normalised
    returns, the mean over runs with the band between the 25th and 75th percentile; no transfer dashed."""
    plt, (fig, ax) = _figure(figsize=(7, 4.2))
    for label, (frames, values) in ([("no transfer", baseline)] if baseline else []) + list(curves.items()):
        style = dict(color="0.3", linestyle="--") if label == "no transfer" else {}
        line, = ax.plot(frames, values.mean(axis=0), label=label, **style)
        lo, hi = np.percentile(values, [25, 75], axis=0)
        ax.fill_between(frames, lo, hi, color=line.get_color(), alpha=0.12)
    ax.set_xlabel("frames")
    ax.xaxis.set_major_formatter(lambda x, _: _frames(x))
    ax.set_ylabel("normalised return (mean; band: 25th-75th percentile of runs)")
    ax.set_title(title)
    ax.legend(fontsize=7, loc="lower right")
    ax.grid(alpha=0.3)
    return _save(plt, fig)
