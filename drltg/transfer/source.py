"""Where transferred knowledge comes from: ``transfer.source``, a source run or a scripted demonstrator.

``transfer.source`` is a drltg run directory (its ``config.yaml`` and the networks of ``checkpoints/last.pt``,
or of its best evaluation with ``transfer.source_checkpoint=best``, read from the networks file of each,
:mod:`drltg.store.networks`), or for methods that reuse a policy on
the manipulation tasks ``demonstrator:TASK``, the scripted policy of ``TASK``
(:func:`drltg.envs.robosuite.demonstrator_for`) acting as the past policy. :func:`check` runs before
anything is trained or written; :func:`source_actor` rebuilds the past policy. In user code,
:func:`load_actor`, :func:`load_critic` and :func:`load_agent` rebuild a run's actor, value or whole
learner from its run directory in one call (``checkpoint="best"``: from its best evaluated checkpoint).
:func:`record` names the source a run loaded by content, for its ``summary.json``; :func:`start_record` keeps
it from the run's first start and refuses a resume from a source changed since.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

from drltg import config
from drltg.config import RunConfig, TransferConfig
from drltg.envs import make_env
from drltg.envs.robosuite.layout import TASKS as MANIPULATION
from drltg.errors import UsageError
from drltg.store import manifest, networks
from drltg.store.networks import NETWORKS
from drltg.store.rundir import (
    CONFIG,
    DEMONSTRATOR,
    SUMMARY,
    check_contents,
    checkpoint_path,
    has_networks,
    is_complete,
    load_networks,
    missing_checkpoint,
)
from drltg.transfer.registry import get_method

if TYPE_CHECKING:
    from tensordict.nn import TensorDictModuleBase
    from torchrl.envs import EnvBase

def check(cfg: RunConfig) -> None:
    """Fail early, before anything is trained or written, on a source the method cannot use."""
    method, t = get_method(cfg.transfer.method), cfg.transfer
    if method.source is None:
        if t.source:
            raise UsageError(f"transfer.source is set, but transfer.method={method.name} reads no source; choose a "
                             "method that reuses it, or drop transfer.source.")
        return
    if not t.source:
        raise UsageError(f"transfer.method={method.name} needs transfer.source, the source run directory.")
    demonstrated = demonstrator_task(t.source)
    if demonstrated is not None and t.source_checkpoint != "last":
        raise UsageError(f"transfer.source_checkpoint={t.source_checkpoint} names a checkpoint of a source run; "
                         f"transfer.source={t.source} is a scripted policy and has none.")
    if demonstrated is None:
        _check_source_run(Path(t.source).expanduser(), t)
    elif method.source != "policy":
        raise UsageError(f"a demonstrator has no weights to reuse; {method.name} needs a source run directory.")
    elif demonstrated not in MANIPULATION or cfg.env.get("task", cfg.task) not in MANIPULATION:
        raise UsageError(  # lift-dense is Lift's scene under another reward: env.task names the scene
            f"transfer.source=demonstrator:{demonstrated} on task '{cfg.task}': the demonstrator reads the "
            f"manipulation observation and solves {', '.join(MANIPULATION)} only."
        )


def _check_source_run(run: Path, t: TransferConfig) -> None:
    if t.source_checkpoint == "best" and not has_networks(run, "best") and (run / CONFIG).is_file():
        raise UsageError(f"transfer.source_checkpoint=best: {missing_checkpoint(t.source, 'best')}")
    if not has_networks(run, t.source_checkpoint) and not networks.listed(run, t.source_checkpoint):
        raise UsageError(f"transfer.source '{t.source}' holds no {NETWORKS[t.source_checkpoint].as_posix()} (nor "
                         f"{checkpoint_path(t.source_checkpoint).as_posix()}); train the source first.")
    if not (run / CONFIG).is_file():
        raise UsageError(f"transfer.source '{t.source}' holds no {CONFIG}; is it a drltg run directory?")
    if not is_complete(run) and not t.allow_incomplete:
        frames = load_networks(run, t.source_checkpoint)[1]["frames"]
        raise UsageError(
            f"transfer.source '{t.source}' did not finish (no {SUMMARY}; its checkpoint is at frame "
            f"{frames}); finish it with `drltg train --resume --run-dir {t.source}`, or reuse it "
            "as it is with transfer.allow_incomplete=true."
        )


RECORD = "source.json"
"""The file of a run directory that holds :func:`record` from the run's first start."""


def record(cfg: RunConfig) -> dict:
    """summary.json's ``source`` entry of a run that loads a source run: the SHA-256 of the networks file it
    reads (``checkpoints/<checkpoint>.safetensors``; the checkpoint itself for a run written before networks
    files) and of the source's ``config.yaml``; the path in the run's ``config.yaml`` is a hint only (a folder
    can be trained again). ``{}`` for a method without a source or a scripted demonstrator. Runs paired by seed
    share a source exactly when these digests are equal (:mod:`drltg.bench.board`)."""
    t = cfg.transfer
    if get_method(t.method).source is None or not t.source or demonstrator_task(t.source) is not None:
        return {}
    run = Path(t.source).expanduser()
    loaded = NETWORKS[t.source_checkpoint]
    loaded = loaded if (run / loaded).is_file() else checkpoint_path(t.source_checkpoint)
    return {"source": {"checkpoint": t.source_checkpoint, "networks": loaded.as_posix(),
                       "networks_sha256": _listed_digest(run, loaded.as_posix()),
                       "config_sha256": manifest.digest(run / CONFIG)}}


def start_record(cfg: RunConfig, run_dir: str | Path, resuming: bool, files: dict[str, str]) -> dict:
    """:func:`record` of a run starting in ``run_dir``, also kept there as :data:`RECORD` (added to ``files``, the
    run's ``Transfer.files``);
    a resumed run whose source now holds other networks or another config than at its first start is refused
    in one sentence, since its training would go on from another teacher than the one it began with."""
    entry = record(cfg)
    path = Path(run_dir) / RECORD
    if entry and resuming and path.is_file():
        from drltg.regular import MAX_META_BYTES, read_bytes

        try:
            earlier = json.loads(read_bytes(path, MAX_META_BYTES, "a source record")).get("source")
        except (OSError, ValueError, AttributeError):
            raise UsageError(f"'{path}' is not the source record drltg wrote (JSON with a 'source' mapping); "
                             "restore it, or train the run again.") from None
        changed = [k for k in ("networks_sha256", "config_sha256")
                   if not isinstance(earlier, dict) or earlier.get(k) != entry["source"][k]]
        if changed:
            what = " and ".join("networks" if k == "networks_sha256" else "config.yaml" for k in changed)
            raise UsageError(f"transfer.source '{cfg.transfer.source}' changed since this run started: {path} "
                             f"records another SHA-256 of its {what}, so the run would go on from another teacher; "
                             "restore the source, or train the run again.")
    if entry:
        files[RECORD] = json.dumps(entry, indent=1) + "\n"
    return entry


def _listed_digest(run: Path, name: str) -> str:
    """The SHA-256 of ``run/name``: the manifest's where it lists one alone (the networks are read only when
    their bytes match it, :func:`drltg.store.networks.load`), else the file's own."""
    listed = manifest.read(run).get(name, [])
    return listed[0] if len(listed) == 1 else manifest.digest(run / name)


def demonstrator_task(source) -> str | None:
    """``TASK`` for a source written ``demonstrator:TASK``, else ``None``."""
    if isinstance(source, str) and source.startswith(DEMONSTRATOR):
        return source[len(DEMONSTRATOR):]
    return None


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


class Rebuilt(NamedTuple):
    agent: Any
    """:class:`drltg.learners.Agent` with the checkpoint's weights"""
    env: Any
    """one env of the run's task, built with its ``env`` settings"""
    cfg: RunConfig
    frames: int | None
    """the frame of the checkpoint the networks are from"""


def rebuild(run_dir, device: str = "cpu", checkpoint: str = "last") -> Rebuilt:
    """A run's learner, its env and its config, rebuilt from ``config.yaml`` and the networks of
    ``checkpoints/last.pt`` (``checkpoint="best"``: of ``best.pt``), read from ``last.safetensors``
    (:func:`drltg.store.rundir.load_networks`); anything that keeps it from being built is one
    :class:`UsageError` sentence."""
    from drltg.learners import make_agent

    run = Path(run_dir).expanduser()
    check_contents(run)
    if not (run / CONFIG).is_file():
        raise UsageError(f"'{run_dir}' is not a drltg run directory: it holds no {CONFIG}.")
    if not has_networks(run, checkpoint) and not networks.listed(run, checkpoint):
        raise UsageError(missing_checkpoint(run_dir, checkpoint) if checkpoint == "best" else
                         f"'{run_dir}' is not a drltg run directory: it holds no {NETWORKS[checkpoint].as_posix()} "
                         f"(nor {checkpoint_path(checkpoint).as_posix()}).")
    from drltg import safe_yaml

    data = safe_yaml.load_file(run / CONFIG)
    if not isinstance(data, dict) or not {"task", "algo", "env"} <= set(data):
        raise UsageError(f"'{run / CONFIG}' is not a drltg run config (it lacks task, algo or env).")
    try:
        cfg = config.build(data, saved=True)
        env = make_env(cfg.task, device=device, **cfg.env)
    except UsageError as err:
        raise UsageError(f"run '{run_dir}' cannot be rebuilt: {err}") from None
    agent = make_agent(env, cfg)
    saved, info = load_networks(run, checkpoint, map_location=device)
    path = run / (NETWORKS[checkpoint] if (run / NETWORKS[checkpoint]).is_file() else checkpoint_path(checkpoint))
    reason = networks.mismatch(agent.loss.state_dict(), saved)
    if reason:
        raise UsageError(f"'{path}' does not fit the {cfg.algo} learner its {CONFIG} describes ({reason}).")
    agent.loss.load_state_dict(saved)
    return Rebuilt(agent, env, cfg, info.get("frames"))


def load_agent(run_dir, *, device: str = "cpu", checkpoint: str = "last"):
    """A trained run's learner (:class:`drltg.learners.Agent`: actor, loss with critics, temperature),
    rebuilt from the run directory's ``config.yaml`` and the networks of ``checkpoints/last.pt``
    (``checkpoint="best"``: of the best evaluation), read from their networks file ``last.safetensors``
    (``best.safetensors``) without opening the training checkpoint. Prints nothing. The file is data only (no
    code in it runs) and checked against the run's manifest, so a run from anyone can be loaded."""
    return rebuild(run_dir, device, checkpoint).agent


def load_actor(run_dir, *, device: str = "cpu", checkpoint: str = "last") -> TensorDictModuleBase:
    """A trained run's actor: reads ``"observation"``, writes ``"action"`` (its mean/greedy action under
    ``ExplorationType.DETERMINISTIC``), e.g. the past policy of :class:`drltg.collectors.PolicyReuse`."""
    return load_agent(run_dir, device=device, checkpoint=checkpoint).actor


def load_critic(run_dir, *, device: str = "cpu", scale: float = 1.0, checkpoint: str = "last"):
    """A trained run's value of a state, V(s) = scale * min_k Q_k(s, mu(s)) (its twin critics at its own
    deterministic action), as a frozen module of the observation: :class:`drltg.transforms.SourceValue`,
    the potential of value shaping. SAC, discrete-SAC and TD3 runs."""
    from torchrl.data import OneHot

    from drltg.transforms import SourceValue

    agent, env, _, _ = rebuild(run_dir, device, checkpoint)
    discrete = isinstance(env.full_action_spec_unbatched["action"], OneHot)
    return SourceValue(agent.loss, discrete=discrete, scale=scale)


def source_agent(cfg: RunConfig, target_env: EnvBase | None = None):
    """The learner of ``transfer.source`` (:func:`load_agent`), from its ``transfer.source_checkpoint``.
    With ``target_env``, a source that observes or acts differently is refused here rather than failing
    inside the first rollout."""
    agent, env, src_cfg, _ = rebuild(cfg.transfer.source, cfg.device, cfg.transfer.source_checkpoint)
    if target_env is not None:
        check_same_spaces(env, target_env, f"transfer.source '{cfg.transfer.source}' ({src_cfg.task})",
                          f"task '{cfg.task}'")
    return agent


def source_actor(cfg: RunConfig, target_env: EnvBase | None = None) -> TensorDictModuleBase:
    """The past policy: the source run's trained actor (:func:`source_agent`), or the scripted
    demonstrator of ``demonstrator:TASK``."""
    task = demonstrator_task(cfg.transfer.source)
    if task is not None:
        from drltg.envs.robosuite.demonstrator import demonstrator_for

        return demonstrator_for(task)
    return source_agent(cfg, target_env).actor
