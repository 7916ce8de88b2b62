"""Fill the generated regions of README.md, docs/ and results/ with drltg's own outputs for the committed runs.

    python results/claims.py [--check]   # rewrite each region between <!-- claims:NAME --> and <!-- /claims:NAME -->
                                         # (--check: change nothing, name the files that differ and exit 1)
A region pastes drltg's outputs, computing nothing: the headline ``drltg report`` prints for every report under
the folders named (:func:`drltg.analysis.claims.headline`, each read alone), a table ``drltg sweep`` wrote
(``summary.md``, ``aggregates.md``), a benchmark's result, a table of drltg's registries, or how many of the reports
matching a pattern give each verdict (:func:`verdicts`), for a sentence that sums them up.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

from drltg import config
from drltg.analysis.claims import headline
from drltg.analysis.tables import render

ROOT = Path(__file__).resolve().parents[1]
GRADED, OPTIONS, BENCH = "results/sweep-fourrooms-graded", "results/sweep-options", "results/bench/v1/quick"
ROWS = ["lift-shaping", "pi-reuse-place", "pi-reuse-barrier", "model-reuse-place", "soc-model-reuse-place",
        "demonstrations-place", "demonstrations-barrier", "combined-place", "combined-barrier",
        "demonstrations-reference-place", "demonstrations-reference-barrier"]


def headlines(*folders: str) -> str:
    """One line per report under ``folders`` (their own included): where it is and its headline."""
    paths = [p for f in folders for p in sorted((ROOT / f).glob("**/transfer_metrics.json"))]
    return "".join(f"- `{p.parent.relative_to(ROOT)}`: {headline(json.loads(p.read_text()))}\n" for p in paths)


def verdicts(*patterns: str) -> str:
    """How the reports matching ``patterns`` decide the mean return gain: ``higher in 3 of 3 reports``."""
    said = [json.loads(p.read_text())["metrics"]["mean_return_gain_verdict"]
            for pattern in patterns for p in sorted(ROOT.glob(f"{pattern}/transfer_metrics.json"))]
    return ", ".join(f"{v} in {said.count(v)} of {len(said)} reports" for v in sorted(set(said)))


def table(path: str) -> str:
    return (ROOT / path).read_text()


def tasks(kind: str) -> str:
    """The registered tasks and pairs of one kind: ``rooms`` (FourRooms and its grid), ``robosuite``, ``gym``."""
    from drltg.envs import PAIRS, TASKS

    def kind_of(name, t):
        return "rooms" if name.startswith(("fourrooms", "gridrooms")) else "gym" if "gym_id" in t.fixed else "robosuite"

    own = {n: t for n, t in TASKS.items() if kind_of(n, t) == kind}
    pairs = [(f"`{n}`", f"`{p.source}` → `{p.target}`", p.description) for n, p in PAIRS.items() if p.source in own]
    return (render([("task", "description")] + [(f"`{n}`", t.description) for n, t in own.items()], "markdown")
            + "\n" + render([("pair", "source → target", "description")] + pairs, "markdown"))


def demo_plan() -> str:
    """What ``drltg demo`` trains, from its own settings (:data:`drltg.cli.demo.DEMO`) and the runs it plans."""
    from drltg.cli.demo import DEMO, plan

    (_, source, _), (_, target, _), *_ = plan(Path("runs/demo"))

    def k(frames: int) -> str:
        return f"{frames / 1000:g}k"

    return (f"`drltg demo`: {DEMO['algo'].upper()} learns `{source.task}` once (one source run, {k(source.frames)} "
            f"frames, evaluated every {k(source.eval.interval(source.frames))}); then `{target.task}` is learnt for "
            f"{k(target.frames)} frames from scratch and from that source's weights "
            f"({DEMO['method'].replace('-', ' ')}) on {DEMO['seeds']} paired seeds, evaluated every "
            f"{k(target.eval.interval(target.frames))} frames on {target.eval.episodes} episodes.")


def methods() -> str:
    kinds = {None: "—", "run": "a run", "policy": "a run or `demonstrator:TASK`"}
    return render([("`transfer.method`", "source", "what it is")] + [
        (f"`{n}`", kinds[m.source], m.help) for n, m in config.METHODS.items()], "markdown")


def sf_psi() -> str:
    """``benchmarks/sf_psi_result.json`` as a table: per source, psi's agreement with the Monte Carlo return
    (correlation) after 2,000 TD steps, 20,000 and the last, and where the opt-in plateau rule stops."""
    result = json.loads((ROOT / "benchmarks" / "sf_psi_result.json").read_text())
    last = result["steps"]
    rows = [("source", "2,000 steps", "20,000 steps", f"{last:,} steps", "plateau rule stops at (correlation there)")]
    for run in result["runs"]:
        stop = run["at_stop"]
        rows.append((f"`{Path(run['source']).name}`", f"{run['at_2000']['corr']:.2f}", f"{run['at_20000']['corr']:.2f}",
                     f"{run['at_last']['corr']:.2f}",
                     f"{run['rule_stops_at']:,} ({stop['corr']:.2f})" if stop else f"not within {last:,}"))
    return render(rows, "markdown")


BOARD = {f"bench-{f}": lambda f=f: table(f"{BENCH}/board/{f}.md") for f in ("ranking", "pairs")}


def costs(folder: str) -> str:
    """What each part of a bench tier took to train, from its runs' summaries (the training loop's wall time and a
    transfer's pretraining): a unit of work (a seed group, or a run alone) is one process on one core, so its wall
    time is its CPU time; a run copied as data is counted where it trained."""
    units: dict[str, dict] = {}
    untimed: set[str] = set()  # parts whose runs pretrained without recording how long (written before it was)
    for path in sorted((ROOT / folder).rglob("summary.json")):
        parts = path.relative_to(ROOT / folder).parts
        if parts[0] == "sources":
            part = "the sources"
        elif parts[0] == "tuning":
            if parts[1] != "none" and "baseline" in parts:
                continue  # the baseline's own tuning runs, copied
            part = "the baseline's tuning" if parts[1] == "none" else f"{parts[1]}'s tuning"
        elif "baseline" in parts:
            part = "the baselines (shared by every row)"
        elif "transfer" in parts:
            part = f"{parts[parts.index('transfer') - 1]}'s row"
        else:
            continue
        summary = json.loads(path.read_text())
        group = (summary.get("seed_group") or {}).get("seeds") or [summary.get("seed")]
        key = f"{path.parent.parent}|{group}"
        if parts[0] == "tuning":  # a tuning grid's settings (folders of their own) may share one seed group: its clock
            key = f"{'/'.join(parts[:5])}|{group}|{summary.get('wall_time_s')}|{summary.get('wall_time_split_s')}"
        unit = units.setdefault(part, {}).setdefault(key, {"runs": 0, "seconds": 0.0})
        unit["runs"] += 1
        seconds = float(summary.get("wall_time_s") or 0.0) + float(summary.get("pretraining_s") or 0.0)
        unit["seconds"] = max(unit["seconds"], seconds)
        if "successor_feature_td" in summary and "pretraining_s" not in summary:
            untimed.add(part)
    rows = [("part", "runs", "units of work", "CPU-minutes")]
    for part, found in units.items():
        label = f"{part} (training only: its psi's TD was not timed)" if part in untimed else part
        rows.append((label, str(sum(u["runs"] for u in found.values())), str(len(found)),
                     f"{sum(u['seconds'] for u in found.values()) / 60:.0f}"))
    return render(rows, "markdown")


def sources(folder: str) -> str:
    """A suite's sources (``sources.json``) per group: how many met the success criterion, in how many frames."""
    listed = json.loads((ROOT / folder / "sources.json").read_text())
    rows = [("group", "sources", "met the success criterion", "frames trained (min, median, max)")]
    for group in sorted({key.split("/")[0] for key in listed}):
        mine = [e for key, e in listed.items() if key.startswith(f"{group}/")]
        frames = sorted(e["frames"] for e in mine)
        met = [e["met"] for e in mine if e["met"] is not None]
        rows.append((f"`{group}`", str(len(mine)), f"{sum(met)} of {len(met)}" if met else "no criterion (the budget)",
                     f"{frames[0]:,}, {frames[len(frames) // 2]:,}, {frames[-1]:,}"))
    return render(rows, "markdown")
REGIONS = {
    "README.md": {"demo": lambda: headlines("results/demo/report")},
    "results/README.md": {
        "demo-plan": demo_plan,
        "demo": lambda: headlines("results/demo/report"),
        "graded-table": lambda: table(f"{GRADED}/summary.md"),
        "graded-verdicts": lambda: headlines(GRADED),
        "grid-table": lambda: table("results/sweep-gridrooms/summary.md"),
        "grid-verdicts": lambda: headlines("results/sweep-gridrooms"),
        "options-table": lambda: table(f"{OPTIONS}/summary.md"),
        "options-k2-table": lambda: table(f"{OPTIONS}-k2/summary.md"),
        "options-verdicts": lambda: headlines(OPTIONS, f"{OPTIONS}-k2"),
        "options-head-to-head": lambda: verdicts(f"{OPTIONS}*/head-to-head/*"),
        "options-near": lambda: verdicts(f"{OPTIONS}*/fourrooms-near/*/model-reuse/report"),
        "options-far": lambda: verdicts(f"{OPTIONS}*/fourrooms-far/*/model-reuse/report"),
        "lift-variants": lambda: headlines("results/lift-demonstrations-variants"),
        "lift-dense-verdicts": lambda: headlines("results/lift-dense/vs-seed"),
        "lift-demonstrations-table": lambda: table("results/sweep-lift-demonstrations/summary.md"),
        "lift-demonstrations-verdicts": lambda: headlines("results/sweep-lift-demonstrations"),
        "lift-to-place-table": lambda: table("results/sweep-lift-to-place/summary.md"),
        "lift-to-place-verdicts": lambda: headlines("results/sweep-lift-to-place"),
        **BOARD, "pendulum-heavier": lambda: headlines(f"{BENCH}/pendulum"),
    },
    "docs/bench.md": {**BOARD, "bench-v2-sources": lambda: sources("results/bench/v2/quick/sources"),
                      **{f"bench-v2-{f}": lambda f=f: table(f"results/bench/v2/quick/board/{f}.md")
                         for f in ("ranking", "pairs")},
                      "bench-v2-costs": lambda: costs("results/bench/v2/quick")},
    "docs/tasks.md": {"tasks": lambda: tasks("rooms"), "tasks-robosuite": lambda: tasks("robosuite"),
                      "tasks-gym": lambda: tasks("gym"),
                      "lift-summary": lambda: headlines("results/sweep-lift-demonstrations/lift/sac/demonstrations",
                                                        "results/sweep-lift-to-place", "results/lift-dense/vs-seed")},
    "docs/training.md": {"config": config.describe},
    "docs/methods.md": {"methods": methods, "sf-psi": sf_psi},
    "docs/results.md": {"results-table": lambda: table(f"{GRADED}/aggregates.md"),
                        "results-verdicts": lambda: headlines(GRADED),
                        "results-others": lambda: headlines("results/sweep-gridrooms", f"{OPTIONS}/head-to-head",
                                                             f"{OPTIONS}-k2/head-to-head"),
                        "seed-rows": lambda: headlines("results/seed-tasks")},
    "results/seed-tasks/README.md": {"seed-rows": lambda: headlines("results/seed-tasks")},
    "results/manipulation/README.md": {
        "manipulation-rows": lambda: headlines(*(f"results/manipulation/{row}" for row in ROWS)),
        "manipulation-earlier": lambda: headlines("results/manipulation/earlier")},
}


def fill(text: str, regions: dict[str, str]) -> str:
    """``text`` with the body between ``<!-- claims:NAME -->`` and ``<!-- /claims:NAME -->`` replaced by
    ``regions[NAME]``; a missing or open marker is an error, as the prose would keep an old number."""
    for name, body in regions.items():
        start, end = f"<!-- claims:{name} -->\n", f"<!-- /claims:{name} -->"
        i = text.find(start)
        j = text.find(end, i + len(start)) if i >= 0 else -1
        if i < 0 or j < 0:
            raise ValueError(f"no region '{name}': add the lines '{start.strip()}' and '{end}' around it")
        text = text[:i + len(start)] + body.rstrip("\n") + "\n" + text[j:]
    return text


def main(argv: list[str]) -> int:
    drift = []
    for file, regions in REGIONS.items():
        text = (ROOT / file).read_text()
        new = fill(text, {name: make() for name, make in regions.items()})
        if new != text:
            drift.append(file)
            if "--check" not in argv:
                (ROOT / file).write_text(new)
    if "--check" in argv and drift:
        print(f"generated regions differ from the committed outputs in: {', '.join(drift)}; run python "
              "results/claims.py")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
