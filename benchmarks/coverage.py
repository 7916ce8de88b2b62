"""Suite ``coverage``: the report's intervals on simulated seeds, thoroughly (``tests/test_coverage.py`` is the
fast check): ``results/coverage/simulate.py``'s tables of the default (betting where the range is known,
withheld elsewhere) and the t interval, on normal, lognormal, bimodal, rate and learn-or-not scores, paired
and unpaired, at 3, 5 and 10 seeds, with false claims under no effect and the default's power."""
from __future__ import annotations

import importlib.util
import time

from benchmarks.common import REPO


def _simulate():
    spec = importlib.util.spec_from_file_location("simulate", REPO / "results" / "coverage" / "simulate.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _cells(markdown: str) -> list[dict]:
    rows = [line.strip("|").split("|") for line in markdown.splitlines() if line.startswith("| ") and "---" not in line]
    header = [c.strip() for c in rows[0]]
    return [dict(zip(header, (c.strip() for c in row))) for row in rows[1:]]


def run(device: str = "cpu", quick: bool = False) -> dict:
    sim = _simulate()
    experiments = 400 if quick else 4000
    start = time.perf_counter()
    cells = _cells(sim.table(experiments, 0, sim.SHAPES + tuple(sim.LEARN)))
    seconds = time.perf_counter() - start
    below = [c for c in cells if c["default (auto): betting or withheld"] != "withheld"
             and float(c["default (auto): betting or withheld"]) < 0.93]
    return {"experiments": experiments, "seconds": round(seconds, 1), "cells": cells,
            "default_below_0.93": len(below), "target": "the default covers >= 0.93 or is withheld in every cell"}
