"""The manipulation study's script plans what it says, without training: one sweep spec per row, each
transfer run reusing the kept source run of its own seed, >= 3 paired seeds, <= 300k frames, one baseline
per target shared by every row on it, and the kept sources reused rather than trained again."""
from __future__ import annotations

import csv
import filecmp
import os
import re
import subprocess
from pathlib import Path

import pytest
import torch
import yaml

from drltg.config import config_changes
from drltg.errors import UsageError
from drltg.experiments.sweep import load_spec, plan
from drltg.transfer import load_actor

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


def test_each_row_reuses_the_kept_source_of_its_own_seed_and_shares_its_targets_baselines(monkeypatch):
    monkeypatch.chdir(ROOT)  # the scripts run from the repository root
    seen: dict[Path, dict] = {}
    for row in ROWS:
        spec = load_spec(SPECS / f"{row}.yaml")
        assert spec.seeds >= 3 and max(spec.frames) <= 300_000 and len(spec.pairs) == len(spec.methods) == 1
        source = spec.overrides.get("transfer.source")
        runs, cells = plan(spec, runs_of(row))
        assert len(cells) == 1 and len(runs) == 2 * spec.seeds  # baselines and transfers, no source trained here
        transfers = [r for r in runs if r.role == "transfer"]
        for run in transfers:
            if source is None or source.startswith("demonstrator:"):  # reward shaping; the scripted reference
                assert run.cfg.transfer.source == source, row
                continue
            kept = ROOT / "runs" / "manipulation" / "sources" / SOURCED.fullmatch(source).group(1)
            assert kept.name in SOURCES and run.cfg.transfer.source == str(kept / f"seed-{run.cfg.seed}"), row
            assert run.cfg.transfer.source_checkpoint == "best"  # what run.sh evaluates and keeps
        assert [r.cfg.seed for r in transfers] == [100 * i for i in range(spec.seeds)], row
        for r in runs:
            if r.role == "baseline":  # the same baselines for every row on the target, whatever its source
                assert r.cfg.transfer.source is None and config_changes(seen.setdefault(r.path, r.cfg), r.cfg) == []
    groups = {p.parent.relative_to(ROOT / "runs" / "manipulation").as_posix() for p in seen}
    assert groups == {"lift/sac/baseline", "lift-to-place/sac/baseline", "lift-to-place/soc/baseline",
                      "lift-to-place-barrier/sac/baseline", "reference/lift-to-place/sac/baseline",
                      "reference/lift-to-place-barrier/sac/baseline"}
    reference = ROOT / "runs" / "manipulation" / "reference"
    for path in [p for p in seen if p.is_relative_to(reference)]:  # copies of the others' (run.sh copies them)
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


def test_rebuild_keeps_only_the_rows_runs_and_their_relative_source(tmp_path, monkeypatch):
    """run.sh's `rebuild.py --only`: the row's baselines, transfers and source runs are copied in the runs'
    layout, another row's are not, and a source path relative to the run still names the kept source."""
    monkeypatch.syspath_prepend(str(ROOT / "results"))
    import rebuild

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


def test_keep_source_keeps_the_weights_and_refuses_an_unfinished_run(tmp_path, monkeypatch):
    monkeypatch.syspath_prepend(str(SCRIPTS))
    from keep_source import keep_source

    run = tmp_path / "run"
    (run / "checkpoints").mkdir(parents=True)
    for name in ("config.yaml", "eval.csv"):
        (run / name).write_text(name)
    for name, frames in (("last.pt", 60000), ("best.pt", 25000)):
        torch.save({"loss": {"actor.weight": torch.full((2, 3), float(frames))}, "frames": frames,
                    "buffer": torch.zeros(1000), "optimizer": {}}, run / "checkpoints" / name)
    with pytest.raises(UsageError, match="no summary.json"):
        keep_source(run, tmp_path / "kept")
    (run / "summary.json").write_text("{}")
    keep_source(run, tmp_path / "kept")
    for name, frames in (("last.pt", 60000), ("best.pt", 25000)):
        kept = torch.load(tmp_path / "kept" / "checkpoints" / name, weights_only=True)
        assert set(kept) == {"loss", "frames"} and kept["frames"] == frames
        assert torch.equal(kept["loss"]["actor.weight"], torch.full((2, 3), float(frames)))
    assert (tmp_path / "kept" / "config.yaml").read_text() == "config.yaml"
    (run / "checkpoints" / "best.pt").unlink()  # a run without keep_best has none, nor has its kept copy
    keep_source(run, tmp_path / "kept-last")
    assert not (tmp_path / "kept-last" / "checkpoints" / "best.pt").exists()


def test_the_script_reuses_the_kept_sources_and_copies_a_reference_rows_baselines(tmp_path):
    """With every source kept in results/manipulation/sources/, run.sh copies them into RUNS and trains, keeps
    and evaluates none; a reference row then copies the complete baselines of its group (config, curve,
    summary), not an unfinished one nor one it holds; DRLTG=false fails the script at the row's sweep. The kept
    sources are weights only and load as actors."""
    subprocess.run(["bash", "-n", str(SCRIPTS / "run.sh")], check=True)
    assert sorted(ROWS) == sorted(p.stem for p in SPECS.glob("*.yaml"))
    assert set(SOURCES) == {"lift-sac-ln-half", "lift-soc4"}
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
            for pt in ("last.pt", "best.pt"):
                assert set(torch.load(kept / "checkpoints" / pt, weights_only=True)) == {"loss", "frames"}
            assert sum(p.numel() for p in load_actor(kept).parameters()) > 0
    copied = runs / "reference" / "lift-to-place" / "sac" / "baseline"
    assert sorted(p.name for p in (copied / "seed-0").iterdir()) == ["config.yaml", "eval.csv", "summary.json"]
    assert (copied / "seed-0" / "eval.csv").read_text() == "eval.csv 0"
    assert not list(mine.iterdir()) and not (copied / "seed-200").exists()


def test_the_demonstration_rows_run_the_sources_episodes_without_the_noise_that_stops_them_lifting():
    """The reason each spec gives is the committed measurement: its counts over the sources at sigma 0 and 0.1."""
    with open(SCRIPTS / "placement-diagnostics" / "source-noise.csv") as f:
        cells = list(csv.DictReader(f))
    (noisy, n), (clean, m) = [[sum(int(r[k]) for r in cells if float(r["sigma"]) == sigma)
                               for k in ("lifted", "episodes")] for sigma in (0.1, 0.0)]
    for row in ("demonstrations-place", "demonstrations-barrier"):
        text = " ".join(line.lstrip("# ") for line in (SPECS / f"{row}.yaml").read_text().splitlines())
        assert f"lift in {noisy} of {n} episodes on lift-place against {clean} of {m} without" in text, row
        overrides = load_spec(SPECS / f"{row}.yaml").overrides
        assert "transfer.demo_noise" not in overrides and overrides["transfer.demo_ratio"] == 0.5, row
