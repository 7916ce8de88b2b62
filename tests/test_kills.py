"""kill -9 at every write point of a run and of a report; the same command run again finishes the work.

A write point is one rename that lands a file: every ``os.replace`` of :func:`drltg.store.atomic.atomic_path`
(config, every manifest, every eval.csv, every checkpoint, summary) and the report folder's swap. The
command runs in a forked child that ends itself with ``os._exit`` (no handler, no cleanup: what SIGKILL
leaves) just before or just after the chosen rename; then the same command runs again (``--resume`` for
a run) and must end with the files of an undisturbed run, every one matching the manifest, and nothing
of the killed process left (no temporary, no lock). Random kill moments of experiments and sweeps are
``benchmarks/faults.py``.
"""
import os
import shutil
import sys
from collections import Counter
from pathlib import Path

import pytest
import torch

from drltg.cli import main
from drltg.store import atomic, manifest, rundir
from tests.test_faults import train_args

KILLED = 137


def _files(folder: Path) -> list[str]:
    """Every file below ``folder`` but TensorBoard's, whose names carry the time they were opened."""
    return sorted(p.relative_to(folder).as_posix() for p in folder.rglob("*")
                  if p.is_file() and "tfevents" not in p.name)


def _run(args: list[str], kill_at: int | None = None, after: bool = False) -> tuple[int, list[str]]:
    """Run ``drltg ARGS`` in a forked child; with ``kill_at`` the child dies at its ``kill_at``-th rename
    (counting from 1), just before or just ``after`` it. The child's exit code (``KILLED`` where it died)
    and every rename's destination up to its end."""
    record = Path(os.environ.get("TMPDIR", "/tmp")) / f"drltg-renames-{os.getpid()}"
    pid = os.fork()
    if pid == 0:  # pragma: no cover - the child
        log = open(record, "w", buffering=1)
        count = 0
        replace, rename, exchange = os.replace, os.rename, atomic._exchange

        def land(dst, do):
            nonlocal count
            count += 1
            log.write(f"{dst}\n")
            if count == kill_at and not after:
                os._exit(KILLED)
            result = do()
            if count == kill_at and after:
                os._exit(KILLED)
            return result

        os.replace = lambda src, dst, *a, **k: land(dst, lambda: replace(src, dst, *a, **k))
        os.rename = lambda src, dst, *a, **k: land(dst, lambda: rename(src, dst, *a, **k))
        atomic._exchange = lambda a, b: land(b, lambda: exchange(a, b))
        sys.stdout = sys.stderr = open(os.devnull, "w")
        os._exit(main(args))
    code = os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1])
    renames = record.read_text().splitlines()
    record.unlink()
    return code, renames


def _finished_like(run: Path, reference: Path) -> str | None:
    """What differs between a rerun run and the undisturbed one, ``None`` if nothing does."""
    if _files(run) != _files(reference):
        return f"files {sorted(set(_files(run)) ^ set(_files(reference)))}"
    if not rundir.is_complete(run) or rundir.unlisted(run):
        return "not complete"
    for name in manifest.read(run):
        manifest.verify(run, name)
    saved, info = rundir.load_networks(run)
    ckpt = torch.load(run / rundir.CHECKPOINT, weights_only=True)
    if info != {"frames": ckpt["frames"], "updates": ckpt["updates"]} or saved.keys() != ckpt["loss"].keys() or not all(
            torch.equal(saved[k], ckpt["loss"][k]) for k in saved):
        return f"last.safetensors holds the networks of frame {info['frames']}, not those of last.pt"
    frames = [[r["frames"] for r in rundir.read_eval_csv(d / "eval.csv")] for d in (run, reference)]
    return None if frames[0] == frames[1] else f"evaluations at {frames[0]}, not {frames[1]}"


@pytest.mark.parametrize("after", [False, True], ids=["before-rename", "after-rename"])
def test_a_run_killed_at_any_write_is_finished_by_resuming_it(tmp_path, after):
    reference = tmp_path / "reference"
    code, renames = _run(train_args(reference))
    assert code == 0
    names = Counter(Path(dst).relative_to(reference).as_posix() for dst in renames)
    assert {"config.yaml", "manifest.json", "eval.csv", "checkpoints/last.pt", "checkpoints/last.safetensors",
            "summary.json"} <= set(names)
    assert names["checkpoints/last.pt"] >= 2  # the first checkpoint and a later one
    wrong = []
    for k, dst in enumerate(renames, 1):
        run = tmp_path / "run"
        shutil.rmtree(run, ignore_errors=True)
        code, _ = _run(train_args(run), k, after)
        again = main(train_args(run) + ["--resume"])
        problem = f"exit {again}" if again != 0 else _finished_like(run, reference)
        if code != KILLED or problem:
            wrong.append(f"rename {k} ({Path(dst).relative_to(reference)}): killed {code}, then {problem}")
    assert not wrong, wrong


@pytest.mark.parametrize("after", [False, True], ids=["before-rename", "after-rename"])
@pytest.mark.parametrize("previous", [False, True], ids=["first-report", "over-a-report"])
def test_a_report_killed_at_any_write_is_written_whole_by_the_same_command(tmp_path, previous, after):
    """Over a previous report, the kill leaves that report or the new one, whole, in its place."""
    baseline, transfer = tmp_path / "baseline", tmp_path / "transfer"
    assert main(train_args(baseline)) == 0 and main(train_args(transfer) + ["--seed", "1"]) == 0
    reference, out = tmp_path / "reference", tmp_path / "out" / "report"

    def args(to):
        return ["report", "--baseline", str(baseline), "--transfer", str(transfer), "--out", str(to)]

    assert main(args(reference)) == 0
    code, renames = _run(args(reference))
    assert code == 0 and renames[-1] == str(reference)  # the folder lands in one rename, after its files
    wrong = []
    for k in range(1, len(renames) + 1):
        shutil.rmtree(out.parent, ignore_errors=True)
        if previous:
            assert main(args(out)) == 0
        code, _ = _run(args(out), k, after)
        if previous and _files(out) != _files(reference):
            wrong.append(f"rename {k}: the report in place holds {_files(out)}")
        again = main(args(out))
        beside = sorted(p.name for p in out.parent.iterdir())
        if code != KILLED or again != 0 or _files(out) != _files(reference) or beside != ["report"]:
            wrong.append(f"rename {k}: killed {code}, then exit {again}, files {_files(out)}, beside it {beside}")
    assert not wrong, wrong


def test_resume_of_a_folder_that_never_held_a_run_is_still_refused(tmp_path, capsys):
    """Starting over is for a folder a kill left with drltg's temporary file or lock alone; a mistyped
    --run-dir, or an empty folder, is no run to resume."""
    for run in (tmp_path / "typo", tmp_path / "empty"):
        if run.name == "empty":
            run.mkdir()
        assert main(train_args(run) + ["--resume"]) == 2
        assert "holds no config.yaml" in capsys.readouterr().err
