"""Every example runs with a tiny budget and prints what it claims: hand-checkable values, not just rc 0.

All examples run in one subprocess, one after the other (``runpy``, so torch is imported once), each with
its own ``sys.argv`` and captured stdout; a failing example fails its own test with its traceback.
"""
import json
import math
import os
import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
FRAMES = "320"
RUNNER = """
import contextlib, io, json, runpy, sys, traceback
examples, out = json.loads(sys.argv[1]), sys.argv[2]
results = {}
for name, argv in examples.items():
    sys.argv, stdout = [argv[0], *argv[1:]], io.StringIO()
    try:
        with contextlib.redirect_stdout(stdout):
            runpy.run_path(argv[0], run_name="__main__")
        results[name] = {"stdout": stdout.getvalue(), "error": None}
    except BaseException:
        results[name] = {"stdout": stdout.getvalue(), "error": traceback.format_exc()}
with open(out, "w") as f:
    json.dump(results, f)
"""
WITH_OUT = ("value_shaping", "policy_reuse", "jumpstart", "model_reuse", "demonstrations", "custom_env", "kickstarting")
NAMES = ("reward_shaping", "soft_option_critic", "train_sac_fourrooms", "successor_features", *WITH_OUT)


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("examples")
    argv = {name: [str(EXAMPLES / f"{name}.py"), "--frames", FRAMES] for name in NAMES}
    for name in WITH_OUT:
        argv[name] += ["--out", str(tmp / name)]
    done = subprocess.run(
        [sys.executable, "-c", RUNNER, json.dumps(argv), str(tmp / "results.json")],
        cwd=tmp, capture_output=True, text=True, timeout=900,
        env={**os.environ, "RL_WARNINGS": "False", "PYTHONPATH": os.pathsep.join([str(EXAMPLES.parent), os.environ.get(
            "PYTHONPATH", "")])},
    )
    assert done.returncode == 0, done.stderr[-3000:]
    return json.loads((tmp / "results.json").read_text())


def output(runs, name) -> list[str]:
    run = runs[name]
    assert run["error"] is None, run["error"]
    return run["stdout"].splitlines()


def tagged(lines, tag) -> list[dict]:
    return [json.loads(line.split(" ", 1)[1]) for line in lines if line.startswith(tag + " ")]


def check_evaluation(result):
    """One deterministic episode on each of 16 eval envs of FourRooms: +1 at the goal, -0.01 a step, 100 steps.
    A failed episode returns exactly -1 (100 steps of -0.01), one that reaches the goal at step s 1 - 0.01 (s - 1),
    in (0, 1]: the mean lies in (-failures, successes] / 16, and is -1 where no episode succeeds."""
    assert result["episodes"] == 16
    successes = result["success_rate"] * 16
    assert 0 <= successes <= 16 and successes == round(successes)
    failed = 16 - round(successes)
    assert -failed / 16 - 1e-6 <= result["return_mean"] <= (successes - failed) / 16 + 1e-6
    if failed < 16:
        assert result["return_mean"] > -failed / 16
    else:
        assert result["return_mean"] == pytest.approx(-1.0, abs=1e-6)


def check_shaping(task_reward, phi, phi_next, terminated, reward, gamma=0.99):
    for r, p, q, done, shaped in zip(task_reward, phi, phi_next, terminated, reward):
        assert shaped == pytest.approx(r + gamma * q * (1 - done) - p, abs=1e-6)


def test_reward_shaping_adds_gamma_phi_next_minus_phi(runs):
    lines = output(runs, "reward_shaping")
    steps = tagged(lines, "step")
    assert len(steps) == 3
    check_shaping(*([s[k] for s in steps] for k in ("next/task_reward", "potential", "next/potential",
                                                      "next/terminated", "next/reward")))
    assert all(-1.0 <= s["potential"] <= 0.0 for s in steps)  # Phi = -(path length to the goal) / max
    assert [s["potential"] for s in steps[1:]] == [s["next/potential"] for s in steps[:-1]]  # each Phi once
    (result,) = tagged(lines, "result")
    check_evaluation(result)


def test_value_shaping_uses_the_source_value_as_potential(runs):
    lines = output(runs, "value_shaping")
    (shaping,) = tagged(lines, "potential")
    assert shaping["phi_minus_source_value"] == 0.0
    check_shaping(shaping["task_reward"], shaping["phi"], shaping["phi_next"], shaping["terminated"], shaping["reward"])
    check_evaluation(tagged(lines, "result")[0])


def test_policy_reuse_acts_with_the_source_action_where_it_reuses(runs):
    (result,) = tagged(output(runs, "policy_reuse"), "result")
    assert result["source_action_gap"] == 0.0
    assert 0.0 < result["reused_fraction"] <= 1.0
    check_evaluation(result)


def test_jumpstart_guides_exactly_the_first_h_steps(runs):
    from drltg.collectors import JumpStart

    (result,) = tagged(output(runs, "jumpstart"), "result")
    assert result["guided_as_scheduled"] is True
    schedule = JumpStart(20, stages=4, tolerance=0.05)  # the horizons JSRL's rule gives after each evaluation
    assert result["horizons"] == [(schedule.evaluated(r), schedule.horizon)[1] for r in result["combined_returns"]]
    assert len(result["horizons"]) >= 4 and set(result["horizons"]) <= {20, 15, 10, 5, 0}
    check_evaluation(result)


def test_model_reuse_starts_as_the_source_policy(runs):
    lines = output(runs, "model_reuse")
    # widened: the first layers of the actor, the critics and the target critics (2 -> 4 inputs)
    assert lines[0].startswith("model reuse: 19 loaded, 3 widened, 0 narrowed, 0 skipped")
    (start,) = tagged(lines, "start")
    assert start["action_gap_to_source"] == 0.0
    check_evaluation(start)
    check_evaluation(tagged(lines, "result")[0])


def test_demonstrations_fill_a_fixed_share_of_every_batch(runs):
    (result,) = tagged(output(runs, "demonstrations"), "result")
    assert result["k"] == round(0.25 * 256) and result["demo_rows"] == result["k"]
    assert result["demonstration_frames"] >= 8 and result["demonstration_frames"] % 8 == 0  # 8 envs, whole steps
    check_evaluation(result)


def test_kickstarting_starts_away_from_the_teacher_and_ends_on_its_own(runs):
    (result,) = tagged(output(runs, "kickstarting"), "result")
    assert result["first_kl"] > 0.0 and result["last_kl"] >= 0.0  # a wider student starts elsewhere
    assert result["final_weight"] == 0.0  # the weight reached 0 at half the frames
    check_evaluation(result)


def test_soft_option_critic_reports_its_options(runs):
    (result,) = tagged(output(runs, "soft_option_critic"), "result")
    usage = [result[f"option_usage/{o}"] for o in range(result["options"])]
    assert result["options"] == 4 and math.isclose(sum(usage), 1.0, abs_tol=1e-6)
    assert result["option_length"] >= 1.0
    check_evaluation(result)


def test_sac_and_custom_env_examples_print_their_evaluations(runs):
    evaluations = [line for line in output(runs, "train_sac_fourrooms") if line.startswith("frames")]
    assert evaluations and all(-1.0 - 1e-6 <= float(line.split("return ")[1].split(",")[0]) <= 1.0
                               for line in evaluations)
    custom = [line for line in output(runs, "custom_env") if ": return " in line]
    assert [line.split(":")[0] for line in custom] == ["source", "target (model reuse)"]
    assert all(0.0 <= float(line.split("success ")[1].split()[0]) <= 1.0 for line in custom)


def test_successor_features_regress_w_and_act_by_gpi(runs):
    (result,) = tagged(output(runs, "successor_features"), "result")
    # the regressed w is exact when the target's goal is in the data; else its weight is 0 (min-norm), 1 + 0.01 off
    assert result["w_error"] == pytest.approx(0.0 if result["target_goal_transitions"] else 1.01, abs=1e-6)
    rates = [v for k, v in result.items() if k.startswith(("source_", "gpi_on"))]
    assert len(rates) == 5 and all(0.0 <= r <= 1.0 and r * 64 == round(r * 64) for r in rates)  # 64 episodes each
    assert set(result["gpi_index_range"]) <= {0, 1}  # one of the two sources
