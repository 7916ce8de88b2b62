"""Model reuse: start a target learner from a source learner's weights.

Every entry of the target's ``state_dict`` that the source holds under the same name is copied:
actor, critics, target networks, temperature. When the observation sizes differ, the layers that
read the observation (2-D or ensemble weights ``W[..., out, in]`` that differ only in ``in``) are
mapped column by column. Each such layer reads ``[observation, other inputs]`` (a critic's action
follows the observation), and target observation entry j reads source entry ``input_map[j]``:

    W_target[..., :, j] = W_source[..., :, input_map[j]]    (0 where input_map[j] is None)

New inputs start with zero weights, so on the shared inputs the target computes exactly the
source's function; removed inputs' columns are dropped. Anything else that differs (action sizes,
layer widths) cannot be mapped, and loading refuses rather than guess.
"""
from __future__ import annotations

import fnmatch
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import torch
from torch import nn

from drltg.config import Field, builtin_options
from drltg.errors import UsageError
from drltg.methods.registry import Transfer, TransferMethod, register_method
from drltg.rundir import MODEL_REUSE, load_checkpoint

__all__ = ["LoadReport", "load_weights", "load_from_run", "freeze_parameters"]


@dataclass
class LoadReport:
    """What :func:`load_weights` did, entry by entry (``state_dict`` names)."""

    loaded: list[str] = field(default_factory=list)
    widened: dict[str, tuple[tuple[int, ...], tuple[int, ...]]] = field(default_factory=dict)
    narrowed: dict[str, tuple[tuple[int, ...], tuple[int, ...]]] = field(default_factory=dict)
    skipped: list[str] = field(default_factory=list)
    unused: list[str] = field(default_factory=list)
    frozen: list[str] = field(default_factory=list)
    input_map: list[int | None] | None = None

    def summary(self) -> str:
        """The one-line count of what was loaded."""
        return (
            f"model reuse: {len(self.loaded)} loaded, {len(self.widened)} widened, "
            f"{len(self.narrowed)} narrowed, {len(self.skipped)} skipped (kept as initialised), "
            f"{len(self.unused)} unused, {len(self.frozen)} frozen"
        )

    def __str__(self) -> str:
        lines = [self.summary()]
        if self.input_map is not None:
            shown = ["new" if i is None else str(i) for i in self.input_map]
            lines.append(f"  target observation entries read source entries [{', '.join(shown)}]")
        for name, shapes in (("widened", self.widened), ("narrowed", self.narrowed)):
            lines += [f"  {name:<8} {k}  {list(s)} -> {list(t)}" for k, (s, t) in shapes.items()]
        lines += [f"  skipped  {k}" for k in self.skipped]
        lines += [f"  unused   {k}" for k in self.unused]
        lines += [f"  frozen   {k}" for k in self.frozen]
        return "\n".join(lines)


def _matches(name: str, pattern: str) -> bool:
    return fnmatch.fnmatchcase(name, pattern) or name.startswith(pattern + ".")


def _select(names: Sequence[str], patterns: Sequence[str], what: str) -> set[str]:
    chosen = set()
    for pattern in patterns:
        hits = {n for n in names if _matches(n, pattern)}
        if not hits:
            raise UsageError(f"{what} pattern '{pattern}' matches no entry of the target.")
        chosen |= hits
    return chosen


def _is_input_layer(name: str, source: torch.Tensor, target: torch.Tensor) -> bool:
    return (
        name.endswith("weight")
        and source.ndim == target.ndim >= 2
        and source.shape[:-1] == target.shape[:-1]
        and source.shape[-1] != target.shape[-1]
    )


def _observation_map(
    layers: dict[str, tuple[torch.Tensor, torch.Tensor]], input_map: Sequence[int | None] | None
) -> tuple[list[int | None], int]:
    """The target -> source observation index map and the source observation size."""
    deltas = {t.shape[-1] - s.shape[-1] for s, t in layers.values()}
    if len(deltas) > 1:
        raise UsageError(
            "the layers reading the observation change input size by different amounts "
            f"({sorted(deltas)}), so they cannot be one observation change."
        )
    (delta,) = deltas
    # Without a map, the narrowest such layer is the one reading the observation alone (the actor).
    obs_target = len(input_map) if input_map is not None else min(t.shape[-1] for _, t in layers.values())
    obs_source = obs_target - delta
    if obs_source <= 0 or any(t.shape[-1] < obs_target for _, t in layers.values()):
        raise UsageError(
            f"an observation of {obs_target} entries does not fit the target's input layers; "
            "check input_map's length."
        )
    if input_map is None:
        shared = min(obs_source, obs_target)
        input_map = list(range(shared)) + [None] * (obs_target - shared)
    bad = [i for i in input_map if i is not None and not 0 <= i < obs_source]
    if bad:
        raise UsageError(f"input_map refers to source entries {bad}, but the source observation has {obs_source}.")
    return list(input_map), obs_source


def _map_columns(source: torch.Tensor, target: torch.Tensor, input_map, obs_source: int) -> torch.Tensor:
    extra = target.shape[-1] - len(input_map)
    columns = [-1 if i is None else i for i in input_map] + [obs_source + j for j in range(extra)]
    columns = torch.tensor(columns, device=source.device)
    out = torch.zeros_like(target)
    keep = columns >= 0
    out[..., keep.to(out.device)] = source[..., columns[keep]].to(out)
    return out


@torch.no_grad()
def load_weights(
    target: nn.Module,
    source_state: Mapping[str, torch.Tensor],
    *,
    input_map: Sequence[int | None] | None = None,
    exclude: Sequence[str] = (),
    freeze: Sequence[str] = (),
    partial: bool = False,
) -> LoadReport:
    """Copy ``source_state`` into ``target`` where names match; map observation-size changes.

    Args:
        target: the module to initialise (e.g. a TorchRL ``LossModule``: actor, critics, targets).
        source_state: a ``state_dict`` of the same kind of module (e.g. the source's loss module).
        input_map: for each target observation entry, the source entry it reads, or ``None`` for a
            new input (zero weights). Default: the first entries are shared in order, new entries
            are appended (or the source's last entries dropped).
        exclude: entries to leave as initialised: ``fnmatch`` patterns or name prefixes.
        freeze: parameters to stop training (``requires_grad=False``): patterns or prefixes, e.g.
            ``"actor_network_params"`` for a loss module's whole actor.
        partial: accept a load that leaves trainable parameters of the target (not excluded) as
            initialised because the source has no such entry, as between two kinds of learner
            (``soc`` -> ``sac``, ``td3`` -> ``sac``). Without it such a load is refused: the target
            would silently start mostly from scratch.

    Raises:
        UsageError: no entry matches, an entry differs in more than its input size, or trainable
            parameters are missing from the source and ``partial`` is false.
    """
    target_state = target.state_dict()
    names = list(target_state)
    excluded = _select(names, exclude, "exclude")
    report = LoadReport(unused=[k for k in source_state if k not in target_state])
    common = [k for k in names if k in source_state and k not in excluded]
    if not common:
        raise UsageError("no entry of the source weights matches the target's names; is it the same kind of learner?")

    trainable = {n for n, _ in target.named_parameters()}
    missing = [n for n in names if n in trainable and n not in source_state and n not in excluded]
    if missing and not partial:
        groups = ", ".join(dict.fromkeys(n.split(".")[0] for n in missing))
        raise UsageError(
            f"the source holds {len(common)} of the target's {len(names)} entries and lacks trainable "
            f"ones ({groups}), so the learner would start partly untrained; reuse a run of the same "
            "learner, or accept a partial load (partial=True, or transfer.partial=true)."
        )

    resized = {}
    for name in common:
        source, dest = source_state[name], target_state[name]
        if source.shape == dest.shape:
            continue
        if not _is_input_layer(name, source, dest):
            raise UsageError(
                f"cannot map '{name}' from shape {list(source.shape)} to {list(dest.shape)}: only the "
                "observation size may differ (action sizes and layer widths must match), or exclude it."
            )
        resized[name] = (source, dest)

    new_state = dict(target_state)
    if resized:
        report.input_map, obs_source = _observation_map(resized, input_map)
    for name in names:
        if name not in common:
            report.skipped.append(name)
        elif name in resized:
            source, dest = resized[name]
            new_state[name] = _map_columns(source, dest, report.input_map, obs_source)
            grown = report.widened if dest.shape[-1] > source.shape[-1] else report.narrowed
            grown[name] = (tuple(source.shape), tuple(dest.shape))
        else:
            new_state[name] = source_state[name].to(target_state[name])
            report.loaded.append(name)
    target.load_state_dict(new_state)

    report.frozen = freeze_parameters(target, freeze)
    return report


def freeze_parameters(module: nn.Module, patterns: Sequence[str]) -> list[str]:
    """Stop training the parameters of ``module`` named by ``patterns`` (fnmatch patterns or name
    prefixes); returns their names."""
    frozen = _select([n for n, _ in module.named_parameters()], patterns, "freeze")
    for name, param in module.named_parameters():
        if name in frozen:
            param.requires_grad_(False)
    return [n for n, _ in module.named_parameters() if n in frozen]


def load_from_run(loss_module: nn.Module, run_dir: str | Path, **kwargs) -> LoadReport:
    """Initialise ``loss_module`` from ``<run_dir>/checkpoints/last.pt`` (its ``"loss"`` entry).

    Keyword arguments go to :func:`load_weights`. The checkpoint is unpickled: load only runs you trust.
    """
    checkpoint = load_checkpoint(Path(run_dir).expanduser())
    return load_weights(loss_module, checkpoint["loss"], **kwargs)


def _build(cfg: dict, agent, env, *, resuming: bool) -> Transfer:
    """Every network of the learner (actor, critics, targets) starts from the source run; a resumed
    run has its weights already, and only its frozen parameters are frozen again."""
    t = cfg["transfer"]
    if resuming:
        freeze_parameters(agent.loss, t["freeze"])
        return Transfer()
    report = load_from_run(agent.loss, t["source"], freeze=t["freeze"], partial=t["partial"])
    print(report.summary(), flush=True)
    return Transfer(files={MODEL_REUSE: f"{report}\n"})


MODEL_REUSE_METHOD = register_method(TransferMethod(
    "model-reuse",
    "the learner starts from the source run's weights (observation-size changes mapped)",
    _build,
    source="run",
    options=builtin_options("model-reuse", {
        "freeze": Field(list, "model reuse: parameter-name patterns to keep fixed", item=Field(str),
                       what="a list of parameter-name patterns (e.g. [actor_network_params])"),
        "partial": Field(bool, "model reuse: accept a source whose core networks cannot all be loaded"),
    }),
))
