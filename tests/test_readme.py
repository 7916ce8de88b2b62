"""The Python blocks of README.md and the docs site are complete programs: each runs on its own, with a
tiny budget.

Every ```python block (README's, then the pages' in the site's order; a block shown on two pages runs once)
runs in a fresh namespace, all in one subprocess (torch imported once), in a scratch folder, in that order;
``FRAMES = ...`` lines are set to a tiny budget. A block that reads runs a user would have (``drltg
report``'s ``runs/exp``) finds Stable-Baselines3 logs shipped with the suite there (tests/data/README.md).
"""
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
DATA = Path(__file__).resolve().parent / "data"
PAGES = [ROOT / "README.md"] + [ROOT / "docs" / next(iter(entry.values()))
                                for entry in yaml.safe_load((ROOT / "mkdocs.yml").read_text())["nav"]]
BLOCKS = list(dict.fromkeys(block for page in PAGES
                            for block in re.findall(r"^```python\n(.*?)^```", page.read_text(), flags=re.S | re.M)))
FRAMES = 320
RUNNER = """
import contextlib, io, json, sys, traceback
blocks, out = json.load(open(sys.argv[1])), sys.argv[2]
results = []
for code in blocks:
    stdout = io.StringIO()
    try:
        with contextlib.redirect_stdout(stdout):
            exec(compile(code, "docs", "exec"), {"__name__": "__main__"})
        results.append({"stdout": stdout.getvalue(), "error": None})
    except BaseException:
        results.append({"stdout": stdout.getvalue(), "error": traceback.format_exc()})
json.dump(results, open(out, "w"))
"""


def tiny(code: str) -> str:
    return re.sub(r"^FRAMES = .*$", f"FRAMES = {FRAMES}", code, flags=re.M)


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("readme")
    shutil.copytree(DATA / "sb3_runs" / "liftplace_sac", tmp / "runs" / "exp" / "baseline" / "liftplace_sac")
    shutil.copytree(DATA / "sb3_runs" / "liftplace_sac_policyreuse", tmp / "runs" / "exp" / "transfer" / "reuse")
    (tmp / "blocks.json").write_text(json.dumps([tiny(b) for b in BLOCKS]))
    done = subprocess.run(
        [sys.executable, "-c", RUNNER, str(tmp / "blocks.json"), str(tmp / "results.json")],
        cwd=tmp, capture_output=True, text=True, timeout=900,
        env={**os.environ, "RL_WARNINGS": "False", "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get(
            "PYTHONPATH", "")])},
    )
    assert done.returncode == 0, done.stderr[-3000:]
    return tmp, json.loads((tmp / "results.json").read_text())


def test_the_readme_has_python_blocks_and_every_budget_is_patchable():
    assert len(BLOCKS) >= 8
    for block in BLOCKS:  # a training budget is spelled FRAMES, so the suite can shrink it
        assert not re.search(r"frames=\d", block), block


@pytest.mark.parametrize("index", range(len(BLOCKS)), ids=[b.splitlines()[0][:40] for b in BLOCKS])
def test_a_readme_block_runs_on_its_own(runs, index):
    _, results = runs
    assert results[index]["error"] is None, f"README block {index}:\n{BLOCKS[index]}\n{results[index]['error']}"


def test_the_readme_blocks_leave_what_they_say(runs):
    tmp, results = runs
    assert (tmp / "runs" / "my-run" / "summary.json").is_file() and (tmp / "runs" / "source" / "summary.json").is_file()
    model_reuse = next(r["stdout"] for b, r in zip(BLOCKS, results) if "load_from_run(agent.loss" in b)
    assert model_reuse.startswith("model reuse: 19 loaded, 3 widened, 0 narrowed, 0 skipped")
    assert "frozen" in model_reuse
    assert (tmp / "report" / "transfer_metrics.json").is_file()
