"""The manipulation study (``results/manipulation/``): its cost, sources, rows and placement diagnostics."""
from __future__ import annotations

import csv
import math
from pathlib import Path

import yaml

from drltg.analysis import claims as cl
from drltg.analysis import metrics as mx
from drltg.analysis.tables import estimate, render
from results.regions.common import (
    PRIMARY,
    RESULTS,
    ROOT,
    curve_table,
    ends,
    evals_at,
    load,
    said,
    seed_dirs,
    seed_number,
    tuned,
    whole_family,
)

MANIP = RESULTS / "manipulation"
ROW_SPECS = ROOT / "examples" / "sweeps" / "manipulation-rows"
WORKERS = 2


def _queue() -> tuple[list[str], dict[str, tuple[int, int]]]:
    """The queue's rows in order and its sources as ``{name: (runs, frames each)}``, read from queue.sh."""
    import re

    text = (MANIP / "queue.sh").read_text()
    rows = re.search(r'ROWS=\$\{ROWS:-"([^"]*)"\}', text).group(1).split()
    soc = int(re.search(r"SOC_FRAMES:-(\d+)", text).group(1))
    sac = int(re.search(r'\[lift-sac-ln-half\]="--frames (\d+)', text).group(1))
    seeds = len(re.search(r'SEEDS="([^"]*)"', text).group(1).split())
    return rows, {"lift-sac-ln-half": (seeds, sac), "lift-soc4": (seeds, soc)}


def run_rate(runs: Path = MANIP, pattern: str = "*/lift-to-place*/sac/**/seed-*/summary.json") -> tuple[float, int]:
    """The median frames/s (evaluations included) of the finished runs ``pattern`` finds under ``runs``
    (default: the rows' SAC runs on the placing targets kept so far, two at a time on this machine's 2 cores),
    and how many: a baseline kept by several rows (the same ``summary.json``) is one run."""
    import statistics

    runs_once = {p.read_bytes(): p for p in sorted(runs.glob(pattern))}
    rates = [load(p)["frames_per_s"] for p in runs_once.values()]
    return statistics.median(rates), len(rates)


def manipulation_cost() -> str:
    """results/manipulation/README.md's table of the study's one-command rows: what each adds in the queue's
    order (a target's baselines are trained by the first row that needs them) and its wall time on 2 cores at the
    measured rate."""
    rows, sources = _queue()
    fps, n = run_rate()
    soc_fps, soc_n = run_rate(MANIP / "sources" / "lift-soc4", "seed-*/summary.json")
    rate = {"lift-sac-ln-half": fps, "lift-soc4": soc_fps, "sac": fps, "soc": soc_fps}
    out = [("step", "command", "runs it adds × frames", "wall time on 2 cores")]
    hours = sum(k * f / rate[name] for name, (k, f) in sources.items()) / WORKERS / 3600
    out.append(("sources: " + ", ".join(f"`{name}` {k} × {cl.frames(f)}" for name, (k, f) in sources.items()),
                "`TRAIN_SOURCES=1 bash results/manipulation/queue.sh` (first step)",
                " + ".join(f"{k} × {cl.frames(f)}" for k, f in sources.values()), f"{hours:.1f} h"))
    total = hours
    seen = set()
    for row in rows:
        spec = yaml.safe_load((ROW_SPECS / f"{row}.yaml").read_text())
        script = (MANIP / f"{row}.sh").read_text()  # in RUNS/reference, with baselines of its own unless shared
        nested = "/reference exec" in script and "BASELINES=" not in script
        group = (nested, spec["pairs"][0], spec["algos"][0])
        k = spec["seeds"] * (1 if group in seen else 2)
        seen.add(group)
        h = math.ceil(k / WORKERS) * spec["frames"] / rate[spec["algos"][0]] / 3600
        total += h
        out.append((f"`{row}`", f"`bash results/manipulation/{row}.sh`", f"{k} × {cl.frames(spec['frames'])}",
                    f"{h:.1f} h"))
    return (render(out, "markdown") + f"\nWall time = ⌈runs / {WORKERS}⌉ × frames / rate (sources: all their frames / "
            f"({WORKERS} × rate)), at {fps:.1f} frames/s per run: the median of the {n} SAC runs of the rows "
            "kept so far (Lift+Place, two at a time on this machine's 2 cores, some beside other work, evaluations "
            "included); the soft option-critic's, "
            f"{soc_fps:.1f} frames/s, is the median of the {soc_n} kept `lift-soc4` source run{'s' * (soc_n != 1)} "
            "(Lift, two at a time): its update evaluates K option copies of every next state, and with demonstrations "
            f"the policy over options at each demonstrated state. All steps in the queue: about {total:.0f} h.\n")


SOURCE_THRESHOLD = 0.8


def _held(seeds: list[Path], threshold: float, column: str = "success_rate") -> tuple[int, str]:
    """How many of ``seeds`` hold ``column`` at or above ``threshold`` to their last evaluation (the
    report's sustained rule), and per seed from when or how low it fell over its second half."""
    held = []
    for p in seeds:
        ev = evals_at(p, column)
        frames, values = list(ev), list(ev.values())
        since = mx.sustained_time_to_threshold(frames, values, threshold)
        late = [v for f, v in ev.items() if f >= frames[-1] / 2]
        held.append(f"seed {p.name.split('-')[1]} " + (f"from {cl.frames(since)}" if since is not None else
                    f"does not, lowest {min(late):.1f} over the second half"))
    return sum("from" in h for h in held), "; ".join(held)


def manipulation_sources() -> str:
    """The kept sources' success rate over training, and per source how many seeds hold 0.8 to the end."""
    rows, lines = [], []
    for source in sorted(p for p in (MANIP / "sources").iterdir() if p.is_dir()):
        seeds = seed_dirs(source)
        rows += [(f"`{source.name}` seed {p.name.split('-')[1]}", [p]) for p in seeds]
        n, held = _held(seeds, SOURCE_THRESHOLD)
        last = max(max(evals_at(p, "success_rate")) for p in seeds)
        lines.append(f"- `{source.name}`: {n} of {len(seeds)} seeds {'holds' if n == 1 else 'hold'} a success rate "
                     f"≥ {SOURCE_THRESHOLD} to the end of {cl.frames(last)} frames ({held}).")
        lines += _best_evaluated(source.name, seeds)
    frames = sorted({f for _, (p,) in rows for f in evals_at(p, "success_rate")})
    lines.append(_how_strict(frames, episodes=int(load(seeds[0] / "summary.json")["final_eval"]["episodes"])))
    return curve_table(rows, "success_rate", frames, fmt=".1f") + "\n" + "\n".join(lines) + "\n"


def _how_strict(frames: list[float], episodes: int, p: float = 0.9, low: float = 0.3) -> str:
    """How often evaluations of ``episodes`` episodes make a policy whose true success rate is ``p`` miss
    the 0.8 rule over the second half of ``frames``, against how rarely they show ``low`` or less."""
    from scipy.stats import binom

    late = sum(f >= frames[-1] / 2 for f in frames)
    below = binom.cdf(math.ceil(SOURCE_THRESHOLD * episodes) - 1, episodes, p)
    deep = binom.cdf(math.floor(low * episodes), episodes, p)
    return (f"- How strict the rule is: an evaluation on {episodes} episodes of a policy whose true success rate "
            f"is {p} shows less than {SOURCE_THRESHOLD} with probability {below:.2f}, so at least one of {late} "
            f"second-half evaluations does with probability {1 - (1 - below) ** late:.2f}; it shows {low} or less "
            f"with probability {deep:.0e}. A fall to {low} or below means the policy changed, not the sample.")


def _best_evaluated(name: str, seeds: list[Path], threshold: float = SOURCE_THRESHOLD,
                    what: str = "the checkpoint the rows reuse, `best.pt`") -> list[str]:
    """The line on ``name``'s kept best checkpoints, evaluated on fresh episodes by queue.sh
    (``evaluate-best-*-50ep.json``), if any seed has one."""
    found = {p: sorted(p.glob("evaluate-best-*-50ep.json")) for p in seeds}
    if not any(found.values()):
        return []
    parts, n = [], 0
    for p, files in found.items():
        seed = p.name.split("-")[1]
        if not files:
            kept = (p / "checkpoints" / "best.pt").is_file()
            why = "not evaluated" if kept else "kept no best.pt: it was trained without keep_best"
            parts.append(f"seed {seed} {why}")
            continue
        r = load(files[0])
        lo, hi = r["success_rate_ci95"]
        n += r["success_rate"] >= threshold
        parts.append(f"seed {seed} {r['success_rate']:.2f} [{lo:.2f}, {hi:.2f}] at {cl.frames(r['frames'])}")
    episodes = load(next(f for files in found.values() for f in files))["episodes"]
    return [f"  - {what}, on {episodes} fresh episodes (95% Clopper-Pearson): "
            f"{n} of {len(seeds)} at or above {threshold} ({'; '.join(parts)})."]


def critic_scale() -> str:
    """The kept SAC sources' critics at the demonstrator's states against the ceiling 1 / (1 - gamma)
    (``results/manipulation/sources/critic_scale.csv``), and which of them dipped."""
    rows = list(csv.DictReader((MANIP / "sources" / "critic_scale.csv").open()))
    table = [("run", "Q(s, a) at demonstrated steps", "Q(s, μ(s))", "ceiling", "final success",
              "lowest success, second half")]
    table += [(f"`{r['source']}` seed {r['seed']}", r["q_demonstrated"], r["q_actor"], r["ceiling"],
               f"{float(r['final_success']):.1f}", f"{float(r['lowest_success_second_half']):.1f}") for r in rows]

    def name(r):
        return f"`{r['source']}` seed {r['seed']}"

    over = [r for r in rows if float(r["q_demonstrated"]) > float(r["ceiling"])]
    under = [r for r in rows if r not in over]

    def dipped(group):
        return [r for r in group if float(r["lowest_success_second_half"]) < SOURCE_THRESHOLD]

    def listed(group):
        return ", ".join(f"{name(r)} (Q {float(r['q_demonstrated']):.0f}, lowest "
                         f"{float(r['lowest_success_second_half']):.1f})" for r in group) or "none"

    sentence = (f"{len(over)} of {len(rows)} SAC sources end with critics that value the demonstrator's states "
                f"above the ceiling, {len(dipped(over))} of them dipping below {SOURCE_THRESHOLD} over the second "
                f"half: {listed(over)}. Of the {len(under)} below it, {len(dipped(under))} dipped as well: "
                f"{listed(dipped(under))}; {listed([r for r in under if r not in dipped(under)])} did not.")
    return render(table, "markdown") + "\n" + sentence + "\n"


PLACE_THRESHOLD = 0.5


def _shared_baselines() -> dict[tuple[str, str], tuple[list[str], list[Path]]]:
    """Per placing target and learner, the rows whose kept baselines are its baselines, and one kept run per
    seed: the rows on one target share them (``row.sh``), so a seed kept by two rows must be the same curve."""
    shared: dict[tuple[str, str], tuple[list[str], dict[str, Path]]] = {}
    for side in sorted(MANIP.glob("*/lift-to-place*/*/baseline")):
        row, pair, algo = side.relative_to(MANIP).parts[:3]
        rows, seeds = shared.setdefault((pair, algo), ([], {}))
        rows.append(row)
        for run in seed_dirs(side):
            first = seeds.setdefault(run.name, run)
            if (first / "eval.csv").read_bytes() != (run / "eval.csv").read_bytes():
                raise ValueError(f"{first} and {run} should be one baseline run, kept twice, but their curves differ.")
    return {key: (rows, sorted(seeds.values(), key=seed_number))
            for key, (rows, seeds) in shared.items()}


def manipulation_placing() -> str:
    """The study's finished runs on the placing targets, kept so far whether or not their row is complete:
    success rate (the cube resting on the target) over training, and per row and side how many seeds
    hold 0.5 to the end; then the measurements beside the rows (``results/manipulation/measurements/NAME``)."""
    groups = []  # (name in the table, name in its line, seeds)
    for (pair, algo), (rows, seeds) in sorted(_shared_baselines().items()):
        named = ", ".join(f"`{row}`" for row in rows)
        side = "no transfer" if algo == "sac" else f"{algo}, no transfer"  # SAC: every row but SOC's
        groups.append((f"`{pair}`, {side}", f"`{pair}`, {side} (the baselines of {named})", seeds))
    for side in sorted(MANIP.glob("*/lift-to-place*/*/*/transfer")):
        row, pair = side.relative_to(MANIP).parts[:2]
        groups.append((f"`{row}`, {side.parent.name}", f"`{row}` ({pair}), {side.parent.name}", seed_dirs(side)))
    for measured in sorted(p for p in (MANIP / "measurements").glob("*") if p.is_dir()):
        seeds = seed_dirs(measured)
        task = yaml.safe_load((seeds[0] / "config.yaml").read_text())["task"] if seeds else ""
        groups.append((f"`measurements/{measured.name}`", f"`measurements/{measured.name}` ({task})", seeds))
    rows, lines = [], []
    for name, line, seeds in groups:
        if not seeds:
            continue
        rows += [(f"{name}, seed {p.name.split('-')[1]}", [p]) for p in seeds]
        n, held = _held(seeds, PLACE_THRESHOLD)
        last = max(max(evals_at(p, "success_rate")) for p in seeds)
        lines.append(f"- {line}: {n} of {len(seeds)} finished seeds {'holds' if n == 1 else 'hold'} "
                     f"a success rate ≥ {PLACE_THRESHOLD} to the end of {cl.frames(last)} frames ({held}).")
        lines += _best_evaluated(name, seeds, PLACE_THRESHOLD, "its best checkpoint, `best.pt`")
    if not rows:
        return "No run on a placing target has finished yet.\n"
    frames = sorted({f for _, (p,) in rows for f in evals_at(p, "success_rate")})
    return curve_table(rows, "success_rate", frames, fmt=".1f") + "\n" + "\n".join(lines) + "\n"


FALLEN_BELOW = -0.01
"""m: a cube whose centre ends below the target's (which rests on the table) has left the table."""


def _off_table(row: dict) -> bool:
    return float(row["height_m"]) < FALLEN_BELOW


def manipulation_collapse() -> str:
    """Where the cube is at the end of each kept measurement's episodes, at ``best.pt`` and at ``last.pt``
    (``results/manipulation/measurements/NAME/collapse.csv``, written by ``collapse.py``)."""
    out = [("run", "checkpoint", "placed at the end", "ever lifted", "held at the end", "off the table",
            "steps placed (mean)", "gap to the demonstrator's action", "min Q at its states")]
    lines = []
    for path in sorted((MANIP / "measurements").glob("*/collapse.csv")):
        rows = list(csv.DictReader(path.open()))
        demo = path.with_name("demonstrated.csv")
        gaps = {(int(r["seed"]), r["checkpoint"]): r for r in csv.DictReader(demo.open())} if demo.is_file() else {}
        seeds = sorted({int(r["seed"]) for r in rows})
        fewer, unplaced = [], []
        for seed in seeds:
            placed = {}
            for checkpoint in ("best", "last"):
                rs = [r for r in rows if int(r["seed"]) == seed and r["checkpoint"] == checkpoint]
                n = len(rs)
                count = {k: sum(int(r[k]) for r in rs) for k in ("placed", "lifted", "grasped")}
                fallen = sum(map(_off_table, rs))
                out.append((f"`measurements/{path.parent.name}` seed {seed}",
                            f"`{checkpoint}.pt` ({cl.frames(int(rs[0]['frames']))})",
                            f"{count['placed']}/{n}", f"{count['lifted']}/{n}", f"{count['grasped']}/{n}",
                            f"{fallen}/{n}", f"{sum(int(r['steps_placed']) for r in rs) / n:.0f}",
                            *((f"{float(g['action_gap']):.3f}", f"{float(g['q_demonstrated']):.0f}")
                              if (g := gaps.get((seed, checkpoint))) else ("—", "—"))))
                placed[checkpoint] = count["placed"]
                if checkpoint == "last":
                    unplaced += [r for r in rs if not int(r["placed"])]
            if placed["last"] < placed["best"]:
                fewer.append(seed)
        fallen = sum(map(_off_table, unplaced))
        held = sum(bool(int(r["grasped"])) and not _off_table(r) for r in unplaced)
        rest = [r for r in unplaced if not int(r["grasped"]) and not _off_table(r)]
        away = (f" ({100 * sum(float(r['distance_m']) for r in rest) / len(rest):.0f} cm from the target's centre "
                "on average)" if rest else "")
        lines.append(f"- `measurements/{path.parent.name}`: at `last.pt` {len(fewer)} of {len(seeds)} seeds place "
                     f"in fewer episodes than at `best.pt`"
                     + (f" (seed{'s' * (len(fewer) > 1)} {', '.join(map(str, fewer))})" if fewer else "")
                     + f"; of the {len(unplaced)} episodes that end unplaced at `last.pt`, the cube is off the table "
                     f"in {fallen}, held in the gripper in {held} and resting on the table in {len(rest)}{away}.")
        if gaps:
            lines.append(f"  - at the demonstrator's own states ({_demo_episodes()} seeded episodes), the actor's mean "
                         "absolute gap to its action (each dimension in [−1, 1]) is "
                         + " and ".join(f"{_span(gaps, c, 'action_gap', '.3f')} at `{c}.pt`" for c in ("best", "last"))
                         + "; the smaller critic values those states at "
                         + " and ".join(f"{_span(gaps, c, 'q_demonstrated', '.0f')} at `{c}.pt`"
                                        for c in ("best", "last"))
                         + " (the ceiling 1 / (1 − γ) is 100).")
    if not lines:
        return "No measurement has a collapse.csv yet.\n"
    return render(out, "markdown") + "\n" + "\n".join(lines) + "\n"


def _span(rows: dict, checkpoint: str, key: str, fmt: str) -> str:
    """``a–b``: the smallest and largest ``key`` over the seeds at ``checkpoint`` (``a`` when they agree)."""
    values = sorted(float(r[key]) for (_, c), r in rows.items() if c == checkpoint)
    low, high = format(values[0], fmt), format(values[-1], fmt)
    return low if low == high else f"{low}–{high}"


def _demo_episodes() -> int:
    import re

    text = (RESULTS / "manipulation" / "measurements" / "collapse.py").read_text()
    return int(re.search(r"^DEMO_EPISODES = (\d+)$", text, re.M).group(1))


EARLIER = MANIP / "earlier"


def _row_report(row: str, tag: str = "success") -> dict | None:
    """The study's report of ``row`` on ``tag`` (``results/manipulation/ROW/PAIR/ALGO/METHOD/report-TAG/``)."""
    found = sorted((MANIP / row).glob(f"*/*/*/report-{tag}/transfer_metrics.json"))
    return load(found[0]) if found else None


def manipulation_rows() -> str:
    """One line per reported row, in the queue's order: the transfer side's gain over no transfer in mean
    success rate over the budget (the area under the curve per frame, paired by seed), and on the placing
    targets in lifted rate; the gains are read in the family of every test of the row's reports, Holm-adjusted
    (:func:`whole_family`). Where any seed holds the
    report's success threshold to the end (its sustained rule), how many on each side do."""
    lines, queue = [], _queue()[0]
    for row in queue:
        reports = {tag: r for tag in ("success", "lifted") if (r := _row_report(row, tag)) is not None}
        if "success" not in reports:
            continue
        adjusted = whole_family(reports)
        m, st = reports["success"]["metrics"], reports["success"]["settings"]
        gains = "; ".join(f"{tag} rate {said(r, PRIMARY, adjusted.get(tag))}{ends(r)}"
                          for tag, r in reports.items())
        size = next(iter(adjusted.values())).size if adjusted else 0
        gains += (f" (Holm over all {size} test{'s' if size != 1 else ''} of its {len(reports)} "
                  f"report{'s' if len(reports) > 1 else ''})")
        held = {side: round(m[f"threshold_reached_{side}"] * m[f"n_seeds_{side}"]) for side in ("transfer", "baseline")}
        if any(held.values()):
            gains += (f"; success rate ≥ {st['threshold']:g} held to the end by {held['transfer']} of "
                      f"{m['n_seeds_transfer']} seeds with transfer and {held['baseline']} of {m['n_seeds_baseline']} "
                      "without")
        never = [side for side in ("baseline", "transfer") if m[f"total_reward_{side}"] == 0]
        what = "placed" if st["task"] != "lift" else "lifted"
        if never:
            side = {"baseline": "without transfer", "transfer": "with transfer"}
            who = "on either side" if len(never) == 2 else side[never[0]]
            gains += f"; no run {who} {what} a cube in any evaluation"
        gains += tuned(row, reports["success"])
        lines.append(f"- `{row}` ({st['task']}, {st['transfer_label']} against {st['baseline_label']}, "
                     f"{m['n_seeds_transfer']} paired seeds × {cl.frames(st['budget'])} frames), mean gain in {gains}.")
    if not lines:
        return "No row of the queue is complete yet (the runs finished so far are below).\n"
    left = len(queue) - len(lines)
    return "\n".join(lines) + "\n" + (f"{left} of the queue's {len(queue)} rows are not complete yet (the runs "
                                     "finished so far are below).\n" if left else "")


def manipulation_earlier() -> str:
    """The earlier implementation's rows (one run a side, its own reward) beside the study's (3 paired seeds)."""
    out = [("row", "earlier runs: no transfer → transfer", "frames", "final return, B / T", "mean return gain",
            "gain at 100k frames", "drltg: mean success-rate gain, 3 paired seeds")]
    order = _queue()[0]
    for folder in sorted((p for p in EARLIER.iterdir() if p.is_dir()), key=lambda p: order.index(p.name)):
        whole, cut = load(folder / "transfer_metrics.json"), load(folder / "at-100k" / "transfer_metrics.json")
        m, st = whole["metrics"], whole["settings"]
        ours = _row_report(folder.name)
        mine = ("not trained yet" if ours is None else
                estimate(ours["metrics"]["mean_return_gain"], ours["metrics"].get("mean_return_gain_ci"),
                         lambda x: format(x if round(x, 2) else 0.0, "+.2f")))  # no "-0.00"
        out.append((f"`{folder.name}`", f"`{Path(st['baseline'][0]).parent.name}` → "
                    f"`{Path(st['transfer'][0]).parent.name}`", cl.frames(st["budget"]),
                    f"{m['final_performance_baseline']:.0f} / {m['final_performance_transfer']:.0f}",
                    estimate(m["mean_return_gain"], None, "+.1f"),
                    estimate(cut["metrics"]["mean_return_gain"], None, "+.1f"), mine))
    return render(out, "markdown")


PLACEMENT = MANIP / "placement-diagnostics"


def placement_noise() -> str:
    s = load(PLACEMENT / "summary.json")
    out = [("task", *(f"σ = {r['sigma']:g}" for r in s["noise"] if r["task"] == "lift-place"))]
    for task in ("lift-place", "lift-place-barrier"):
        cells = [f"lifted {r['lifted']}/{r['episodes']}, placed {r['placed']}/{r['episodes']}, "
                 f"return {r['return_mean']:.0f}" for r in s["noise"] if r["task"] == task]
        out.append((task, *cells))
    return render(out, "markdown")


def source_noise() -> str:
    """The learned Lift sources as noisy demonstrators on lift-place (``source_noise.py``)."""
    with open(PLACEMENT / "source-noise.csv") as f:
        rows = list(csv.DictReader(f))
    sigmas = sorted({float(r["sigma"]) for r in rows})
    sources = sorted({r["source"] for r in rows}, key=lambda name: int(name.rsplit("-", 1)[1]))
    cell = {(r["source"], float(r["sigma"])): f"{r['lifted']}/{r['episodes']}" for r in rows}
    table = [("source (best.pt)", *(f"σ = {x:g}" for x in sigmas))]
    table += [(f"`{name}`", *(cell[name, x] for x in sigmas)) for name in sources]
    total = {x: (sum(int(r["lifted"]) for r in rows if float(r["sigma"]) == x),
                 sum(int(r["episodes"]) for r in rows if float(r["sigma"]) == x)) for x in sigmas}
    low, high = sigmas[0], sigmas[-1]
    scripted = next(r for r in load(PLACEMENT / "summary.json")["noise"]
                    if r["task"] == "lift-place" and r["sigma"] == high)
    return (render(table, "markdown").rstrip() + f"\n\nThe learned sources lift the cube in {total[low][0]} of "
            f"{total[low][1]} episodes without noise and in {total[high][0]} of {total[high][1]} at σ = {high:g}, "
            f"where the scripted demonstrator places in {scripted['placed']} of {scripted['episodes']} "
            "(the table above).")


SHAPING = MANIP / "shaping-diagnostics"


def shaping_stages() -> str:
    """The ``lift-shaping`` row's final policies on Lift, stage by stage (``stages.py``)."""
    with open(SHAPING / "stages.csv") as f:
        rows = list(csv.DictReader(f))
    table = [("side", "seed", "start (m)", "closest (m)", "mean (m)", "steps grasped", "grasped", "lifted")]
    table += [(r["side"], r["seed"], r["start_m"], r["closest_m"], r["mean_m"], r["grasped_share"],
               f"{r['grasped']}/{r['episodes']}", f"{r['lifted']}/{r['episodes']}") for r in rows]
    sides: dict[str, list[dict]] = {}
    for r in rows:
        sides.setdefault(r["side"], []).append(r)
    parts = []
    for side, runs in sides.items():
        mean = {k: sum(float(r[k]) for r in runs) / len(runs) for k in ("start_m", "closest_m", "mean_m")}
        episodes = sum(int(r["episodes"]) for r in runs)
        closer = sum(float(r["closest_m"]) < float(r["start_m"]) - 0.01 for r in runs)
        parts.append(f"{side} ({len(runs)} seeds), the gripper comes {mean['start_m'] - mean['closest_m']:.3f} m "
                     f"closer to the cube than where it starts ({mean['start_m']:.3f} m) on average, more than "
                     f"1 cm closer in {closer} of {len(runs)} runs, and averages {mean['mean_m']:.2f} m from it; "
                     f"the cube is grasped in {sum(int(r['grasped']) for r in runs)} and lifted in "
                     f"{sum(int(r['lifted']) for r in runs)} of {episodes} episodes")
    return render(table, "markdown").rstrip() + "\n\nAt the last checkpoint, " + "; ".join(parts) + ".\n"


def placement_verdicts() -> str:
    s = load(PLACEMENT / "summary.json")
    p, h, phi = s["place_demonstrator"], s["lift_demonstrator_on_lift_place"], s["phi_states"]
    gain = phi["resting_on_target"] - phi["held_above_target"]
    release = "does not pay the release" if gain <= 0 else f"pays the release {gain:.2f}"
    lines = [
        f"- The sparse reward pays placing and nothing else: on one noise-free episode (seed 0) the place "
        f"demonstrator grasps at step {p['first_grasped']}, lifts at {p['first_lifted']}, places at "
        f"{p['first_placed']} and earns {p['return']:.0f} (discounted, γ = {s['gamma']}: "
        f"{p['discounted_return']:.1f}); the Lift demonstrator on the same task grasps at {h['first_grasped']}, "
        f"lifts at {h['first_lifted']}, holds the cube up to the end and earns {h['return']:.0f}. A hold is not paid "
        "like a placement, so the reward does not hold a learner at lifting; it pays nothing until a carry and a "
        "release, which the Lift source never shows, have been found.",
        f"- The registered shaping potential {release}: Φ is {phi['held_above_target']:.2f} with the "
        f"cube held 5 cm above the target's centre and {phi['resting_on_target']:.2f} with it released on the "
        f"target; along the episode Φ goes from {p['phi_start']:.2f} to {p['phi_end']:.2f} for the place "
        f"demonstrator and to {h['phi_end']:.2f} for the Lift demonstrator (the cube lifted, away from the target). "
        "Under `reward-shaping` only the sparse term tells a carry-and-hold from a placement.",
    ]
    parts = []
    for task in ("lift-place", "lift-place-barrier"):
        cells = [r for r in s["noise"] if r["task"] == task]
        every = [r["sigma"] for r in cells if r["placed"] == r["episodes"]]
        none = [r["sigma"] for r in cells if r["placed"] == 0]
        parts.append(f"on {task} it places in every episode up to σ = {max(every):g}" if every else
                     f"on {task} it never places in every episode")
        if none:
            lifted = sum(r["lifted"] for r in cells if r["sigma"] >= min(none))
            parts[-1] += f" and in none from σ = {min(none):g} (lifting in {lifted} of those episodes)"
    lines.append("- With Gaussian action noise (the table above), " + "; ".join(parts) + ".")
    return "\n".join(lines) + "\n"
