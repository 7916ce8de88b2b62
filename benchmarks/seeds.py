"""Suite ``seeds``: N seeds in one process (a seed group) against the same N seeds run one after another.

Everything single-threaded (``OMP_NUM_THREADS=1``, ``torch.set_num_threads(1)``), N = 1, 4, 8, 16:

* ``fourrooms``: whole commands, as a user runs them, on ``fourrooms/northeast`` with the task's
  defaults: ``drltg train fourrooms/northeast --seeds N --frames F`` against N commands
  ``drltg train fourrooms/northeast --seed k --frames F`` one after another. Reported: the commands'
  wall time (start-up included) and the training loop's time per frame from each run's summary.json
  (``frames / frames_per_s``: start-up, imports and the final files excluded), summed over the N
  separate runs. The group and the separate runs of each N alternate, round after round.
* ``lift_update``: the update alone at Lift's size (SAC, 2x256 actor and twin critics, batch 256,
  observation 50, action 7; ``benchmarks.sac``'s work): one :class:`~drltg.training.seeds.SeedGroup` update
  of N seeds against N ``UpdateStep`` updates one after another, each seed drawing from its own replay
  buffer, in interleaved rounds; and the group against the matrix-product bound of the same N-seed
  work (the update's products as N-batched ``bmm`` into preallocated outputs); ``split``: where a group
  update of 8 and 16 seeds spends its time, by kind of operator (:func:`update_split`);
* ``psi_pretraining``: SF-GPI's psi TD for the 10 members of a seed group, one after another against one
  vmapped update (:func:`psi_pretraining`).
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import torch

from benchmarks.common import REPO, interleaved, ratios
from benchmarks.sac import SpecEnv, _buffer, _config, sac_matmuls, transitions
from drltg.learners import UpdateStep, make_sac_agent, sample_batches
from drltg.training.seeds import SeedGroup

SEEDS = (1, 4, 8, 16)
TASK = "fourrooms/northeast"


def _command(args: list[str], run_dir: Path, task: str = TASK) -> float:
    env = {**os.environ, "OMP_NUM_THREADS": "1", "PYTHONPATH": str(REPO)}
    start = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "drltg.cli", "train", task, *args, "--run-dir", str(run_dir),
                           "--no-progress"], cwd=REPO, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - start
    if done.returncode:
        raise RuntimeError(done.stderr.strip().splitlines()[-1])
    return wall


def _loop_seconds(run_dir: Path) -> float:
    summary = json.loads((run_dir / "summary.json").read_text())
    return summary["frames"] / summary["frames_per_s"]


def fourrooms(frames: int, rounds: int) -> dict:
    walls = {f"{kind}_{n}": [] for n in SEEDS for kind in ("group", "separate")}
    loops = {name: [] for name in walls}
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(rounds):
            for n in SEEDS:
                order = ("group", "separate") if r % 2 == 0 else ("separate", "group")
                for kind in order:
                    root = Path(tmp) / f"{kind}{n}-{r}"
                    if kind == "group":
                        walls[f"group_{n}"].append(_command(["--seeds", str(n), "--frames", str(frames)], root))
                        loops[f"group_{n}"].append(_loop_seconds(root / "seed-0"))
                    else:
                        dirs = [root / f"seed-{k}" for k in range(n)]
                        walls[f"separate_{n}"].append(sum(
                            _command(["--seed", str(k), "--frames", str(frames)], d) for k, d in enumerate(dirs)))
                        loops[f"separate_{n}"].append(sum(_loop_seconds(d) for d in dirs))

    def median(xs):
        return sorted(xs)[len(xs) // 2]

    out = {"frames_per_seed": frames, "rounds": rounds, "per_n": {}}
    for n in SEEDS:
        g, s = f"group_{n}", f"separate_{n}"
        out["per_n"][n] = {
            "command_wall_s": {"group": round(median(walls[g]), 2), "separate": round(median(walls[s]), 2)},
            "loop_frames_per_s": {"group": round(n * frames / median(loops[g]), 1),
                                  "separate": round(n * frames / median(loops[s]), 1)},
            "ratio_command_wall": round(median(walls[s]) / median(walls[g]), 3),
            "ratio_loop": round(median(loops[s]) / median(loops[g]), 3),
        }
    out["commands"] = {"group": f"drltg train {TASK} --seeds N --frames {frames}",
                       "separate": f"drltg train {TASK} --seed k --frames {frames}  (k = 0 .. N-1, one after another)"}
    return out


LIFT_TASK = "lift-place-seed"
LIFT_OPTIONS = ["-o", "collector.init_random_frames=500", "-o", "eval.every=1000000", "-o", "eval.episodes=1",
                "-o", "checkpoint.every=1000000"]
"""The study's task with its settings (1 update a frame, 2 envs a seed in worker processes), a short warm-up
and one 1-episode evaluation at the end, so the loop's time is nearly all training."""


def lift_runs(n: int, frames: int, rounds: int) -> dict:
    """Whole ``drltg train lift-place-seed`` commands on the cores this process may use (pin it with ``taskset``
    to measure one core): ``--seeds n`` (one process, one vmapped update, each seed's envs in a worker process)
    against ``n`` commands ``--seed k`` one after another, their envs stepped in-process (what a run pinned to
    one core does) and in worker processes (``env.parallel=true``, what it did before it counted its cores).
    Loop frames/s: every seed's frames over the training loop's time (summary.json), start-up excluded;
    command wall time with it."""
    kinds = {"group": [], "separate": [], "separate_workers": []}
    walls, loops = {k: [] for k in kinds}, {k: [] for k in kinds}
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(rounds):
            for kind in kinds if r % 2 == 0 else reversed(list(kinds)):
                root = Path(tmp) / f"{kind}-{r}"
                if kind == "group":
                    walls[kind].append(_command(["--seeds", str(n), "--frames", str(frames), *LIFT_OPTIONS], root,
                                                LIFT_TASK))
                    loops[kind].append(_loop_seconds(root / "seed-0"))
                else:
                    extra = ["-o", "env.parallel=true"] if kind == "separate_workers" else []
                    dirs = [root / f"seed-{k}" for k in range(n)]
                    walls[kind].append(sum(_command(["--seed", str(k), "--frames", str(frames), *LIFT_OPTIONS,
                                                     *extra], d, LIFT_TASK) for k, d in enumerate(dirs)))
                    loops[kind].append(sum(_loop_seconds(d) for d in dirs))
    median = {kind: sorted(xs)[len(xs) // 2] for kind, xs in loops.items()}
    wall = {kind: sorted(xs)[len(xs) // 2] for kind, xs in walls.items()}
    return {
        "seeds": n, "frames_per_seed": frames, "rounds": rounds, "cpus": len(os.sched_getaffinity(0)),
        "loop_frames_per_s": {kind: round(n * frames / t, 1) for kind, t in median.items()},
        "command_wall_s": {kind: round(t, 1) for kind, t in wall.items()},
        "ratio_loop": round(median["separate"] / median["group"], 3),
        "ratio_command_wall": round(wall["separate"] / wall["group"], 3),
        "ratio_loop_in_process_vs_workers": round(median["separate_workers"] / median["separate"], 3),
        "commands": {"group": f"drltg train {LIFT_TASK} --seeds {n} --frames {frames} {' '.join(LIFT_OPTIONS)}",
                     "separate": f"drltg train {LIFT_TASK} --seed k --frames {frames} ... (k = 0 .. {n - 1})",
                     "separate_workers": "the same with -o env.parallel=true"},
    }


TERM_OPTIONS = ["-o", "transfer.method=demonstrations", "-o", "transfer.demo_episodes=8"]
"""Demonstrations on FourRooms: a quarter of every batch from the source policy's episodes, and the
behaviour-cloning term (a :class:`~drltg.losses.terms.LossTerm`) on them at every update."""


def loss_term_runs(n: int = 4, frames: int = 2048, rounds: int = 1) -> dict:
    """A method with a loss term, whole commands on ``fourrooms/northeast`` (task defaults):
    ``drltg train TASK --seeds n`` with :data:`TERM_OPTIONS` (its seeds as one group, each seed's
    behaviour-cloning term inside the vmapped loss) against the same command with ``--no-group`` (the seeds
    one after another in one process, as the method trained before its loss term grouped), and the same pair
    without a transfer method (the plain learner's ratio, for reference), alternating by round, after one
    source run of ``frames`` frames. Loop frames/s: every seed's frames over the training loops' time
    (summary.json), start-up excluded; command wall time with it."""
    kinds = ("terms_group", "terms_separate", "plain_group", "plain_separate")
    walls, loops = {k: [] for k in kinds}, {k: [] for k in kinds}
    with tempfile.TemporaryDirectory() as tmp:
        source = Path(tmp) / "source"
        _command(["--frames", str(frames), "--seed", "50"], source)
        terms = [*TERM_OPTIONS, "-o", f"transfer.source={source}"]
        for r in range(rounds):
            for kind in kinds if r % 2 == 0 else reversed(kinds):
                root = Path(tmp) / f"{kind}-{r}"
                args = [*(terms if kind.startswith("terms") else []), "--seeds", str(n), "--frames", str(frames),
                        *(["--no-group"] if kind.endswith("separate") else [])]
                walls[kind].append(_command(args, root))
                loops[kind].append(sum(_loop_seconds(d) for d in sorted(root.glob("seed-*")))
                                   / (n if kind.endswith("group") else 1))
    median = {kind: sorted(xs)[len(xs) // 2] for kind, xs in loops.items()}
    wall = {kind: sorted(xs)[len(xs) // 2] for kind, xs in walls.items()}
    return {
        "seeds": n, "frames_per_seed": frames, "rounds": rounds,
        "loop_frames_per_s": {kind: round(n * frames / t, 1) for kind, t in median.items()},
        "command_wall_s": {kind: round(t, 1) for kind, t in wall.items()},
        "ratio_loop": {m: round(median[f"{m}_separate"] / median[f"{m}_group"], 3) for m in ("terms", "plain")},
        "ratio_command_wall": {m: round(wall[f"{m}_separate"] / wall[f"{m}_group"], 3) for m in ("terms", "plain")},
        "commands": {"terms_group": f"drltg train {TASK} --seeds {n} --frames {frames} {' '.join(TERM_OPTIONS)} "
                                    "-o transfer.source=SOURCE",
                     "terms_separate": "the same with --no-group",
                     "plain_group": f"drltg train {TASK} --seeds {n} --frames {frames}",
                     "plain_separate": "the same with --no-group"},
    }


def run_lift(device: str = "cpu", quick: bool = False) -> dict:
    if device != "cpu":
        return {"missing": "the lift-seeds suite measures single-threaded CPU runs"}
    return {"threads": 1, "lift": lift_runs(3, 2000 if quick else 4000, 1 if quick else 2),
            "target": "a Lift-sized run >= 2x the frames per core of runs one after another"}


def _separate_case(n: int, chunk: int):
    steps, buffers = [], []
    for k in range(n):
        torch.manual_seed(k)
        steps.append(UpdateStep(make_sac_agent(SpecEnv(), _config())))
        buffers.append(_buffer(transitions(seed=k), "cpu"))

    def run() -> int:
        for step, buffer in zip(steps, buffers):
            for batch in sample_batches(buffer, chunk):
                step(batch)
        return n * chunk

    return run


def _group_case(n: int, chunk: int):
    agents, buffers = [], []
    for k in range(n):
        torch.manual_seed(k)
        agents.append(make_sac_agent(SpecEnv(), _config()))
        buffers.append(_buffer(transitions(seed=k), "cpu"))
    group = SeedGroup(agents)

    def run() -> int:
        per_seed = [sample_batches(buffer, chunk) for buffer in buffers]
        for batches in zip(*per_seed):
            group.update(torch.stack(batches))
        return n * chunk

    return run


def _matmul_case(n: int, chunk: int):
    g = torch.Generator().manual_seed(0)
    operands = [(torch.randn(n, m, k, generator=g), torch.randn(n, k, p, generator=g), torch.empty(n, m, p))
                for m, k, p in sac_matmuls()]

    def run() -> int:
        for _ in range(chunk):
            for a, b, out in operands:
                torch.bmm(a, b, out=out)
        return n * chunk

    return run


SPLIT = {"matrix products": ("aten::bmm", "aten::mm"),
         "bias adds and gradient sums": ("aten::add", "aten::add_", "aten::sum"),
         "activations": ("aten::clamp_min", "aten::threshold_backward", "aten::relu", "aten::tanh",
                         "aten::tanh_backward", "Vmapped_SafeTanhNoEps", "Vmapped_SafeTanhNoEpsBackward"),
         "Adam and target updates": ("Optimizer.step#Adam.step", "aten::_fused_adam_", "aten::sqrt", "aten::addcdiv_",
                                     "aten::addcmul_", "aten::lerp_", "aten::div_"),
         "concatenation, indexing and copies": ("aten::cat", "aten::index", "aten::stack", "aten::copy_")}
"""The update's operators by kind: torch.profiler's self CPU time of each, the rest summed as ``other``."""


def update_split(n: int, updates: int) -> dict:
    """Where a group update of ``n`` seeds spends its time: each kind's share of the self CPU time
    (:data:`SPLIT`), profiled over ``updates`` updates after a warm-up. The matmul bound counts the first
    kind alone; the others are what the update must do besides."""
    from torch.profiler import ProfilerActivity, profile

    step = _group_case(n, 2)
    step()
    with profile(activities=[ProfilerActivity.CPU]) as prof:
        for _ in range(-(-updates // 2)):
            step()
    times = {e.key: e.self_cpu_time_total for e in prof.key_averages()}
    total = sum(times.values())
    shares = {kind: sum(times.get(op, 0.0) for op in ops) / total for kind, ops in SPLIT.items()}
    shares["other"] = 1.0 - sum(shares.values())
    return {kind: round(share, 3) for kind, share in shares.items()}


def lift_update(chunk: int, rounds: int) -> dict:
    cases = {}
    for n in SEEDS:
        cases[f"group_{n}"] = _group_case(n, chunk)
        cases[f"separate_{n}"] = _separate_case(n, chunk)
        cases[f"matmul_bound_{n}"] = _matmul_case(n, chunk)
    results = interleaved(cases, rounds=rounds, warmup=1)
    pairs = [(f"group_{n}", f"separate_{n}") for n in SEEDS] + [(f"group_{n}", f"matmul_bound_{n}") for n in SEEDS]
    return {"unit": "seed-updates/s", "work": "SAC, batch 256, obs 50, act 7, 2x256 actor and twin critics",
            "chunk": chunk, "rates": results, "ratios": ratios(results, pairs),
            "split": {f"group_{n}": update_split(n, 2 * chunk) for n in (8, 16)}}


def psi_pretraining(n: int = 10, updates: int = 2000, rounds: int = 2) -> dict:
    """SF-GPI's psi TD for ``n`` members of a seed group (seeds 0 .. n-1, one source each, as an experiment's
    transfer runs have: ``fourrooms/northeast`` sources of 1,024 frames, target ``fourrooms/northeast-shifted``,
    task defaults, ``sf_updates=updates``): each member's :func:`~drltg.training.pretraining.pretrain` one
    after another against :func:`~drltg.training.pretraining.pretrain_together` (one vmapped update), the CPU
    time of the TD alone (the builds' rollouts excluded), alternating by round."""
    from drltg import config as config_lib
    from drltg.envs import make_env
    from drltg.learners import make_agent
    from drltg.training.pretraining import pretrain, pretrain_together
    from drltg.transfer import get_method

    with tempfile.TemporaryDirectory() as tmp:
        sources = [Path(tmp) / f"source-{k}" for k in range(n)]
        for k, source in enumerate(sources):
            _command(["--frames", "1024", "--seed", str(50 + k)], source)

        def problems():
            built = []
            for k, source in enumerate(sources):
                cfg = config_lib.resolve({}, ["transfer.method=sf-gpi", f"transfer.source={source}",
                                              f"transfer.sf_updates={updates}", f"seed={k}"],
                                         task="fourrooms/northeast-shifted")
                env = make_env(cfg.task, batch_size=(cfg.collector.num_envs,), seed=cfg.seed)
                torch.manual_seed(cfg.seed)
                built.append(get_method("sf-gpi").build(cfg, make_agent(env, cfg), env, resuming=False).pretraining)
            return built

        seconds = {"alone": [], "together": []}
        for r in range(rounds):
            for kind in ("alone", "together") if r % 2 == 0 else ("together", "alone"):
                todo = problems()
                start = time.process_time()
                if kind == "alone":
                    for p in todo:
                        pretrain(p)
                else:
                    pretrain_together(todo)
                seconds[kind].append(time.process_time() - start)
    median = {kind: sorted(xs)[len(xs) // 2] for kind, xs in seconds.items()}
    return {"members": n, "sf_updates": updates, "rounds": rounds,
            "cpu_s": {kind: round(t, 1) for kind, t in median.items()},
            "ratio_cpu": round(median["alone"] / median["together"], 3)}


def run(device: str = "cpu", quick: bool = False) -> dict:
    if device != "cpu":
        return {"missing": "the seeds suite measures single-threaded CPU runs"}
    torch.set_num_threads(1)
    frames, rounds = (2048, 1) if quick else (4096, 2)
    chunk, update_rounds = (4, 3) if quick else (8, 7)
    return {
        "threads": 1,
        "lift_update": lift_update(chunk, update_rounds),
        "fourrooms": fourrooms(frames, rounds),
        "psi_pretraining": psi_pretraining(4 if quick else 10, 200 if quick else 2000, 1 if quick else 2),
        "targets": ">= 4x at 8 seeds on FourRooms, >= 1.5x on the Lift-sized update, group >= 0.85 of the "
                   "matmul bound",
    }
