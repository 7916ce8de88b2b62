"""Which runs a report may count: a diverged or unfinished drltg run is not a seed like the others.

A drltg run directory says what became of it: ``summary.json`` (written last) holds ``status:
diverged`` for a run whose losses or weights became non-finite, and a run with its ``config.yaml`` and
``logs/`` or ``checkpoints/`` but no ``summary.json`` was stopped before its end. Both are listed apart
and left out of the metrics unless asked for (``--include-unfinished``). So is an ``eval.csv`` without a
``config.yaml`` (a torn or copied run directory): nothing says which settings it was trained with, so
the report cannot check it against the other runs. Foreign logs (SB3, TensorBoard, CSVLogger of other
tools) carry no such record and are taken as they are.
"""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

from drltg.report.curves import Curve
from drltg.store import rundir

CONFIG_LESS = "without config.yaml"
LEFT_OUT = (rundir.DIVERGED, "incomplete", CONFIG_LESS)
"""States left out of the metrics unless asked for."""
WHY = {CONFIG_LESS: "nothing records the settings they were trained with, so they cannot be checked against "
                    "the other runs"}


def run_directory(curve: Curve) -> Path | None:
    """The drltg run directory a curve was read from (``None`` for a foreign log)."""
    source = Path(curve.source)
    folder = source if source.is_dir() else source.parent
    for candidate in [folder, *folder.parents][:4]:
        if (candidate / rundir.CONFIG).is_file() or (candidate / rundir.EVAL).is_file():
            return candidate
    return None


def run_state(curve: Curve) -> str | None:
    """``diverged``, ``incomplete``, ``without config.yaml`` or ``None`` (a complete or foreign run)."""
    run = run_directory(curve)
    if run is None:
        return None
    finished = rundir.summary_status(run)
    if finished is not None and finished[0] != rundir.COMPLETE:
        return rundir.DIVERGED if finished[0] == rundir.DIVERGED else "incomplete"
    if not (run / rundir.CONFIG).is_file():
        return CONFIG_LESS
    if finished is None and ((run / rundir.LOGS).is_dir() or (run / rundir.CHECKPOINT.parent).is_dir()):
        return "incomplete"
    return None


def partition(side: str, curves: Sequence[Curve], include_unfinished: bool,
              warnings: list[str]) -> tuple[list[Curve], dict[str, list[str]]]:
    """The curves the metrics count, and ``{state: [run, ...]}`` of the flagged ones; a warning per state."""
    kept, flagged = [], {}
    for c in curves:
        state = run_state(c)
        if state is not None:
            flagged.setdefault(state, []).append(str(run_directory(c)))
        if state not in LEFT_OUT or include_unfinished:
            kept.append(c)
    for state, runs in flagged.items():
        counted = state not in LEFT_OUT or include_unfinished
        why = f" ({WHY[state]})" if state in WHY and not counted else ""
        warnings.append(f"{len(runs)} {side} run(s) {state}, {'counted' if counted else 'left out of the metrics'}"
                        f"{why}{' (--include-unfinished counts them)' if not counted else ''}: {', '.join(runs)}")
    return kept, flagged
