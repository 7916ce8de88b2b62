"""The manipulation study's script plans what it says, without training: one sweep spec per row, each
transfer run reusing the kept source run of its own seed, >= 3 paired seeds, <= 300k frames, one baseline
per target shared by every row on it, and the kept sources reused rather than trained again."""
from __future__ import annotations

import os
import re
import subprocess
from pathlib import Path

import pytest

from drltg.config import config_changes
from drltg.experiments.sweep import load_spec, plan

ROOT = Path(__file__).resolve().parents[1]
SCRIPTS = ROOT / "results" / "manipulation"
SCRIPT = (SCRIPTS / "run.sh").read_text()
SPECS = ROOT / "examples" / "sweeps" / "manipulation-rows"
ROWS = re.search(r'ROWS=\$\{ROWS:-"([^"]*)"\}', SCRIPT).group(1).split()
SOURCES = dict(re.findall(r'^\s+\[([\w-]+)\]="([^"]*)"', SCRIPT, re.M))
SOURCED = re.compile(r"runs/manipulation/sources/([\w-]+)/seed-\{seed\}")


def runs_of(row: str) -> Path:
    """Where a row's runs go: the reference rows, whose method folder another row also uses, in their own."""
    return ROOT / "runs" / "manipulation" / ("reference" if row.startswith("demonstrations-reference-") else "")


def test_the_script_parses_and_runs_every_row_spec_and_two_sources():
    subprocess.run(["bash", "-n", str(SCRIPTS / "run.sh")], check=True)
    assert sorted(ROWS) == sorted(p.stem for p in SPECS.glob("*.yaml"))
    assert set(SOURCES) == {"lift-sac-ln-half", "lift-soc4"}


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
        assert name in SOURCES
        kept = ROOT / "runs" / "manipulation" / "sources" / name / f"seed-{run.cfg.seed}"
        assert run.cfg.transfer.source == str(kept)
        assert run.cfg.transfer.source_checkpoint == "best"  # what run.sh evaluates and keeps
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
    for path in copies:  # the reference rows' baselines are copies of the others' (run.sh copies them)
        assert config_changes(seen[ROOT / "runs" / "manipulation" / path.relative_to(reference)], seen[path]) == []


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


def test_rebuild_keeps_only_the_rows_runs_and_their_relative_source(tmp_path):
    """run.sh's `rebuild.py --only`: the row's baselines, transfers and source runs are copied in the runs'
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
    weights = {name: {"actor.weight": torch.full((2, 3), float(i))} for i, name in enumerate(("last.pt", "best.pt"))}
    for name, frames in (("last.pt", 60000), ("best.pt", 25000)):
        torch.save({"loss": weights[name], "frames": frames, "buffer": torch.zeros(1000), "optimizer": {}},
                   run / "checkpoints" / name)
    with pytest.raises(UsageError, match="no summary.json"):
        keep_source(run, tmp_path / "kept")
    (run / "summary.json").write_text("{}")
    keep_source(run, tmp_path / "kept")
    for name, frames in (("last.pt", 60000), ("best.pt", 25000)):
        kept = torch.load(tmp_path / "kept" / "checkpoints" / name, weights_only=True)
        assert set(kept) == {"loss", "frames"} and kept["frames"] == frames
        assert torch.equal(kept["loss"]["actor.weight"], weights[name]["actor.weight"])
    assert (tmp_path / "kept" / "config.yaml").read_text() == "config.yaml"
    (run / "checkpoints" / "best.pt").unlink()  # a run without keep_best has none, nor has its kept copy
    keep_source(run, tmp_path / "kept-last")
    assert not (tmp_path / "kept-last" / "checkpoints" / "best.pt").exists()


@pytest.mark.parametrize("seed", [0, 100, 200])
def test_kept_lift_sources_are_weights_only_and_load_as_actors(seed):
    import torch

    from drltg.transfer import load_actor
    source = SCRIPTS / "sources" / "lift-sac-ln-half" / f"seed-{seed}"
    assert set(torch.load(source / "checkpoints" / "last.pt", weights_only=True)) == {"loss", "frames"}
    actor = load_actor(source)
    assert sum(p.numel() for p in actor.parameters()) > 0


def test_the_script_reuses_the_kept_sources_and_copies_a_reference_rows_baselines(tmp_path):
    """With every source kept in results/manipulation/sources/, run.sh copies them into RUNS and trains, keeps
    and evaluates none; a reference row then copies the complete baselines of its group (config, curve,
    summary), not an unfinished one nor one it holds; DRLTG=false fails the script at the row's sweep."""
    import filecmp

    runs = tmp_path / "runs"
    shared = runs / "lift-to-place" / "sac" / "baseline"
    for seed in (0, 100, 200):
        (shared / f"seed-{seed}").mkdir(parents=True)
        for name in ("config.yaml", "eval.csv", "summary.json"):
            if not (seed == 200 and name == "summary.json"):  # seed 200 has not finished
                (shared / f"seed-{seed}" / name).write_text(f"{name} {seed}")
    mine = runs / "reference" / "lift-to-place" / "sac" / "baseline" / "seed-100"
    mine.mkdir(parents=True)
    env = {**os.environ, "RUNS": str(runs), "ROWS": "demonstrations-reference-place", "DRLTG": "false",
           "FORCE": "1"}
    done = subprocess.run(["bash", str(SCRIPTS / "run.sh")], cwd=ROOT, env=env, capture_output=True, text=True)
    assert done.returncode != 0 and "No such file" not in done.stderr, done.stderr
    for name in SOURCES:
        for seed in (0, 100, 200):
            kept, run = SCRIPTS / "sources" / name / f"seed-{seed}", runs / "sources" / name / f"seed-{seed}"
            assert filecmp.cmp(kept / "checkpoints" / "best.pt", run / "checkpoints" / "best.pt", shallow=False)
    copied = runs / "reference" / "lift-to-place" / "sac" / "baseline"
    assert sorted(p.name for p in (copied / "seed-0").iterdir()) == ["config.yaml", "eval.csv", "summary.json"]
    assert (copied / "seed-0" / "eval.csv").read_text() == "eval.csv 0"
    assert not list(mine.iterdir()) and not (copied / "seed-200").exists()


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
