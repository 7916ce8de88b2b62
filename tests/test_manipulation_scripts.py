"""The manipulation study's scripts plan what they say, without training: one sweep spec per row, each
transfer run reusing the kept source run of its own seed, >= 3 paired seeds, <= 300k frames, one
baseline per target shared by every row on it, and a queue that trains the sources it names first."""
from __future__ import annotations

import os
import re
import subprocess
from pathlib import Path

import pytest

from drltg.config import config_changes
from drltg.experiments.experiment import plan_runs
from drltg.experiments.sweep import load_spec, plan

ROOT = Path(__file__).resolve().parents[1]
SCRIPTS = ROOT / "results" / "manipulation"
SPECS = ROOT / "examples" / "sweeps" / "manipulation-rows"
ROWS = sorted(p.stem for p in SCRIPTS.glob("*.sh") if p.stem not in ("row", "queue", "earlier"))
SOURCED = re.compile(r"runs/manipulation/sources/([\w-]+)/seed-\{seed\}")


def runs_of(row: str) -> Path:
    """Where a row's runs go: the reference rows, whose method folder another row also uses, in their own."""
    nested = "/reference exec" in (SCRIPTS / f"{row}.sh").read_text()
    return ROOT / "runs" / "manipulation" / ("reference" if nested else "")


def queue_sources() -> set[str]:
    return set(re.findall(r"^\s+\[([\w-]+)\]=", (SCRIPTS / "queue.sh").read_text(), re.M))


def test_every_script_parses_and_every_row_has_its_spec_and_a_place_in_the_queue():
    for script in SCRIPTS.glob("*.sh"):
        subprocess.run(["bash", "-n", str(script)], check=True)
    assert ROWS == sorted(p.stem for p in SPECS.glob("*.yaml"))
    for row in ROWS:
        assert (SCRIPTS / f"{row}.sh").read_text().rstrip().endswith(f'row.sh" {row}')
    queued = re.search(r'ROWS=\$\{ROWS:-"([^"]*)"\}', (SCRIPTS / "queue.sh").read_text()).group(1).split()
    assert sorted(queued) == ROWS
    assert queue_sources() == {"lift-sac-ln-half", "lift-soc4"}


@pytest.mark.parametrize("row", ROWS)
def test_each_row_reuses_the_kept_source_of_its_own_seed(row, monkeypatch):
    monkeypatch.chdir(ROOT)  # the scripts run from the repository root
    spec = load_spec(SPECS / f"{row}.yaml")
    assert spec.seeds >= 3 and max(spec.frames) <= 300_000 and len(spec.pairs) == len(spec.methods) == 1
    source = spec.overrides.get("transfer.source")
    runs, cells = plan(spec, runs_of(row))
    assert len(cells) == 1 and len(runs) == 2 * spec.seeds  # baselines and transfers, no source trained here
    transfers = [r for r in runs if r.role == "transfer"]
    for run in transfers:
        if source is None or source.startswith("demonstrator:"):  # reward shaping; the scripted reference
            assert run.cfg.transfer.source == source
            continue
        name = SOURCED.fullmatch(source).group(1)
        assert name in queue_sources()
        kept = ROOT / "runs" / "manipulation" / "sources" / name / f"seed-{run.cfg.seed}"
        assert run.cfg.transfer.source == str(kept)
        assert run.cfg.transfer.source_checkpoint == "best"  # what queue.sh evaluates and keeps
    assert [r.cfg.seed for r in transfers] == [100 * i for i in range(spec.seeds)]
    if source is None or "{seed}" in source:  # the baselines of every row on the target, whatever its source
        assert all(r.cfg.transfer.source is None for r in runs if r.role == "baseline")


def test_rows_on_one_target_share_its_baselines():
    seen: dict[Path, dict] = {}
    for row in ROWS:
        runs, _ = plan(load_spec(SPECS / f"{row}.yaml"), runs_of(row))
        for r in runs:
            if r.role == "baseline":
                assert config_changes(seen.setdefault(r.path, r.cfg), r.cfg) == [], r.path
    groups = {p.parent.relative_to(ROOT / "runs" / "manipulation").as_posix() for p in seen}
    assert groups == {"lift/sac/baseline", "lift-to-place/sac/baseline", "lift-to-place/soc/baseline",
                      "lift-to-place-barrier/sac/baseline", "reference/lift-to-place/sac/baseline",
                      "reference/lift-to-place-barrier/sac/baseline"}
    reference = ROOT / "runs" / "manipulation" / "reference"
    copies = [path for path in seen if path.is_relative_to(reference)]
    assert len(copies) == 6
    for path in copies:  # the reference rows' baselines are copies of the others' (BASELINES in row.sh)
        assert config_changes(seen[ROOT / "runs" / "manipulation" / path.relative_to(reference)], seen[path]) == []


def test_a_row_with_baselines_elsewhere_copies_the_complete_ones_it_lacks(tmp_path):
    """row.sh with BASELINES=DIR copies DIR's complete baselines of its group (config, curve, summary) into
    RUNS before its sweep, and leaves an unfinished one and one RUNS already holds alone."""
    shared, runs = tmp_path / "shared" / "lift-to-place" / "sac" / "baseline", tmp_path / "runs"
    for seed in (0, 100, 200):
        (shared / f"seed-{seed}").mkdir(parents=True)
        for name in ("config.yaml", "eval.csv", "summary.json"):
            if not (seed == 200 and name == "summary.json"):  # seed 200 has not finished
                (shared / f"seed-{seed}" / name).write_text(f"{name} {seed}")
    mine = runs / "lift-to-place" / "sac" / "baseline" / "seed-100"
    mine.mkdir(parents=True)
    env = {**os.environ, "RUNS": str(runs), "BASELINES": str(tmp_path / "shared"), "DRLTG": "false", "FORCE": "1"}
    done = subprocess.run(["bash", str(SCRIPTS / "row.sh"), "demonstrations-reference-place"], cwd=ROOT, env=env,
                          capture_output=True)
    assert done.returncode != 0  # DRLTG=false: the sweep after the copies fails
    copied = runs / "lift-to-place" / "sac" / "baseline"
    assert sorted(p.name for p in (copied / "seed-0").iterdir()) == ["config.yaml", "eval.csv", "summary.json"]
    assert (copied / "seed-0" / "eval.csv").read_text() == "eval.csv 0"
    assert not list(mine.iterdir()) and not (copied / "seed-200").exists()


def test_a_source_written_with_seed_serves_each_transfer_run_from_its_own_seed(tmp_path):
    runs = plan_runs("fourrooms/northeast-shifted", "model-reuse", frames=100, out=tmp_path, seeds=3, seed=7,
                     overrides=["transfer.source=kept/seed-{seed}"])
    got = [(role, cfg.seed, cfg.transfer.source) for role, cfg, _ in runs]
    kept = Path.cwd() / "kept"
    assert got == [("baseline", 7, None), ("transfer", 7, str(kept / "seed-7")),
                   ("baseline", 107, None), ("transfer", 107, str(kept / "seed-107")),
                   ("baseline", 207, None), ("transfer", 207, str(kept / "seed-207"))]
    # a source without {seed} serves every transfer run; the baselines have none either way
    runs = plan_runs("fourrooms/northeast-shifted", "model-reuse", frames=100, out=tmp_path, seeds=2,
                     overrides=["transfer.source=kept/one"])
    assert {(role, cfg.transfer.source) for role, cfg, _ in runs} == {("baseline", None),
                                                                             ("transfer", "kept/one")}


@pytest.mark.parametrize("row", [r for r in ROWS if "model-reuse" in load_spec(SPECS / f"{r}.yaml").methods[0]])
def test_the_rows_that_reuse_weights_build_the_learner_of_their_kept_source(row, monkeypatch):
    """Model reuse loads the kept source's best.pt whole (no partial load): each such row's transfer
    learner has its source's networks, LayerNorm included, on the target task."""
    pytest.importorskip("robosuite")
    from drltg.envs import make_env
    from drltg.learners import make_agent
    from drltg.transfer.model_reuse import load_from_run

    monkeypatch.chdir(ROOT)
    spec = load_spec(SPECS / f"{row}.yaml")
    run = next(r for r in plan(spec, runs_of(row))[0] if r.role == "transfer")
    kept = SCRIPTS / "sources" / SOURCED.fullmatch(spec.overrides["transfer.source"]).group(1) / f"seed-{run.cfg.seed}"
    env = make_env(run.cfg.task, **run.cfg.env)
    report = load_from_run(make_agent(env, run.cfg).loss, kept, checkpoint="best")
    env.close()
    assert not (report.widened or report.narrowed or report.skipped), report.summary()


def test_a_soc_lift_learner_hands_every_weight_to_a_soc_lift_place_learner():
    """The soft option-critic row: SOC-4's weights on lift fit its learner on lift-place entry for entry
    (the tasks share one observation layout), so model reuse copies them all."""
    pytest.importorskip("robosuite")
    import torch

    from drltg.config import resolve
    from drltg.envs import make_env
    from drltg.learners import make_agent
    from drltg.modules import load_weights

    agents = []
    for seed, task in enumerate(("lift", "lift-place")):
        torch.manual_seed(seed)
        env = make_env(task)
        agents.append(make_agent(env, resolve(task=task, algo="soc", overrides=["soc.num_options=4"])))
        env.close()
    source, target = agents
    report = load_weights(target.loss, source.loss.state_dict())
    assert not (report.widened or report.narrowed or report.skipped or report.unused)
    state = target.loss.state_dict()
    assert state.keys() == source.loss.state_dict().keys()
    for name, value in source.loss.state_dict().items():
        assert torch.equal(state[name], value), name


def test_rebuild_keeps_only_the_rows_runs_and_their_relative_source(tmp_path):
    """row.sh's `rebuild.py --only`: the row's baselines, transfers and source runs are copied in the runs'
    layout, another row's are not, and a source path relative to the run still names the kept source."""
    import importlib.util

    import yaml

    spec = importlib.util.spec_from_file_location("rebuild", ROOT / "results" / "rebuild.py")
    rebuild = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(rebuild)
    runs, kept = tmp_path / "runs", tmp_path / "kept"
    relative = "../../../../../sources/lift-sac/seed-0"
    for folder, source in (("p/sac/baseline/seed-0", None), ("p/sac/m/transfer/seed-0", relative),
                           ("p/sac/other/transfer/seed-0", relative), ("sources/lift-sac/seed-0", None),
                           ("sources/lift-soc4/seed-0", None)):
        (runs / folder).mkdir(parents=True)
        (runs / folder / "config.yaml").write_text(yaml.safe_dump({"transfer": {"source": source}}))
        (runs / folder / "eval.csv").write_text("frames,return_mean\n0,0.0\n")
        (runs / folder / "summary.json").write_text("{}")
    assert rebuild.keep_curves(runs, kept, ["p/sac/baseline", "p/sac/m", "sources/lift-sac"]) == 3
    assert sorted(str(p.parent.relative_to(kept)) for p in kept.rglob("summary.json")) == [
        "p/sac/baseline/seed-0", "p/sac/m/transfer/seed-0", "sources/lift-sac/seed-0"]
    transfer = kept / "p/sac/m/transfer/seed-0"
    assert yaml.safe_load((transfer / "config.yaml").read_text())["transfer"]["source"] == relative
    assert (transfer / relative / "eval.csv").is_file()


def test_keep_source_keeps_the_weights_and_refuses_an_unfinished_run(tmp_path):
    import sys

    import torch

    from drltg.errors import UsageError
    sys.path.insert(0, str(SCRIPTS))
    from keep_source import keep_source

    run = tmp_path / "run"
    (run / "checkpoints").mkdir(parents=True)
    for name in ("config.yaml", "eval.csv"):
        (run / name).write_text(name)
    weights = {"actor.weight": torch.arange(6.0).reshape(2, 3)}
    torch.save({"loss": weights, "frames": 60000, "buffer": torch.zeros(1000), "optimizer": {}},
               run / "checkpoints" / "last.pt")
    with pytest.raises(UsageError, match="no summary.json"):
        keep_source(run, tmp_path / "kept")
    (run / "summary.json").write_text("{}")
    keep_source(run, tmp_path / "kept")
    kept = torch.load(tmp_path / "kept" / "checkpoints" / "last.pt", weights_only=True)
    assert set(kept) == {"loss", "frames"} and kept["frames"] == 60000
    assert torch.equal(kept["loss"]["actor.weight"], weights["actor.weight"])
    assert (tmp_path / "kept" / "config.yaml").read_text() == "config.yaml"
    assert not (tmp_path / "kept" / "checkpoints" / "best.pt").exists()  # a run without keep_best has none

    best = {"actor.weight": -torch.arange(6.0).reshape(2, 3)}
    torch.save({"loss": best, "frames": 25000, "buffer": torch.zeros(1000), "optimizer": {}},
               run / "checkpoints" / "best.pt")
    keep_source(run, tmp_path / "kept-best")
    kept = torch.load(tmp_path / "kept-best" / "checkpoints" / "best.pt", weights_only=True)
    assert set(kept) == {"loss", "frames"} and kept["frames"] == 25000
    assert torch.equal(kept["loss"]["actor.weight"], best["actor.weight"])
    last = torch.load(tmp_path / "kept-best" / "checkpoints" / "last.pt", weights_only=True)
    assert last["frames"] == 60000 and torch.equal(last["loss"]["actor.weight"], weights["actor.weight"])


@pytest.mark.parametrize("seed", [0, 100, 200])
def test_kept_lift_sources_are_weights_only_and_load_as_actors(seed):
    import torch

    from drltg.transfer import load_actor
    source = SCRIPTS / "sources" / "lift-sac-ln-half" / f"seed-{seed}"
    assert set(torch.load(source / "checkpoints" / "last.pt", weights_only=True)) == {"loss", "frames"}
    actor = load_actor(source)
    assert sum(p.numel() for p in actor.parameters()) > 0


def resolve_args(task: str, line: str, **kwargs):
    """The config ``drltg train TASK`` resolves from the flags of a script's ``line``."""
    import shlex

    from drltg.config import resolve

    args, overrides = shlex.split(line), []
    for flag, value in zip(args[::2], args[1::2]):
        if flag == "-o":
            overrides.append(value)
        elif flag == "--options":
            overrides.append(f"soc.num_options={value}")
        else:
            kwargs[flag.removeprefix("--")] = int(value) if flag == "--frames" else value
    return resolve(task=task, overrides=overrides, **kwargs)


def test_the_soc_source_learns_lift_from_the_same_demonstrations_as_the_sac_source():
    """lift-soc4's config is lift-sac-ln-half's but for the learner and the SAC critics' stabilisers
    (LayerNorm, half of every batch demonstrated): the same demonstrator, episodes, cloning weight and frames."""
    import shlex

    from drltg.config import resolve

    text = (SCRIPTS / "queue.sh").read_text()
    text = text.replace("$SOC_FRAMES", re.search(r"SOC_FRAMES:-(\d+)", text).group(1))
    configs = {name: resolve_args("lift", line) for name, line in re.findall(r'^\s+\[([\w-]+)\]="([^"]*)"', text, re.M)}
    sac, soc = configs["lift-sac-ln-half"], configs["lift-soc4"]
    assert config_changes(sac, soc) == ["algo", "network.layer_norm", "transfer.demo_ratio"]
    kept = resolve(task="lift", overrides=shlex.split(re.search(r'^EVAL="([^"]*)"', text, re.M).group(1))[1::2])
    assert kept.checkpoint.keep_best  # best.pt, which the rows reuse
    assert (soc.algo, soc.soc.num_options, soc.frames) == ("soc", 4, 60_000)
    assert (soc.transfer.method, soc.transfer.source) == ("demonstrations", "demonstrator:lift")


def test_the_kept_measurements_are_the_runs_their_scripts_train():
    """Each kept run in results/manipulation/measurements/NAME/ has the config NAME.sh trains for its seed
    (so the script reproduces it), and its best checkpoint is kept and evaluated; a measurement's seeds
    (0, 100, 200) are kept as they finish."""
    import yaml

    subprocess.run(["bash", "-n", str(SCRIPTS / "measurements" / "measure.sh")], check=True)
    scripts = sorted(p for p in (SCRIPTS / "measurements").glob("*.sh") if p.stem != "measure")
    kept_any = False
    for script in scripts:
        subprocess.run(["bash", "-n", str(script)], check=True)
        text = script.read_text()
        assert re.search(r"^NAME=([\w-]+)$", text, re.M).group(1) == script.stem
        assert text.rstrip().endswith('. "$(dirname "$0")/measure.sh"')
        task = re.search(r"^TASK=([\w-]+)$", text, re.M).group(1)
        line = " ".join(re.search(r'^ARGS="([^"]*)"', text, re.M | re.S).group(1).split())
        resolve_args(task, line)  # a script whose runs are still to come resolves its config too
        folder = SCRIPTS / "measurements" / script.stem
        if not folder.exists():
            continue
        kept_any = True
        kept = sorted(folder.glob("seed-*"))
        assert kept and {p.name for p in kept} <= {"seed-0", "seed-100", "seed-200"}
        for run in kept:
            seed = int(run.name.split("-")[1])
            saved = yaml.safe_load((run / "config.yaml").read_text())
            assert config_changes(saved, resolve_args(task, line, seed=seed)) == []
            assert (run / "checkpoints" / "best.pt").is_file() and list(run.glob("evaluate-best-*-50ep.json"))
    assert kept_any


def test_the_queue_reuses_the_kept_sources_and_trains_none(tmp_path):
    """With every source kept in results/manipulation/sources/, queue.sh copies them into RUNS and trains,
    keeps and evaluates nothing (DRLTG=false would fail the script if it were called)."""
    import filecmp

    runs = tmp_path / "runs"
    env = {**os.environ, "RUNS": str(runs), "ROWS": " ", "DRLTG": "false", "PYTHON": "false"}
    subprocess.run(["bash", str(SCRIPTS / "queue.sh")], cwd=ROOT, env=env, check=True, capture_output=True)
    for name in queue_sources():
        for seed in (0, 100, 200):
            kept, run = SCRIPTS / "sources" / name / f"seed-{seed}", runs / "sources" / name / f"seed-{seed}"
            assert filecmp.cmp(kept / "checkpoints" / "best.pt", run / "checkpoints" / "best.pt", shallow=False)
            assert (run / "summary.json").read_text() == (kept / "summary.json").read_text()


@pytest.mark.parametrize("row", ["demonstrations-place", "demonstrations-barrier"])
def test_the_rows_run_the_learned_sources_episodes_without_the_noise_that_stops_them_lifting(row):
    """The reason the spec gives is the committed measurement: its counts over the sources at sigma 0 and 0.1."""
    import csv

    with open(SCRIPTS / "placement-diagnostics" / "source-noise.csv") as f:
        rows = list(csv.DictReader(f))

    def lifted(sigma):
        cells = [r for r in rows if float(r["sigma"]) == sigma]
        return sum(int(r["lifted"]) for r in cells), sum(int(r["episodes"]) for r in cells)

    (noisy, n), (clean, m) = lifted(0.1), lifted(0.0)
    text = " ".join(line.lstrip("# ") for line in (SPECS / f"{row}.yaml").read_text().splitlines())
    assert f"lift in {noisy} of {n} episodes on lift-place against {clean} of {m} without" in text
    spec = load_spec(SPECS / f"{row}.yaml")
    assert "transfer.demo_noise" not in spec.overrides and spec.overrides["transfer.demo_ratio"] == 0.5
