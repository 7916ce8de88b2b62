r"""Reward features for successor features: :math:`r(s, a, s') = \phi(s, a, s')^\top w`.

Successor features (Barreto et al. 2017) split a task's reward into features the tasks of a family share
and weights that tell the tasks apart. For a family of goal-reaching tasks with the FourRooms rewards
(``+1`` on entering the goal, ``-step_cost`` on every other step) and a fixed list of ``K`` candidate goals,
the task's own reward-relevant features are exact:

.. math::

    \phi(s') = \big[\mathbb 1\{s' \in G_1\}, \dots, \mathbb 1\{s' \in G_K\}, 1\big], \qquad
    w_j = (1 + c)\, e_j - c\, e_{K+1}

where :math:`G_k` is goal ``k``'s region (a grid cell, or the continuous goal disc
:math:`\|p' - g_k\| \le \rho`) and :math:`c` the step cost: entering goal ``j`` pays
:math:`(1 + c) - c = 1`, any other step :math:`-c`. The assumption: the target's goal is one of the
candidates, with the same disc radius and step cost; the regions do not overlap.

Where the weights are not known, :func:`regress_weights` learns them from the target's transitions by least
squares, the papers' reward regression.
"""
from __future__ import annotations

from collections.abc import Sequence

import torch
from tensordict import NestedKey, TensorDictBase
from tensordict.nn import TensorDictModuleBase

from drltg.errors import UsageError

__all__ = ["GoalFeatures", "regress_weights"]


class GoalFeatures(TensorDictModuleBase):
    r"""``phi(s') = [in goal 1, ..., in goal K, 1]`` from the next state (see the module docstring).

    Reads ``("next", state_key)`` and writes ``("next", "features")`` ``[*, K + 1]`` (float32), so it runs
    on collected or replayed batches before :class:`~drltg.losses.SuccessorFeatureLoss`.

    Args:
        goals: the ``K`` candidate goals: grid cells ``(row, col)`` or continuous centres ``(x, y)``.
        radius: the goal disc's radius for continuous states; ``None`` for grid cells (exact match).
        state_key: the state entry (``"cell"`` on the grid, ``"position"`` in continuous FourRooms).
        features_key: where the features are written, under ``"next"``.

    Use :meth:`for_env` to read the radius and state entry off a FourRooms env, and :meth:`task_weights` for
    the exact ``w`` of one candidate goal.
    """

    def __init__(
        self,
        goals: Sequence[Sequence[float]] | torch.Tensor,
        *,
        radius: float | None = None,
        state_key: NestedKey = "cell",
        features_key: NestedKey = "features",
    ) -> None:
        super().__init__()
        goals_t = torch.as_tensor(goals, dtype=torch.float32)
        if goals_t.ndim != 2 or goals_t.shape[0] < 1:
            raise UsageError(f"goals must be a non-empty list of points, got shape {tuple(goals_t.shape)}.")
        if radius is not None and not radius > 0:
            raise UsageError(f"the goal radius {radius} must be positive.")
        self.register_buffer("goals", goals_t)
        self.radius = None if radius is None else float(radius)
        self.in_keys = [("next", state_key)]
        self.out_keys = [("next", features_key)]

    @classmethod
    def for_env(cls, env, goals: Sequence[Sequence[float]], **kwargs) -> GoalFeatures:
        """Features over ``goals`` for a FourRooms env (grid or continuous): its state entry and goal radius."""
        return cls(goals, radius=getattr(env, "goal_radius", None), state_key=env.state_key, **kwargs)

    @property
    def num_features(self) -> int:
        """``K + 1``: one per candidate goal and the constant (step cost) feature."""
        return self.goals.shape[0] + 1

    def phi(self, state: torch.Tensor) -> torch.Tensor:
        """``[*, K + 1]`` features of next states ``[*, D]``."""
        goals = self.goals.to(state.device)
        offset = state.unsqueeze(-2).to(goals.dtype) - goals
        if self.radius is None:
            inside = (offset == 0).all(-1)
        else:
            inside = torch.linalg.vector_norm(offset, dim=-1) <= self.radius
        ones = torch.ones_like(inside[..., :1])
        return torch.cat((inside, ones), -1).to(torch.float32)

    def task_weights(self, goal: Sequence[float], step_cost: float) -> torch.Tensor:
        """The exact ``w`` of the task whose goal is ``goal`` (one of the candidates): ``(1 + c) e_j - c e_{K+1}``."""
        match = (self.goals == torch.as_tensor(goal, dtype=torch.float32)).all(-1).nonzero()
        if match.numel() != 1:
            raise UsageError(f"goal {tuple(goal)} is not one of the candidate goals {self.goals.tolist()}.")
        w = torch.zeros(self.num_features)
        w[match.item()] = 1.0 + step_cost
        w[-1] = -step_cost
        return w

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        return tensordict.set(self.out_keys[0], self.phi(tensordict.get(self.in_keys[0])))


def regress_weights(features: torch.Tensor, reward: torch.Tensor) -> torch.Tensor:
    r"""Reward regression: :math:`w = \arg\min_w \|\Phi w - r\|^2` over transitions (Barreto et al. 2017).

    Args:
        features: ``[N, d]`` (or any ``[..., d]``) features of the target's transitions.
        reward: their rewards, ``[N]`` or ``[N, 1]`` (any shape with ``N`` elements).

    Returns ``w`` ``[d]`` (float32). The minimum-norm solution: a feature that is zero on every transition
    (a goal never reached in the data) gets weight 0, so exact features recover the exact ``w`` whenever
    the target's own goal and an ordinary step are both in the data.
    """
    phi = features.reshape(-1, features.shape[-1]).detach().cpu().double()
    r = reward.reshape(-1, 1).detach().cpu().double()
    if phi.shape[0] == 0 or phi.shape[0] != r.shape[0]:
        raise UsageError(f"reward regression needs one reward per feature row and at least one row; got "
                         f"{phi.shape[0]} feature rows and {r.shape[0]} rewards.")
    return torch.linalg.lstsq(phi, r, driver="gelsd").solution.squeeze(-1).float()
