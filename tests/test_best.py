"""The best networks (checkpoints/best.safetensors; with checkpoint.keep_best also best.pt), `drltg evaluate` and
transfer.source_checkpoint.

The evaluations are scripted (``AgentLearner.evaluate`` returns chosen scores by frame), so the frame
best.pt must come from is known; the weights at each evaluation are recorded to compare with it.
"""
import json
import math
from pathlib import Path

import pytest
import torch
import yaml

import drltg.training.loop as loop
from drltg import config as config_lib
from drltg.cli import main
from drltg.errors import UsageError
from drltg.store import networks, rundir
from drltg.training.loop import read_eval_csv, train

TINY = [
    "network.hidden=[16,16]",
    "collector.num_envs=4",
    "collector.frames_per_batch=16",
    "collector.init_random_frames=128",
    "optim.updates_per_batch=1",
    "buffer.batch_size=32",
    "eval.every=256",
    "eval.episodes=4",
    "checkpoint.every=512",
    "log.every=128",
    "log.tensorboard=false",
]


def keep_best_cfg(*overrides, frames=1024):
    return config_lib.resolve({}, [*TINY, "checkpoint.keep_best=true", *overrides], task="fourrooms/northeast",
                              frames=frames, seed=3)


def rows(success=None, returns=None):
    """Evaluation results by frame: success rates (return 0) or returns (no success reported), or both."""
    frames = list(success or returns)
    return {f: {"return_mean": (returns or {}).get(f, 0.0), "return_std": 0.0, "episodes": 4,
                **({"success_rate": success[f]} if success else {})} for f in frames}


def script(monkeypatch, results: dict, *, stop_at=None):
    """Make every evaluation return ``results[frames]`` and record the learner's weights at each; raise
    KeyboardInterrupt at the evaluation of frame ``stop_at``."""
    weights = {}

    def evaluate(self, check=lambda: None):
        frames = len(self.buffer)  # every collected frame is stored (buffer.size is larger than the run)
        if frames == stop_at:
            raise KeyboardInterrupt
        weights[frames] = {k: v.detach().clone() for k, v in self.agent.loss.state_dict().items()}
        return [dict(results[frames])]

    monkeypatch.setattr(loop.AgentLearner, "evaluate", evaluate)
    return weights


def record_saves(monkeypatch, written=None):
    """``[(file name, frames)]`` of every checkpoint written, in order (and into ``written`` their bytes)."""
    saves, real = [], rundir.atomic_torch_save

    def save(obj, path):
        saves.append((path.name, obj["frames"]))
        real(obj, path)
        if written is not None:
            written[saves[-1]] = path.read_bytes()

    monkeypatch.setattr(rundir, "atomic_torch_save", save)
    return saves


def load(run, name="best"):
    return torch.load(run / "checkpoints" / f"{name}.pt", weights_only=True)


def same(a: dict, b: dict) -> bool:
    return a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)


# ------------------------------------------------------------------------------------------ keep_best
SUCCESS = {0: 0.0, 256: 0.5, 512: 0.25, 768: 0.5, 1024: 0.25}
RETURNS = {0: -1.0, 256: -0.5, 512: 0.0, 768: -0.2, 1024: 0.0}


@pytest.mark.parametrize("results, overrides, metric, best", [
    # success rates: 256 beats 0; 768 ties 256, and a tie keeps the earlier
    (rows(success=SUCCESS), [], "success_rate", [0, 256]),
    # a task that reports no success: return_mean (512 beats -0.5; 1024 ties it)
    (rows(returns=RETURNS), [], "return_mean", [0, 256, 512]),
    # both reported: auto ranks the success rates, checkpoint.best_metric=return_mean the returns
    (rows(SUCCESS, RETURNS), [], "success_rate", [0, 256]),
    (rows(SUCCESS, RETURNS), ["checkpoint.best_metric=return_mean"], "return_mean", [0, 256, 512]),
])
def test_best_pt_is_the_checkpoint_of_the_first_highest_evaluation(tmp_path, monkeypatch, results, overrides, metric,
                                                                   best):
    weights = script(monkeypatch, results)
    written = {}
    saves = record_saves(monkeypatch, written)
    run = train(keep_best_cfg(*overrides), tmp_path / "run", progress=False)
    assert [f for name, f in saves if name == "best.pt"] == best
    # last.pt at each new best (not at frame 0: nothing trained), at checkpoint.every=512 unless saved there
    # already, and once more at the end
    assert [f for name, f in saves if name == "last.pt"] == [*sorted({*best[1:], 512, 1024}), 1024]
    for frames in best[1:]:  # last.pt first, then the same checkpoint as best.pt
        assert saves.index(("last.pt", frames)) + 1 == saves.index(("best.pt", frames))
        assert written[("last.pt", frames)] == written[("best.pt", frames)]
    assert (run / "checkpoints" / "best.pt").read_bytes() == written[("best.pt", best[-1])]
    saved = load(run)
    assert saved["frames"] == best[-1] and saved["evaluations"] == [f for f in results if f <= best[-1]]
    assert same(saved["loss"], weights[best[-1]])
    assert not same(saved["loss"], load(run, "last")["loss"])  # trained on after it
    assert set(saved) == set(load(run, "last"))  # the same content as last.pt
    summary = json.loads((run / "summary.json").read_text())
    assert summary["best"] == {"networks": "checkpoints/best.safetensors", "checkpoint": "checkpoints/best.pt",
                               "frames": best[-1], "metric": metric, "score": results[best[-1]][metric]}
    rundir.manifest.verify(run, "checkpoints/best.pt")


def test_by_default_the_best_is_kept_as_its_networks_alone(tmp_path, monkeypatch, capsys):
    """checkpoint.keep_best's default (false) keeps no best.pt, but the networks of the best evaluation, which
    ``drltg evaluate --checkpoint best`` reads: the run saves the same checkpoints as with keep_best."""
    weights = script(monkeypatch, rows({0: 0.0, 256: 0.5, 512: 0.25}))
    saves = record_saves(monkeypatch)
    cfg = config_lib.resolve({}, TINY, task="fourrooms/northeast", frames=512, seed=3)
    assert cfg.checkpoint.keep_best is False
    run = train(cfg, tmp_path / "run", progress=False)
    assert not (run / "checkpoints" / "best.pt").exists()
    assert saves == [("last.pt", 256), ("last.pt", 512), ("last.pt", 512)]  # at the new best, then as always
    saved, info = rundir.load_networks(run, "best")
    assert info["frames"] == 256 and same(saved, weights[256])
    assert json.loads((run / "summary.json").read_text())["best"] == {
        "networks": "checkpoints/best.safetensors", "frames": 256, "metric": "success_rate", "score": 0.5}
    rundir.manifest.verify(run, "checkpoints/best.safetensors")
    monkeypatch.undo()
    out = tmp_path / "e.json"
    assert main(["evaluate", str(run), "--checkpoint", "best", "--episodes", "2", "--out", str(out)]) == 0
    result = json.loads(out.read_text())
    assert (result["checkpoint"], result["frames"]) == ("best", 256)


def test_a_stop_between_last_pt_and_the_best_networks_is_repaired_on_resume(tmp_path, monkeypatch):
    weights = script(monkeypatch, rows({0: 0.0, 256: 0.25, 512: 0.5, 768: 0.5, 1024: 0.0}))
    real = rundir.write_tracked
    cfg = config_lib.resolve({}, TINY, task="fourrooms/northeast", frames=1024, seed=3)

    def stop_before_best(run_dir, name, data):
        if name == "checkpoints/best.safetensors" and networks.header(data, Path(name))["frames"] == 512:
            raise KeyboardInterrupt
        return real(run_dir, name, data)

    monkeypatch.setattr(rundir, "write_tracked", stop_before_best)
    with pytest.raises(KeyboardInterrupt):
        train(cfg, tmp_path / "run", progress=False)
    assert networks.read_header(tmp_path / "run", "best")["frames"] == 256
    assert load(tmp_path / "run", "last")["frames"] == 512
    monkeypatch.setattr(rundir, "write_tracked", real)
    run = train(cfg, tmp_path / "run", resume=True, progress=False)
    saved, info = rundir.load_networks(run, "best")
    assert info["frames"] == 512 and same(saved, weights[512])
    assert json.loads((run / "summary.json").read_text())["best"]["frames"] == 512


def test_a_resume_without_the_best_networks_is_refused_in_one_sentence(tmp_path, monkeypatch, capsys):
    script(monkeypatch, rows(SUCCESS), stop_at=768)
    cfg = config_lib.resolve({}, TINY, task="fourrooms/northeast", frames=1024, seed=3)
    with pytest.raises(KeyboardInterrupt):
        train(cfg, tmp_path / "run", progress=False)
    (tmp_path / "run" / "checkpoints" / "best.safetensors").unlink()
    assert main(["train", "--resume", "--run-dir", str(tmp_path / "run"), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert ("checkpoints/best.safetensors is missing, not those of its best evaluation (frame 256, success_rate "
            "0.5)") in err


def test_a_resumed_run_knows_the_best_score_so_far(tmp_path, monkeypatch):
    script(monkeypatch, rows(SUCCESS), stop_at=768)  # stopped after the checkpoint at 512
    with pytest.raises(KeyboardInterrupt):
        train(keep_best_cfg(), tmp_path / "run", progress=False)
    before = load(tmp_path / "run")
    assert before["frames"] == 256
    script(monkeypatch, rows(SUCCESS))
    saves = record_saves(monkeypatch)
    run = train(keep_best_cfg(), tmp_path / "run", resume=True, progress=False)
    assert [f for name, f in saves if name == "best.pt"] == []  # 0.5 at 768 ties the 0.5 at 256 before the stop
    assert same(load(run)["loss"], before["loss"])
    assert json.loads((run / "summary.json").read_text())["best"]["frames"] == 256
    assert [r["frames"] for r in read_eval_csv(run / "eval.csv")] == [0, 256, 512, 768, 1024]


def test_a_stop_between_last_pt_and_best_pt_is_repaired_on_resume(tmp_path, monkeypatch):
    weights = script(monkeypatch, rows({0: 0.0, 256: 0.25, 512: 0.5, 768: 0.5, 1024: 0.0}))
    real = rundir.atomic_torch_save

    def stop_before_best(obj, path):
        if path.name == "best.pt" and obj["frames"] == 512:
            raise KeyboardInterrupt
        return real(obj, path)

    monkeypatch.setattr(rundir, "atomic_torch_save", stop_before_best)
    with pytest.raises(KeyboardInterrupt):
        train(keep_best_cfg(), tmp_path / "run", progress=False)
    assert load(tmp_path / "run")["frames"] == 256 and load(tmp_path / "run", "last")["frames"] == 512
    monkeypatch.setattr(rundir, "atomic_torch_save", real)
    run = train(keep_best_cfg(), tmp_path / "run", resume=True, progress=False)
    assert load(run)["frames"] == 512 and same(load(run)["loss"], weights[512])
    rundir.manifest.verify(run, "checkpoints/best.pt")


def test_a_stop_between_best_pt_and_its_networks_file_is_repaired_on_resume(tmp_path, monkeypatch):
    """best.safetensors is written after best.pt; stopped between them, the run holds the networks of the
    previous best beside the new best.pt, and no later evaluation improves on it to write them again."""
    weights = script(monkeypatch, rows({0: 0.0, 256: 0.25, 512: 0.5, 768: 0.5, 1024: 0.0}))
    real = rundir.write_tracked

    def stop_before_networks(run_dir, name, data):
        if name == "checkpoints/best.safetensors" and networks.header(data, Path(name))["frames"] == 512:
            raise KeyboardInterrupt
        return real(run_dir, name, data)

    monkeypatch.setattr(rundir, "write_tracked", stop_before_networks)
    with pytest.raises(KeyboardInterrupt):
        train(keep_best_cfg(), tmp_path / "run", progress=False)
    assert load(tmp_path / "run")["frames"] == 512 and networks.read_header(tmp_path / "run", "best")["frames"] == 256
    monkeypatch.setattr(rundir, "write_tracked", real)
    run = train(keep_best_cfg(), tmp_path / "run", resume=True, progress=False)
    saved, info = rundir.load_networks(run, "best")
    assert info["frames"] == 512 and same(saved, weights[512]) and same(saved, load(run)["loss"])


def test_a_resume_without_the_best_pt_is_refused_in_one_sentence(tmp_path, monkeypatch, capsys):
    script(monkeypatch, rows(SUCCESS), stop_at=768)
    with pytest.raises(KeyboardInterrupt):
        train(keep_best_cfg(), tmp_path / "run", progress=False)
    (tmp_path / "run" / "checkpoints" / "best.pt").unlink()
    assert main(["train", "--resume", "--run-dir", str(tmp_path / "run"), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert "checkpoints/best.pt is missing, not that of its best evaluation (frame 256, success_rate 0.5)" in err


def test_a_best_metric_the_task_does_not_report_is_refused_before_the_run(tmp_path):
    with pytest.raises(UsageError, match="checkpoint.best_metric=lifted_rate, but task 'fourrooms/northeast' reports "
                                         "no 'lifted'"):
        train(keep_best_cfg("checkpoint.best_metric=lifted_rate"), tmp_path / "run", progress=False)
    assert not (tmp_path / "run").exists()


# ------------------------------------------------------------------------------------------ evaluate
@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """A real tiny run with keep_best."""
    return train(keep_best_cfg(frames=768), tmp_path_factory.mktemp("runs") / "run", progress=False)


def test_keep_best_changes_no_number_of_the_run(tmp_path, monkeypatch):
    script(monkeypatch, rows(SUCCESS))
    saves = record_saves(monkeypatch)
    kept = train(keep_best_cfg(frames=512), tmp_path / "kept", progress=False)
    assert ("best.pt", 256) in saves  # a checkpoint between the regular ones
    plain = train(keep_best_cfg("checkpoint.keep_best=false", frames=512), tmp_path / "plain", progress=False)
    a, b = load(kept, "last"), load(plain, "last")
    assert same(a["loss"], b["loss"]) and torch.equal(a["rng"], b["rng"]) and a["updates"] == b["updates"]
    assert (kept / "eval.csv").read_text() == (plain / "eval.csv").read_text()


def test_evaluate_reports_the_training_evaluation_of_fresh_episodes(trained, tmp_path, capsys):
    from torchrl.envs import TransformedEnv

    from drltg.envs import make_env
    from drltg.transfer import load_actor

    out = tmp_path / "e.json"
    assert main(["evaluate", str(trained), "--checkpoint", "best", "--episodes", "7", "--out", str(out)]) == 0
    assert len(capsys.readouterr().out.strip().splitlines()) == 1
    result = json.loads(out.read_text())
    cfg = yaml.safe_load((trained / "config.yaml").read_text())
    assert result["seed"] == 3 + 30_000  # the training evaluations' env is seeded 3 + 10_000
    env = TransformedEnv(make_env("fourrooms/northeast", batch_size=(7,), seed=3 + 30_000, **cfg["env"]))
    direct = loop.evaluate(env, load_actor(trained, checkpoint="best"))
    assert {k: result[k] for k in direct if k != "episodes"} == {k: v for k, v in direct.items() if k != "episodes"}
    assert result["episodes"] == 7 and result["checkpoint"] == "best"
    assert result["frames"] == json.loads((trained / "summary.json").read_text())["best"]["frames"]
    k = round(result["success_rate"] * 7)
    from scipy import stats
    assert result["success_rate_ci95"] == pytest.approx([stats.beta.ppf(0.025, k, 8 - k) if k else 0.0,
                                                         stats.beta.ppf(0.975, k + 1, 7 - k) if k < 7 else 1.0])


def test_evaluate_runs_many_episodes_in_batches_of_the_runs_evaluation(trained):
    """More episodes than the run evaluated at once: batches of eval.episodes envs, batch i seeded seed + i,
    pooled over every episode (a robosuite run's 100 episodes never hold 100 envs at once)."""
    from torchrl.envs import TransformedEnv

    from drltg.envs import make_env
    from drltg.training.reevaluate import evaluate_run
    from drltg.transfer import load_actor

    cfg = yaml.safe_load((trained / "config.yaml").read_text())
    batch = cfg["eval"]["episodes"]
    result = evaluate_run(trained, episodes=batch + 3, seed=5)
    actor = load_actor(trained)
    rows = [loop.evaluate(TransformedEnv(make_env("fourrooms/northeast", batch_size=(n,), seed=s, **cfg["env"])),
                          actor) for n, s in ((batch, 5), (3, 6))]
    n = batch + 3
    mean = (batch * rows[0]["return_mean"] + 3 * rows[1]["return_mean"]) / n
    var = sum(r["episodes"] * (r["return_std"] ** 2 + r["return_mean"] ** 2) for r in rows) / n - mean**2
    assert result["episodes"] == n
    assert result["return_mean"] == pytest.approx(mean) and result["return_std"] == pytest.approx(var**0.5)
    assert result["success_rate"] == pytest.approx((batch * rows[0]["success_rate"] + 3 * rows[1]["success_rate"]) / n)


def test_evaluate_with_a_seed_writes_its_default_file(trained, capsys):
    assert main(["evaluate", str(trained), "--episodes", "2", "--seed", "11"]) == 0
    result = json.loads((trained / "evaluate-last-seed11-2ep.json").read_text())
    assert result["seed"] == 11 and result["checkpoint"] == "last" and result["frames"] == 768


@pytest.mark.parametrize("k, n, expected", [
    (10, 10, (0.025 ** (1 / 10), 1.0)),  # Clopper-Pearson at k = n: [(alpha/2)^(1/n), 1]
    (0, 10, (0.0, 1 - 0.025 ** (1 / 10))),
    (7, 10, None),  # [B(0.025; 7, 4), B(0.975; 8, 3)]
])
def test_the_rate_interval_is_clopper_pearson(k, n, expected):
    from scipy import stats

    from drltg.training.reevaluate import rate_interval

    if expected is None:
        expected = (stats.beta.ppf(0.025, k, n - k + 1), stats.beta.ppf(0.975, k + 1, n - k))
    assert rate_interval(k, n) == pytest.approx(expected, abs=1e-12)
    assert math.isclose(rate_interval(7, 10)[0], 0.3475471499, rel_tol=1e-8)  # R: binom.test(7, 10)$conf.int


@pytest.mark.parametrize("args, message", [
    (["evaluate", "{tmp}/missing"], "run directory '{tmp}/missing' does not exist."),
    (["evaluate", "{tmp}", "--checkpoint", "best"], "holds no best networks (checkpoints/best.safetensors, nor "
                                                    "checkpoints/best.pt): a run keeps them from its first evaluation"),
    (["evaluate", "{run}", "--episodes", "0"], "--episodes must be between 1 and 10000, got 0."),
    (["evaluate", "{run}", "--seed", "-1"], "--seed must be an integer in [0, 2147483647], got -1."),
    (["evaluate", "{run}/eval.csv"], "eval.csv' is a file, not a directory"),
    (["evaluate", "{run}", "--checkpoint", "first"], "invalid choice: 'first'"),
])
def test_evaluate_bad_input_is_one_sentence_and_exit_2(trained, tmp_path, capsys, args, message):
    (tmp_path / "config.yaml").write_text(yaml.safe_dump(config_lib.defaults()))
    args = [a.format(tmp=tmp_path, run=trained) for a in args]
    try:
        code = main(args)
    except SystemExit as stop:  # argparse's own refusal
        code = stop.code
    assert code == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and message.format(tmp=tmp_path) in err, err


# ------------------------------------------------------------------------------------------ a source's checkpoint
@pytest.fixture(scope="module")
def source(tmp_path_factory):
    """A finished run whose best.pt (frame 256) is not its last.pt."""
    with pytest.MonkeyPatch.context() as mp:
        script(mp, rows({0: 0.0, 256: 0.5, 512: 0.25}))
        return train(keep_best_cfg(frames=512), tmp_path_factory.mktemp("src") / "run", progress=False)


def part(weights: dict, prefix: str) -> dict:
    return {k.removeprefix(prefix): v for k, v in weights.items() if k.startswith(prefix)}


def test_every_loader_reads_the_named_checkpoint(source):
    from drltg.envs import make_env
    from drltg.learners import make_agent
    from drltg.transfer import load_actor, load_agent, load_critic, load_from_run

    best, last = load(source)["loss"], load(source, "last")["loss"]
    assert not same(best, last)
    for name, weights in (("best", best), ("last", last)):
        assert same(load_agent(source, checkpoint=name).loss.state_dict(), weights)
        assert same(load_actor(source, checkpoint=name).state_dict(), part(weights, "actor_network_params."))
        critic = load_critic(source, checkpoint=name).critic_params.flatten_keys(".")
        assert same(dict(critic.items()), part(weights, "qvalue_network_params."))
        cfg = config_lib.build(yaml.safe_load((source / "config.yaml").read_text()))
        agent = make_agent(make_env(cfg.task, **cfg.env), cfg)
        load_from_run(agent.loss, source, checkpoint=name)
        assert same(agent.loss.state_dict(), weights)


@pytest.mark.parametrize("method", ["model-reuse", "policy-reuse", "value-shaping"])
def test_transfer_source_checkpoint_best_is_what_the_methods_reuse(source, tmp_path, method):
    from drltg.transfer import get_method
    from drltg.transfer import source as source_mod

    cfg = config_lib.resolve({}, [*TINY, f"transfer.method={method}", f"transfer.source={source}",
                                  "transfer.source_checkpoint=best"], task="fourrooms/northeast", frames=32, seed=3)
    source_mod.check(cfg)
    assert same(source_mod.source_agent(cfg).loss.state_dict(), load(source)["loss"])
    if method == "model-reuse":
        probe, agent = loop.check_config(cfg)
        get_method(method).build(cfg, agent, probe, resuming=False)
        assert same(agent.loss.state_dict(), load(source)["loss"])


def test_a_source_without_best_pt_is_one_sentence(trained, tmp_path, capsys):
    import shutil

    from drltg.transfer import source as source_mod

    src = shutil.copytree(trained, tmp_path / "src")
    (src / "checkpoints" / "best.pt").unlink()
    (src / "checkpoints" / "best.safetensors").unlink()
    assert main(["train", "fourrooms/northeast", "--run-dir", str(tmp_path / "t"), "-o", "transfer.method=model-reuse",
                 "-o", f"transfer.source={src}", "-o", "transfer.source_checkpoint=best"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert f"transfer.source_checkpoint=best: '{src}' holds no best networks (checkpoints/best.safetensors" in err
    assert not (tmp_path / "t").exists()
    cfg = config_lib.resolve({}, ["transfer.method=policy-reuse", "transfer.source=demonstrator:lift",
                                  "transfer.source_checkpoint=best"], task="fourrooms/northeast")
    with pytest.raises(UsageError, match="demonstrator:lift is a scripted policy and has none"):
        source_mod.check(cfg)


def test_each_seed_of_a_group_keeps_its_own_best(tmp_path, monkeypatch):
    from drltg.training import seeds as seeds_mod

    results = [rows({0: 0.0, 256: 0.5, 512: 0.25}), rows({0: 0.0, 256: 0.0, 512: 0.75})]
    monkeypatch.setattr(seeds_mod.GroupLearner, "evaluate",
                        lambda self, check=None: [dict(r[len(self.buffers[0])]) for r in results])
    saves = []
    real = rundir.atomic_torch_save

    def save(obj, path):
        saves.append((path.parents[1].name, path.name, obj["frames"]))
        return real(obj, path)

    monkeypatch.setattr(rundir, "atomic_torch_save", save)
    dirs = seeds_mod.train_seeds(keep_best_cfg(frames=512), tmp_path / "group", 2, progress=False)
    assert [d.name for d in dirs] == ["seed-3", "seed-103"]
    assert [(s, f) for s, name, f in saves if name == "best.pt"] == [
        ("seed-3", 0), ("seed-103", 0), ("seed-3", 256), ("seed-103", 512)]
    for d, best in zip(dirs, (256, 512)):
        assert load(d)["frames"] == best
        assert json.loads((d / "summary.json").read_text())["best"]["frames"] == best


@pytest.mark.parametrize("argv", [["--help"], ["evaluate", "--help"]])
def test_the_help_lists_evaluate(argv, capsys):
    with pytest.raises(SystemExit) as stop:
        main(argv)
    assert stop.value.code == 0 and "evaluate" in capsys.readouterr().out


def test_a_run_says_how_it_went_and_names_a_collapse():
    """The first week's source: success 0.81 at 10k frames, 0.06 at 20k, unremarked. Now it is said."""
    from drltg.training.best import Outcome, outcome

    cfg = config_lib.resolve(None, [], task="fourrooms/northeast", frames=20_000)
    rows = [{"frames": f, "return_mean": r, "success_rate": s} for f, r, s in
            [(0, -1.0, 0.0), (5_000, -0.5, 0.4), (10_000, 0.5, 0.81), (15_000, -0.2, 0.3), (20_000, -0.9, 0.06)]]
    went = outcome(cfg, rows)
    assert went.final == "final evaluation: success rate 0.06 at frame 20,000; best: 0.81 at frame 10,000"
    assert went.collapse == ("the run collapsed: its success rate fell from 0.81 at frame 10,000 to 0.06 (frame "
                       "20,000 average 0.06); the last checkpoint holds the collapsed policy, "
                       "checkpoints/best.safetensors keeps the best policy's networks (drltg evaluate RUN "
                       "--checkpoint best).")
    rows[-1]["success_rate"] = 0.7  # a dip, not a collapse: 0.11 below the best of a 0.81 range
    assert outcome(cfg, rows).collapse is None
    rising = [{"frames": f, "return_mean": float(f)} for f in range(0, 5)]
    assert outcome(config_lib.resolve(None, [], task="pendulum/g10"), rising) == Outcome(
        "final evaluation: return 4 at frame 4; best: 4 at frame 4")
    assert outcome(cfg, []) is None


def test_drltg_train_ends_with_its_final_and_best_evaluation(tmp_path, capsys):
    from drltg.cli import main
    from tests.test_faults import train_args

    assert main(train_args(tmp_path / "run")) == 0
    out = capsys.readouterr().out
    assert "final evaluation: success rate " in out and "; best: " in out
