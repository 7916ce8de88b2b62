"""Figures of ``drltg report``: both learning curves with the transfer metrics drawn on them, and the
transfer-matrix heatmap. Rendered off-screen (Agg) to PNG and SVG bytes."""
from __future__ import annotations

import io

import numpy as np

COLORS = {"baseline": "#0072B2", "transfer": "#D55E00"}  # colour-blind safe blue / vermillion


def _figure(*args, **kwargs):
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt, plt.subplots(*args, **kwargs)


def _save(plt, fig) -> tuple[bytes, bytes]:
    out = []
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


def plot_transfer(result: dict) -> tuple[bytes, bytes]:
    """Mean curve per side (CI band over seeds where there are >= 2), faint raw runs, the threshold
    line, time-to-threshold markers, jumpstart and asymptotic gaps as annotated segments."""
    from matplotlib.ticker import FuncFormatter

    m, st, curves = result["metrics"], result["settings"], result["curves"]
    plt, (fig, ax) = _figure(figsize=(10, 5.5))
    start, budget = st["start"], st["budget"]
    lo_w, hi_w = st["asymptote_frames"]

    for side in ("baseline", "transfer"):
        c, color = curves[side], COLORS[side]
        n = len(c["runs"])
        for frames, values in c["runs"]:
            keep = frames <= budget
            ax.plot(frames[keep], values[keep], color=color, lw=0.6, alpha=0.18, zorder=1)
        smooth = f", moving average of {c['smooth']} evals" if c["smooth"] > 1 else ""
        what = f"mean of {n} seeds" if n > 1 else "1 seed"
        ax.plot(c["grid"], c["mean"], color=color, lw=2.0, zorder=3,
                label=f"{st[side + '_label']} ({side}; {what}{smooth})")
        if c["band"] is not None:
            ax.fill_between(c["grid"], *c["band"], color=color, alpha=0.2, lw=0, zorder=2,
                            label=f"{round(100 * st['confidence'])}% bootstrap CI of the mean")

    ax.plot([], [], color="0.4", lw=0.6, alpha=0.4, label="raw evaluations, one line per seed")
    # asymptotic performance: the window, both levels, and the gap at the budget
    ax.axvspan(lo_w, hi_w, color="0.5", alpha=0.08, lw=0, zorder=0)
    ax.plot([], [], color="0.4", lw=2.2, ls=(0, (4, 2)), label="mean over the asymptote window")
    fb, ft = m["final_performance_baseline"], m["final_performance_transfer"]
    for side, level in (("baseline", fb), ("transfer", ft)):
        ax.hlines(level, lo_w, hi_w, colors=COLORS[side], lw=2.2, linestyles=(0, (4, 2)), zorder=4)
    _gap(ax, hi_w, fb, ft, f"asymptotic\n{_signed(m['asymptotic_performance'])}", side="left")

    # jumpstart: the first evaluations of both sides
    x0 = min(min(r[0][0] for r in curves[s]["runs"]) for s in curves)
    ib, it = m["initial_performance_baseline"], m["initial_performance_transfer"]
    for side, level in (("baseline", ib), ("transfer", it)):
        ax.plot([x0], [level], "o", color=COLORS[side], ms=7, mec="white", mew=1.2, zorder=6)
    _gap(ax, x0, ib, it, f"jumpstart\n{_signed(m['jumpstart'])}", side="right")

    if st["threshold"] is not None:
        thr = st["threshold"]
        how = f" (moving average of {st['smooth']})" if st["smooth"] else " (raw evaluations)"
        if len(curves["baseline"]["runs"]) + len(curves["transfer"]["runs"]) > 2:
            how = ", median over seeds" + how
        basis = st["threshold_basis"]
        of_best = "" if basis == "absolute" else f" ({basis.split(' x ')[0]} x best baseline mean)"
        ax.axhline(thr, color="0.15", lw=1.1, ls="--", zorder=2, label=f"threshold {thr:.4g}{of_best}")
        for side in ("baseline", "transfer"):
            t = m[f"time_to_threshold_{side}"]
            if t is not None:
                ax.axvline(t, color=COLORS[side], lw=1.0, ls=":", zorder=2)
                ax.plot([t], [thr], marker="v", ms=11, color=COLORS[side], mec="black", mew=0.8, zorder=7,
                        label=f"{side} first reaches it at {_frames(t)} frames{how}")
            else:
                ax.plot([], [], marker="v", ls="", ms=9, color=COLORS[side], mec="black", mew=0.8,
                        label=f"{side} never reaches it (within budget)")

    ci_note = f", [{round(100 * st['confidence'])}% CI]" if m.get("jumpstart_ci") else ""
    summary = [
        f"transfer - baseline{ci_note}",
        f"jumpstart {_signed(m['jumpstart'])}" + _ci(m, "jumpstart"),
        f"asymptotic {_signed(m['asymptotic_performance'])}" + _ci(m, "asymptotic_performance"),
        f"transfer ratio {_signed(m['transfer_ratio'])}" + _ci(m, "transfer_ratio"),
        f"P(improvement) {m['probability_of_improvement']:.2f}",
        f"area B {m['total_reward_baseline']:.4g}, T {m['total_reward_transfer']:.4g}",
    ]
    ax.text(1.0, -0.12, "\n".join(summary), transform=ax.transAxes, ha="right", va="top",
            fontsize=9, family="monospace", zorder=8,
            bbox=dict(boxstyle="round,pad=0.4", fc="white", ec="0.7", alpha=0.9))

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
    return _save(plt, fig)


def _ci(m: dict, name: str) -> str:
    ci = m.get(f"{name}_ci")
    return f" [{ci[0]:+.3g}, {ci[1]:+.3g}]" if ci else ""


def _gap(ax, x, y_from, y_to, text, side):
    """A vertical arrow from ``y_from`` (baseline) to ``y_to`` (transfer) at ``x`` with a label."""
    ax.annotate("", xy=(x, y_to), xytext=(x, y_from), zorder=6,
                arrowprops=dict(arrowstyle="<|-|>", color="black", lw=1.4, shrinkA=0, shrinkB=0))
    dx = 8 if side == "right" else -8
    ax.annotate(text, xy=(x, (y_from + y_to) / 2), xytext=(dx, 0), textcoords="offset points",
                ha="left" if side == "right" else "right", va="center", fontsize=9, zorder=8,
                bbox=dict(boxstyle="round,pad=0.25", fc="white", ec="0.6", alpha=0.9))


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
