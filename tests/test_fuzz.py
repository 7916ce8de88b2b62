"""Property-based checks of what a user types or hands over: every ``-o`` override, sweep spec and report
input either gives a result or one :class:`UsageError` sentence — never another exception.

The profile here is short and derandomized (``make test`` sees the same inputs every run); ``python -m
benchmarks.fuzz`` runs the same properties with many more, random, examples.
"""
from __future__ import annotations

import json
import math
import os
from pathlib import Path

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from drltg import config as config_lib
from drltg.errors import UsageError
from drltg.report import compute, render
from drltg.report.curves import Curve

EXAMPLES = int(os.environ.get("DRLTG_FUZZ_EXAMPLES", "0"))
"""Examples per property: a fixed, derandomized 60 in ``make test`` (the same inputs every run), else random."""
FUZZ = settings(max_examples=EXAMPLES or 60, derandomize=not EXAMPLES, database=None, deadline=None,
                suppress_health_check=[HealthCheck.too_slow])

texts = st.text(st.characters(codec="utf-8"), max_size=30)
scalars = st.one_of(st.none(), st.booleans(), st.integers(-(2**70), 2**70), texts,
                    st.floats(allow_nan=True, allow_infinity=True))
values = st.recursive(scalars, lambda inner: st.one_of(st.lists(inner, max_size=4),
                                                       st.dictionaries(texts, inner, max_size=4)), max_leaves=12)
keys = st.one_of(st.sampled_from(config_lib.keys()), texts,
                 st.sampled_from(config_lib.keys()).map(lambda k: k + ".x"))


def one_sentence(err: UsageError) -> None:
    text = str(err)
    assert text and "\n" not in text.strip() and "Traceback" not in text, text


@FUZZ
@given(key=keys, value=st.one_of(texts, values.map(lambda v: yaml.safe_dump(v, default_flow_style=True).strip())))
def test_any_override_is_a_config_or_one_sentence(key, value):
    try:
        cfg = config_lib.resolve(None, [f"{key}={value}"], task="fourrooms/northeast")
    except UsageError as err:
        one_sentence(err)
    else:
        assert isinstance(cfg, config_lib.RunConfig)


@FUZZ
@given(data=st.dictionaries(st.sampled_from(["pairs", "methods", "algos", "seeds", "frames", "threshold", "grid",
                                             "overrides", "tasks", "source_frames"]) | texts, values, max_size=6))
def test_any_sweep_spec_is_a_plan_or_one_sentence(data):
    from drltg.experiments.spec import parse_spec

    try:
        parse_spec(data)
    except UsageError as err:
        one_sentence(err)


finite = st.floats(min_value=-1e307, max_value=1e307, allow_nan=False, allow_infinity=False)


@st.composite
def curves(draw, side: str):
    """A set of runs on a shared or drawn frame grid, with any finite returns (huge, equal, constant)."""
    n_runs = draw(st.integers(1, 4))
    grid = draw(st.lists(st.integers(0, 10**7), min_size=1, max_size=6, unique=True).map(sorted))
    runs = []
    for k in range(n_runs):
        ys = draw(st.one_of(st.lists(finite, min_size=len(grid), max_size=len(grid)),
                            st.just([float(k)] * len(grid)), st.just([0.0] * len(grid))))
        runs.append(Curve(grid, ys, Path(f"/{side}/seed-{k}"), f"{side}/seed-{k}"))
    return runs


@FUZZ
@given(baseline=curves("baseline"), transfer=curves("transfer"), same=st.booleans())
@pytest.mark.filterwarnings("ignore:overflow encountered:RuntimeWarning")  # squares of returns near 1e308
def test_any_curves_give_a_report_or_one_sentence(baseline, transfer, same):
    if same:  # a method with no effect: the transfer runs equal their paired baselines
        transfer = [Curve(c.frames, c.values, Path(f"/transfer/{c.source.name}"), f"transfer/{c.source.name}")
                    for c in baseline]
    try:
        result = compute(baseline, transfer)
        files = render(result)
    except UsageError as err:
        one_sentence(err)
        return
    def refuse(token):
        raise AssertionError(f"{token} in a report's JSON")

    for name, data in files.items():
        if name.endswith(".json"):
            json.loads(data, parse_constant=refuse)  # strict JSON: no NaN or Infinity tokens
    for key, value in result["metrics"].items():
        for v in value if isinstance(value, (list, tuple)) else [value]:
            assert v is None or isinstance(v, (bool, str)) or math.isfinite(v), (key, value)


def test_an_override_with_a_control_character_is_one_sentence_or_a_string():
    """Found by the property above: PyYAML's reader refuses a control character before parsing starts."""
    try:
        config_lib.resolve(None, ["network.hidden=\x08"], task="fourrooms/northeast")
    except UsageError as err:
        one_sentence(err)


# ----------------------------------------------------------------------------- hostile run directories
@pytest.fixture(scope="module")
def two_runs(tmp_path_factory):
    """A finished tiny baseline and transfer run (two seeds of one config)."""
    from drltg.cli import main
    from tests.test_faults import train_args

    root = tmp_path_factory.mktemp("hostile")
    for seed in (0, 1):
        assert main(train_args(root / f"seed-{seed}") + ["--seed", str(seed)]) == 0
    return root


SHAPES = ["link to a file outside", "link to a folder outside", "link to ..", "link to /", "fifo", "socket",
          "sparse 300 MB", "empty"]
PLACES = ["", "logs", "logs/csv/scalars/eval", "logs/tensorboard", "checkpoints"]
NAMES = ["eval.csv", "config.yaml", "manifest.json", "summary.json", "last.pt", "return_mean.csv",
         "events.out.tfevents.1.host", "extra.csv", "extra"]


def _plant(path: Path, shape: str, outside: Path) -> None:
    """Put ``shape`` at ``path``, replacing whatever was there."""
    import shutil
    import stat

    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path)
    elif path.exists() or path.is_symlink():
        path.unlink()
    path.parent.mkdir(parents=True, exist_ok=True)
    if shape.startswith("link"):
        target = {"link to a file outside": outside / "bystander.csv", "link to a folder outside": outside,
                  "link to ..": Path(".."), "link to /": Path("/")}[shape]
        path.symlink_to(target)
    elif shape == "fifo":
        os.mkfifo(path)
    elif shape == "socket":
        os.mknod(path, stat.S_IFSOCK | 0o600)
    elif shape == "sparse 300 MB":
        with open(path, "wb") as f:
            f.write(b"frames,return_mean\n")
            f.truncate(300 * 2**20)
    else:
        path.touch()


@settings(max_examples=EXAMPLES or 40, derandomize=not EXAMPLES, database=None, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(shape=st.sampled_from(SHAPES), place=st.sampled_from(PLACES), name=st.sampled_from(NAMES),
       command=st.sampled_from(["report", "resume", "evaluate", "video"]))
def test_any_hostile_entry_in_a_run_is_a_result_or_one_sentence_and_touches_nothing_outside(
        two_runs, shape, place, name, command, capsys):
    """A link, pipe, socket, huge or empty file anywhere in a run, under any name: every command that opens
    the run ends within seconds in a result or one sentence, and nothing outside the run changes."""
    import shutil
    import signal
    import tempfile

    from drltg.cli import main

    root = Path(tempfile.mkdtemp(prefix="drltg-hostile-"))
    try:
        outside = root / "outside"
        outside.mkdir()
        (outside / "bystander.csv").write_text("frames,return_mean\n0,1.0\n")
        before = {p: p.read_bytes() for p in outside.rglob("*") if p.is_file()}
        for seed in (0, 1):
            shutil.copytree(two_runs / f"seed-{seed}", root / "runs" / f"seed-{seed}")
        run = root / "runs" / "seed-1"
        _plant(run / place / name, shape, outside)
        args = {"report": ["report", "--baseline", str(root / "runs" / "seed-0"), "--transfer", str(run),
                           "--out", str(root / "report")],
                "resume": ["train", "fourrooms/northeast", "--run-dir", str(run), "--resume", "--no-progress"],
                "evaluate": ["evaluate", str(run), "--episodes", "1"],
                "video": ["video", str(run), "--episodes", "1", "--max-steps", "2", "--out", str(root / "video")],
                }[command]

        def hang(*_):
            raise AssertionError(f"{command} still runs after 60 s")

        signal.signal(signal.SIGALRM, hang)
        signal.alarm(60)
        try:
            code = main(args)
        finally:
            signal.alarm(0)
        err = capsys.readouterr().err
        assert code in (0, 2), (code, err)
        if code == 2:
            assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
        assert {p: p.read_bytes() for p in outside.rglob("*") if p.is_file()} == before
    finally:
        shutil.rmtree(root, ignore_errors=True)
