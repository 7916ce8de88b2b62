"""Return ranges where drltg knows them, so a user never has to invent one: a Gymnasium task registered
with its range, an experiment's or sweep's ``value_range``, a drltg task named for foreign logs, and a
negative range on the command line."""
import json

import pytest

from drltg.cli import main
from drltg.envs import get_task, register_gym_task
from drltg.errors import UsageError
from drltg.experiments.spec import parse_spec


def _sb3_logs(root, side, values):
    """SB3 ``progress.csv`` logs, one folder per seed, evaluations every 1000 frames."""
    for seed, offset in enumerate(values):
        log = root / side / f"seed-{seed}" / "progress.csv"
        log.parent.mkdir(parents=True)
        rows = [f"{1000 * k},{offset - 0.02 * (10 - k)}" for k in range(11)]
        log.write_text("time/total_timesteps,eval/mean_reward\n" + "\n".join(rows) + "\n")
    return root / side


def test_a_gymnasium_task_registers_its_return_range():
    register_gym_task("pendulum/ranged", "Pendulum-v1", returns=(-1700.0, 0.0), replace=True, g=10.0)
    assert get_task("pendulum/ranged").return_range() == (-1700.0, 0.0)


def test_a_negative_value_range_is_taken_as_a_value(tmp_path, capsys):
    """``--value-range -50,0`` was read as an unknown option by argparse; ``=`` was needed."""
    base = _sb3_logs(tmp_path, "b", [-0.5, -0.4, -0.3])
    trans = _sb3_logs(tmp_path, "t", [-0.3, -0.2, -0.1])
    assert main(["report", "--baseline", str(base), "--transfer", str(trans), "--value-range", "-50,0",
                 "--out", str(tmp_path / "r")]) == 0, capsys.readouterr().err
    saved = json.loads((tmp_path / "r" / "transfer_metrics.json").read_text())
    assert saved["settings"]["value_range"] == [-50.0, 0.0]


def test_foreign_logs_of_a_drltg_task_take_its_range_by_name_or_gymnasium_id(tmp_path, capsys):
    base = _sb3_logs(tmp_path, "b", [-0.5, -0.4, -0.3])
    trans = _sb3_logs(tmp_path, "t", [0.0, 0.1, 0.2])
    for k, task in enumerate(["fourrooms/northeast", "drltg/fourrooms-northeast-v0"]):
        assert main(["report", "--baseline", str(base), "--transfer", str(trans), "--task", task,
                     "--out", str(tmp_path / f"r{k}")]) == 0, capsys.readouterr().err
        saved = json.loads((tmp_path / f"r{k}" / "transfer_metrics.json").read_text())
        assert saved["settings"]["value_range"] == [-1.0, 1.0]
    code = main(["report", "--baseline", str(base), "--transfer", str(trans), "--task", "fourrooms/nowhere",
                 "--out", str(tmp_path / "r9")])
    assert code == 2 and "unknown task 'fourrooms/nowhere'" in capsys.readouterr().err.lower()


def test_a_sweep_spec_takes_a_value_range():
    spec = parse_spec({"pairs": ["fourrooms-near"], "methods": ["model-reuse"], "frames": 1000,
                       "value_range": [-50, 0]})
    assert spec.value_range == (-50.0, 0.0)
    with pytest.raises(UsageError, match="'value_range' must be \\[LOW, HIGH\\], two numbers"):
        parse_spec({"pairs": ["fourrooms-near"], "methods": ["model-reuse"], "frames": 1000, "value_range": "0,1"})


def test_an_experiment_reports_with_the_value_range_it_is_given(tmp_path, capsys):
    from tests.test_experiment import TINY

    out = tmp_path / "x"
    assert main(["experiment", "gridrooms/northeast", "--method", "reward-shaping", "--seeds", "1", "--frames", "64",
                 "--out", str(out), "--value-range", "-5,5", "--no-progress", *TINY]) == 0, capsys.readouterr().err
    saved = json.loads((out / "report" / "transfer_metrics.json").read_text())
    assert saved["settings"]["value_range"] == [-5.0, 5.0]


def test_a_report_is_named_after_the_methods_and_written_beside_the_runs(tmp_path, monkeypatch, capsys):
    """``drltg report`` without labels or --out: the labels are the runs' transfer methods (not 'transfer vs
    baseline') and the report folder lands beside the runs, not in the working directory."""
    from tests.test_faults import train_args

    runs = tmp_path / "runs"
    for side, method in (("baseline", []), ("transfer", ["-o", "transfer.method=reward-shaping"])):
        for seed in (0, 100):
            assert main(train_args(runs / side / f"seed-{seed}") + ["--seed", str(seed), *method]) == 0
    elsewhere = tmp_path / "cwd"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    assert main(["report", "--baseline", str(runs / "baseline"), "--transfer", str(runs / "transfer")]) == 0
    assert list(elsewhere.iterdir()) == []
    (report,) = runs.glob("report-*")
    assert report.name == "report-reward-shaping-vs-no-transfer"
    saved = json.loads((report / "transfer_metrics.json").read_text())
    labels = saved["settings"]["baseline_label"], saved["settings"]["transfer_label"]
    assert labels == ("no transfer", "reward-shaping")


def test_an_equivalence_margin_turns_an_undecided_mean_difference_into_equivalent():
    """TOST, hand-checked: paired differences 0.01, -0.01, 0.02, 0.00, -0.02, 0.01 (mean 0.00167, sd 0.01472,
    se 0.00601, 5 df); within +-0.05 the larger one-sided p is t.sf((0.00167 + 0.05) / 0.00601, 5) = 2.2e-5."""
    import numpy as np
    from scipy import stats as sp

    from drltg.analysis.stats import tost
    from drltg.report import report_from_curves

    b = np.array([0.5, 0.6, 0.4, 0.55, 0.45, 0.5])
    d = np.array([0.01, -0.01, 0.02, 0.0, -0.02, 0.01])
    se = d.std(ddof=1) / np.sqrt(6)
    assert tost(b, b + d, True, 0.05) == pytest.approx(max(sp.t.sf((d.mean() + 0.05) / se, 5),
                                                          sp.t.cdf((d.mean() - 0.05) / se, 5)))
    assert tost(b, b + d, True, 0.001) > 0.05  # a margin inside the noise shows nothing
    frames = np.arange(0, 11) * 1000.0
    base = np.tile(b[:, None], (1, 11))
    trans = base + d[:, None]
    plain = report_from_curves(frames, base, trans)["metrics"]
    assert plain["mean_return_gain_verdict"] == "undecided"
    report = report_from_curves(frames, base, trans, equivalence_margin=0.05)
    m = report["metrics"]
    assert m["mean_return_gain_verdict"] == "equivalent"
    assert m["mean_return_gain_verdict_test"] == "TOST within +-0.05, paired t"
    assert m["mean_return_gain_verdict_p"] < 0.05
    from drltg.analysis.claims import verdict_of

    said = verdict_of(report, "mean_return_gain")
    assert said.startswith("+0.00, equivalent (TOST within +-0.05, paired t, p = ")
    assert "by paired t, assuming normal differences" in said  # TOST stands on the t interval's assumption
    from drltg.report import outputs

    assert "equivalent (TOST within +-0.05, paired t, p < 0.001, assuming normal differences)" in \
        outputs.magnitudes_table(report)
    with pytest.raises(UsageError, match="--equivalence-margin must be a finite number above 0"):
        report_from_curves(frames, base, trans, equivalence_margin=-1)
