"""A transfer's learning before its run trains (:class:`~drltg.transfer.registry.Pretraining`): for a run alone,
and for the members of a seed group as one vmapped update."""
from __future__ import annotations

import time
from typing import Sequence

import torch
from tensordict import TensorDict

from drltg.learners import UpdateStep, sample_batches
from drltg.training.seed_group import SeedGroup
from drltg.transfer import Pretraining


def pretrain(problem: Pretraining) -> dict:
    """``problem.steps`` updates of its agent on batches of its buffer (fewer where its ``stop`` may end it),
    drawn from its own random state, the run's own generator left as it was; returns its summary entries, with
    the seconds it took (``pretraining_s``)."""
    start = time.perf_counter()
    step, taken, stopped = UpdateStep(problem.agent, threads=None), 0, False
    with torch.random.fork_rng(devices=[]):
        torch.set_rng_state(problem.rng)
        while taken < problem.steps and not stopped:
            losses = step(problem.buffer.sample())
            taken += 1
            stopped = problem.stop is not None and problem.stop(losses) and problem.can_stop
    return {**problem.finish(taken, stopped), "pretraining_s": round(time.perf_counter() - start, 2)}


PRETRAIN_CHUNK = 100
"""Steps of a group's pretraining whose batches each member draws at once, from its own random state."""


def pretrain_together(problems: Sequence[Pretraining]) -> list[dict]:
    """The members' :class:`~drltg.transfer.registry.Pretraining` as one vmapped update (:class:`SeedGroup`),
    each member's batches drawn from its own random state as it draws them alone (:func:`sample_batches`, equal
    draw for draw), so each learns what it learns alone up to the vmapped arithmetic's round-off; members of one
    ``key`` learn once. Where a member may stop early, or the members take different numbers of steps, each
    learns alone (:func:`pretrain`). Returns each member's summary entries."""
    if any(p.can_stop for p in problems) or len({p.steps for p in problems}) > 1:
        return [pretrain(p) for p in problems]
    start = time.perf_counter()
    keyed: dict = {}
    for p in problems:
        keyed.setdefault(id(p) if p.key is None else p.key, []).append(p)
    members = list(keyed.values())
    group = SeedGroup([same[0].agent for same in members])
    states = [same[0].rng for same in members]
    done, steps = 0, problems[0].steps
    while done < steps:
        count = min(PRETRAIN_CHUNK, steps - done)
        drawn = []
        for k, same in enumerate(members):
            with torch.random.fork_rng(devices=[]):
                torch.set_rng_state(states[k])
                drawn.append(sample_batches(same[0].buffer, count))
                states[k] = torch.get_rng_state()
        for i in range(count):
            losses = group.update(torch.stack([batches[i] for batches in drawn]))
            for k, same in enumerate(members):
                for p in same:
                    if p.stop is not None:
                        p.stop(losses[k])
        done += count
    group.sync()
    with torch.no_grad():
        for same in members:
            learnt = TensorDict.from_module(same[0].agent.loss)
            for p in same[1:]:
                TensorDict.from_module(p.agent.loss).update_(learnt)
    seconds = round(time.perf_counter() - start, 2)  # the group's, as each member's wall_time_s is
    return [{**p.finish(steps, False), "pretraining_s": seconds} for p in problems]
