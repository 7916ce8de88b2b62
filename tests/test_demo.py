"""`drltg demo` plans one source run that every paired seed transfers from."""
import math
from pathlib import Path

from drltg.cli import demo


def test_the_demo_reuses_one_source_over_paired_seeds(tmp_path):
    d = demo.DEMO

    def budget(cfg, frames):  # rounded up to whole collector batches
        per_batch = cfg.collector.frames_per_batch
        return math.ceil(frames / per_batch) * per_batch

    runs = demo.plan(tmp_path)
    roles = [role for role, _, _ in runs]
    assert roles == ["source"] + ["baseline", "transfer"] * d["seeds"]
    (_, source_cfg, source_dir), pairs = runs[0], runs[1:]
    assert source_cfg.task == "fourrooms/northeast"
    assert source_cfg.frames == budget(source_cfg, d["source_frames"])
    assert source_dir == tmp_path / "source" / f"seed-{d['source_seed']}"
    for (_, b, b_dir), (_, t, t_dir) in zip(pairs[::2], pairs[1::2]):
        assert b.seed == t.seed and b_dir.name == t_dir.name == f"seed-{b.seed}"  # paired by seed
        assert b.task == t.task == "fourrooms/northeast-shifted"
        assert b.frames == t.frames == budget(b, d["frames"])
        assert b.transfer.method == "none"
        assert t.transfer.method == "model-reuse" and Path(t.transfer.source) == source_dir
    assert len({b.seed for _, b, _ in pairs}) == d["seeds"]
    assert source_cfg.seed not in {b.seed for _, b, _ in pairs}  # the source shares no seed with a target run


def test_the_demo_trains_its_baselines_and_its_transfer_runs_as_two_seed_groups(tmp_path):
    from drltg.experiments.executor import seed_groups
    from drltg.experiments.experiment import as_runs

    units = seed_groups(as_runs(demo.plan(tmp_path), tmp_path))
    assert [[r.role for r in unit] for unit in units] == [["source"], ["baseline"] * demo.DEMO["seeds"],
                                                          ["transfer"] * demo.DEMO["seeds"]]


def test_the_committed_demo_is_the_one_this_code_runs_and_its_readme_says_so():
    """results/demo/ holds the runs of drltg demo's settings, and results/README.md describes them from those
    settings (results/claims.py's demo-plan region): 40k source frames evaluated every 5k, 20k target frames."""
    import yaml

    root = Path(__file__).resolve().parents[1]
    assert yaml.safe_load((root / "results" / "demo" / "demo.yaml").read_text()) == demo.DEMO
    readme = (root / "results" / "README.md").read_text()
    assert ("`drltg demo`: SAC learns `fourrooms/northeast` once (one source run, 40k frames, evaluated every 5k); "
            "then `fourrooms/northeast-shifted` is learnt for 20k frames from scratch and from that source's weights "
            "(model reuse) on 10 paired seeds, evaluated every 1k frames on 16 episodes.") in readme
