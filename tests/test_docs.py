"""The docs site builds strictly (every page in the navigation, every link and API reference resolved), and
README stays the front door: short, with the site's composed example."""
import os
import re
import subprocess
import sys
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
NAV = [next(iter(entry.values())) for entry in yaml.safe_load((ROOT / "mkdocs.yml").read_text())["nav"]]


def test_the_site_builds_strictly(tmp_path):
    done = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")],
                          cwd=ROOT, capture_output=True, text=True, timeout=300,
                          env={**os.environ, "NO_MKDOCS_2_WARNING": "1"})
    assert done.returncode == 0, done.stderr[-3000:]
    api = (tmp_path / "site" / "api" / "index.html").read_text()
    for name in ("FourRoomsEnv", "PotentialShaping", "PolicyReuse", "SoftOptionCriticLoss", "load_weights"):
        assert f"{name}" in api, name
    home = (tmp_path / "site" / "index.html").read_text()
    assert "Quickstart" in home and "One composed example" in home  # README's front, included
    assert 'src="results/demo/report/transfer_plot.png"' in home  # README's figure, served from results/
    figures = {page.stem: re.findall(r"\]\(\.\./(results/[^)]+\.png)\)", page.read_text())
               for page in (ROOT / "docs").glob("*.md")}
    assert sum(map(len, figures.values())) >= 4
    for page, paths in figures.items():  # each figure results/ keeps is served from there, and shown
        folder = "" if page == "index" else page
        html = (tmp_path / "site" / folder / "index.html").read_text()
        for path in paths:
            assert (tmp_path / "site" / path).read_bytes() == (ROOT / path).read_bytes(), path
            assert f'src="{os.path.relpath(path, folder or ".")}"' in html, (page, path)


def test_every_page_is_in_the_navigation():
    assert sorted(NAV) == sorted(p.name for p in (ROOT / "docs").glob("*.md"))


def test_the_readme_is_short_and_its_example_is_the_methods_page_one():
    readme = (ROOT / "README.md").read_text()
    assert len(readme.splitlines()) <= 300
    example = re.search(r"## One composed example\n.*?(```python\n.*?^```)", readme, flags=re.S | re.M).group(1)
    assert example in (ROOT / "docs" / "methods.md").read_text()


def test_the_readme_links_to_every_page():
    readme = (ROOT / "README.md").read_text()
    assert [p for p in NAV if f"(docs/{p})" not in readme] == []


def test_the_custom_task_docs_state_the_settings_the_built_in_tasks_carry():
    """docs/extending.md's table of the defaults that matter quotes drltg/envs/tasks.py; the plugin example sets
    the entropy temperature the docs tell a sparse task to set."""
    import ast

    from drltg.envs import tasks

    source = ast.parse((ROOT / "examples" / "plugin" / "drltg_example_plugin" / "__init__.py").read_text())
    plugin_train = next(ast.literal_eval(node.value) for node in source.body  # read, not imported: it registers
                        if isinstance(node, ast.Assign) and [t.id for t in node.targets] == ["TRAIN"])
    row = {line.split("|")[1].strip(" `"): line for line in (ROOT / "docs" / "extending.md").read_text().splitlines()
           if line.startswith("| `")}
    assert "0.01 (`ROOMS_TRAIN`)" in row["sac.alpha_init"] and tasks.ROOMS_TRAIN["sac"]["alpha_init"] == 0.01
    assert tasks.GRID_TRAIN["sac"]["fixed_alpha"] is True and "`sac.fixed_alpha=true`" in row["sac.alpha_init"]
    assert plugin_train["sac"]["alpha_init"] == 0.01
    assert tasks.ROOMS_TRAIN["network"]["hidden"] == tasks.PENDULUM_TRAIN["network"]["hidden"] == [64, 64]
    robosuite, pendulum = tasks.ROBOSUITE_TRAIN, tasks.PENDULUM_TRAIN
    assert f"robosuite {robosuite['collector']['init_random_frames']:,}, Pendulum " \
           f"{pendulum['collector']['init_random_frames']:,}" in row["collector.init_random_frames"]
    assert f"robosuite {robosuite['buffer']['size']:,}" in row["buffer.size"]
    assert f"robosuite {robosuite['eval']['every']:,}, Pendulum {pendulum['eval']['every']:,}" in row["eval.every"]


def test_the_api_page_holds_every_exported_name_and_each_path_it_names_imports():
    import importlib

    import drltg

    paths = re.findall(r"^::: ([\w.]+)$", (ROOT / "docs" / "api.md").read_text(), re.M)
    for path in paths:
        module, _, name = path.rpartition(".")
        try:
            importlib.import_module(path)
        except ModuleNotFoundError:
            assert hasattr(importlib.import_module(module), name), path
    documented = {p.rpartition(".")[2] for p in paths}
    assert sorted(set(drltg.__all__) - documented) == []
    for name in drltg.__all__:  # the page's promise: an exported name is the documented object itself
        found = [p for p in paths if p.endswith(f".{name}")]
        module, _, _ = found[0].rpartition(".")
        assert getattr(drltg, name) is getattr(importlib.import_module(module), name), name
