"""The benchmark's suites: each version fixes, for every tier, the pairs, budgets, seeds and evaluation a
method is run on, so that a new method lands beside the reference rows without re-running them.

A tier is a few *groups*; a group is one sweep spec without its methods (its pairs share a scale of
budgets). A version never changes once published: a new protocol is a new version.

**The score of a pair** is forward transfer as Continual World defines it (Wolczyk et al. 2021), on the
target task's return normalised to [0, 1] by its declared range, :math:`n(x) = (x - lo) / (hi - lo)`:

.. math::  FT = \\frac{AUC_T - AUC_B}{1 - AUC_B}

where :math:`AUC` is the mean of :math:`n` over the budget (the area under the evaluation curve divided by
the frames) and :math:`AUC_B` no transfer's, averaged over the seeds. Seed :math:`i`'s score is
:math:`FT_i = (AUC_{T,i} - AUC_{B,i}) / (1 - \\overline{AUC_B})`, so the pair's score is the mean of its
seeds' and every verdict on it is the report's exact sign-flip test of the paired differences.
"""
from __future__ import annotations

import itertools
import json
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

from drltg.errors import UsageError, closest

__all__ = ["Group", "Sources", "Tier", "SUITES", "LATEST", "get_tier", "SMOKE", "TUNE_SEED", "TUNE_SEEDS", "tier_root",
           "tuning_root", "REFERENCE_FILES", "copy_run"]


@dataclass(frozen=True)
class Sources:
    """A group's sources as part of the suite: trained once on the pairs' shared source task, each to the
    first evaluation whose success rate reaches ``success`` (``eval.stop_at_success``; ``None``: no success
    criterion, the whole budget), within ``frames``; kept as networks files and named by their SHA-256 in the
    suite's sources file, so every row of the board learns from the same teachers."""

    frames: int
    success: float | None = None


@dataclass(frozen=True)
class Group:
    """Pairs benchmarked on one sweep spec (``spec`` holds every sweep key but ``methods``)."""

    name: str
    spec: dict
    sources: Sources | None = None
    baseline_search: dict[str, tuple] = field(default_factory=dict)
    """The learner's tuning space on these pairs, ``config key -> values``, each list starting at the pairs'
    own default (a task sets some, e.g. FourRooms' ``sac.alpha_init``): ``drltg bench tune --method none`` tries
    it on the tuning seeds within a method's budget, and every run of the group (baseline and transfer, not the
    sources) trains at its choice."""

    @property
    def pairs(self) -> list[str]:
        return list(self.spec["pairs"])

    @property
    def baseline_settings(self) -> list[dict]:
        """The settings of the baseline search, the defaults first (``[{}]`` for a group without one)."""
        keys = list(self.baseline_search)
        return [dict(zip(keys, point)) for point in itertools.product(*(self.baseline_search[k] for k in keys))]

    def sweep_spec(self, methods: list[str], smoke: bool = False) -> dict:
        """The sweep spec that runs ``methods`` on this group (at :data:`SMOKE` budgets where ``smoke``)."""
        spec = {**self.spec, "methods": list(methods)}
        if smoke:
            spec = {**spec, **smoke_budgets(spec)}
        return spec


@dataclass(frozen=True)
class Tier:
    name: str
    summary: str
    groups: tuple[Group, ...]
    hours: str = ""
    digests: str | None = None
    """The package file (under ``drltg/bench/sources/``) naming each source of the tier by its SHA-256:
    ``{"<group>/seed-<target seed>": {"networks_sha256", "config_sha256"}}``."""

    @property
    def pairs(self) -> list[str]:
        return [p for g in self.groups for p in g.pairs]

    @property
    def tunes_baseline(self) -> bool:
        return any(g.baseline_search for g in self.groups)


TUNE_SEED = 5_000
TUNE_SEEDS = 3
"""The tuning seeds, ``5000 + 100 i`` (sources ``+ 50``): no leaderboard run has one, so a row is never scored
on the seeds that chose its setting."""

REFERENCE_FILES = ("config.yaml", "eval.csv", "summary.json", "manifest.json", "checkpoints/last.safetensors")
"""What a finished run holds that another bench folder copies as data: the curve a report reads, and the
networks a source is reused from (:mod:`drltg.store.rundir`'s and :mod:`drltg.store.manifest`'s names)."""


def copy_run(kept: Path, path: Path) -> None:
    """Copy a finished run's :data:`REFERENCE_FILES` from ``kept`` into ``path``, as data."""
    import shutil

    for name in REFERENCE_FILES:
        if (kept / name).is_file():
            (path / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(kept / name, path / name)


def tier_root(out: str | Path, version: str, tier: str, smoke: bool = False) -> Path:
    """A tier's folder in a bench folder: ``OUT/<version>/<tier>`` (``<tier>-smoke`` at smoke budgets)."""
    return Path(out) / version / (f"{tier}-smoke" if smoke else tier)


def tuning_root(out: str | Path, version: str, tier: str, method: str, smoke: bool = False) -> Path:
    return tier_root(out, version, tier, smoke) / "tuning" / method


SMOKE = {"seeds": 2, "divisor": 50, "episodes": 2}
"""A smoke run: 2 seeds, every budget (and the evaluation period) divided by 50, 2 evaluation episodes.
Its rows are labelled ``smoke`` and never ranked."""


def smoke_budgets(spec: dict) -> dict:
    d = SMOKE["divisor"]
    frames = {k: max(1, int(spec[k]) // d) for k in ("frames", "source_frames") if k in spec}
    every = max(1, int(spec.get("overrides", {}).get("eval.every", 5_000)) // d)
    return {**frames, "seeds": SMOKE["seeds"],
            "overrides": {**spec.get("overrides", {}), "eval.every": every, "eval.episodes": SMOKE["episodes"]}}


_FOURROOMS = {"algos": ["sac"], "seeds": 10, "seed": 0, "frames": 20_000, "source_frames": 40_000,
              "threshold": 0.5, "overrides": {"eval.every": 1_000}}

V1 = {
    "quick": Tier(
        "quick", "FourRooms' graded goals, grid FourRooms and a heavier Pendulum: 8 pairs, 10 paired seeds",
        (Group("fourrooms", {"pairs": ["fourrooms-near", "fourrooms-inner", "fourrooms-southeast",
                                       "fourrooms-northwest", "fourrooms-far"], **_FOURROOMS}),
         Group("gridrooms", {"pairs": ["gridrooms-near", "gridrooms-far"], **_FOURROOMS}),
         Group("pendulum", {"pairs": ["pendulum-heavier"], "algos": ["sac"], "seeds": 10, "seed": 0,
                            "frames": 6_000, "source_frames": 6_000, "threshold": -400,
                            "overrides": {"eval.every": 500, "eval.episodes": 10}})),
        hours="about 0.5 on 2 cores a method (seed groups)"),
    "manipulation": Tier(
        "manipulation", "robosuite Lift (dense reward) to Lift+Place, open and over a barrier: 2 pairs, 3 seeds",
        (Group("lift", {"pairs": ["lift-dense-to-place-seed", "lift-dense-to-place-barrier-seed"],
                        "algos": ["sac"], "seeds": 3, "seed": 10, "frames": 300_000, "source_frames": 60_000,
                        "threshold": 1, "overrides": {"eval.every": 10_000, "eval.episodes": 10}}),),
        hours="about 30 on 2 cores a method"),
}
_FOURROOMS_V2 = {k: v for k, v in _FOURROOMS.items() if k != "source_frames"}
V2 = {
    "quick": Tier(
        "quick", "FourRooms' graded goals, grid FourRooms and a heavier Pendulum: 8 pairs, 10 paired seeds, "
        "the suite's own sources and a tuned baseline",
        (Group("fourrooms", {"pairs": V1["quick"].groups[0].pairs, **_FOURROOMS_V2}, Sources(80_000, 0.9),
               {"sac.alpha_init": (0.01, 0.1), "optim.lr": (3.0e-4, 1.0e-3)}),
         Group("gridrooms", {"pairs": V1["quick"].groups[1].pairs, **_FOURROOMS_V2}, Sources(80_000, 0.9),
               {"sac.alpha_init": (0.01, 0.003), "optim.lr": (3.0e-4, 1.0e-3)}),
         Group("pendulum", {k: v for k, v in V1["quick"].groups[2].spec.items() if k != "source_frames"},
               Sources(6_000), {"sac.alpha_init": (1.0, 0.1), "optim.lr": (1.0e-3, 3.0e-4)})),
        hours="about 1 on 2 cores a method, tuning included (seed groups)",
        digests="v2-quick.json"),
}
SUITES = {"v1": V1, "v2": V2}
LATEST = "v2"


def declared_sources(tier: Tier) -> dict[str, dict]:
    """The tier's sources by SHA-256 as its suite declares them (``{}``: none declared yet)."""
    if tier.digests is None:
        return {}
    found = resources.files("drltg.bench").joinpath("sources", tier.digests)
    return json.loads(found.read_text()) if found.is_file() else {}


def get_tier(version: str, tier: str) -> Tier:
    """The tier of a suite version; an unknown name is one sentence."""
    if version not in SUITES:
        raise UsageError(f"unknown suite version '{version}'; the versions are {', '.join(SUITES)}.")
    tiers = SUITES[version]
    if tier not in tiers:
        hint = closest(tier, tiers)
        raise UsageError(f"suite {version} has no tier '{tier}'" +
                         (f"; did you mean '{hint}'?" if hint else f"; its tiers are {', '.join(tiers)}."))
    return tiers[tier]
