"""Kickstarting's distillation term: hand-computed divergences, the weight schedule, weight 0 is the learner's
own update exactly, and a teacher of another size distils."""

import math

import pytest
import torch
from tensordict import TensorDict
from tensordict.nn import TensorDictModule
from torch import nn
from torchrl.data import Bounded, OneHot
from torchrl.modules import OneHotCategorical, ProbabilisticActor, TanhNormal, ValueOperator
from torchrl.objectives import DiscreteSACLoss, SACLoss

from drltg import config as config_lib
from drltg.envs import make_env
from drltg.learners import UpdateStep, make_agent
from drltg.losses import KickstartingWeight, distillation

BOX = Bounded(-torch.ones(1), torch.ones(1), (1,))


class Constant(nn.Module):
    """Outputs fixed parameters whatever the observation (a policy computed by hand)."""

    def __init__(self, *values):
        super().__init__()
        self.values = nn.ParameterList([nn.Parameter(torch.tensor(v)) for v in values])

    def forward(self, obs):
        return tuple(v.expand(*obs.shape[:-1], *v.shape) for v in self.values)


def gaussian_actor(loc, scale):
    return ProbabilisticActor(TensorDictModule(Constant([loc], [scale]), ["observation"], ["loc", "scale"]),
                              in_keys=["loc", "scale"], spec=BOX, distribution_class=TanhNormal,
                              distribution_kwargs={"low": BOX.space.low, "high": BOX.space.high})


def states(n=4):
    return TensorDict({"observation": torch.randn(n, 2), "action": torch.zeros(n, 1)}, [n])


def sac_loss(actor):
    critic = ValueOperator(nn.Linear(3, 1), in_keys=["observation", "action"])
    return SACLoss(actor, critic, action_spec=BOX)


def test_gaussian_kl_is_the_hand_computed_kl_before_the_tanh():
    # KL(N(0, 1) || N(1, 2)) = log(2/1) + (1 + (0 - 1)^2) / (2 * 4) - 1/2
    term = distillation(sac_loss(gaussian_actor(1.0, 2.0)), gaussian_actor(0.0, 1.0), 3.0)
    out = term(states())
    expected = math.log(2.0) + 2.0 / 8.0 - 0.5
    assert out["distill_gap"].item() == pytest.approx(expected, rel=1e-6)
    assert out["loss_actor_distill"].item() == pytest.approx(3.0 * expected, rel=1e-6)


def test_the_same_policy_has_zero_gap_and_a_deterministic_teacher_is_scored_by_log_likelihood():
    assert distillation(sac_loss(gaussian_actor(0.5, 0.3)), gaussian_actor(0.5, 0.3), 1.0)(states())[
        "distill_gap"].item() == pytest.approx(0.0, abs=1e-7)
    teacher = TensorDictModule(lambda obs: torch.full((*obs.shape[:-1], 1), 0.25), ["observation"], ["action"])
    student = gaussian_actor(0.0, 1.0)
    gap = distillation(sac_loss(student), teacher, 1.0)(states())["distill_gap"].item()
    dist = TanhNormal(torch.zeros(1), torch.ones(1), low=BOX.space.low, high=BOX.space.high)
    assert gap == pytest.approx(-dist.log_prob(torch.tensor([0.25])).item(), rel=1e-5)


def test_categorical_kl_is_the_hand_computed_kl():
    spec = OneHot(2)

    def actor(p):
        logits = torch.log(torch.tensor(p))
        return ProbabilisticActor(TensorDictModule(Constant(logits.tolist()), ["observation"], ["logits"]),
                                  in_keys=["logits"], spec=spec, distribution_class=OneHotCategorical)

    critic = TensorDictModule(nn.Linear(2, 2), ["observation"], ["action_value"])
    loss = DiscreteSACLoss(actor([0.25, 0.75]), critic, action_space=spec, num_actions=2)
    gap = distillation(loss, actor([0.5, 0.5]), 1.0)(states())["distill_gap"].item()
    assert gap == pytest.approx(0.5 * math.log(0.5 / 0.25) + 0.5 * math.log(0.5 / 0.75), rel=1e-6)


@pytest.mark.parametrize("decay, frames, expected", [
    ("linear", 0, 2.0), ("linear", 25, 1.5), ("linear", 100, 0.0), ("linear", 150, 0.0),
    ("exponential", 0, 2.0), ("exponential", 50, 0.2), ("exponential", 99, 2.0 * 0.01 ** 0.99),
    ("exponential", 100, 0.0),
])
def test_weight_schedule(decay, frames, expected):
    assert KickstartingWeight(2.0, 100, decay)(frames) == pytest.approx(expected, rel=1e-12)


def test_an_exponential_weight_reaches_its_floor_at_frames():
    """floor 0.25 over F = 100: lambda_0 0.25^(f/100), so 2 * 0.5 at f = 50 and 2 * 0.25^0.75 at f = 75."""
    weight = KickstartingWeight(2.0, 100, "exponential", floor=0.25)
    assert [weight(f) for f in (0, 50, 75, 100)] == pytest.approx([2.0, 1.0, 2.0 * 0.25 ** 0.75, 0.0], rel=1e-12)
    with pytest.raises(ValueError, match="floor must lie in"):
        KickstartingWeight(1.0, 10, "exponential", floor=0.0)


def test_a_weight_without_frames_is_constant_and_bad_schedules_are_refused():
    assert KickstartingWeight(0.5, 0)(10**9) == 0.5
    with pytest.raises(ValueError, match="decay"):
        KickstartingWeight(1.0, 10, "cosine")
    with pytest.raises(ValueError, match="initial >= 0"):
        KickstartingWeight(-1.0, 10)


def agent(hidden, algo="sac", task="fourrooms/northeast", seed=0):
    cfg = config_lib.resolve({}, [f"network.hidden={list(hidden)}"], task=task, algo=algo)
    torch.manual_seed(seed)
    return make_agent(make_env(task, seed=0, **cfg.env), cfg)


def batch(task="fourrooms/northeast", n=32):
    env = make_env(task, batch_size=(n,), seed=3)
    torch.manual_seed(3)
    return env.rand_step(env.reset())


@pytest.mark.parametrize("algo", ["sac", "td3"])
def test_weight_zero_is_the_learners_own_update_exactly(algo):
    plain, kicked, teacher = agent((16, 16), algo), agent((16, 16), algo), agent((8,), algo, seed=1)
    data = batch()
    torch.manual_seed(7)
    UpdateStep(plain)(data.clone(), True)
    torch.manual_seed(7)
    UpdateStep(kicked, loss_terms=distillation(kicked.loss, teacher.actor, 0.0))(data.clone(), True)
    for a, b in zip(plain.loss.parameters(), kicked.loss.parameters()):
        assert torch.equal(a, b)


@pytest.mark.parametrize("algo, task", [("sac", "fourrooms/northeast"), ("td3", "fourrooms/northeast"),
                                        ("sac", "gridrooms/northeast")])
def test_a_smaller_teacher_pulls_the_student_towards_it_and_stays_as_it_was(algo, task):
    student, teacher = agent((32, 32), algo, task), agent((8,), algo, task, seed=1)
    teacher_before = [p.clone() for p in teacher.actor.parameters()]
    term = distillation(student.loss, teacher.actor, 1.0)
    data = batch(task)
    gaps = []
    optimizer = torch.optim.Adam(student.loss.actor_network_params.values(True, True), lr=1e-2)
    for _ in range(30):
        out = term(data)
        gaps.append(out["distill_gap"].item())
        optimizer.zero_grad()
        out["loss_actor_distill"].backward()
        optimizer.step()
    assert gaps[-1] < 0.5 * gaps[0]
    assert all(torch.equal(a, b) for a, b in zip(teacher_before, teacher.actor.parameters()))
