"""Seed groups on robosuite's Lift: one worker process per seed, each building its run alone's env.

Kept cheap: 2 seeds, 2 envs per seed stepped in the worker (``env.parallel=false``), forked workers,
horizon 50, 400 frames, 1 evaluation episode."""
from __future__ import annotations

import json

import pytest
import torch
import yaml
from torchrl.data import LazyTensorStorage, ReplayBuffer

pytest.importorskip("robosuite")

from drltg import config as config_lib  # noqa: E402
from drltg.store.rundir import load_checkpoint  # noqa: E402
from drltg.training.grouping import group_support, in_process  # noqa: E402
from drltg.training.loop import build_env  # noqa: E402
from drltg.training.replay import load_buffer_state  # noqa: E402
from drltg.training.seeds import _group_env, train_seeds  # noqa: E402

TINY = ["network.hidden=[16,16]", "env.horizon=50", "env.parallel=false", "env.mp_start_method=fork",
        "collector.num_envs=2", "collector.frames_per_batch=100", "collector.init_random_frames=100",
        "optim.updates_per_batch=2", "buffer.size=1000", "buffer.batch_size=16", "eval.episodes=1",
        "eval.every=400", "checkpoint.every=400", "log.every=200"]


def lift_cfg(**kw):
    return config_lib.resolve({}, TINY, **{"task": "lift", "algo": "sac", "frames": 400, "seed": 5, **kw})


def test_lift_groups_in_worker_processes():
    cfg = lift_cfg()
    assert group_support(cfg) is None and not in_process(cfg)


def test_a_group_env_resets_each_seed_as_its_run_alone():
    cfg = lift_cfg()
    group = _group_env(cfg, [5, 6], 2, 0)
    try:
        assert tuple(group.batch_size) == (4,)
        grouped = group.reset()["observation"].reshape(2, 2, -1)
    finally:
        group.close()
    alone = []
    for seed in (5, 6):
        env = build_env(config_lib.updated(cfg, {"seed": seed}), batch_size=(2,), seed=seed)
        try:
            alone.append(env.reset()["observation"])
        finally:
            env.close()
    assert torch.equal(grouped[0], alone[0]) and torch.equal(grouped[1], alone[1])
    assert not torch.equal(alone[0], alone[1])  # the seeds place their cubes apart


def test_a_lift_group_writes_each_seeds_run_to_the_end(tmp_path):
    dirs = train_seeds(lift_cfg(), tmp_path, 2, progress=False)
    assert [d.name for d in dirs] == ["seed-5", "seed-105"]
    for seed, run in zip((5, 105), dirs):
        assert yaml.safe_load((run / "config.yaml").read_text()) == lift_cfg(seed=seed).model_dump()
        summary = json.loads((run / "summary.json").read_text())
        assert summary["frames"] == 400 and summary["seed_group"] == {"seeds": [5, 105]}
    # each seed's buffer holds its own env's transitions: the seeds' warm-ups differ
    buffers = [ReplayBuffer(storage=LazyTensorStorage(1000)) for _ in dirs]
    for buffer, run in zip(buffers, dirs):
        load_buffer_state(buffer, load_checkpoint(run)["buffer"])
        assert len(buffer) == 400
    assert not torch.equal(buffers[0].storage[:100]["observation"], buffers[1].storage[:100]["observation"])
