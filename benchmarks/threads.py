"""Suite ``threads``: SAC update steps under torch's default thread count against one thread.

A loop composed by hand (``make_agent`` + ``UpdateStep``) runs in torch's default of one thread per
core unless its script says otherwise. Three cases step the same agent, interleaved in one process:

* ``default_threads``: ``UpdateStep(agent, threads=None)``, torch's default (the loop of a user who never
  calls ``torch.set_num_threads``, before ``UpdateStep`` took a ``threads`` argument);
* ``step_threads_1``: ``UpdateStep(agent)``, whose default ``threads=1`` sets and restores torch's
  thread count around every step;
* ``process_threads_1``: ``torch.set_num_threads(1)`` once for the whole chunk, what every script in
  ``examples/`` does: the ceiling, so ``step_threads_1/process_threads_1`` is what the per-step switch costs.

Each runs with the machine idle and with one core busy (a spinning process pinned to the last CPU this
process may use, as a second run or an env worker would be), for FourRooms' 64x64 networks and the
default 256x256. Ratios: ``step_threads_1/default_threads`` (what a user's loop gains) and
``step_threads_1/process_threads_1``.
"""
from __future__ import annotations

import contextlib
import os
import subprocess
import sys

import torch

from benchmarks.common import interleaved, ratios
from drltg.config import resolve
from drltg.envs import make_env
from drltg.learners import UpdateStep, make_agent

TASK = "fourrooms/northeast"


@contextlib.contextmanager
def busy_core():
    """A process spinning on the last CPU of this process's affinity, for the duration."""
    cpu = max(os.sched_getaffinity(0))
    spin = subprocess.Popen(["taskset", "-c", str(cpu), sys.executable, "-c", "while True: pass"])
    try:
        yield cpu
    finally:
        spin.kill()
        spin.wait()


def _cases(hidden: list[int], steps: int) -> dict:
    torch.manual_seed(0)
    cfg = resolve(task=TASK, overrides=[f"network.hidden={hidden}"])
    env = make_env(TASK, batch_size=(8,), seed=0)
    agent = make_agent(env, cfg)
    batch = env.rollout(cfg.buffer.batch_size // 8, break_when_any_done=False).reshape(-1)

    def case(step, process_threads=None):
        def run() -> int:
            before = torch.get_num_threads()
            if process_threads is not None:
                torch.set_num_threads(process_threads)
            try:
                for _ in range(steps):
                    step(batch)
            finally:
                torch.set_num_threads(before)
            return steps

        return run

    return {"default_threads": case(UpdateStep(agent, threads=None)),
            "step_threads_1": case(UpdateStep(agent)),
            "process_threads_1": case(UpdateStep(agent, threads=None), process_threads=1)}


def run(device: str = "cpu", quick: bool = False) -> dict:
    steps, rounds = (20, 3) if quick else (50, 7)
    harness = torch.get_num_threads()
    torch.set_num_threads(len(os.sched_getaffinity(0)))  # torch's default, whatever --threads says
    out = {"device": "cpu", "torch_default_threads": torch.get_num_threads(), "rates_updates_per_s": {},
           "ratios": {}}
    for hidden in ([64, 64], [256, 256]):
        cases = _cases(hidden, steps)
        for load in ("idle", "one_core_busy"):
            with busy_core() if load == "one_core_busy" else contextlib.nullcontext():
                results = interleaved(cases, rounds=rounds)
            name = f"hidden_{hidden[0]}/{load}"
            out["rates_updates_per_s"][name] = results
            out["ratios"][name] = ratios(results, [("step_threads_1", "default_threads"),
                                                   ("step_threads_1", "process_threads_1")])
    torch.set_num_threads(harness)
    return out
