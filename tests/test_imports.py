"""Imports point down the pipeline, form no cycle, and the CLI's quick answers import no torch.

The layers, lowest first (a module may import its own package and lower layers only; packages of one
layer import nothing from each other)::

    errors       drltg.errors
    analysis     drltg.analysis (pure functions over arrays and records: no torch, no run directory)
    regular      drltg.regular (reading a file that must be a regular one)
    yaml         drltg.safe_yaml (bounded YAML from files and command lines)
    base         drltg.plugins | drltg.store (a run directory on disk: files, manifest, checkpoints, lock)
    envs         drltg.envs
    modules      drltg.modules (networks, and min_k Q_k of a critic ensemble: what the parts run, as
                 torchrl.modules sits below torchrl.objectives)
    parts        drltg.transforms | drltg.collectors | drltg.losses
    config       drltg.config
    learners     drltg.learners
    transfer     drltg.transfer (methods compose parts; a source is rebuilt with a learner)
    training     drltg.training
    report       drltg.report (a report over run directories and logs: no torch)
    experiments  drltg.experiments, drltg.video (run, then report)
    bench        drltg.bench (a suite's tiers run as sweeps, and their leaderboard)
    cli          drltg.cli
    main         drltg.__main__ (``python -m drltg``)

Every import counts, those inside functions included: a lazy import is still a dependency.
"""
import ast
import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "drltg"

LAYERS = [
    ["drltg.errors"],
    ["drltg.analysis"],
    ["drltg.regular"],
    ["drltg.safe_yaml"],
    ["drltg.plugins", "drltg.store"],
    ["drltg.envs"],
    ["drltg.gymnasium_ids"],
    ["drltg.modules"],
    ["drltg.transforms", "drltg.collectors", "drltg.losses"],
    ["drltg.config"],
    ["drltg.learners"],
    ["drltg.transfer"],
    ["drltg.training"],
    ["drltg.report"],
    ["drltg.experiments", "drltg.video"],
    ["drltg.bench"],
    ["drltg.cli"],
    ["drltg.__main__"],
]
HEAVY = ("torch", "torchrl", "tensordict")


def _modules() -> dict[str, Path]:
    modules = {}
    for path in PACKAGE.rglob("*.py"):
        parts = path.relative_to(ROOT).with_suffix("").parts
        modules[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return modules


MODULES = _modules()


def imports(name: str, *, top_level_only: bool = False) -> set[str]:
    """The modules ``name`` imports (submodules resolved; ``from pkg import sub`` is ``pkg.sub``)."""
    path = MODULES[name]
    tree = ast.parse(path.read_text())
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    nodes = tree.body if top_level_only else ast.walk(tree)
    found = set()
    for node in nodes:
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(anchor + ([base] if base else []))
            for alias in node.names:
                found.add(f"{base}.{alias.name}" if f"{base}.{alias.name}" in MODULES else base)
    return found


def layer(name: str) -> tuple[int, str]:
    """(rank, the layer entry ``name`` belongs to): the longest listed prefix wins."""
    best = None
    for rank, entries in enumerate(LAYERS):
        for entry in entries:
            if (name == entry or name.startswith(entry + ".")) and (best is None or len(entry) > len(best[1])):
                best = (rank, entry)
    assert best is not None, f"{name} belongs to no layer: add it to LAYERS"
    return best


def _edges(top_level_only=False):
    for name in MODULES:
        for target in imports(name, top_level_only=top_level_only):
            if target.startswith("drltg.") and target != name:
                yield name, target


def test_every_module_has_a_layer():
    for name in MODULES:
        if name != "drltg":
            layer(name)


def test_imports_point_down_the_pipeline():
    wrong = []
    for name, target in _edges():
        if name == "drltg":  # the package's own surface is checked by test_import_drltg_is_cheap
            continue
        (rank, entry), (target_rank, target_entry) = layer(name), layer(target)
        if entry == target_entry:
            continue
        if target_rank > rank or (target_rank == rank and entry != target_entry):
            wrong.append(f"{name} ({LAYERS[rank][0]}) imports {target} ({LAYERS[target_rank][0]})")
    assert not wrong, "\n".join(wrong)


def test_packages_that_hold_a_lower_layer_import_nothing_above_it():
    # importing a low module runs its packages' __init__.py files first: they must not pull a higher layer in
    for name in MODULES:
        rank, _ = layer(name) if name != "drltg" else (0, "")
        parent = name.rpartition(".")[0]
        while parent and parent != "drltg":
            above = [t for t in imports(parent, top_level_only=True) if t.startswith("drltg.") and layer(t)[0] > rank]
            assert not above, f"importing {name} runs {parent}/__init__.py, which imports {above}"
            parent = parent.rpartition(".")[0]


def test_no_import_cycles():
    graph: dict[str, set[str]] = {name: set() for name in MODULES}
    for name, target in _edges():
        graph[name].add(target)
    state: dict[str, int] = {}

    def visit(node, path):
        state[node] = 1
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                cycle = path[path.index(nxt):] + [nxt]
                pytest.fail("import cycle: " + " -> ".join(cycle))
            if nxt not in state:
                visit(nxt, path + [nxt])
        state[node] = 2

    for name in sorted(graph):
        if name not in state:
            visit(name, [name])


def test_analysis_the_report_and_the_package_root_import_no_torch_at_all():
    for name in MODULES:
        if name == "drltg" or name.startswith(("drltg.analysis", "drltg.report")):
            heavy = {t for t in imports(name) if t.split(".")[0] in HEAVY}
            assert not heavy, f"{name} imports {heavy}"


def _python(code: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=60)


NO_TORCH = "import sys; assert not [m for m in sys.modules if m.split('.')[0] in ('torch', 'torchrl', 'tensordict')]"


@pytest.mark.parametrize(
    "argv, rc, stream, text",
    [
        (["tasks"], 0, "stdout", "fourrooms/northeast"),
        (["train", "fourrooms/northeastt"], 2, "stderr", "did you mean 'fourrooms/northeast'?"),
        (["train", "fourrooms/northeast", "-o", "optim.lrr=1"], 2, "stderr", "optim.lrr"),
        (["train", "fourrooms/northeast", "-o", "optim.lr=-1"], 2, "stderr", "optim.lr"),
        (["train", "fourrooms/northeast", "-o", "env.horizon=abc"], 2, "stderr", "env.horizon"),  # the env unimported
        (["train", "gridrooms/northeast", "-o", "transfer.method=model-reuse"], 2, "stderr", "needs transfer.source"),
        (["train", "fourrooms/northeast", "-o", "seed=1", "-o", "seed=2"], 2, "stderr", "'seed' is set twice"),
    ],
)
def test_cli_answers_without_importing_torch(argv, rc, stream, text):
    code = f"from drltg.cli import main; rc = main({argv!r}); {NO_TORCH}; print('rc', rc)"
    done = _python(code)
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines()[-1] == f"rc {rc}"
    assert text in getattr(done, stream)


def test_python_dash_m_drltg_is_the_drltg_command():
    done = subprocess.run([sys.executable, "-m", "drltg", "train", "fourrooms/northeastt"], cwd=ROOT,
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 2
    assert "did you mean 'fourrooms/northeast'?" in done.stderr


def test_a_report_of_manipulation_runs_bounds_by_the_task_s_return_range_without_importing_robosuite(tmp_path):
    """The range [0, horizon] comes from the task's defaults: neither torch nor robosuite is imported for it."""
    for side, values in (("b", (1.0, 40.0)), ("t", (3.0, 60.0))):
        for seed in (0, 1):
            run = tmp_path / side / f"seed-{seed}"
            run.mkdir(parents=True)
            (run / "config.yaml").write_text(f"task: lift-place-seed\nseed: {seed}\nenv:\n  horizon: 200\n")
            (run / "eval.csv").write_text(f"frames,return_mean\n0,{values[0] + seed}\n1000,{values[1] + seed}\n")
    code = (f"from drltg.cli import main; rc = main(['report', '--baseline', {str(tmp_path / 'b')!r}, '--transfer', "
            f"{str(tmp_path / 't')!r}, '--out', {str(tmp_path / 'r')!r}]); {NO_TORCH}; "
            "assert 'robosuite' not in sys.modules; print('rc', rc)")
    done = _python(code)
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines()[-1] == "rc 0"
    settings = json.loads((tmp_path / "r" / "transfer_metrics.json").read_text())["settings"]
    assert settings["value_range"] == [0.0, 200.0]


def test_the_parts_register_nothing_and_load_no_upper_layer():
    code = (
        "import sys, drltg, drltg.envs, drltg.transforms, drltg.collectors, drltg.losses, drltg.modules\n"
        "upper = ('drltg.transfer', 'drltg.report', 'drltg.cli', 'drltg.experiments', 'drltg.config',"
        " 'drltg.learners', 'drltg.training')\n"
        "print(sorted(m for m in sys.modules if m.startswith(upper)))"
    )
    done = _python(code)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[]"


def test_import_drltg_is_cheap():
    done = _python(f"import drltg; import drltg.envs; {NO_TORCH}")
    assert done.returncode == 0, done.stderr


def test_the_top_level_surface_is_documented_and_resolves():
    import importlib

    import drltg

    for name, module in drltg._WHERE.items():
        assert name in drltg.__doc__, f"drltg's docstring does not list {name}"
        assert getattr(drltg, name) is getattr(importlib.import_module(module), name)


# ------------------------------------------------------------------------------------------ sizes
MAX_MODULE_LINES, MAX_FUNCTION_LINES = 600, 80


def test_every_module_and_function_stays_readable_in_one_sitting():
    """One idea a module: no module over 600 lines, no function over 80."""
    too_long = []
    for name, path in sorted(MODULES.items()):
        text = path.read_text()
        if len(text.splitlines()) > MAX_MODULE_LINES:
            too_long.append(f"{name}: {len(text.splitlines())} lines")
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                length = node.end_lineno - node.lineno + 1
                if length > MAX_FUNCTION_LINES:
                    too_long.append(f"{name}.{node.name}: {length} lines")
    assert too_long == []
