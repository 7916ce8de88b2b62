"""The sections of a run config, one pydantic model each: every key with its type, range and help."""
from __future__ import annotations

from typing import Annotated, Literal, Optional, Union

from pydantic import Field

from drltg.config.values import (
    MAX_BATCH,
    MAX_EPISODES,
    MAX_FRAMES,
    MAX_OPTIONS,
    MAX_REPEATS,
    Bool,
    Float,
    Int,
    Probability,
    Section,
    accepts,
)

__all__ = [
    "CollectorConfig", "BufferConfig", "OptimConfig", "NetworkConfig", "SACConfig", "TD3Config", "SOCConfig",
    "EvalConfig", "CheckpointConfig", "LogConfig", "ALGO_SECTIONS", "OPTION_POLICIES", "AUTO_EVALUATIONS",
]


class CollectorConfig(Section):
    num_envs: Int = Field(8, ge=1, le=MAX_BATCH, description="training envs stepped as one batch")
    frames_per_batch: Int = Field(32, ge=1, le=MAX_BATCH,
                                  description="frames per collector batch, a multiple of num_envs")
    init_random_frames: Int = Field(1024, ge=0, le=MAX_FRAMES, description="random-action warm-up frames")

    @property
    def warm_up_frames(self) -> int:
        """The frames of random actions a run takes: ``init_random_frames`` rounded up to whole batches."""
        return -(-self.init_random_frames // self.frames_per_batch) * self.frames_per_batch


class BufferConfig(Section):
    size: Int = Field(100_000, ge=1, description="replay capacity (transitions)")
    batch_size: Int = Field(256, ge=1, le=MAX_BATCH, description="minibatch size")


class OptimConfig(Section):
    lr: Float = Field(3.0e-4, gt=0, description="Adam learning rate")
    updates_per_batch: Int = Field(8, ge=1, le=MAX_REPEATS, description="gradient steps per collected batch")
    # (UTD = updates_per_batch / collector.frames_per_batch)
    gamma: Float = Field(0.99, gt=0, le=1, description="discount")
    tau: Float = Field(0.005, gt=0, le=1, description="target-network smoothing")
    cudagraphs: Bool = Field(False, description="replay each gradient update as a captured CUDA graph "
                                                "(CUDA devices only)")


class NetworkConfig(Section):
    hidden: list[Annotated[Int, Field(ge=1)]] = Field(
        [256, 256], min_length=1, description="MLP widths of actor and critics",
        json_schema_extra=accepts("a non-empty list of positive integers (e.g. [64, 64])"))
    layer_norm: Literal["none", "critics", "all"] = Field(
        "none", description="LayerNorm after every hidden layer of the critics, of every network, or none")


class SACConfig(Section):
    alpha_init: Float = Field(1.0, gt=0, description="initial entropy temperature")
    fixed_alpha: Bool = Field(False, description="keep the temperature at alpha_init")
    target_entropy: Union[Literal["auto"], Float] = Field("auto", description="entropy the temperature is tuned to")


class TD3Config(Section):
    exploration_noise: Float = Field(0.1, ge=0, description="std of the exploration noise")
    policy_noise: Float = Field(0.2, ge=0, description="std of the target policy smoothing noise")
    noise_clip: Float = Field(0.5, ge=0, description="clip of the target policy noise")
    policy_delay: Int = Field(2, ge=1, le=MAX_REPEATS, description="critic updates per actor update")


OPTION_POLICIES = ("soft", "egreedy")  # as drltg.losses.soc declares them: a config is checked without torch


class SOCConfig(Section):
    """The soft option-critic (drltg.losses.soc); its action temperature comes from the ``sac`` section."""

    num_options: Int = Field(4, ge=1, le=MAX_OPTIONS, description="options of the soft option-critic (--options)")
    option_policy: Literal[OPTION_POLICIES] = Field(
        "soft", description="policy over options", json_schema_extra=accepts(noun="option policy"))
    option_alpha_init: Optional[Annotated[Float, Field(gt=0)]] = Field(
        None, description="initial option temperature; null: sac.alpha_init")
    fixed_option_alpha: Bool = Field(False, description="keep the option temperature fixed")
    option_target_entropy: Union[Literal["auto"], Float] = Field(
        "auto", description="entropy over options; auto: 0.5 log(num_options)")
    option_epsilon: Probability = Field(0.1, description="exploration of the egreedy option policy")
    deliberation_cost: Float = Field(0.01, ge=0, description="xi, added to the termination advantage")
    option_entropy_bonus: Bool = Field(False, description="the option choice's entropy enters V_Omega")


AUTO_EVALUATIONS = 20
"""The evaluations after frame 0 that ``eval.every=auto`` gives a run at least. The report reads a curve at its
evaluations: its convergence check fits a line to the last 25% of the budget and needs 4 points there
(12 intervals), its asymptote is the mean over the last 10% (2 points at 20), and a time to threshold is
known to within one interval (5% of the budget at 20)."""


class EvalConfig(Section):
    every: Union[Literal["auto"], Annotated[Int, Field(ge=1, le=MAX_FRAMES)]] = Field(
        "auto", description=f"frames between evaluations; auto: the largest 1, 2 or 5 x 10^k frames that gives at "
                            f"least {AUTO_EVALUATIONS} after frame 0 (1000 at 20k frames, 5000 at 100k)")
    episodes: Int = Field(16, ge=1, le=MAX_EPISODES, description="evaluation episodes")
    stop_at_success: Optional[Annotated[Float, Field(gt=0, le=1)]] = Field(
        None, description="end the run at the first evaluation whose success rate reaches this (its last "
                          "checkpoint that policy); null: train every frame")

    def interval(self, frames: int) -> int:
        """The frames between evaluations of a run of ``frames`` frames: ``every``, or for ``auto`` the largest
        n = m x 10^k (m in 1, 2, 5) with n <= frames / :data:`AUTO_EVALUATIONS`: between 20 and 50 evaluations
        after frame 0, at round frames."""
        if self.every != "auto":
            return self.every
        most = max(1, int(frames) // AUTO_EVALUATIONS)
        power = 10 ** (len(str(most)) - 1)
        return max(m * power for m in (1, 2, 5) if m * power <= most)


class CheckpointConfig(Section):
    every: Int = Field(10_000, ge=1, le=MAX_FRAMES, description="frames between checkpoints")
    keep_best: Bool = Field(False, description="also keep checkpoints/best.pt, the whole training checkpoint of the "
                            "best evaluation (its networks, checkpoints/best.safetensors, are kept in any case)")
    best_metric: Literal["auto", "success_rate", "lifted_rate", "return_mean"] = Field(
        "auto", description="the evaluation score the best networks maximise; auto: success_rate where the task "
                            "reports it, else return_mean")


class LogConfig(Section):
    tensorboard: Bool = Field(True, description="also log to TensorBoard")
    every: Int = Field(1_000, ge=1, le=MAX_FRAMES, description="frames between logged training scalars")


ALGO_SECTIONS = {"sac": ("sac",), "td3": ("td3",), "soc": ("sac", "soc")}
"""The learner sections each built-in algorithm reads: another algorithm's section does not change its runs
(a registered learner not listed here counts as reading them all)."""

ENV_HELP = "keyword arguments of the task's env factory, checked against its declared defaults"
