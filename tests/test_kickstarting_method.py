"""The kickstarting method end to end: `drltg experiment --method kickstarting` distils the source run's actor
with the configured weight schedule, and at weight 0 trains exactly as the baseline of its seed."""
import json

import pytest
import torch

from drltg.cli import main
from drltg.store.rundir import load_checkpoint, read_eval_csv
from tests.test_experiment import TINY

LOGGED = ["-o", "log.every=16", "-o", "transfer.kick_frames=256"]


def _logged(run, name):
    (path,) = [p for p in (run / "logs" / "csv").rglob(f"{name}.csv")]
    return [(int(step), float(value)) for step, value in (line.split(",") for line in path.read_text().split())]


@pytest.fixture(scope="module")
def experiment(tmp_path_factory):
    out = tmp_path_factory.mktemp("kick") / "near"
    assert main(["experiment", "fourrooms-near", "--method", "kickstarting", "--seeds", "1", "--frames", "512",
                 "--out", str(out), "--threshold", "0", "--no-progress", *TINY, *LOGGED]) == 0
    return out


def test_the_experiment_reports_and_the_weight_falls_linearly_to_zero_at_kick_frames(experiment):
    report = json.loads((experiment / "report" / "transfer_metrics.json").read_text())
    assert report["metrics"]["n_seeds_transfer"] == 1
    run = experiment / "transfer" / "seed-0"
    summary = json.loads((run / "summary.json").read_text())
    assert summary["kickstarting"] == {"weight": 1.0, "frames": 256, "decay": "linear", "floor": 0.01}
    weights = _logged(run, "distill_weight")
    # one batch of 16 frames per log row: the weight of its updates is 1 - f / 256 at the frames f collected
    assert [s for s, _ in weights] == list(range(128, 513, 16))  # updates start after 128 random frames
    assert [w for _, w in weights] == pytest.approx([max(0.0, 1 - f / 256) for f, _ in weights])
    assert weights[0][1] == 0.5 and weights[-1][1] == 0.0
    distill = dict(_logged(run, "loss_actor_distill"))
    assert all(distill[f] > 0 for f, w in weights if w > 0) and all(distill[f] == 0 for f, w in weights if w == 0)


def test_weight_zero_trains_exactly_as_the_baseline_of_the_seed(experiment, tmp_path):
    args = ["train", "fourrooms/northeast-shifted", "--frames", "512", "--seed", "0", "--no-progress", *TINY,
            *LOGGED, "-o", "transfer.method=kickstarting", "-o", f"transfer.source={experiment / 'source' / 'seed-50'}",
            "-o", "transfer.kick_weight=0", "--run-dir", str(tmp_path / "zero")]
    assert main(args) == 0
    baseline = experiment / "baseline" / "seed-0"
    assert read_eval_csv(tmp_path / "zero" / "eval.csv") == read_eval_csv(baseline / "eval.csv")
    assert _same_weights(tmp_path / "zero", baseline)
    # the same with the term on ends with other weights: the comparison can fail
    assert main([*args[:-4], "-o", "transfer.kick_weight=1", "--run-dir", str(tmp_path / "one")]) == 0
    assert not _same_weights(tmp_path / "one", baseline)


def _same_weights(run, other):
    mine, theirs = (load_checkpoint(r)["loss"] for r in (run, other))
    return mine.keys() == theirs.keys() and all(torch.equal(mine[k], theirs[k]) for k in mine)


@pytest.mark.parametrize("algo, source_algo", [("td3", "td3"), ("soc", "sac")])
def test_td3_and_soft_option_critic_learners_are_kickstarted(algo, source_algo, tmp_path):
    common = ["--frames", "256", "--no-progress", *TINY, "-o", "log.every=16"]
    source = ["train", "fourrooms/northeast", "--algo", source_algo, *common, "--run-dir", str(tmp_path / "src")]
    assert main(source) == 0
    assert main(["train", "fourrooms/northeast-shifted", "--algo", algo, *common, "-o", "transfer.method=kickstarting",
                 "-o", f"transfer.source={tmp_path / 'src'}", "--run-dir", str(tmp_path / "run")]) == 0
    distill = _logged(tmp_path / "run", "loss_actor_distill")
    assert distill and all(v > 0 for _, v in distill)


def test_a_soft_option_critic_teacher_is_refused_in_one_sentence(tmp_path, capsys):
    common = ["--frames", "128", "--no-progress", *TINY]
    assert main(["train", "fourrooms/northeast", "--algo", "soc", *common, "--run-dir", str(tmp_path / "src")]) == 0
    assert main(["train", "fourrooms/northeast-shifted", *common, "-o", "transfer.method=kickstarting",
                 "-o", f"transfer.source={tmp_path / 'src'}", "--run-dir", str(tmp_path / "run")]) == 2
    assert "kickstarting distils a SAC or TD3 source's actor" in capsys.readouterr().err
    assert not (tmp_path / "run").exists()


def test_a_decay_other_than_linear_or_exponential_is_refused_naming_the_key():
    from drltg import config as config_lib
    from drltg.errors import UsageError

    assert config_lib.resolve({}, ["transfer.method=kickstarting", "transfer.kick_decay=exponential"]).transfer.\
        kick_decay == "exponential"
    with pytest.raises(UsageError, match="transfer.kick_decay"):
        config_lib.resolve({}, ["transfer.method=kickstarting", "transfer.kick_decay=cosine"])


def test_every_knob_of_the_schedule_is_an_option_with_its_default(tmp_path):
    """kick_weight, kick_frames, kick_decay and kick_floor reach the weight the term reads: the defaults give
    1 - f / 10,000; exponential with floor 0.25 over 400 frames gives 2 * 0.25^(f / 400)."""
    from drltg import config as config_lib
    from drltg.envs import make_env
    from drltg.learners import make_agent
    from drltg.transfer import get_method
    from tests.test_methods import _source_run

    run, _ = _source_run(tmp_path / "src")
    env = make_env("fourrooms/northeast")
    weights = []
    for options in ([], ["transfer.kick_weight=2", "transfer.kick_frames=400", "transfer.kick_decay=exponential",
                         "transfer.kick_floor=0.25"]):
        cfg = config_lib.resolve({}, ["network.hidden=[8,8]", "transfer.method=kickstarting",
                                      f"transfer.source={run}", *options], task="fourrooms/northeast")
        transfer = get_method("kickstarting").build(cfg, make_agent(env, cfg), env, resuming=False)
        row = []
        for frames in (0, 200, 5_000):
            transfer.on_frames(frames)
            row.append(transfer.loss_terms.weights().item())
        weights.append(row)
    assert weights[0] == pytest.approx([1.0, 0.98, 0.5])
    assert weights[1] == pytest.approx([2.0, 1.0, 0.0])


def test_kickstarted_seeds_train_as_one_seed_group(tmp_path):
    out = tmp_path / "near"
    assert main(["experiment", "fourrooms-near", "--method", "kickstarting", "--seeds", "2", "--frames", "256",
                 "--out", str(out), "--threshold", "0", "--no-progress", *TINY, *LOGGED]) == 0
    said = "".join(log.read_text() for log in (out / "logs" / "transfer").glob("*.log"))
    assert f"start seed group {out / 'transfer' / 'seed-0'}, {out / 'transfer' / 'seed-100'}" in said
    for seed in ("seed-0", "seed-100"):
        weights = _logged(out / "transfer" / seed, "distill_weight")
        assert weights and weights[0][1] == 0.5  # each seed's own schedule, as a run alone
