"""Regenerate the tables of results/seed-tasks/README.md from the kept curves: `python results/seed-tasks/progress.py`.

Every number in the README's generated regions comes from the kept eval.csv files and from the earlier
implementation's logs (tests/data/sb3_runs), read at the same frames: the baselines' progress, the Lift sources
(does each hold its success over the second half of training?) and the rows beside the earlier runs.
"""
from __future__ import annotations

import io
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from drltg.analysis.curves import read_curves  # noqa: E402
from drltg.config.overrides import load_yaml  # noqa: E402
from drltg.store.rundir import atomic_write, read_eval_csv  # noqa: E402

HERE = Path(__file__).resolve().parent
BASELINES = HERE / "lift-place-seed" / "sac" / "baseline"
SB3 = ROOT / "tests" / "data" / "sb3_runs"
EARLIER = SB3 / "liftplace_sac"
TARGET, BUDGET = 50.0, 300_000
SEEDS = (10, 11, 12)
HOLD_LOWEST, HOLD_MEAN = 0.7, 0.9
SOURCES = {  # folder: what it is
    "lift-dense-sac": "SAC + the demonstrator's episodes (LayerNorm critics, half of every batch)",
    "lift-dense-soc4": "SOC-4 + the demonstrator's episodes (a quarter of every batch)",
    "lift-dense-sac-plain": "SAC alone, as the earlier implementation's source (stopped)",
}
ROWS = {  # row: (target folder, baseline folder, earlier no-transfer log, earlier transfer log)
    "shaping-lift-seed": ("lift/sac", "baseline", "lift_sparse_sac", "lift_shaped_sac"),
    "pi-reuse-place-seed": ("lift-place-seed/sac", "baseline", "liftplace_sac", "liftplace_sac_policyreuse"),
    "pi-reuse-barrier-seed": ("lift-place-barrier-seed/sac", "baseline", "liftplacebarrier_sac",
                              "liftplacebarrier_sac_policyreuse"),
    "model-reuse-place-seed": ("lift-place-seed/sac", "baseline-ln", "liftplace_sac", None),
    "soc-model-reuse-place-seed": ("lift-place-seed/soc", "baseline", None, "liftplace_soc4"),
}
SIDE_BY_SIDE_FRAMES = (100_000, 200_000, 300_000)


def runs() -> dict[str, list[dict]]:
    return {d.name: read_eval_csv(d / "eval.csv") for d in sorted(BASELINES.glob("seed-*"))
            if (d / "eval.csv").is_file()}


def region() -> str:
    kept = runs()
    earlier = read_curves(EARLIER)[0]
    common = sorted(set.intersection(*({r["frames"] for r in rows} for rows in kept.values())))
    seeds = list(kept)
    lines = [f"| frames | {' | '.join(f'return, {s}' for s in seeds)} | mean | earlier SAC (1 run) | lifted | pushed "
             "| placed (strict) |", "|---" * (len(seeds) + 6) + "|"]
    for f in common:
        rows = [next(r for r in kept[s] if r["frames"] == f) for s in seeds]
        returns = [r["return_mean"] for r in rows]
        mean_of = lambda key: np.mean([r.get(key, float("nan")) for r in rows])  # noqa: E731
        then = f"{np.interp(f, earlier.frames, earlier.values):.1f}" if f >= earlier.frames[0] else "—"
        lines.append(f"| {f:,} | {' | '.join(f'{x:.1f}' for x in returns)} | {np.mean(returns):.1f} | "
                     f"{then} | {mean_of('lifted_rate'):.2f} | {mean_of('pushed_rate'):.2f} | "
                     f"{mean_of('success_rate'):.2f} |")
    last3 = np.mean([np.mean([next(r for r in kept[s] if r["frames"] == f)["return_mean"] for f in common[-3:]])
                     for s in seeds])
    finished = all((BASELINES / s / "summary.json").is_file() for s in seeds)
    state = ("finished" if finished else
             f"still training (the last evaluation every seed reached is at {common[-1]:,} frames)")
    final = "final return" if finished else "return so far"
    sentence = (f"The {len(seeds)} baseline seeds are {state}. Mean over seeds of the {final} (mean of the last 3 "
                f"evaluations, frames {common[-3]:,} to {common[-1]:,}): {last3:.1f}, against the target of at least "
                f"{TARGET:g} within {BUDGET:,} frames.")
    return "\n".join(lines) + "\n\n" + sentence


def second_half(rows: list[dict], frames: int) -> list[float]:
    """Success rates of the evaluations in the second half of a run of ``frames`` frames, rounded to 6 digits
    (a rate is kept as float32: 7 of 10 reads 0.699999988)."""
    return [round(r["success_rate"], 6) for r in rows if r["frames"] >= frames / 2]


def pass_probability(p: float, evaluations: int, episodes: int) -> float:
    """The chance that a policy succeeding in each episode with probability ``p`` passes the hold rule: each of
    ``evaluations`` evaluations of ``episodes`` episodes at least HOLD_LOWEST, their mean at least HOLD_MEAN.
    An evaluation's successes are Binomial(episodes, p), independent; their sum is the convolution of that law
    cut below HOLD_LOWEST * episodes."""
    from scipy.stats import binom

    k = np.arange(episodes + 1)
    one = np.where(k >= np.ceil(HOLD_LOWEST * episodes - 1e-9), binom.pmf(k, episodes, p), 0.0)
    total = np.ones(1)
    for _ in range(evaluations):
        total = np.convolve(total, one)
    return float(total[int(np.ceil(HOLD_MEAN * episodes * evaluations - 1e-9)):].sum())


def what_the_rule_asks(run: Path) -> str:
    """The hold rule read as a test of the source's success probability, on the evaluations ``run`` made."""
    rows = read_eval_csv(run / "eval.csv")
    n, episodes = len(second_half(rows, int(load_yaml(run / "config.yaml")["frames"]))), int(rows[-1]["episodes"])
    at = ", ".join(f"{pass_probability(p, n, episodes):.2f} if p = {p:.2f}" for p in (0.85, 0.90, 0.95, 0.99))
    grid = np.round(np.arange(0.5, 1.0, 0.01), 2)
    reliable = next(p for p in grid if pass_probability(p, n, episodes) >= 0.9)
    return (f"- What the rule asks: a source's second half holds {n} evaluations of {episodes} episodes, so a policy "
            f"that succeeds in an episode with probability p passes it with probability {at} (binomial, "
            f"evaluations independent): 9 times in 10 only from p = {reliable:.2f}. A seed that misses it need not "
            "have collapsed; its policy may succeed in 9 episodes of 10.")


def sources() -> str:
    lines = ["| source | seed | frames | success, last evaluation | best.pt, which the rows reuse "
             "(95% Clopper-Pearson) | second half: lowest / mean | holds |", "|---|---|---|---|---|---|---|"]
    verdicts = []
    for name, what in SOURCES.items():
        trainings = sorted((HERE / "sources" / name).glob("seed-*"))
        seeds = [d for d in trainings if "-retrained" not in d.name]  # the rule judges each seed's first training
        held, again = 0, []
        for d in trainings:
            rows = read_eval_csv(d / "eval.csv")
            planned = int(load_yaml(d / "config.yaml")["frames"])
            done = (d / "summary.json").is_file()
            half = second_half(rows, planned)
            best = json.loads((d / "summary.json").read_text()).get("best") if done else None
            reused = f"{best['score']:.1f} at {best['frames']:,}" if best else "—"
            for fresh in sorted(d.glob("evaluate-best-*-50ep.json")):  # drltg evaluate, fresh episodes
                r = json.loads(fresh.read_text())
                lo, hi = r["success_rate_ci95"]
                reused += f"; {r['success_rate']:.2f} [{lo:.2f}, {hi:.2f}] on {r['episodes']} fresh episodes"
            seed = d.name.removeprefix("seed-").replace("-retrained", ", trained again")
            if done:
                holds = min(half) >= HOLD_LOWEST and np.mean(half) >= HOLD_MEAN
                if d in seeds:
                    held += holds
                else:
                    again.append(f"seed {seed.split(',')[0]} {'holds' if holds else 'does not hold'}")
                cells = f"{min(half):.1f} / {np.mean(half):.2f} | {'yes' if holds else 'no'}"
            else:
                cells = "— | not finished"
            lines.append(f"| `{name}` | {seed} | {rows[-1]['frames']:,} of {planned:,} | "
                         f"{rows[-1]['success_rate']:.1f} | {reused} | {cells} |")
        finished = sum((d / "summary.json").is_file() for d in seeds)
        if seeds and not finished:
            verdicts.append(f"- `{name}`, {what}: no seed finished, so none is judged.")
        elif seeds:
            verdicts.append(f"- `{name}`, {what}: {held} of {finished} finished seeds hold"
                            + (f" ({len(seeds) - finished} not finished)" if finished < len(seeds) else "")
                            + (f"; trained again, {', '.join(again)}" if again else "") + ".")
    verdicts.append(what_the_rule_asks(HERE / "sources" / "lift-dense-sac" / "seed-60"))
    earlier = read_curves(SB3 / "lift_shaped_sac")[0]
    late = earlier.frames >= earlier.frames[-1] / 2
    low = int(np.argmin(earlier.values[late]))
    at = lambda x: f"{int(x):,}"  # noqa: E731
    verdicts.append(
        f"- The earlier implementation's source (`lift_shaped_sac`, SAC alone on the dense reward, "
        f"{at(earlier.frames[-1])} frames; its log records return only): over its second half the evaluation "
        f"return averaged {np.mean(earlier.values[late]):.1f} and fell to {earlier.values[late][low]:.1f} at "
        f"{at(earlier.frames[late][low])} frames (its best {earlier.values.max():.1f}).")
    return "\n".join(lines) + "\n\n" + "\n".join(verdicts)


def _mean_at(folder: Path, frames: int, *keys: str) -> str:
    """Mean over the seeds under ``folder`` that reached ``frames``, of each key (joined by " / "); how many
    seeds, where not all 3 did."""
    rows = [r for d in sorted(folder.glob("seed-*/eval.csv")) for r in read_eval_csv(d) if r["frames"] == frames]
    if not rows:
        return " / ".join("—" for _ in keys)
    means = [format(float(np.mean([r[k] for r in rows])), ".1f" if k == "return_mean" else ".2f")
             if k in rows[0] else "n/a" for k in keys]  # (Lift has no target, so no pushed rate)
    return " / ".join(means) + (f" ({len(rows)} seed{'s' * (len(rows) > 1)})" if len(rows) < len(SEEDS) else "")


def _earlier_at(log: str | None, frames: int) -> str:
    if log is None:
        return "not run"
    curve = read_curves(SB3 / log)[0]
    return f"{np.interp(frames, curve.frames, curve.values):.1f}" if curve.frames[0] <= frames else "—"


def _metric(row: str) -> str:
    """The quantity a row is read in: Lift's success for shaping (its sides are paid by different rewards),
    else the return on the seed's reward."""
    return "success_rate" if row == "shaping-lift-seed" else "return_mean"


def _sides(row: str) -> tuple[Path, Path]:
    """A row's baseline and transfer folders: the finished row's, or before that its runs' curves so far."""
    target, baseline = ROWS[row][:2]
    kept = HERE / row
    return (kept / "baseline", kept / "transfer") if kept.is_dir() else (HERE / target / baseline, HERE / target / row)


def side_by_side() -> str:
    lines = ["| row | frames | earlier: no transfer | earlier: transfer | drltg: no transfer | drltg: transfer "
             "| drltg no transfer: placed / pushed / lifted | drltg transfer: placed / pushed / lifted |",
             "|---" * 8 + "|"]
    for row, (_, _, before, after) in ROWS.items():
        key = _metric(row)
        base, moved = _sides(row)
        for f in SIDE_BY_SIDE_FRAMES:
            rates = [_mean_at(side, f, "success_rate", "pushed_rate", "lifted_rate") for side in (base, moved)]
            lines.append(f"| `{row}` | {f:,} | {_earlier_at(before, f)} | {_earlier_at(after, f)} | "
                         f"{_mean_at(base, f, key)} | {_mean_at(moved, f, key)} | {rates[0]} | {rates[1]} |")
    return "\n".join(lines)


def binned(curve, width: int = 10_000) -> tuple[np.ndarray, np.ndarray]:
    """A curve's mean in each ``width`` frames up to the budget, ``(end - width, end]``, at each window's end."""
    ends = np.arange(width, min(BUDGET, curve.frames[-1]) + 1, width)
    return ends, np.array([curve.values[(curve.frames > f - width) & (curve.frames <= f)].mean() for f in ends])


def figure() -> bytes:
    """Each row's curves beside the earlier runs', cut at the row's budget: drltg's seeds (thin) and their mean
    (thick) per side; the earlier single runs (evaluated every 500 frames) dashed, as the mean of their
    evaluations in each 10k frames, drltg's evaluation interval. PNG bytes."""
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    colors = {"no transfer": "#0072B2", "transfer": "#D55E00"}
    fig, axes = plt.subplots(2, 3, figsize=(13, 7.5))
    for ax, (row, (_, _, before, after)) in zip(axes.flat, ROWS.items()):
        key, trained = _metric(row), 0
        for (side, color), folder, log in zip(colors.items(), _sides(row), (before, after)):
            curves = [read_eval_csv(d) for d in sorted(folder.glob("seed-*/eval.csv"))]
            trained += len(curves)
            for rows in curves:
                ax.plot([r["frames"] for r in rows], [r[key] for r in rows], color=color, lw=0.6, alpha=0.35)
            if curves:
                common = sorted(set.intersection(*({r["frames"] for r in rows} for rows in curves)))
                mean = [np.mean([next(r[key] for r in rows if r["frames"] == f) for rows in curves]) for f in common]
                seeds = f"{len(curves)} seed{'s' * (len(curves) > 1)}"
                ax.plot(common, mean, color=color, lw=2, label=f"drltg, {side} ({seeds})")
            if log is not None and key == "return_mean":
                ends, means = binned(read_curves(SB3 / log)[0])
                ax.plot(ends, means, color=color, lw=1.2, ls="--", label=f"earlier, {side} (1 run)")
        if not trained:
            ax.text(0.5, 0.5, "drltg: not trained yet", ha="center", va="center", transform=ax.transAxes, color="0.4")
        ax.set_title(f"{row}\n" + ("Lift success (the earlier runs logged return, each on its own reward)"
                                    if key == "success_rate" else "return on the seed's reward"), fontsize=9)
        ax.set_xlim(0, BUDGET)
        if key == "success_rate":
            ax.set_ylim(-0.03, 1.03)
        ax.xaxis.set_major_formatter(matplotlib.ticker.FuncFormatter(lambda x, _: f"{x / 1000:.0f}k"))
        ax.set_xlabel("frames")
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=7, loc="upper left")
    axes.flat[-1].axis("off")
    axes.flat[-1].text(0, 0.5, "thin: drltg's seeds; thick: their mean at the\nframes every seed reached.\n"
                       "dashed: the earlier implementation's single run,\nthe mean of its evaluations in each "
                       "10k frames.\ndrltg evaluates on 10 episodes every 10k frames.", fontsize=8, va="center")
    fig.tight_layout()
    out = io.BytesIO()
    fig.savefig(out, format="png", dpi=110, metadata={"Software": None})
    plt.close(fig)
    return out.getvalue()


REGIONS = {"progress": region, "sources": sources, "side-by-side": side_by_side}


def filled(text: str) -> str:
    """``text`` (the README) with its generated regions rebuilt from the kept curves."""
    for name, make in REGIONS.items():
        start, end = f"<!-- {name} -->", f"<!-- /{name} -->"
        head, rest = text.split(start, 1)
        _, tail = rest.split(end, 1)
        text = f"{head}{start}\n{make()}\n{end}{tail}"
    return text


def main() -> None:
    path = HERE / "README.md"
    atomic_write(path, filled(path.read_text()))
    atomic_write(HERE / "side-by-side.png", figure())


if __name__ == "__main__":
    main()
