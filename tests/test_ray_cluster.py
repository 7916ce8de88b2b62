"""`drltg sweep --backend ray`: a stopped sweep cancels its tasks, and a sweep on a two-node Ray cluster on
this machine, bound to 127.0.0.1 only, survives the loss of its worker node.

The two-node test is slow (about a minute: two Ray nodes start, one is lost and its work redone), so it
checks everything on one cluster. ``examples/ray_two_nodes.sh`` (the documented script) runs a tiny sweep
while the test kills every process of the worker node, as the loss of that machine would; the sweep must
still complete, each run byte for byte the run trained here by the same function a local pool's worker
runs. The runs stop before their first checkpoint (``checkpoint.every`` is 10k frames), so the rerun
starts its run over; a run resumed from a checkpoint equals the undisturbed run up to that checkpoint, as
after ``kill -9`` (benchmarks/faults.py).
"""
import csv
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest
import yaml

from drltg.cli import _terminate
from drltg.experiments import sweep
from drltg.experiments.backends import RayBackend
from drltg.experiments.executor import run_group, run_one, seed_groups
from drltg.store import rundir

REPO = Path(__file__).resolve().parents[1]
TINY = {"network.hidden": [16, 16], "collector.num_envs": 4, "collector.frames_per_batch": 16,
        "collector.init_random_frames": 64, "optim.updates_per_batch": 1, "buffer.batch_size": 32,
        "eval.every": 32, "eval.episodes": 2, "log.tensorboard": False}
SPEC = {"pairs": ["fourrooms-near"], "methods": ["reward-shaping"], "seeds": 2, "frames": 256,
        "threshold": 0, "overrides": TINY}
# The head declares a node lost after failure_threshold missed health checks, period_ms apart (Ray's
# defaults, 5 x 3 s, would only make the test slower).
FAST_HEALTH_CHECK = {"RAY_health_check_period_ms": "500", "RAY_health_check_failure_threshold": "3"}


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def session(sid: int) -> list[int]:
    """The running processes of session ``sid`` (a node's, as examples/ray_two_nodes.sh starts it)."""
    found = []
    for proc in Path("/proc").iterdir():
        try:
            if proc.name.isdigit():
                fields = (proc / "stat").read_text().rsplit(")", 1)[1].split()
                if int(fields[3]) == sid and fields[0] != "Z":
                    found.append(int(proc.name))
        except (OSError, IndexError, ValueError):
            pass
    return found


def curves(out: Path) -> dict[str, str]:
    return {str(p.relative_to(out)): p.read_text() for p in sorted(out.glob("fourrooms-*/**/eval.csv"))}


def starts(log: Path) -> list[tuple[str, int]]:
    """``(start | resume, worker pid)`` each time a task took up the run (from its log)."""
    lines = log.read_text().splitlines() if log.is_file() else []
    return [(line.split("] ", 1)[1].split()[0], int(line.rsplit("(pid ", 1)[1].rstrip(")")))
            for line in lines if line.endswith(")") and "(pid " in line]


def rows(run: Path) -> int:
    return len(rundir.read_eval_csv(run / rundir.EVAL)) if (run / rundir.EVAL).is_file() else 0


def test_a_stopped_sweep_cancels_its_ray_tasks_and_their_runs_unwind(tmp_path, capsys):
    """What SIGTERM or Ctrl-C of ``drltg sweep --backend ray`` does on its way out (``RayBackend.close``): the
    running task is cancelled and its run stops at its next batch, its lock released, resumable."""
    spec = sweep.parse_spec({**SPEC, "frames": 100_000})
    run = sweep.plan(spec, tmp_path / "out")[0][0]
    unwind = signal.signal(signal.SIGTERM, _terminate)
    try:
        backend = RayBackend(None, {"num_cpus": 1}, num_cpus=1)
        assert signal.getsignal(signal.SIGTERM) is _terminate  # ray.init's own handler is undone: SIGTERM unwinds
    finally:
        signal.signal(signal.SIGTERM, unwind)
    try:
        backend.submit(run)
        deadline = time.monotonic() + 600  # a wait, not a timing: a loaded machine starts Ray's worker slowly
        while rows(run.path) < 2 and time.monotonic() < deadline:
            time.sleep(0.05)
        reached = rows(run.path)
    finally:
        backend.close(grace=60)
    assert reached >= 2 and "ray: cancelled 1 task(s) of this sweep\n" in capsys.readouterr().err  # none killed
    assert starts(run.log)[0][0] == "start"
    assert run.log.read_text().splitlines()[-1].endswith("] interrupted; a rerun continues it")
    assert not (run.path / rundir.LOCK).exists()
    assert not rundir.entries(run.path)  # stopped before its first checkpoint: what it wrote is gone, a rerun starts it


@pytest.mark.slow
def test_a_sweep_on_two_nodes_survives_the_loss_of_the_worker_node(tmp_path):
    spec = tmp_path / "tiny.yaml"
    spec.write_text(yaml.safe_dump(SPEC))
    ray_tmp = Path(tempfile.mkdtemp(prefix="drltg-ray.", dir="/tmp"))  # Ray's socket paths must stay short
    out, port = tmp_path / "ray", free_port()
    env = {**os.environ, **FAST_HEALTH_CHECK, "RAY_PORT": str(port), "RAY_TMP": str(ray_tmp),
           "PYTHON": sys.executable, "DRLTG": f"{sys.executable} -m drltg.cli", "PYTHONPATH": str(REPO),
           "OMP_NUM_THREADS": "1"}
    script = subprocess.Popen(["bash", str(REPO / "examples" / "ray_two_nodes.sh"), str(spec), str(out)],
                              env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    plan = sweep.plan(sweep.load_spec(spec), out)[0]
    runs = [r.path.relative_to(out) for r in plan]
    try:
        # a run that trains on the worker node and has evaluated at least 3 times: kill the node under it
        deadline, victim = time.monotonic() + 120, None
        while victim is None and script.poll() is None and time.monotonic() < deadline:
            node = session(int((ray_tmp / "worker.sid").read_text())) if (ray_tmp / "worker.sid").is_file() else []
            for run in runs:
                log, started = out / "logs" / f"{run}.log", starts(out / "logs" / f"{run}.log")
                if started and started[-1][1] in node and rows(out / run) >= 3 \
                        and not (out / run / rundir.SUMMARY).exists():
                    victim = run, log, started[-1][1], rows(out / run)
                    break
            else:
                time.sleep(0.05)
        assert victim is not None, "no run trained on the worker node"
        sids = [int((ray_tmp / f"{name}.sid").read_text()) for name in ("head", "worker")]
        for pid in node:
            os.kill(pid, signal.SIGKILL)  # every process of the node at once, as a lost machine
        output, _ = script.communicate(timeout=180)
    finally:
        if script.poll() is None:
            script.send_signal(signal.SIGTERM)
            script.wait(60)
        shutil.rmtree(ray_tmp, ignore_errors=True)
    assert script.returncode == 0, output
    local = tmp_path / "local"  # the reference: the same units of work, here, as a local pool's worker runs them
    for unit in seed_groups(sweep.plan(sweep.load_spec(spec), local)[0]):
        if len(unit) == 1:
            assert run_one(unit[0].cfg, str(unit[0].path), str(unit[0].log)) == ("done", "")
        else:
            args = [r.cfg for r in unit], [str(r.path) for r in unit], [str(r.log) for r in unit]
            assert run_group(*args) == [("done", "")] * len(unit)
    run, log, pid, reached = victim
    assert reached < rows(out / run) == 256 // 32 + 1  # killed partway, then complete
    assert starts(log) == [("start", pid), ("resume", starts(log)[1][1])]  # taken up again ...
    assert starts(log)[1][1] not in node  # ... by a worker of the head node
    with open(out / "runs.csv") as f:
        assert sorted(r["status"] for r in csv.DictReader(f)) == ["done"] * 4
    assert curves(out) == curves(local)  # every run equals the local pool's, the rerun one included
    assert "ray: both nodes stopped" in output and not session(sids[0]) and not session(sids[1])


RAY_SCRIPT = '''
import sys
import drltg
from drltg.envs import register_pair, register_task
from drltg.envs.fourrooms import FourRoomsEnv


def rooms(**options):
    return FourRoomsEnv(**options)


def main(out):
    register_task("mine/a", rooms, "the script's source task", goal=(8.0, 8.0), horizon=40)
    register_task("mine/b", rooms, "the script's target task", goal=(8.0, 7.0), horizon=40)
    register_pair("mine-near", "mine/a", "mine/b", "registered inside main()")
    spec = {**SPEC, "pairs": ["mine-near"], "methods": ["model-reuse"], "seeds": 1}
    result = drltg.sweep(spec, out, backend="ray", workers=1, progress=False)
    print("status", sorted(set(s for s, _ in result["status"].values())))


SPEC = %r
if __name__ == "__main__":
    main(sys.argv[1])
'''


def test_tasks_registered_inside_a_script_s_function_reach_the_ray_workers(tmp_path):
    """A script registers its pair inside main() and sweeps it on a local Ray instance: Ray's workers import
    drltg, not the script, and get its tasks from the driver, so every run trains on the script's task."""
    (tmp_path / "script.py").write_text(RAY_SCRIPT % (SPEC,))
    env = {**os.environ, "RAY_ADDRESS": "", "RL_WARNINGS": "False"}
    done = subprocess.run([sys.executable, "script.py", str(tmp_path / "out")], cwd=tmp_path, capture_output=True,
                          text=True, timeout=600, env=env)
    assert done.returncode == 0, done.stderr[-3000:]
    assert "status ['done']" in done.stdout, done.stdout[-2000:]
    configs = sorted((tmp_path / "out").glob("**/seed-0/config.yaml"))
    assert configs and {yaml.safe_load(c.read_text())["task"] for c in configs} <= {"mine/a", "mine/b"}
    assert "mine/b" in {yaml.safe_load(c.read_text())["task"] for c in configs}
