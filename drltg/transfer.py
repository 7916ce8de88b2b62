"""The transfer methods as the training loop composes them, from the config's ``transfer`` section.

    transfer.method = none            plain learning on the task (the baseline)
                    = reward-shaping  PotentialShaping(task potential) on the training env
                    = policy-reuse    PolicyReuse(source actor, PiReuse(psi, upsilon)) after the policy
                    = model-reuse     the learner starts from the source run's weights
                    = demonstrations  episodes of the source policy in a buffer of their own, a fixed
                                      share of every batch (drltg.collectors.demonstrations)

Each method is one of drltg's parts (``drltg.transforms``, ``drltg.collectors``, ``drltg.model_reuse``);
this module only reads the config and builds them. ``transfer.source`` is a run directory, or for
policy reuse and demonstrations on the manipulation tasks ``demonstrator:TASK``, the scripted policy of
``TASK`` (``drltg.envs.robosuite.demonstrator_for``) acting as the past policy.
"""
from __future__ import annotations

from pathlib import Path

import yaml
from tensordict.nn import TensorDictModuleBase, TensorDictSequential
from torchrl.envs import EnvBase, TransformedEnv

from drltg.envs import get_task, make_env
from drltg.envs.robosuite.layout import TASKS as MANIPULATION
from drltg.errors import UsageError
from drltg.learners import Agent, make_agent
from drltg.rundir import CHECKPOINT, CONFIG, SUMMARY, is_complete, load_checkpoint

METHODS = ("none", "reward-shaping", "policy-reuse", "model-reuse", "demonstrations")
NEEDS_SOURCE = ("policy-reuse", "model-reuse", "demonstrations")
DEMONSTRATOR = "demonstrator:"


def check(cfg: dict) -> None:
    """Fail early, before anything is trained or written, on an unusable transfer section."""
    t = cfg["transfer"]
    if t["method"] not in METHODS:
        raise UsageError(f"unknown transfer method '{t['method']}'; choose one of: {', '.join(METHODS)}.")
    if t["method"] in NEEDS_SOURCE:
        if not t["source"]:
            raise UsageError(f"transfer.method={t['method']} needs transfer.source, the source run directory.")
        demonstrated = demonstrator_task(t["source"])
        if demonstrated is not None:
            _check_demonstrator(cfg, demonstrated)
            return
        _check_source_run(Path(t["source"]).expanduser(), t)
    if t["method"] == "reward-shaping" and get_task(cfg["task"]).potential is None:
        raise UsageError(f"task '{cfg['task']}' has no shaping potential registered.")


def _check_source_run(run: Path, t: dict) -> None:
    if not (run / CHECKPOINT).is_file():
        raise UsageError(f"transfer.source '{t['source']}' holds no {CHECKPOINT.as_posix()}; train the source first.")
    if not (run / CONFIG).is_file():
        raise UsageError(f"transfer.source '{t['source']}' holds no {CONFIG}; is it a drltg run directory?")
    if not is_complete(run) and not t.get("allow_incomplete"):
        frames = load_checkpoint(run, mmap=True).get("frames", "?")
        raise UsageError(
            f"transfer.source '{t['source']}' did not finish (no {SUMMARY}; its checkpoint is at frame {frames}); "
            f"finish it with `drltg train --resume --run-dir {t['source']}`, or reuse it as it is with "
            "transfer.allow_incomplete=true."
        )


def shaping(cfg: dict):
    """The task's potential-based shaping transform (the task's own potential, the learner's gamma)."""
    from drltg.transforms import PotentialShaping

    spec = get_task(cfg["task"])
    potential = spec.potential({**spec.defaults, **cfg["env"]})
    return PotentialShaping(potential, gamma=cfg["optim"]["gamma"])


def demonstrator_task(source) -> str | None:
    """``TASK`` for a source written ``demonstrator:TASK``, else ``None``."""
    if isinstance(source, str) and source.startswith(DEMONSTRATOR):
        return source[len(DEMONSTRATOR):]
    return None


def _check_demonstrator(cfg: dict, task: str) -> None:
    if cfg["transfer"]["method"] == "model-reuse":
        raise UsageError("a demonstrator has no weights to reuse; use it with policy-reuse or demonstrations.")
    if task not in MANIPULATION or cfg["task"] not in MANIPULATION:
        raise UsageError(
            f"transfer.source=demonstrator:{task} on task '{cfg['task']}': the demonstrator reads the "
            f"manipulation observation and solves {', '.join(MANIPULATION)} only."
        )


def _spaces(env: EnvBase) -> tuple[str, str]:
    """What a policy of ``env`` reads and writes: the observation size, the action spec's kind and size."""
    action = env.full_action_spec_unbatched["action"]
    return (f"{env.full_observation_spec_unbatched['observation'].shape[-1]} observation entries",
            f"{type(action).__name__} actions of shape {tuple(action.shape)}")


def check_same_spaces(source: EnvBase, target: EnvBase, source_name: str, target_name: str) -> None:
    """Refuse to run a policy of ``source`` on ``target`` when they differ in observation or action space."""
    mine, theirs = _spaces(source), _spaces(target)
    if mine != theirs:
        raise UsageError(
            f"the policy of {source_name} reads {mine[0]} and writes {mine[1]}, but {target_name} has "
            f"{theirs[0]} and {theirs[1]}."
        )


def source_actor(cfg: dict, target_env: EnvBase | None = None) -> TensorDictModuleBase:
    """The past policy: the source run's trained actor, rebuilt from its saved config and checkpoint,
    or the scripted demonstrator of ``demonstrator:TASK``. With ``target_env``, a source that observes
    or acts differently is refused here rather than failing inside the first rollout."""
    task = demonstrator_task(cfg["transfer"]["source"])
    if task is not None:
        from drltg.envs.robosuite.demonstrator import demonstrator_for

        return demonstrator_for(task)
    run = Path(cfg["transfer"]["source"]).expanduser()
    src_cfg = yaml.safe_load((run / CONFIG).read_text())
    env = make_env(src_cfg["task"], device=cfg["device"], **src_cfg["env"])
    if target_env is not None:
        check_same_spaces(env, target_env, f"transfer.source '{cfg['transfer']['source']}' ({src_cfg['task']})",
                          f"task '{cfg['task']}'")
    agent = make_agent(env, src_cfg)
    agent.loss.load_state_dict(load_checkpoint(run, map_location=cfg["device"])["loss"])
    return agent.actor


def reuse_policy(cfg: dict, agent: Agent, target_env: EnvBase | None = None):
    """The learner's exploration policy followed by the pi-reuse mixer over the source actor."""
    from drltg.collectors import PiReuse, PolicyReuse

    t = cfg["transfer"]
    schedule = PiReuse(t["psi"], t["upsilon"], psi_end=t["psi_end"], annealing_frames=t["annealing_frames"])
    mixer = PolicyReuse(source_actor(cfg, target_env), schedule=schedule)
    return TensorDictSequential(agent.policy, mixer), mixer


def reuse_weights(cfg: dict, agent: Agent):
    """Initialise every network of the learner (actor, critics, targets) from the source run; a source
    of another kind of learner is refused unless ``transfer.partial`` accepts a partial load."""
    from drltg.model_reuse import load_from_run

    t = cfg["transfer"]
    return load_from_run(agent.loss, t["source"], freeze=t["freeze"], partial=t.get("partial", False))


def demonstrations(cfg: dict, agent: Agent, target_env: EnvBase):
    """``transfer.demo_episodes`` episodes of the source policy (deterministic) on the training task,
    from an env seeded apart from the training and evaluation envs, in a buffer of their own; returns
    it and the frames they took."""
    from drltg.collectors.demonstrations import collect_demonstrations, demonstration_buffer

    policy = source_actor(cfg, target_env)
    env = TransformedEnv(make_env(cfg["task"], batch_size=(cfg["collector"]["num_envs"],), device=cfg["device"],
                                  seed=cfg["seed"] + 20_000, **cfg["env"]))
    for t in agent.env_transforms:
        env.append_transform(t.clone())
    try:
        data = collect_demonstrations(env, policy, cfg["transfer"]["demo_episodes"])
    finally:
        env.close()
    return demonstration_buffer(data, agent.loss.in_keys), data.numel()
