"""The scripts that made results/ still say commands drltg accepts. Each script runs with stand-ins for
`drltg` and `python` that record their command lines (and leave the files a finished run has, where a
script copies them); every recorded `drltg` line then goes through drltg's own command line with the
training replaced, so a renamed option, task, override key or sweep spec, or a kept folder that a report
reads and that is gone, fails here rather than in a reader's hands."""
from __future__ import annotations

import contextlib
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from drltg.cli import main
from drltg.report.curves import read_curves

ROOT = Path(__file__).resolve().parents[1]
SCRIPTS = sorted(p for p in (ROOT / "results").glob("*.sh") if p.name != "demo.sh")  # demo.sh: `drltg demo`
RECORDER = """#!{python}
import json, os, sys
from pathlib import Path
args = sys.argv[1:]
with open(os.environ["RECORD"], "a") as f:
    f.write(json.dumps([Path(sys.argv[0]).name, *args]) + "\\n")
if args[:1] == ["train"] and "--run-dir" in args and "--seeds" not in args:
    run = Path(args[args.index("--run-dir") + 1])
    run.mkdir(parents=True, exist_ok=True)
    (run / "config.yaml").touch()
    (run / "summary.json").touch()
    frames = args[args.index("--frames") + 1] if "--frames" in args else "0"
    (run / "eval.csv").write_text(f"frames,return_mean\\n0,0.0\\n{{frames}},0.0\\n")
"""


class Planned(Exception):
    """Raised where the command would start training or writing a report: everything before it was checked."""


def recorded(script: Path, tmp_path: Path) -> list[list[str]]:
    """The command lines ``script`` runs, run from an empty folder so that nothing it writes lands in the repo."""
    bin_dir, work = tmp_path / "bin", tmp_path / "work"
    bin_dir.mkdir()
    work.mkdir()
    for name in ("drltg", "python"):
        (bin_dir / name).write_text(RECORDER.format(python=sys.executable))
        (bin_dir / name).chmod(0o755)
    env = {**os.environ, "RECORD": str(tmp_path / "calls.jsonl"), "DRLTG": str(bin_dir / "drltg"),
           "PYTHON": str(bin_dir / "python"), "WORKERS": "1"}
    done = subprocess.run(["bash", str(script)], cwd=work, env=env, capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    return [json.loads(line) for line in (tmp_path / "calls.jsonl").read_text().splitlines()]


def planned(argv: list[str], out: Path, monkeypatch) -> list:
    """Run one `drltg` line up to the point where it would train or report; what it would have trained or read."""
    seen = []

    def stop(*args, **kwargs):
        seen.append(args)
        raise Planned

    monkeypatch.setattr("drltg.training.loop.train", lambda cfg, run_dir, **kw: seen.append(cfg) or run_dir)
    monkeypatch.setattr("drltg.training.seeds.train_seeds", lambda cfg, run_dir, n, **kw: seen.append(cfg) or [])
    monkeypatch.setattr("drltg.cli.train._say_how_it_went", lambda run_dir, name=None: None)  # nothing was trained
    monkeypatch.setattr("drltg.experiments.experiment.execute_and_report", stop)
    monkeypatch.setattr("drltg.cli.report.transfer_report", stop)
    monkeypatch.setattr("drltg.experiments.sweep.sweep", stop)  # drltg bench run's groups
    monkeypatch.setattr("drltg.bench.report.leaderboard", stop)
    if "--out" in argv:  # what a sweep, an experiment or a report writes goes to the test's folder
        argv = [*argv[:argv.index("--out") + 1], str(out), *argv[argv.index("--out") + 2:]]
    argv = [*argv, "--dry-run"] if argv[0] == "sweep" else argv
    with contextlib.suppress(Planned):
        assert main(argv) == 0, argv
    return seen


@pytest.mark.parametrize("script", SCRIPTS, ids=lambda p: p.name)
def test_a_results_script_says_only_commands_that_drltg_accepts(script, tmp_path, monkeypatch):
    calls = recorded(script, tmp_path)
    assert any(program == "drltg" for program, *_ in calls)
    monkeypatch.chdir(ROOT)  # the scripts run from the repository root
    for i, (program, *argv) in enumerate(calls):
        if program == "python":
            assert argv[0] == "-c" or (ROOT / argv[0]).is_file(), argv
            continue
        seen = planned(argv, tmp_path / f"out-{i}", monkeypatch)
        if argv[0] == "train":
            assert [cfg.task for cfg in seen] == [argv[1]]
        elif argv[0] in ("experiment", "report"):
            assert len(seen) == 1, argv
        if argv[0] == "report":  # the kept runs it reads are still there
            baseline, transfer = seen[0][:2]
            assert read_curves(baseline) and read_curves(transfer), argv
