"""Regenerate the table of results/seed-tasks/README.md from the kept curves: `python results/seed-tasks/progress.py`.

Every number in the README's generated region comes from the kept eval.csv files and from the earlier
implementation's SAC log on its Lift+Place task (tests/data/sb3_runs/liftplace_sac), read at the same frames.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from drltg.analysis.curves import read_curves  # noqa: E402
from drltg.store.rundir import atomic_write, read_eval_csv  # noqa: E402

HERE = Path(__file__).resolve().parent
BASELINES = HERE / "lift-place-seed" / "sac" / "baseline"
EARLIER = ROOT / "tests" / "data" / "sb3_runs" / "liftplace_sac"
START, END = "<!-- progress -->", "<!-- /progress -->"
TARGET, BUDGET = 50.0, 300_000


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


def filled(text: str) -> str:
    """``text`` (the README) with its generated region rebuilt from the kept curves."""
    head, rest = text.split(START, 1)
    _, tail = rest.split(END, 1)
    return f"{head}{START}\n{region()}\n{END}{tail}"


def main() -> None:
    path = HERE / "README.md"
    atomic_write(path, filled(path.read_text()))


if __name__ == "__main__":
    main()
