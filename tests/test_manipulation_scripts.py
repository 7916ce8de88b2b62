"""The manipulation study's run.sh plans what it says, without training: a spec per row, each transfer reusing the
kept source of its own seed, >= 3 paired seeds, <= 300k frames, a target's baselines shared, the sources reused."""
from __future__ import annotations

import csv
import filecmp
import importlib.util
import os
import re
import subprocess
from pathlib import Path

import yaml

from drltg.config import config_changes
from drltg.experiments.sweep import load_spec, plan
from drltg.transfer import load_actor

ROOT = Path(__file__).resolve().parents[1]
SCRIPTS = ROOT / "results" / "manipulation"
SCRIPT = (SCRIPTS / "run.sh").read_text()
SPECS = ROOT / "examples" / "sweeps" / "manipulation-rows"
ROWS = re.search(r'ROWS=\$\{ROWS:-"([^"]*)"\}', SCRIPT).group(1).split()
SOURCES = dict(re.findall(r'^\s+\[([\w-]+)\]="([^"]*)"', SCRIPT, re.M))
SOURCED = re.compile(r"runs/manipulation/sources/([\w-]+)/seed-\{seed\}")


def left_unloaded(cfg, kept: Path) -> str:
    """What model reuse could not load of ``kept``'s best networks into ``cfg``'s learner ("" when all)."""
    from drltg.envs import make_env
    from drltg.learners import make_agent
    from drltg.transfer.model_reuse import load_from_run

    env = make_env(cfg.task, **cfg.env)
    report = load_from_run(make_agent(env, cfg).loss, kept, checkpoint="best")
    env.close()
    return report.summary() if report.widened or report.narrowed or report.skipped else ""


def test_each_row_reuses_the_kept_source_of_its_own_seed_and_shares_its_targets_baselines(monkeypatch):
    """A model-reuse row's learner takes its kept source's networks whole (LayerNorm included, nothing
    widened, narrowed or skipped), where robosuite is installed; a demonstration row's reason for running the
    sources' episodes without noise quotes the committed counts over the sources at sigma 0 and 0.1."""
    monkeypatch.chdir(ROOT)  # the scripts run from the repository root
    with open(SCRIPTS / "placement-diagnostics" / "source-noise.csv") as f:
        cells = list(csv.DictReader(f))
    (noisy, n), (clean, m) = [[sum(int(r[k]) for r in cells if float(r["sigma"]) == sigma)
                               for k in ("lifted", "episodes")] for sigma in (0.1, 0.0)]
    seen: dict[Path, dict] = {}
    for row in ROWS:
        spec = load_spec(SPECS / f"{row}.yaml")
        if row in ("demonstrations-place", "demonstrations-barrier"):
            text = " ".join(line.lstrip("# ") for line in (SPECS / f"{row}.yaml").read_text().splitlines())
            assert f"lift in {noisy} of {n} episodes on lift-place against {clean} of {m} without" in text, row
            assert "transfer.demo_noise" not in spec.overrides and spec.overrides["transfer.demo_ratio"] == 0.5, row
        assert spec.seeds >= 3 and max(spec.frames) <= 300_000 and len(spec.pairs) == len(spec.methods) == 1
        source = spec.overrides.get("transfer.source")
        own = row.startswith("demonstrations-reference-")  # its method folder is another row's: own runs
        runs, cells = plan(spec, ROOT / "runs" / "manipulation" / ("reference" if own else ""))
        assert len(cells) == 1 and len(runs) == 2 * spec.seeds  # baselines and transfers, no source trained here
        transfers = [r for r in runs if r.role == "transfer"]
        for run in transfers:
            if source is None or source.startswith("demonstrator:"):  # reward shaping; the scripted reference
                assert run.cfg.transfer.source == source, row
                continue
            kept = ROOT / "runs" / "manipulation" / "sources" / SOURCED.fullmatch(source).group(1)
            assert kept.name in SOURCES and run.cfg.transfer.source == str(kept / f"seed-{run.cfg.seed}"), row
            assert run.cfg.transfer.source_checkpoint == "best"  # what run.sh evaluates and keeps
        if "model-reuse" in spec.methods[0] and importlib.util.find_spec("robosuite"):
            assert not left_unloaded(transfers[0].cfg, SCRIPTS / "sources" / kept.name / "seed-0"), row
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


def test_the_script_reuses_the_kept_sources_and_copies_a_reference_rows_baselines(tmp_path):
    """With every source kept in results/manipulation/sources/, run.sh copies them into RUNS and trains, keeps
    and evaluates none; a reference row then copies the complete baselines of its group (config, curve,
    summary), not an unfinished one nor one it holds; DRLTG=false fails the script at the row's sweep. The kept
    sources are weights only and load as actors."""
    assert sorted(ROWS) == sorted(p.stem for p in SPECS.glob("*.yaml"))
    assert set(SOURCES) == {"lift-sac-ln-half", "lift-soc4"}
    shared = (runs := tmp_path / "runs") / "lift-to-place" / "sac" / "baseline"
    for seed in (0, 100, 200):
        (shared / f"seed-{seed}").mkdir(parents=True)
        for name in ("config.yaml", "eval.csv", "summary.json"):
            if not (seed == 200 and name == "summary.json"):  # seed 200 has not finished
                (shared / f"seed-{seed}" / name).write_text(f"{name} {seed}")
    (mine := runs / "reference" / "lift-to-place" / "sac" / "baseline" / "seed-100").mkdir(parents=True)
    env = {**os.environ, "RUNS": str(runs), "ROWS": "demonstrations-reference-place", "DRLTG": "false", "FORCE": "1"}
    done = subprocess.run(["bash", str(SCRIPTS / "run.sh")], cwd=ROOT, env=env, capture_output=True, text=True)
    assert done.returncode != 0 and "No such file" not in done.stderr, done.stderr
    for name in SOURCES:
        for seed in (0, 100, 200):
            kept, run = SCRIPTS / "sources" / name / f"seed-{seed}", runs / "sources" / name / f"seed-{seed}"
            assert filecmp.cmp(kept / "checkpoints" / "best.pt", run / "checkpoints" / "best.pt", shallow=False)
            assert sum(p.numel() for p in load_actor(kept).parameters()) > 0
    copied = runs / "reference" / "lift-to-place" / "sac" / "baseline"
    assert sorted(p.name for p in (copied / "seed-0").iterdir()) == ["config.yaml", "eval.csv", "summary.json"]
    assert (copied / "seed-0" / "eval.csv").read_text() == "eval.csv 0"
    assert not list(mine.iterdir()) and not (copied / "seed-200").exists()
