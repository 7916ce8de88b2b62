"""Environment throughput: frames per second of the FourRooms tasks at several batch sizes.

Times three loops with random actions: ``step_and_maybe_reset`` (what a collector runs: steps
plus the partial resets of finished episodes), ``env.step`` + ``step_mdp`` (no resets), and the
raw batched dynamics ``_step`` without TorchRL's per-call bookkeeping. Prints one JSON object.

    python benchmarks/env_throughput.py [--device cpu] [--steps 200]
"""
import argparse
import json
import time

import torch
from torchrl.envs.utils import step_mdp

from drltg.envs import make_env


def frames_per_second(env, steps: int, mode: str) -> float:
    td = env.reset()
    torch.manual_seed(0)
    actions = [env.action_spec.rand() for _ in range(8)]
    for i in range(10):
        td = step_mdp(env.step(td.set("action", actions[i % 8])))
    if env.device is not None and env.device.type == "cuda":
        torch.cuda.synchronize()
    start = time.perf_counter()
    for i in range(steps):
        td["action"] = actions[i % 8]
        if mode == "collect":
            _, td = env.step_and_maybe_reset(td)
        elif mode == "raw":
            td.update(env._step(td).exclude("reward", "done", "terminated", "truncated"))
        else:
            td = step_mdp(env.step(td))
    if env.device is not None and env.device.type == "cuda":
        torch.cuda.synchronize()
    return steps * env.batch_size.numel() / (time.perf_counter() - start)


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--threads", type=int, default=1)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    results = {"device": args.device, "threads": args.threads, "steps": args.steps, "frames_per_s": {}}
    for task in ("fourrooms/northeast", "gridrooms/northeast"):
        for batch in (1, 1024, 4096):
            env = make_env(task, batch_size=(batch,), device=args.device, seed=0)
            results["frames_per_s"][f"{task} batch={batch}"] = {
                mode: round(frames_per_second(env, args.steps, mode)) for mode in ("collect", "step", "raw")
            }
    print(json.dumps(results, indent=1))


if __name__ == "__main__":
    main()
