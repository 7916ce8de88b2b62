"""drltg bench report refuses, in one sentence and before writing anything, a record or report it cannot trust:
one copied from another pair, a score not finite or outside its range, a malformed shape, a link out of the
bench folder, a bench.json of another suite, or resamples out of bounds."""
import json
import os

import pytest

from drltg.bench import suite
from drltg.bench.suite import Group, Tier
from drltg.cli import main

SEEDS = [0, 100, 200]
SPEC = {"pairs": ["fourrooms-near", "fourrooms-far"], "algos": ["sac"], "seeds": 3, "seed": 0, "frames": 20000,
        "source_frames": 40000, "overrides": {"eval.every": 1000}}
TARGETS = {"fourrooms-near": "fourrooms/northeast-shifted", "fourrooms-far": "fourrooms/southwest"}


def _report(pair):
    return {"settings": {"task": TARGETS[pair], "budget": 20000, "value_range": [-1.0, 1.0]},
            "per_seed": {side: [{"seed": s, "mean_return": x} for s, x in zip(SEEDS, xs)]
                         for side, xs in (("baseline", [0.0, 0.1, 0.2]), ("transfer", [0.5, 0.6, 0.7]))},
            "metrics": {"mean_return_gain_verdict": "higher", "mean_return_gain_verdict_p": 0.25,
                        "mean_return_gain_verdict_test": "sign-flip"}}


def _bench(tmp_path, monkeypatch, edit_record=None, edit_report=None):
    monkeypatch.setitem(suite.SUITES, suite.LATEST, {"two": Tier("two", "two pairs", (Group("g", SPEC),))})
    root = tmp_path / suite.LATEST / "two"
    reports = {}
    for pair in SPEC["pairs"]:
        folder = root / "g" / pair / "sac" / "m" / "report"
        folder.mkdir(parents=True)
        reports[pair] = _report(pair)
    if edit_report:
        edit_report(reports, root)
    for pair, report in reports.items():
        path = root / "g" / pair / "sac" / "m" / "report" / "transfer_metrics.json"
        if not path.is_symlink():
            path.write_text(report if isinstance(report, str) else json.dumps(report))
    record = {"suite": suite.LATEST, "tier": "two", "methods": {"m": {"versions": {"drltg": "0", "torch": "0"},
                                                              "smoke": False, "groups": {"g": SPEC}, "left_out": {}}}}
    if edit_record:
        record = edit_record(record)
    (root / "bench.json").write_text(record if isinstance(record, str) else json.dumps(record))
    return root


def _set(path, value):
    def edit(reports, root):
        for pair in ([path[0]] if path[0] in reports else reports):
            node = reports[pair]
            keys = path[1:] if path[0] in reports else path
            for k in keys[:-1]:
                node = node[k]
            node[keys[-1]] = value
    return edit


def _copy_near_over_far(reports, root):
    reports["fourrooms-far"] = reports["fourrooms-near"]


def _link_outside(reports, root):
    outside = root.parent.parent / "elsewhere.json"
    outside.write_text(json.dumps(reports["fourrooms-far"]))
    os.symlink(outside, root / "g" / "fourrooms-far" / "sac" / "m" / "report" / "transfer_metrics.json")


def _deep(reports, root):
    reports["fourrooms-far"] = "[" * 100_000 + "]" * 100_000


def _summary(source):
    """Each transfer run of the near pair recording ``source`` as the source it loaded."""
    def edit(reports, root):
        for seed in SEEDS:
            run = root / "g" / "fourrooms-near" / "sac" / "m" / "transfer" / f"seed-{seed}"
            run.mkdir(parents=True)
            (run / "summary.json").write_text(json.dumps({"status": "complete", "source": source}))
    return edit


def _entry(**kw):
    return lambda r: {**r, "methods": {"m": {**r["methods"]["m"], **kw}}}


REPORTS = [
    ("copied", _copy_near_over_far, "not fourrooms-far's target task 'fourrooms/southwest'"),
    ("budget", _set(("settings", "budget"), 400), "its budget is 400 frames, not the 20,000"),
    ("range declared", _set(("settings", "value_range"), [-2.0, 2.0]), "the target task declares"),
    ("inf", _set(("per_seed", "transfer", 0, "mean_return"), float("inf")), "not a finite number"),
    ("nan", _set(("per_seed", "transfer", 0, "mean_return"), float("nan")), "not a finite number"),
    ("reversed", _set(("settings", "value_range"), [1.0, -1.0]), "does not have low < high"),
    ("same", _set(("settings", "value_range"), [0.5, 0.5]), "does not have low < high"),
    ("outside", _set(("per_seed", "transfer", 0, "mean_return"), 50), "lies outside the value range"),
    ("string", _set(("per_seed", "transfer", 0, "mean_return"), "0.5"), "not a finite number"),
    ("huge", _set(("per_seed", "transfer", 0, "mean_return"), 10**400), "not a finite number"),
    ("no metrics", lambda reports, root: reports["fourrooms-far"].pop("metrics"), "'metrics' is None"),
    ("list", _set(("fourrooms-far", "settings"), None), "'settings' is None"),
    ("verdict", _set(("metrics", "mean_return_gain_verdict"), "much-better"), "not one of higher"),
    ("deep", _deep, "nests deeper than a transfer report"),
    ("link", _link_outside, "outside the bench folder"),
    ("source digest", _summary({"networks_sha256": "abc", "config_sha256": "0" * 64}),
     "summary.json' is not a run summary (its source's networks_sha256 is 'abc', not a SHA-256 in hex)"),
    ("source list", _summary(["abc"]), "summary.json' is not a run summary (its 'source' is ['abc'], not a mapping)"),
]
RECORDS = [
    ("top-level list", lambda r: [r], "the record is [{"),
    ("suite", lambda r: {**r, "suite": "v0"},
     f"it records suite 'v0', but it lies in the folder of suite '{suite.LATEST}'"),
    ("method 5", lambda r: {**r, "methods": {"m": 5}}, "method 'm' is 5, not a mapping"),
    ("groups list", _entry(groups=["g"]), "method 'm''s 'groups' is ['g'], not a mapping"),
    ("left_out list", _entry(left_out=["p"]), "method 'm''s 'left_out' is ['p'], not a mapping"),
    ("versions string", _entry(versions="1.0"), "method 'm''s 'versions' is '1.0', not a mapping"),
]


def _refused(tmp_path, capsys, argv, fragment):
    assert main(["bench", "report", "--out", str(tmp_path), "--reference", "none", "--tier", "two", *argv]) == 2
    err = capsys.readouterr().err
    assert fragment in err and err.count("\n") == 1, err
    assert not (tmp_path / suite.LATEST / "two" / "board").exists()


@pytest.mark.parametrize("case, edit, fragment", REPORTS, ids=[c[0] for c in REPORTS])
def test_an_untrusted_report_is_one_sentence_and_writes_nothing(tmp_path, monkeypatch, capsys, case, edit, fragment):
    _bench(tmp_path, monkeypatch, edit_report=edit)
    _refused(tmp_path, capsys, ["--reps", "200"], fragment)


@pytest.mark.parametrize("case, edit, fragment", RECORDS, ids=[c[0] for c in RECORDS])
def test_an_untrusted_record_is_one_sentence_and_writes_nothing(tmp_path, monkeypatch, capsys, case, edit, fragment):
    _bench(tmp_path, monkeypatch, edit_record=edit)
    _refused(tmp_path, capsys, ["--reps", "200"], fragment)


@pytest.mark.parametrize("reps", ["0", "-1", "1000000000"])
def test_reps_out_of_bounds_is_one_sentence(tmp_path, monkeypatch, capsys, reps):
    _bench(tmp_path, monkeypatch)
    _refused(tmp_path, capsys, ["--reps", reps], "--reps must be an integer from 100 to 100,000")


def test_a_trusted_bench_folder_is_reported(tmp_path, monkeypatch, capsys):
    _bench(tmp_path, monkeypatch)
    assert main(["bench", "report", "--out", str(tmp_path), "--reference", "none", "--tier", "two",
                 "--reps", "200"]) == 0
    assert (tmp_path / suite.LATEST / "two" / "board" / "leaderboard.json").is_file()
