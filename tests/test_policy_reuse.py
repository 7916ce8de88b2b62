import math

import pytest
import torch
from tensordict import TensorDict
from tensordict.nn import NormalParamExtractor, TensorDictModule, TensorDictSequential
from torch import nn
from torchrl.collectors import Collector
from torchrl.data import Bounded, Composite, Unbounded
from torchrl.envs import EnvBase, StepCounter, TransformedEnv, step_mdp
from torchrl.envs.utils import ExplorationType, set_exploration_type
from torchrl.modules import ProbabilisticActor, TanhNormal

from drltg.collectors import PRQL, JumpStart, PiReuse, PolicyReuse
from drltg.collectors.policy_reuse import NOT_CHOSEN
from drltg.errors import UsageError

LEARNER, PAST = -0.5, 0.5


class LineEnv(EnvBase):
    """Environment i terminates after lengths[i] steps; the observation counts the steps."""

    def __init__(self, lengths):
        super().__init__(batch_size=(len(lengths),))
        n = len(lengths)
        self.lengths = torch.as_tensor(lengths).unsqueeze(-1)
        self.observation_spec = Composite(observation=Unbounded((n, 1)), shape=(n,))
        self.action_spec = Bounded(-1.0, 1.0, (n, 1))
        self.reward_spec = Unbounded((n, 1))

    def _reset(self, tensordict):
        return TensorDict(observation=torch.zeros(*self.batch_size, 1), batch_size=self.batch_size)

    def _step(self, tensordict):
        t = tensordict["observation"] + 1
        done = t >= self.lengths
        return TensorDict(
            observation=t, reward=torch.ones_like(t), terminated=done, done=done.clone(), batch_size=self.batch_size
        )

    def _set_seed(self, seed):
        pass


def constant(value):
    return TensorDictModule(lambda obs: torch.full_like(obs, value), in_keys=["observation"], out_keys=["action"])


def steps_td(step_count, obs_dim=1):
    step_count = torch.as_tensor(step_count).reshape(-1, 1)
    n = step_count.shape[0]
    return TensorDict(
        observation=torch.zeros(n, obs_dim),
        step_count=step_count,
        reuse_index=torch.full((n, 1), NOT_CHOSEN),
        batch_size=(n,),
    )


def mix(module, td, learner=LEARNER):
    td["action"] = torch.full((*td.batch_size, 1), learner)
    with set_exploration_type(ExplorationType.RANDOM):
        return module(td)


def with_primer(env, mixer):
    return env.append_transform(mixer.primer())


def collect(env, policy, frames):
    collector = Collector(
        env, policy, frames_per_batch=frames, total_frames=frames, auto_register_policy_transforms=False
    )
    batch = next(iter(collector))
    collector.shutdown()
    return batch


def test_pi_reuse_psi_h_per_env():
    schedule = PiReuse(psi=0.8, upsilon=0.5)
    psi_h = schedule.probability(torch.tensor([[0], [1], [3]]))
    torch.testing.assert_close(psi_h, torch.tensor([[0.8], [0.4], [0.1]]))


def test_pi_reuse_psi_decays_over_training():
    schedule = PiReuse(psi=1.0, upsilon=0.9, psi_end=0.5, annealing_frames=100)
    schedule.set_progress(50)
    torch.testing.assert_close(schedule.probability(torch.tensor([[0], [2]])), torch.tensor([[0.75], [0.75 * 0.81]]))
    schedule.set_progress(1000)
    assert schedule.psi.item() == pytest.approx(0.5)


def test_psi_resets_at_each_episode_start_per_env():
    # psi = 1, upsilon = 0: the past policy acts exactly at each episode's first step.
    mixer = PolicyReuse(constant(PAST), schedule=PiReuse(1.0, 0.0))
    env = with_primer(TransformedEnv(LineEnv([2, 3, 5]), StepCounter()), mixer)
    policy = TensorDictSequential(constant(LEARNER), mixer)
    batch = collect(env, policy, 3 * 12)
    steps = batch["step_count"].squeeze(-1)
    for i, length in enumerate([2, 3, 5]):
        assert steps[i].tolist() == [t % length for t in range(12)]
    assert torch.equal(batch["reused"].squeeze(-1), steps == 0)
    expected = torch.where(steps == 0, PAST, LEARNER)
    torch.testing.assert_close(batch["action"].squeeze(-1), expected)


def test_fraction_reused_matches_psi_h():
    torch.manual_seed(0)
    psi, upsilon, n = 0.9, 0.8, 4000
    hs = torch.tensor([0, 2, 5, 10])
    mixer = PolicyReuse(constant(PAST), schedule=PiReuse(psi, upsilon))
    td = mix(mixer, steps_td(hs.repeat_interleave(n)))
    reused = td["reused"].squeeze(-1).reshape(len(hs), n)
    for h, row in zip(hs.tolist(), reused):
        p = psi * upsilon**h
        assert abs(row.float().mean().item() - p) < 4 * math.sqrt(p * (1 - p) / n)
    torch.testing.assert_close(td["action"].squeeze(-1), torch.where(td["reused"].squeeze(-1), PAST, LEARNER))


def test_random_actions_lie_in_the_action_box():
    torch.manual_seed(0)
    spec = Bounded(low=torch.tensor([2.0, -10.0]), high=torch.tensor([3.0, -5.0]), shape=(2,))
    mixer = PolicyReuse(constant(PAST), spec=spec, schedule=PiReuse(psi=0.0), epsilon=1.0)
    td = steps_td(torch.zeros(2000, dtype=torch.long))
    td["action"] = torch.zeros(2000, 2)
    with set_exploration_type(ExplorationType.RANDOM):
        action = mixer(td)["action"]
    assert (action >= spec.space.low).all() and (action <= spec.space.high).all()
    torch.testing.assert_close(action.mean(0), torch.tensor([2.5, -7.5]), atol=0.1, rtol=0)
    assert (action[:, 0] > 2.9).any() and (action[:, 1] < -9.5).any()


def test_epsilon_only_replaces_learner_actions():
    torch.manual_seed(0)
    spec = Bounded(2.0, 3.0, shape=(1,))
    mixer = PolicyReuse(constant(PAST), spec=spec, schedule=PiReuse(psi=0.5, upsilon=1.0), epsilon=0.5)
    td = mix(mixer, steps_td(torch.zeros(4000, dtype=torch.long)))
    action, reused = td["action"].squeeze(-1), td["reused"].squeeze(-1)
    assert (action[reused] == PAST).all()
    random = action[~reused] >= 2.0
    assert ((action[~reused] == LEARNER) | random).all()
    assert abs(random.float().mean().item() - 0.5) < 4 * math.sqrt(0.25 / (~reused).sum().item())


def test_deterministic_mode_passes_the_learner_action_through():
    mixer = PolicyReuse(constant(PAST), schedule=PiReuse(psi=1.0))
    td = steps_td(torch.zeros(5, dtype=torch.long))
    td["action"] = torch.full((5, 1), LEARNER)
    with set_exploration_type(ExplorationType.DETERMINISTIC):
        out = mixer(td)
    assert (out["action"] == LEARNER).all() and not out["reused"].any()


def test_past_policy_is_frozen_deterministic_and_not_a_learner_parameter():
    torch.manual_seed(0)
    spec = Bounded(-1.0, 1.0, shape=(1,))
    past = ProbabilisticActor(
        TensorDictModule(
            nn.Sequential(nn.Linear(1, 2), NormalParamExtractor()), in_keys=["observation"], out_keys=["loc", "scale"]
        ),
        in_keys=["loc", "scale"],
        spec=spec,
        distribution_class=TanhNormal,
        distribution_kwargs={"low": -1.0, "high": 1.0},
    )
    learner = TensorDictModule(nn.Linear(1, 1), in_keys=["observation"], out_keys=["action"])
    mixer = PolicyReuse(past, schedule=PiReuse(psi=0.5, upsilon=1.0))
    td = steps_td(torch.zeros(64, dtype=torch.long))
    td["observation"] = torch.randn(64, 1)
    with set_exploration_type(ExplorationType.RANDOM):
        out = TensorDictSequential(learner, mixer)(td.clone())
    out["action"].sum().backward()

    assert all(p.grad is None and not p.requires_grad for p in mixer.past_policies.parameters())
    assert all(p.grad is not None for p in learner.parameters())
    assert {id(p) for p in mixer.past_policies.parameters()}.isdisjoint(map(id, learner.parameters()))
    assert all(p.requires_grad for p in past.parameters())  # the caller's module is left as it was
    with set_exploration_type(ExplorationType.DETERMINISTIC), torch.no_grad():
        greedy = past(td.clone())["action"]
    reused = out["reused"].squeeze(-1)
    assert reused.any()
    torch.testing.assert_close(out["action"][reused], greedy[reused])


def test_prql_choice_probabilities_and_gains_by_hand():
    schedule = PRQL(tau=0.0, tau_step=0.5, gamma=0.5)
    PolicyReuse([constant(PAST), constant(0.25)], schedule=schedule)
    torch.testing.assert_close(schedule.choice_probabilities(), torch.full((3,), 1 / 3))
    schedule.update(torch.tensor([0, 0, 2]), torch.tensor([1.0, 3.0, 4.0]))
    torch.testing.assert_close(schedule.gain, torch.tensor([2.0, 0.0, 4.0]))
    assert schedule.tau.item() == pytest.approx(1.5)
    expected = torch.tensor([3.0, 0.0, 6.0]).exp()
    torch.testing.assert_close(schedule.choice_probabilities(), expected / expected.sum())


def test_prql_learns_discounted_returns_across_batches():
    schedule = PRQL(tau_step=0.0, gamma=0.5)
    mixer = PolicyReuse([constant(PAST), constant(0.25)], schedule=schedule)

    def batch(steps, done):
        t = len(steps)
        return TensorDict(
            reuse_index=torch.ones(1, t, 1, dtype=torch.long),
            step_count=torch.tensor(steps).reshape(1, t, 1),
            next=TensorDict(reward=torch.ones(1, t, 1), done=torch.tensor(done).reshape(1, t, 1)),
            batch_size=(1, t),
        )

    mixer.observe(batch([0, 1], [False, False]))
    assert schedule.uses.tolist() == [0, 0, 0]
    mixer.observe(batch([2, 0], [True, False]))
    assert schedule.uses.tolist() == [0, 1, 0]
    assert schedule.gain[1].item() == pytest.approx(1 + 0.5 + 0.25)


def test_prql_chooses_one_policy_per_episode():
    torch.manual_seed(0)
    mixer = PolicyReuse([constant(PAST), constant(0.25)], schedule=PRQL(PiReuse(1.0, 1.0), tau_step=0.0))
    env = with_primer(TransformedEnv(LineEnv([2, 3, 4, 5]), StepCounter()), mixer)
    batch = collect(env, TensorDictSequential(constant(LEARNER), mixer), 4 * 30)
    steps, index = batch["step_count"].squeeze(-1), batch["reuse_index"].squeeze(-1)
    starts = steps == 0
    same_as_previous = index[:, 1:] == index[:, :-1]
    assert (same_as_previous | starts[:, 1:]).all()
    assert len(index.unique()) == 3
    expected = torch.tensor([PAST, 0.25, LEARNER])[index]
    torch.testing.assert_close(batch["action"].squeeze(-1), expected)


def test_jump_start_advances_when_the_combined_return_holds_near_its_best():
    """JSRL's curriculum, by hand: stages 4, tolerance 0.1, so a return advances when >= B - 0.1 |B|.

    returns   B before   threshold   advance   k   H
    -1.0      -inf       -           no        0   100   (the first evaluation sets B = -1)
    -1.05     -1.0       -1.1        yes       1    75   (B stays -1: -1.05 < -1)
     0.5      -1.0       -1.1        yes       2    50   (B = 0.5)
     0.4       0.5        0.45       no        2    50
     0.46      0.5        0.45       yes       3    25
     0.2       0.5        0.45       no        3    25
     0.9       0.5        0.45       yes       4     0   (the learner alone)
     0.9       -          -          no        4     0   (the last stage stays)
    """
    schedule = JumpStart(100, stages=4, tolerance=0.1)
    moved, horizons = [], []
    for value in (-1.0, -1.05, 0.5, 0.4, 0.46, 0.2, 0.9, 0.9):
        moved.append(schedule.evaluated(value))
        horizons.append(schedule.horizon)
    assert moved == [False, True, True, False, True, False, True, False]
    assert horizons == [100, 75, 50, 50, 25, 25, 0, 0]
    schedule.set_progress(10**9)  # frames alone never move it
    assert schedule.horizon == 0 and float(schedule.best) == 0.9


def test_jump_start_compares_the_mean_of_a_stages_last_window_evaluations():
    """window 2, tolerance 0: a stage needs 2 evaluations; the mean of the last 2 at the stage is compared with the
    best such mean. Stage 0: 0.2, 0.4 (mean 0.3 sets B), 0.4 (mean 0.4 >= 0.3: stage 1, its window empties);
    stage 1: 0.1 (one evaluation: no decision), 0.3 (mean 0.2 < 0.4), 0.6 (mean 0.45 >= 0.4: stage 2)."""
    schedule = JumpStart(10, stages=5, tolerance=0.0, window=2)
    stages = []
    for value in (0.2, 0.4, 0.4, 0.1, 0.3, 0.6):
        schedule.evaluated(value)
        stages.append(schedule.current_stage)
    assert stages == [0, 0, 1, 1, 1, 2]
    assert float(schedule.best) == pytest.approx(0.45)


def test_the_curriculum_is_saved_in_the_schedules_state_dict():
    schedule = JumpStart(100, stages=4, tolerance=0.1, window=2)
    for value in (0.5, 0.5, 0.5, 0.7):
        schedule.evaluated(value)
    restored = JumpStart(100, stages=4, tolerance=0.1, window=2)
    restored.load_state_dict(schedule.state_dict())
    assert (restored.horizon, float(restored.best)) == (75, 0.5)
    assert restored.evaluated(0.5) is True  # the window (0.7, 0.5) carried over: mean 0.6 >= 0.45


def test_the_mixer_evaluates_the_combined_policy_only_when_asked():
    """Under DETERMINISTIC, a mixer built with mix_deterministic acts with the guide for the first H steps, as
    in training; by default evaluation sees the learner alone."""
    for mix, expected in ((True, [PAST, PAST, LEARNER, LEARNER]), (False, [LEARNER] * 4)):
        mixer = PolicyReuse(constant(PAST), schedule=JumpStart(2, stages=2, tolerance=0.0), mix_deterministic=mix)
        env = with_primer(TransformedEnv(LineEnv([4]), StepCounter()), mixer)
        with set_exploration_type(ExplorationType.DETERMINISTIC):
            batch = env.rollout(4, TensorDictSequential(constant(LEARNER), mixer), break_when_any_done=False)
        assert batch["action"].squeeze(-1).squeeze(0).tolist() == expected


def test_jump_start_horizon_shrinks_on_a_frame_clock():
    schedule = JumpStart(100, stages=4, frames_per_stage=1000)
    horizons = []
    for frames in [0, 999, 1000, 2500, 3999, 4000, 10**6]:
        schedule.set_progress(frames)
        horizons.append(schedule.horizon)
    assert horizons == [100, 100, 75, 50, 25, 0, 0]
    schedule.set_progress(2500)
    psi_h = schedule.probability(torch.tensor([[0], [49], [50]]))
    assert psi_h.squeeze(-1).tolist() == [1.0, 1.0, 0.0]


def test_mixer_progress_is_saved_in_its_state_dict():
    mixer = PolicyReuse(constant(PAST), schedule=JumpStart(10, stages=2, frames_per_stage=5))
    mixer.set_progress(7)
    restored = PolicyReuse(constant(PAST), schedule=JumpStart(10, stages=2, frames_per_stage=5))
    restored.load_state_dict(mixer.state_dict())
    assert restored.schedule.horizon == 5


def test_step_advances_by_collected_frames_as_torchrl_exploration_modules_do():
    stepped = PolicyReuse(constant(PAST), schedule=JumpStart(10, stages=2, frames_per_stage=5))
    stepped.step(3)
    assert stepped.schedule.horizon == 10 and int(stepped.schedule.frames) == 3
    stepped.step(4)  # 7 frames in all: the second stage, as set_progress(7) gives
    assert stepped.schedule.horizon == 5 and int(stepped.schedule.frames) == 7


def test_bad_arguments_are_usage_errors():
    with pytest.raises(UsageError):
        PolicyReuse([constant(PAST), constant(0.25)])  # a library needs PRQL
    with pytest.raises(UsageError):
        PolicyReuse(constant(PAST), epsilon=0.1)  # random actions need the spec
    with pytest.raises(UsageError):
        PiReuse(psi=1.5)
    with pytest.raises(UsageError, match="must be a TensorDict module writing 'action'.*not a Linear"):
        PolicyReuse(nn.Linear(2, 2))


def library_mixer(generator=None):
    """Two past policies and the learner, each chosen with probability 1/3 at an episode's start."""
    return PolicyReuse(
        [constant(PAST), constant(0.25)], schedule=PRQL(PiReuse(1.0, 1.0), tau_step=0.0), generator=generator
    )


def test_the_episode_choice_is_carried_in_the_rollout_tensordict():
    torch.manual_seed(0)
    mixer = library_mixer()
    env = with_primer(TransformedEnv(LineEnv([3, 3, 3, 3, 3, 3]), StepCounter()), mixer)
    assert env.observation_spec["reuse_index"].dtype == torch.int64
    policy = TensorDictSequential(constant(LEARNER), mixer)
    with set_exploration_type(ExplorationType.RANDOM):
        rollout = env.rollout(9, policy, break_when_any_done=False)
    index = rollout["reuse_index"].squeeze(-1)
    # reset -> -1 (not chosen), drawn at the first step, then carried unchanged to the episode's end
    assert (index >= 0).all()
    episodes = index.reshape(6, 3, 3)
    assert (episodes == episodes[..., :1]).all()
    assert (rollout["next", "reuse_index"].squeeze(-1).reshape(6, 3, 3)[..., :2] == episodes[..., :2]).all()
    assert len(index.unique()) == 3
    torch.testing.assert_close(rollout["action"].squeeze(-1), torch.tensor([PAST, 0.25, LEARNER])[index])


def test_a_partial_reset_redraws_only_the_reset_envs():
    mixer = library_mixer(torch.Generator().manual_seed(7))
    reference = torch.Generator().manual_seed(7)
    probs = torch.full((3,), 1 / 3)
    env = with_primer(TransformedEnv(LineEnv([100] * 6), StepCounter()), mixer)
    policy = TensorDictSequential(constant(LEARNER), mixer)
    with set_exploration_type(ExplorationType.RANDOM):
        td = policy(env.reset())
        first = torch.multinomial(probs, 6, replacement=True, generator=reference)
        assert torch.equal(td["reuse_index"].squeeze(-1), first)
        for _ in range(3):
            td = policy(step_mdp(env.step(td)))
            assert torch.equal(td["reuse_index"].squeeze(-1), first)

        reset = torch.tensor([False, True, False, True, True, False])
        td = env.reset(td.set("_reset", reset.unsqueeze(-1)))
        index = td["reuse_index"].squeeze(-1)
        assert torch.equal(index, torch.where(reset, NOT_CHOSEN, first))
        assert torch.equal(td["step_count"].squeeze(-1), torch.where(reset, 0, 3))
        td = policy(td)
    redrawn = torch.multinomial(probs, 3, replacement=True, generator=reference)
    expected = first.clone()
    expected[reset] = redrawn
    assert torch.equal(td["reuse_index"].squeeze(-1), expected)


def test_the_mixer_refuses_an_environment_without_its_primer():
    mixer = PolicyReuse(constant(PAST))
    td = steps_td([0, 1]).exclude("reuse_index")
    with pytest.raises(KeyError, match="primer"):
        mix(mixer, td)
