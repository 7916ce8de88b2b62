"""Suites ``train``, ``memory`` and ``checkpoint``: whole training runs, and the memory and the checkpoint
of a 1e6-transition replay buffer.

``train`` runs ``drltg.training.loop.train`` (what ``drltg train`` runs) on ``fourrooms/northeast`` with the
task's own settings, alternating the training step as shipped with the reference step (TorchRL's
default ``SACLoss``, its critics under ``torch.vmap``, one ``buffer.sample()`` per update), and
reports frames/s and wall time from each run's ``summary.json``. With robosuite installed (and not
``--quick``) it also runs a short ``lift`` training.

``memory`` fills a ``LazyTensorStorage`` of 1e6 Lift-sized transitions in a fresh process, as the
training loop stores them (only the keys the loss reads), and reports the growth of the peak resident
memory against the raw bytes of the stored tensors; the same for every key a Lift collector batch
carries (what the loop stored before it selected the loss's keys).

``checkpoint`` fills such a buffer (the loss's keys) with 300k transitions, as a Lift run holds at 300k
frames, and saves it with ``torch.save`` as TorchRL's ``state_dict`` holds it (the whole capacity) and as a
drltg checkpoint holds it (``drltg.training.replay.buffer_state``: the written rows), alternating, and
reports each file's size and save time and that the saved rows load back equal.
"""
from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from benchmarks.common import REPO


def _train_once(cfg, run_dir: Path, reference: bool) -> dict:
    import drltg.training.loop as train_mod
    from drltg import learners

    shipped = learners.DEACTIVATE_VMAP, train_mod.sample_batches
    if reference:
        learners.DEACTIVATE_VMAP = False
        train_mod.sample_batches = lambda buffer, n: [buffer.sample() for _ in range(n)]
    try:
        start = time.perf_counter()
        train_mod.train(cfg, run_dir, progress=False)
        wall = time.perf_counter() - start
    finally:
        learners.DEACTIVATE_VMAP, train_mod.sample_batches = shipped
    summary = json.loads((run_dir / "summary.json").read_text())
    return {"wall_s": round(wall, 2), "loop_frames_per_s": summary["frames_per_s"], "updates": summary["updates"],
            "final_return": round(summary["final_eval"]["return_mean"], 4)}


def run_train(device: str = "cpu", quick: bool = False) -> dict:
    from drltg import config as config_lib

    frames, repeats = (4096, 1) if quick else (16_384, 2)
    cfg = config_lib.resolve({}, [], task="fourrooms/northeast", frames=frames, seed=0, device=device)
    runs: dict[str, list[dict]] = {"drltg": [], "reference_step": []}
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(repeats):
            for name in runs:
                runs[name].append(_train_once(cfg, Path(tmp) / f"{name}{i}", reference=name != "drltg"))
    out = {
        "fourrooms": {
            "command": f"drltg train --task fourrooms/northeast --frames {frames} --seed 0",
            "frames": cfg.frames,
            "runs": runs,
            "median_wall_s": {k: sorted(r["wall_s"] for r in v)[len(v) // 2] for k, v in runs.items()},
        }
    }
    w = out["fourrooms"]["median_wall_s"]
    out["fourrooms"]["speedup_vs_reference_step"] = round(w["reference_step"] / w["drltg"], 3)
    out["fourrooms"]["same_final_return"] = len({r["final_return"] for v in runs.values() for r in v}) == 1
    if not quick:
        out["lift"] = _lift(device)
    return out


def _lift(device: str) -> dict:
    from drltg import config as config_lib

    try:
        import robosuite  # noqa: F401
    except ImportError:
        return {"missing": "robosuite not installed; pip install -e '.[robosuite]'"}
    overrides = ["collector.init_random_frames=1000", "eval.episodes=2", "log.tensorboard=false"]
    cfg = config_lib.resolve({}, overrides, task="lift", frames=2000, seed=0, device=device)
    with tempfile.TemporaryDirectory() as tmp:
        result = _train_once(cfg, Path(tmp) / "lift", reference=False)
    return {"command": "drltg train --task lift --frames 2000 --seed 0 " + " ".join(overrides), **result,
            "note": "2 ParallelEnv workers, 1000 random frames then one update per frame, "
                    "2 eval episodes of 500 steps at frames 0 and 2000"}


# Lift transitions (drltg.envs.robosuite: 50 observations, 7 actions) as a collector batch holds them.
LIFT_KEYS = {
    "observation": ((50,), "float32"), "action": ((7,), "float32"), "success": ((1,), "bool"),
    "step_count": ((1,), "int64"), "done": ((1,), "bool"), "terminated": ((1,), "bool"), "truncated": ((1,), "bool"),
    "episode_reward": ((1,), "float32"), ("collector", "traj_ids"): ((), "int64"),
    ("next", "observation"): ((50,), "float32"), ("next", "reward"): ((1,), "float32"),
    ("next", "success"): ((1,), "bool"), ("next", "step_count"): ((1,), "int64"), ("next", "done"): ((1,), "bool"),
    ("next", "terminated"): ((1,), "bool"), ("next", "truncated"): ((1,), "bool"),
    ("next", "episode_reward"): ((1,), "float32"),
}
LOSS_KEYS = [
    "observation", "action", ("next", "observation"), ("next", "reward"), ("next", "done"), ("next", "terminated")
]

_MEMORY_CHILD = r"""
import json, sys
import torch
from tensordict import TensorDict
from torchrl.data import LazyTensorStorage, ReplayBuffer
sys.path.insert(0, {repo!r})
from benchmarks.e2e import LIFT_KEYS, LOSS_KEYS
size, keys = {size}, {keys}
def rss_mib():  # this process image's peak RSS (ru_maxrss would carry the parent's peak over exec)
    for line in open("/proc/self/status"):
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024
def batch(n):
    td = TensorDict({{}}, [n])
    for k, (shape, dtype) in LIFT_KEYS.items():
        td.set(k, torch.ones(n, *shape, dtype=getattr(torch, dtype)))
    return td.select(*keys) if keys else td
buffer = ReplayBuffer(storage=LazyTensorStorage(size))
probe = batch(1)
raw = size * sum(t.element_size() * t.numel() for t in probe.values(True, True))
base = rss_mib()
chunk = 5000
for _ in range(size // chunk):
    buffer.extend(batch(chunk))
peak = rss_mib()
print(json.dumps({{"transitions": len(buffer), "raw_mib": round(raw / 2**20, 1),
                  "rss_growth_mib": round(peak - base, 1), "ratio": round((peak - base) / (raw / 2**20), 3),
                  "bytes_per_transition": raw // size, "keys": len(list(probe.keys(True, True)))}}))
"""


def _memory_child(size: int, keys) -> dict:
    code = _MEMORY_CHILD.format(repo=str(REPO), size=size, keys=keys)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600, cwd=REPO)
    if out.returncode:
        raise RuntimeError(out.stderr.strip().splitlines()[-1])
    return json.loads(out.stdout.strip().splitlines()[-1])


def run_memory(device: str = "cpu", quick: bool = False) -> dict:
    size = 200_000 if quick else 1_000_000
    return {
        "transitions": size,
        "loss_keys": _memory_child(size, LOSS_KEYS),
        "all_collector_keys": _memory_child(size, None),
        "target": "peak RSS growth <= 1.3x the raw bytes of the stored transitions",
        "note": "CPU storage; peak RSS growth measured from just before the buffer is created",
    }


def run_checkpoint(device: str = "cpu", quick: bool = False) -> dict:
    import statistics

    import torch
    from tensordict import TensorDict
    from torchrl.data import LazyTensorStorage, ReplayBuffer

    from drltg.training.replay import buffer_state, load_buffer_state

    capacity, written, rounds = (200_000, 60_000, 2) if quick else (1_000_000, 300_000, 3)
    buffer = ReplayBuffer(storage=LazyTensorStorage(capacity), batch_size=256)
    g = torch.Generator().manual_seed(0)
    for start in range(0, written, 10_000):
        batch = TensorDict({}, [10_000])
        for key in LOSS_KEYS:
            shape, dtype = LIFT_KEYS[key]
            batch.set(key, (torch.rand(10_000, *shape, generator=g) < 0.5).to(getattr(torch, dtype)))
        buffer.extend(batch)
    forms = {"whole_storage": buffer.state_dict, "written_rows": lambda: buffer_state(buffer)}
    seconds, sizes = {name: [] for name in forms}, {}
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "buffer.pt"
        for _ in range(rounds):
            for name, state in forms.items():
                start = time.perf_counter()
                torch.save(state(), path)
                seconds[name].append(time.perf_counter() - start)
                sizes[name] = path.stat().st_size
        resumed = ReplayBuffer(storage=LazyTensorStorage(capacity), batch_size=256)
        load_buffer_state(resumed, torch.load(path, weights_only=True))
        equal = len(resumed) == written and all(
            torch.equal(resumed.storage[:written][k], buffer.storage[:written][k]) for k in LOSS_KEYS)
    return {
        "capacity": capacity, "written": written, "rounds": rounds, "loads_back_equal": equal,
        "mib": {name: round(size / 2**20, 1) for name, size in sizes.items()},
        "save_s": {name: round(statistics.median(s), 2) for name, s in seconds.items()},
        "note": "torch.save to a temporary directory on the local disk, wall clock, median over rounds",
    }
