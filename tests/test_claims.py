"""Result sentences follow fixed rules, and the committed prose says what the committed numbers say."""
import importlib.util
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from drltg.analysis import claims as cl
from drltg.analysis import stats

ROOT = Path(__file__).resolve().parents[1]


def generator():
    spec = importlib.util.spec_from_file_location("results_claims", ROOT / "results" / "claims.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def regions(name: str):
    """One study's module of ``results/regions/`` (``results/claims.py`` puts the repository on the path)."""
    generator()
    return importlib.import_module(f"results.regions.{name}")


def report(times=(1000.0, None, 3000.0), crossing="sustained", value=0.4, ci=(0.1, 0.7), p_adjusted=0.01, **st):
    """A hand-made transfer_metrics.json: three transfer seeds with the given threshold times."""
    per_seed = [{"seed": 100 * i, "mean_return": 0.5 + i, "time_to_threshold": t} for i, t in enumerate(times)]
    return {
        "metrics": {"n_seeds_baseline": len(times), "n_seeds_transfer": len(times), "mean_return_gain": value,
                    "mean_return_gain_ci": list(ci) if ci else None, "mean_return_gain_p_adjusted": p_adjusted,
                    "time_to_threshold_transfer": None},
        "settings": {"threshold": 0.5, "crossing": crossing, "sustain": None, "sustain_after": 2, "paired": True,
                     "budget": 20000, "transfer_label": "model-reuse", "baseline_label": "no transfer",
                     "family": {"size": 3}, **st},
        "per_seed": {"transfer": per_seed, "baseline": per_seed},
    }


# ------------------------------------------------------------------------------------------ rules
@pytest.mark.parametrize("value, ci, p_adjusted, expected", [
    (0.3, (0.1, 0.5), None, 1), (-0.3, (-0.5, -0.1), None, -1), (0.2, (-0.1, 0.5), None, 0), (0.0, None, None, 0),
    (0.3, (0.1, 0.5), 0.2, 0),  # no exact test: the interval excludes 0 alone, not after Holm: no verdict
    (0.3, (0.1, 0.5), 0.049, 1),
])
def test_without_an_exact_test_the_interval_decides(value, ci, p_adjusted, expected):
    assert cl.direction(value, ci, p_adjusted) == expected


@pytest.mark.parametrize("value, ci, p_adjusted, expected", [
    (0.3, (0.1, 0.5), cl.Adjusted(0.01, 0.03), 1),
    (0.3, (0.1, 0.5), cl.Adjusted(0.01, 0.25), 0),   # the interval excludes 0, the exact test does not decide
    (0.3, (-0.9, 1.5), cl.Adjusted(0.9, 0.03), 1),   # a range-bounded interval holds 0, the exact test decides
    (-0.3, None, cl.Adjusted(None, 0.002), -1),      # no interval at all: the test still decides
    (0.0, (-0.1, 0.1), cl.Adjusted(0.9, 0.01), 0),   # no direction to give
])
def test_the_exact_test_decides_and_the_interval_does_not(value, ci, p_adjusted, expected):
    assert cl.direction(value, ci, p_adjusted) == expected


def test_verdicts_read_higher_lower_or_no_evidence():
    assert cl.verdict(1.08, (0.91, 1.24)) == "+1.08 [+0.91, +1.24], higher with transfer"
    assert cl.verdict(-0.41, (-0.6, -0.21)) == "\u22120.41 [\u22120.60, \u22120.21], lower with transfer"
    assert cl.verdict(0.25, (-0.03, 0.53)) == "+0.25 [\u22120.03, +0.53]: no evidence of a difference at this budget"
    assert cl.verdict(0.0, None) == "+0.00: no evidence of a difference at this budget"
    # the same +0.89 in every pair: no interval, and neither "higher" nor "no evidence"
    assert cl.verdict(0.895, None) == "+0.90: no interval, so no verdict"
    assert cl.verdict(0.004, None) == "+0.00: no evidence of a difference at this budget"
    held_back = cl.verdict(-0.32, (-0.51, -0.13), p_adjusted=0.079, family=20)
    assert held_back == ("\u22120.32 [\u22120.51, \u22120.13]: no evidence of a difference at this budget after Holm's "
                         "adjustment (adjusted p = 0.079 of 20)")


def test_every_seed_only_when_every_seed():
    assert cl.seeds(5, 5) == "every seed (5 of 5)"
    assert cl.seeds(4, 5) == "4 of 5 seeds"
    assert cl.seeds(0, 3) == "no seed (0 of 3)"
    assert [cl.agree(k, 5, "holds", "hold") for k in (0, 1, 3, 5)] == ["holds", "holds", "hold", "holds"]


def test_a_sustained_threshold_names_its_confirming_evaluations_and_counts_seeds():
    text = cl.threshold_sentence(report(), "transfer", "near")
    assert text == ("near: 2 of 3 seeds hold 0.5 to the end (sustained: at least 2 evaluations after the crossing), "
                    "from 1k, 3k frames")
    every = cl.threshold_sentence(report(times=(1000.0, 2500.0, 3000.0)), "transfer", "near")
    assert every.startswith("near: every seed (3 of 3) holds 0.5") and every.endswith("the last of them from 3k frames")


def test_a_first_crossing_is_never_called_sustained_or_held():
    text = cl.threshold_sentence(report(crossing="first"), "transfer", "near")
    assert text == ("near: 2 of 3 seeds reach 0.5 at least once (a first crossing, not a sustained one), "
                    "from 1k, 3k frames")
    assert " hold" not in text


def test_a_crossing_too_late_to_confirm_is_unconfirmed_never_not_held():
    """Seeds at or above the threshold at the budget's last evaluation without a confirmed crossing (the
    sustained rule needs 2 more evaluations) are counted apart; a first-crossing rule says nothing of them."""
    from types import SimpleNamespace

    def curve(*values):
        return SimpleNamespace(frames=np.arange(len(values)) * 1000.0, values=np.array(values))

    r = report(times=(1000.0, None, None))
    r["settings"]["budget"] = 4000
    runs = [curve(0, 0.6, 0.7, 0.8, 0.9), curve(0, 0.1, 0.2, 0.4, 0.6, 0.9), curve(0, 0.6, 0.7, 0.2, 0.3)]
    assert cl.late_crossings(r, "transfer", runs) == 1  # the second: 0.6 at 4k (0.9 at 5k is past the budget)
    text = cl.threshold_sentence(r, "transfer", "near", late=1)
    assert text.endswith("; of the other 2, 1 ends the budget at or above it: unconfirmed at the end of the budget, "
                         "too late for the evaluations that would confirm a crossing")
    assert text.startswith("near: 1 of 3 seeds holds 0.5 to the end")
    none = report(times=(None, None, None))
    none["settings"]["budget"] = 4000
    assert cl.threshold_sentence(none, late=3).endswith("; every seed (3 of 3) ends the budget at or above it: "
                                                        "unconfirmed at the end of the budget, too late for the "
                                                        "evaluations that would confirm a crossing")
    first = report(crossing="first")
    assert "unconfirmed" not in cl.threshold_sentence(first, late=1)


def test_best_needs_the_exact_test_to_decide_every_paired_difference():
    def method(scores):  # reports read with the t interval (--interval t)
        return {"per_seed": {"transfer": [{"seed": s, "mean_return": v} for s, v in enumerate(scores)]},
                "settings": {"interval_method": "t"}}

    a, b = method([3.0, 4.2, 4.8, 6.0]), method([1.0, 2.0, 3.0, 4.0])  # A − B = 2.0, 2.2, 1.8, 2.0
    c = method([3.5, 3.0, 5.5, 5.0])  # A − C = −0.5, +1.2, −0.7, +1.0: mean 0.25, sd 0.988, t(3) 3.182
    # 4 pairs: the t test separates A from B, but no sign-flip test of 4 pairs goes below 2 / 2^4 = 0.125
    four = cl.best_sentence({"A": a, "B": b}, "near")
    assert four == ("near: no method is best at 4 pairs; A leads, and its paired difference to B, "
                    "+2.00 [+1.74, +2.26], has the exact sign-flip test's p = 0.125")
    level = cl.best_sentence({"A": a, "B": b, "C": c}, "near")
    assert level == ("near: no method is best at 4 pairs; A leads, and its paired difference to C, +0.25 [\u22121.32, "
                     "+1.82], has the exact sign-flip test's p = 0.75 after Holm")
    a6, b6 = method([3.0, 4.2, 4.8, 6.0, 5.1, 7.0]), method([1.0, 2.0, 3.0, 4.0, 3.0, 5.1])  # 6 pairs: p = 2 / 64
    best = cl.best_sentence({"A": a6, "B": b6}, "near")
    assert best.startswith("near: A is best, ahead of every other method (paired by seed, Holm over 1): B +2.00 [")


@pytest.mark.parametrize("value, ci, n, paired, family, expected", [
    (0.4, (0.1, 0.7), 3, True, 1, 6),     # power: 1 pair (3 x 0.238); a sign-flip test reaches 0.05 from 6 (2/64)
    (0.4, (0.1, 0.7), 3, False, 1, 4),    # a permutation of 4 + 4 runs reaches 2/70 = 0.029
    (0.4, (0.1, 0.7), 5, True, 20, 10),   # Holm over 20: 2 / 2^10 < 0.05 / 20
    (0.1, (-0.9, 1.1), 5, True, 1, 510),  # power: 5 (2.8016 x 0.36023 / 0.1)^2 = 509.3
])
def test_seeds_to_decide_is_the_power_estimate_or_the_exact_tests_floor(value, ci, n, paired, family, expected):
    assert cl.seeds_to_decide(value, ci, n, paired, family) == expected


def test_a_verdict_names_the_exact_test_that_decided_it():
    assert cl.verdict(0.4, (0.1, 0.7), cl.Adjusted(0.01, 0.03)) == (
        "+0.40 [+0.10, +0.70], higher with transfer (exact test, p = 0.03)")
    assert cl.verdict(0.4, (-0.1, 0.7), cl.Adjusted(0.2, 0.03), design=(6, True)) == (
        "+0.40 [\u22120.10, +0.70], higher with transfer (exact sign-flip test, p = 0.03)")
    assert cl.verdict(0.4, (0.1, 0.7), cl.Adjusted(0.01, 0.2), design=(10, True)) == (
        "+0.40 [+0.10, +0.70]: undecided at 10 pairs (exact sign-flip test, p = 0.2)")
    # 3 pairs: the sign-flip test's smallest p is 2 / 2^3 = 0.25, so no data could decide
    assert cl.verdict(0.4, (0.1, 0.7), cl.Adjusted(0.01, 0.25), design=(3, True)) == (
        "+0.40 [+0.10, +0.70]: undecided at 3 pairs, which cannot decide (the exact sign-flip test gives no p below "
        "0.25; p = 0.25)")
    # 5 + 5 runs: the permutation test's smallest p is 2 / C(10, 5) = 0.0079, below 0.05 / 4
    assert cl.verdict(-0.4, (-0.7, -0.1), cl.Adjusted(0.02, 0.2, 4), design=(5, False)) == (
        "\u22120.40 [\u22120.70, \u22120.10]: undecided at 5 seeds a side (exact permutation test, p = 0.2 after Holm)")


def test_the_smallest_exact_p_is_the_two_extreme_arrangements():
    assert [cl.smallest_exact_p(n, True) for n in (3, 5, 6, 10)] == [0.25, 0.0625, 0.03125, 2 / 1024]
    assert cl.smallest_exact_p(4, False) == pytest.approx(2 / 70) and cl.smallest_exact_p(3, False, 5) == 2 / 56


def test_the_headline_concludes_or_says_there_is_no_evidence():
    assert cl.headline(report()) == ("Headline (model-reuse vs no transfer, 3 paired seeds, 20k frames): mean return "
                                     "gain +0.40 [+0.10, +0.70], higher with transfer.")
    assert cl.headline(report(ci=(-0.1, 0.9))).endswith(
        "+0.40 [\u22120.10, +0.90]: no evidence of a difference at this budget.")


def test_regions_are_replaced_between_their_markers_and_a_missing_one_is_an_error():
    text = "a\n<!-- claims:x -->\nold 1\n<!-- /claims:x -->\nb\n"
    assert cl.fill_regions(text, {"x": "new 2"}) == "a\n<!-- claims:x -->\nnew 2\n<!-- /claims:x -->\nb\n"
    with pytest.raises(ValueError, match="no region 'y'"):
        cl.fill_regions(text, {"y": "z"})


# -------------------------------------------------------------------------------- committed prose
@pytest.mark.parametrize("file", sorted(generator().REGIONS))
def test_every_generated_region_matches_the_committed_numbers(file):
    """Fails on any drift: regenerate with `python results/claims.py`."""
    g = generator()
    text = (ROOT / file).read_text()
    drift = f"{file} drifted from results/**: run python results/claims.py"
    assert cl.fill_regions(text, g.generated(file)) == text, drift


def test_a_changed_number_changes_the_sentences(tmp_path):
    g = generator()
    for path in g.sweeps.GRADED.rglob("transfer_metrics.json"):
        target = tmp_path / path.relative_to(g.sweeps.GRADED)
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(path, target)
    changed = tmp_path / "fourrooms-near" / "sac" / "model-reuse" / "report" / "transfer_metrics.json"
    data = json.loads(changed.read_text())
    data["metrics"]["mean_return_gain_ci"] = [-0.2, 2.3]
    changed.write_text(json.dumps(data))
    order = ["model-reuse", "value-shaping", "policy-reuse", "reward-shaping"]
    before, after = g.sweeps.sweep_verdicts(g.sweeps.GRADED, order), g.sweeps.sweep_verdicts(tmp_path, order)
    assert "near +0.89 [\u22120.21, +1.41], higher with transfer (exact sign-flip test, p = 0.0391" in before
    assert "near +0.89 [\u22120.20, +2.30], higher with transfer (exact sign-flip test, p = 0.0391" in after


def test_the_registry_tables_list_every_builtin_task_method_and_key():
    g = generator()
    from drltg import config
    from drltg.envs import PAIRS, TASKS
    from drltg.transfer.registry import METHODS

    tasks = g.reference.tasks_table("rooms") + g.reference.tasks_table("robosuite") + g.reference.tasks_table("gym")
    methods, keys = g.reference.methods_table(), g.reference.config_table()
    builtin = {n for n, m in METHODS.items() if m.build.__module__.startswith("drltg.")}
    assert {"none", "reward-shaping", "value-shaping", "policy-reuse", "jumpstart", "model-reuse",
            "demonstrations", "kickstarting", "sf-gpi"} <= builtin
    assert all(f"| `{name}` |" in methods for name in builtin)
    assert all(f"| `{name}` |" in tasks for name, t in TASKS.items() if t.factory.__module__.startswith("drltg."))
    assert all(f"| `{name}` |" in tasks for name in ("fourrooms-near", "gridrooms-far", "lift-to-place"))
    assert len(PAIRS) >= 11
    plugin_keys = {f"transfer.{k}" for k, m in config.option_owners().items() if m not in builtin}
    assert all(f"| `{key}` |" in keys for key in config.keys() if key not in plugin_keys)
    assert "transfer.demo_episodes" in config.keys() and "| `transfer.demo_episodes` |" in keys


def test_the_report_command_ends_with_the_generated_headline(tmp_path, capsys):
    from drltg.cli import report

    demo = ROOT / "results" / "demo"
    code = report.main(["--baseline", str(demo / "baseline"), "--transfer", str(demo / "transfer"),
                        "--threshold", "0.5", "--baseline-label", "no transfer", "--transfer-label", "model-reuse",
                        "--out", str(tmp_path / "rep")])
    assert code == 0
    printed = capsys.readouterr().out
    committed = json.loads((demo / "report" / "transfer_metrics.json").read_text())
    assert cl.headline(committed) in printed  # the committed curves give back the quoted headline
    assert committed["metrics"]["n_seeds_transfer"] == 10 and committed["settings"]["paired"]


def test_each_reported_row_gets_its_gains_holm_adjusted_within_the_row(tmp_path, monkeypatch):
    """Two rows of the queue reported (8 pairs each, so the exact test could decide), each report with a jumpstart
    test beside its gain (p = 0.5), so a row's
    family holds every test of its two reports: pi-reuse-place, where no run placed and the success gain has
    no p-value, so the lifted gain's 0.02 is read among 3 tests (Holm: 3 x 0.02 = 0.06); model-reuse-place,
    whose 0.03 and 0.04 are read among 4 (4 x 0.03, then the larger of that and 3 x 0.04: 0.12 both), and
    where 2 of 3 transfer seeds hold the success threshold; only pi-reuse-place's lifted rate differs at its
    ends (+1.00 at the first evaluation, +0.20 at the last), so only its gain says where it comes from."""
    from types import SimpleNamespace

    claims = regions("manipulation")
    monkeypatch.setattr(claims, "MANIP", tmp_path)
    lifted = {"baseline": [0.0, 0.0], "transfer": [1.0, 0.9]}  # pi-reuse-place's jumpstart still there at 5k
    monkeypatch.setattr(regions("common"), "report_curves", lambda report, side: [
        SimpleNamespace(frames=np.array([0.0, 5000.0]), values=np.array(lifted[side]))] * 3)

    def put(row, method, tag, value, ci, p, totals=(1.0, 1.0), reached=(0.0, 0.0), ends=(0.0, 0.0)):
        folder = tmp_path / row / "lift-to-place" / "sac" / method / f"report-{tag}"
        folder.mkdir(parents=True)
        metrics = {"mean_return_gain": value, "mean_return_gain_ci": ci, "mean_return_gain_p_value": p,
                   "mean_return_gain_p_exact": p, "n_seeds_transfer": 8, "n_seeds_baseline": 8,
                   "total_reward_baseline": totals[0],
                   "total_reward_transfer": totals[1], "threshold_reached_baseline": reached[0],
                   "threshold_reached_transfer": reached[1], "jumpstart": ends[0], "asymptotic_performance": ends[1],
                   "jumpstart_p_value": 0.5, "jumpstart_p_exact": 0.5}
        settings = {"task": "lift-place", "transfer_label": method, "baseline_label": "no transfer", "budget": 100000,
                    "paired": True,
                    "threshold": 0.5, "asymptote_window": 0.1, "family": {"metrics": ["mean_return_gain", "jumpstart"]}}
        (folder / "transfer_metrics.json").write_text(json.dumps({"metrics": metrics, "settings": settings}))

    put("pi-reuse-place", "policy-reuse", "success", 0.0, None, None, totals=(0.0, 0.0))
    put("pi-reuse-place", "policy-reuse", "lifted", 0.3, [0.1, 0.5], 0.02, ends=(1.0, 0.2))
    put("model-reuse-place", "model-reuse", "success", 0.2, [0.05, 0.35], 0.03, totals=(0.0, 2.0), reached=(0, 0.25))
    put("model-reuse-place", "model-reuse", "lifted", 0.4, [0.1, 0.7], 0.04)
    rows = len(claims.ROWS)
    assert claims.manipulation_rows().splitlines() == [
        "- `pi-reuse-place` (lift-place, policy-reuse against no transfer, 8 paired seeds × 100k frames), mean gain "
        "in success rate +0.00: no evidence of a difference at this budget; lifted rate +0.30 [+0.10, +0.50]: "
        "undecided at 8 pairs (exact sign-flip test, p = 0.06 after Holm) (at the first evaluation +1.00, over the "
        "last 10% of the budget +0.20) (Holm over all 3 tests of its 2 reports); no run on either side placed a cube "
        "in any evaluation.",
        "- `model-reuse-place` (lift-place, model-reuse against no transfer, 8 paired seeds × 100k frames), mean gain "
        "in success rate +0.20 [+0.05, +0.35]: undecided at 8 pairs (exact sign-flip test, p = 0.12 after Holm); "
        "lifted rate +0.40 [+0.10, +0.70]: undecided at 8 pairs (exact sign-flip test, p = 0.12 after Holm) (Holm "
        "over all 4 tests of its 2 reports); success rate ≥ 0.5 held to the end by 2 of 8 seeds with transfer and 0 "
        "of 8 without; no run without transfer placed a cube in any evaluation.",
        f"{rows - 2} of the queue's {rows} rows are not complete yet (the runs finished so far are below).",
    ]
    shutil.rmtree(tmp_path / "pi-reuse-place")
    shutil.rmtree(tmp_path / "model-reuse-place")
    assert claims.manipulation_rows() == "No row of the queue is complete yet (the runs finished so far are below).\n"


def test_a_seed_row_reads_its_three_reports_as_one_family(tmp_path, monkeypatch):
    """pi-reuse-place-seed reported on return, success and lifted rate, each report with a jumpstart test beside
    its gain (p = 0.5): the gains' p = 0.01, 0.02 and 0.03 are read among 6 tests (Holm: 6 x 0.01 = 0.06, then
    5 x 0.02 = 0.10, then 4 x 0.03 = 0.12); the other four rows are not reported yet."""
    claims = regions("seed_tasks")
    monkeypatch.setattr(claims, "SEED", tmp_path)

    def put(sub, value, ci, p):
        folder = tmp_path / "pi-reuse-place-seed" / sub
        folder.mkdir(parents=True)
        metrics = {"mean_return_gain": value, "mean_return_gain_ci": ci, "mean_return_gain_p_value": p,
                   "mean_return_gain_p_exact": p, "n_seeds_transfer": 8, "n_seeds_baseline": 8, "jumpstart": 0.0,
                   "asymptotic_performance": 0.0, "jumpstart_p_value": 0.5, "jumpstart_p_exact": 0.5}
        settings = {"paired": True, "task": "lift-place-seed", "transfer_label": "pi-reuse-place-seed", "baseline_label":
                    "no transfer", "budget": 300000, "family": {"metrics": ["mean_return_gain", "jumpstart"]}}
        (folder / "transfer_metrics.json").write_text(json.dumps({"metrics": metrics, "settings": settings}))

    assert claims.seed_rows() == "No row of the 5 is reported yet: the table above shows their runs so far.\n"
    put("report", 40.0, [10.0, 70.0], 0.01)
    put("report-success", 0.1, [0.02, 0.18], 0.02)
    put("report-lifted", 0.2, [0.05, 0.35], 0.03)
    assert claims.seed_rows().splitlines() == [
        "- `pi-reuse-place-seed` (lift-place-seed, pi-reuse-place-seed against no transfer, 8 paired seeds × 300k "
        "frames), mean gain in return +40.00 [+10.00, +70.00]: undecided at 8 pairs (exact sign-flip test, p = 0.06 "
        "after Holm); success rate +0.10 [+0.02, +0.18]: undecided at 8 pairs (exact sign-flip test, p = 0.1 after "
        "Holm); lifted rate +0.20 [+0.05, +0.35]: undecided at 8 pairs (exact sign-flip test, p = 0.12 after Holm) "
        "(Holm over all 6 tests of its 3 reports).",
        "4 of the 5 rows are not reported yet.",
    ]


def test_a_recipe_reported_on_the_seeds_that_chose_it_says_so():
    g = regions("common")
    ran = {"settings": {"tuned_on": {"baseline": [], "transfer": [0, 100]}}}  # the report's reading of tuned_on
    said = g.tuned("demonstrations-reference-place", ran)
    assert said == ("; the placement reference's recipe (measurements/place-reference-ln-half-noisy): chosen on seeds "
                    "0, 100, which are reported here too (tuned on the seeds it reports, not a fresh-seed result)")
    assert g.tuned("demonstrations-reference-place", {"settings": {"tuned_on": {"transfer": []}}}) == ""
    assert g.tuned("model-reuse-place", ran).startswith("; its recipe: chosen on seeds 0, 100")


def test_a_frame_0_jumpstart_gone_by_the_next_evaluation_is_said_to_be_one(monkeypatch):
    """The note says the whole-budget difference is the carried jumpstart only where it is: the triangle
    j (f1 - f0) / 2 over the budget, here 1 x 5000 / 2 / 10000 = 0.25, with the jumpstart's sign."""
    from types import SimpleNamespace

    g = regions("common")

    def report(jumpstart, gain):
        return {"metrics": {"jumpstart": jumpstart, "asymptotic_performance": 0.0, "mean_return_gain": gain},
                "settings": {"asymptote_window": 0.1}}

    def runs(*seconds):
        return [SimpleNamespace(frames=np.array([0.0, 5000.0, 10000.0]), values=np.array([v0, v1, 0.0]))
                for v0, v1 in seconds]

    curves = {"baseline": runs((0, 0), (0, 0)), "transfer": runs((1, 0), (1, 0))}
    monkeypatch.setattr(g, "report_curves", lambda report, side: curves[side])
    assert g.ends(report(1.0, 0.25)).endswith("; gone by the second evaluation, 5k frames: +0.00, so this gain is the "
                                              "frame-0 jumpstart carried over the first interval, not a gain over the run)")
    assert g.ends(report(1.0, 0.6)) == " (at the first evaluation +1.00, over the last 10% of the budget +0.00)"
    assert g.ends(report(1.0, -0.25)) == " (at the first evaluation +1.00, over the last 10% of the budget +0.00)"
    curves["transfer"] = runs((-1, 0), (-1, 0))
    assert g.ends(report(-1.0, -0.25)).endswith("so this loss is the frame-0 jumpstart carried over the first "
                                                "interval, not a loss over the run)")
    curves["transfer"] = runs((1, 1), (1, 1))  # still there at the second evaluation: nothing more to say
    assert g.ends(report(1.0, 0.25)) == " (at the first evaluation +1.00, over the last 10% of the budget +0.00)"


def test_a_betting_p_value_by_hand():
    # x = 1, 1, 1 against m = 1/2: every bet is capped at c/m = 1.5 (the plug-in bets are above 3), so the
    # up-gambler's wealth is 1.75^3 and the down-gambler's falls; p = 1 / (max wealth / 2)
    assert stats.betting_p(np.ones((1, 3)), [0.5])[0, 0] == pytest.approx(2 / 1.75 ** 3)
    # the largest paired differences possible: 6 pairs cannot reach 0.05, 7 can
    for n, p in ((6, 2 / 1.75 ** 6), (7, 2 / 1.75 ** 7)):
        lo, hi, p0 = stats.betting_interval(np.zeros(n), np.ones(n), (0, 1), paired=True)
        assert p0 == pytest.approx(p) and (lo > 0) == (p < 0.05)


def test_a_betting_interval_holds_0_and_says_how_many_seeds_would_decide():
    rows = {side: [{"seed": i, "mean_return": v} for i, v in enumerate(values)]
            for side, values in (("baseline", [0.0] * 3), ("transfer", [1.0] * 3))}
    ranged = {"metrics": {"n_seeds_baseline": 3, "n_seeds_transfer": 3, "mean_return_gain": 1.0,
                          "mean_return_gain_ci": [-0.2, 1.0], "mean_return_gain_p_exact": 0.25},
              "settings": {"paired": True, "interval_method": "auto", "value_range": [0, 1]}, "per_seed": rows}
    # 7 pairs like these reach p = 2 / 1.75^7 < 0.05 (and a sign-flip test of 7 pairs can: 2/128)
    assert cl.betting_seeds([0.0] * 3, [1.0] * 3, (0, 1), paired=True) == 7
    assert cl.verdict_of(ranged, "mean_return_gain") == (  # the exact test decides: 3 pairs cannot
        "+1.00 [\u22120.20, +1.00]: undecided at 3 pairs, which cannot decide (the exact sign-flip test gives no p "
        "below 0.25; p = 0.25)")
    no_exact = {**ranged, "metrics": {k: v for k, v in ranged["metrics"].items() if not k.endswith("_p_exact")}}
    assert cl.verdict_of(no_exact, "mean_return_gain") == (
        "+1.00 [\u22120.20, +1.00]: no verdict at 3 pairs; about 7 would decide it if further seeds scored like these "
        "(estimate)")
    unknown = {**no_exact, "metrics": {k: v for k, v in no_exact["metrics"].items() if not k.endswith("_ci")},
               "settings": {**ranged["settings"], "value_range": None}}
    assert cl.verdict_of(unknown, "mean_return_gain") == (
        "+1.00: no interval without the curves' range (--value-range), so no verdict")
    assert cl.betting_seeds([0.5] * 3, [0.5] * 3, (0, 1), paired=True) is None  # alike: no number decides


def test_best_under_the_betting_interval_is_decided_by_the_exact_test():
    def method(scores):  # reports read with --interval auto, returns in [0, 1]
        return {"per_seed": {"transfer": [{"seed": s, "mean_return": v} for s, v in enumerate(scores)]},
                "settings": {"interval_method": "auto", "value_range": [0, 1]}}

    # A − B = 1 in each of 3 pairs: the betting interval holds 0 (3 pairs can multiply the wealth by at most
    # 1.75^3), and 7 such pairs reach p = 2 / 1.75^7 < 0.05 (cl.betting_seeds)
    said = cl.best_sentence({"A": method([1.0, 1.0, 1.0]), "B": method([0.0, 0.0, 0.0])}, "near")
    assert said.startswith("near: no method is best at 3 pairs; A leads, and its paired difference to B, +1.00 [")
    assert said.endswith("has the exact sign-flip test's p = 0.25")
