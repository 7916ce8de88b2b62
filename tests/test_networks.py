"""A run's networks file (checkpoints/last.safetensors, best.safetensors): what reusing a run reads.

Every way of reusing a run (the methods, ``load_actor``, ``load_critic``, ``load_agent``, ``load_from_run``)
reads the networks file and never the training checkpoint; the file holds exactly the checkpoint's
networks, is data only, and is refused when it does not match the manifest.
"""
import hashlib
import json
import shutil
import struct

import pytest
import torch

import drltg.transfer
from drltg import config as config_lib
from drltg.cli import main
from drltg.errors import UsageError
from drltg.store import manifest, networks, rundir
from drltg.training.loop import train
from tests.test_best import TINY

METHODS = {
    "model-reuse": [],
    "policy-reuse": [],
    "value-shaping": [],
    "demonstrations": ["transfer.demo_episodes=2"],
}
LOADERS = ("load_actor", "load_critic", "load_agent")


def same(a: dict, b: dict) -> bool:
    return a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)


def checkpoint(run, name="last") -> dict:
    return torch.load(run / rundir.CHECKPOINTS[name], weights_only=True)


@pytest.fixture(scope="module")
def source(tmp_path_factory):
    """A finished SAC run that keeps its best checkpoint."""
    cfg = config_lib.resolve({}, [*TINY, "eval.every=64", "checkpoint.keep_best=true",
                                  "checkpoint.best_metric=return_mean"], task="fourrooms/northeast", frames=256, seed=3)
    return train(cfg, tmp_path_factory.mktemp("src") / "run", progress=False)


@pytest.fixture
def no_checkpoint(source, tmp_path, monkeypatch):
    """A copy of the source without its training checkpoints, and any read of a checkpoint an error."""
    run = shutil.copytree(source, tmp_path / "src")
    for name in rundir.CHECKPOINTS.values():
        (run / name).unlink()

    def refuse(*args, **kwargs):
        raise AssertionError("a training checkpoint was opened")

    monkeypatch.setattr(rundir, "load_checkpoint", refuse)
    monkeypatch.setattr(torch, "load", refuse)
    return run


@pytest.mark.parametrize("name", ["last", "best"])
def test_the_networks_file_holds_exactly_the_checkpoint_s_networks(source, name):
    saved, info = rundir.load_networks(source, name)
    ckpt = checkpoint(source, name)
    assert same(saved, ckpt["loss"])
    assert info == {"frames": ckpt["frames"], "updates": ckpt["updates"]}
    assert manifest.read(source)[networks.NETWORKS[name].as_posix()] == [
        manifest.digest(source / networks.NETWORKS[name])]


def test_the_networks_file_is_a_header_and_raw_tensor_bytes_only(source):
    """The whole file is accounted for by its JSON header and the tensors' little-endian bytes that it
    places end to end: there is nothing else in it to interpret, let alone run."""
    data = (source / networks.NETWORKS["last"]).read_bytes()
    (size,) = struct.unpack("<Q", data[:8])
    entries = json.loads(data[8:8 + size])
    assert json.loads(entries.pop("__metadata__")["drltg"])["format"] == "drltg networks"
    body, weights = data[8 + size:], checkpoint(source)["loss"]
    assert set(entries) == set(weights)
    spans = sorted(tuple(e["data_offsets"]) for e in entries.values())
    assert spans[0][0] == 0 and spans[-1][1] == len(body)
    assert all(a[1] == b[0] for a, b in zip(spans, spans[1:]))
    for key, entry in entries.items():
        start, end = entry["data_offsets"]
        dtype = {"F32": torch.float32, "I64": torch.int64, "BOOL": torch.bool}[entry["dtype"]]
        raw = torch.frombuffer(bytearray(body[start:end]), dtype=dtype) if end > start else torch.empty(0, dtype=dtype)
        assert torch.equal(raw.reshape(entry["shape"]), weights[key]), key


@pytest.mark.parametrize("name", ["last", "best"])
def test_the_loaders_read_the_networks_without_the_checkpoint(source, no_checkpoint, name):
    weights = rundir.load_networks(source, name)[0]
    assert same(drltg.transfer.load_agent(no_checkpoint, checkpoint=name).loss.state_dict(), weights)
    actor = drltg.transfer.load_actor(no_checkpoint, checkpoint=name)
    assert same(actor.state_dict(), {k.removeprefix("actor_network_params."): v for k, v in weights.items()
                                     if k.startswith("actor_network_params.")})
    critic = drltg.transfer.load_critic(no_checkpoint, checkpoint=name).critic_params.flatten_keys(".")
    assert same(dict(critic.items()), {k.removeprefix("qvalue_network_params."): v for k, v in weights.items()
                                       if k.startswith("qvalue_network_params.")})
    target = drltg.transfer.load_agent(no_checkpoint, checkpoint="last" if name == "best" else "best")
    drltg.transfer.load_from_run(target.loss, no_checkpoint, checkpoint=name)
    assert same(target.loss.state_dict(), weights)


@pytest.mark.parametrize("method", METHODS)
def test_every_method_reuses_a_source_without_its_checkpoint_and_records_its_digests(no_checkpoint, tmp_path, method):
    cfg = config_lib.resolve({}, [*TINY, *METHODS[method], f"transfer.method={method}",
                                  f"transfer.source={no_checkpoint}", "transfer.source_checkpoint=best"],
                             task="fourrooms/northeast-shifted", frames=32, seed=4)
    run = train(cfg, tmp_path / "target", progress=False)
    assert rundir.is_complete(run)
    recorded = json.loads((run / rundir.SUMMARY).read_text())["source"]
    loaded = no_checkpoint / networks.NETWORKS["best"]
    assert recorded == {"checkpoint": "best", "networks": "checkpoints/best.safetensors",
                        "networks_sha256": hashlib.sha256(loaded.read_bytes()).hexdigest(),
                        "config_sha256": hashlib.sha256((no_checkpoint / rundir.CONFIG).read_bytes()).hexdigest()}


def _other_networks(run):
    """Rewrite ``run``'s last networks file with other weights (each float entry + 1), as training it again would."""
    weights, info = rundir.load_networks(run)
    weights = {k: v + 1 if v.is_floating_point() else v for k, v in weights.items()}
    rundir.write_tracked(run, networks.NETWORKS["last"].as_posix(),
                         networks.encode(weights, info["frames"], info["updates"]))
    rundir.finalize_manifest(run)


def test_a_resumed_run_refuses_a_source_changed_since_it_started(source, tmp_path, monkeypatch, capsys):
    from drltg.training import loop

    src = shutil.copytree(source, tmp_path / "src")
    cfg = config_lib.resolve({}, [*TINY, "checkpoint.every=128", "eval.every=128", "transfer.method=policy-reuse",
                                  f"transfer.source={src}"], task="fourrooms/northeast-shifted", frames=256, seed=4)
    real, target = loop._episode_stats, tmp_path / "target"

    def crash_after_first_checkpoint(data, stats):
        if (target / "checkpoints" / "last.pt").exists():
            raise KeyboardInterrupt
        return real(data, stats)

    monkeypatch.setattr(loop, "_episode_stats", crash_after_first_checkpoint)
    with pytest.raises(KeyboardInterrupt):
        train(cfg, target, progress=False)
    monkeypatch.setattr(loop, "_episode_stats", real)
    started = json.loads((target / "source.json").read_text())["source"]
    kept = (src / networks.NETWORKS["last"]).read_bytes()
    assert started["networks_sha256"] == hashlib.sha256(kept).hexdigest()
    _other_networks(src)
    with pytest.raises(UsageError, match=r"changed since this run started: .*source.json records another SHA-256 "
                                         r"of its networks, so the run would go on from another teacher"):
        train(cfg, target, resume=True, progress=False)
    rundir.write_tracked(src, networks.NETWORKS["last"].as_posix(), kept)  # the source restored
    rundir.finalize_manifest(src)
    run = train(cfg, target, resume=True, progress=False)
    assert json.loads((run / rundir.SUMMARY).read_text())["source"] == started


def test_a_run_without_a_source_records_none(source):
    assert "source" not in json.loads((source / rundir.SUMMARY).read_text())
    assert not (source / "source.json").exists()


def test_a_seed_group_records_each_seed_s_own_source(source, tmp_path):
    """Two seeds trained as one group, each reusing another source run: each summary names its own."""
    other = shutil.copytree(source, tmp_path / "other")
    path = other / networks.NETWORKS["last"]
    _other_networks(other)
    from drltg.training.seeds import train_group

    cfgs = [config_lib.resolve({}, [*TINY, "transfer.method=model-reuse", f"transfer.source={src}"],
                               task="fourrooms/northeast-shifted", frames=32, seed=seed)
            for seed, src in ((4, source), (5, other))]
    dirs = train_group(cfgs, [tmp_path / "t" / "seed-4", tmp_path / "t" / "seed-5"], progress=False)
    digests = [json.loads((d / rundir.SUMMARY).read_text())["source"]["networks_sha256"] for d in dirs]
    assert digests == [hashlib.sha256(p.read_bytes()).hexdigest()
                       for p in (source / networks.NETWORKS["last"], path)]
    assert digests[0] != digests[1]


def test_an_unfinished_source_is_read_once_from_its_networks_file(source, tmp_path, monkeypatch, capsys):
    run = shutil.copytree(source, tmp_path / "src")
    (run / rundir.SUMMARY).unlink()
    monkeypatch.setattr(rundir, "load_checkpoint", lambda *a, **k: pytest.fail("a training checkpoint was opened"))
    args = ["train", "fourrooms/northeast-shifted", "--frames", "32", "--run-dir", str(tmp_path / "t"), "--no-progress",
            "-o", "transfer.method=policy-reuse", "-o", f"transfer.source={run}"]
    assert main(args) == 2
    frames = checkpoint(source)["frames"]
    assert f"did not finish (no summary.json; its checkpoint is at frame {frames})" in capsys.readouterr().err
    assert main([*args, "-o", "transfer.allow_incomplete=true"]) == 0


def test_a_changed_networks_file_is_refused_in_one_sentence(source, tmp_path, capsys):
    run = shutil.copytree(source, tmp_path / "src")
    path = run / networks.NETWORKS["last"]
    data = bytearray(path.read_bytes())
    data[-1] ^= 1  # one bit of the last tensor: still a valid safetensors file
    path.write_bytes(bytes(data))
    for loader in LOADERS:
        with pytest.raises(UsageError, match="does not match its SHA-256"):
            getattr(drltg.transfer, loader)(run)
    code = main(["train", "fourrooms/northeast-shifted", "--frames", "32", "--run-dir", str(tmp_path / "t"),
                 "-o", "transfer.method=model-reuse", "-o", f"transfer.source={run}"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and "last.safetensors': it does not match its SHA-256" in err, err


def test_a_networks_file_the_manifest_lists_but_the_run_lacks_is_refused(source, tmp_path):
    """The checkpoint is there, but the run names its networks file: it is not read in its place."""
    run = shutil.copytree(source, tmp_path / "src")
    (run / networks.NETWORKS["last"]).unlink()
    with pytest.raises(UsageError, match="holds no checkpoints/last.safetensors though its manifest lists it"):
        drltg.transfer.load_actor(run)


def test_a_run_from_before_networks_files_is_read_from_its_checkpoint(source, tmp_path):
    """The old-run path: no networks file, and a manifest that names none."""
    run = shutil.copytree(source, tmp_path / "src")
    files = manifest.read(run)
    for name in networks.NETWORKS.values():
        (run / name).unlink()
        files.pop(name.as_posix())
    (run / manifest.MANIFEST).write_text(manifest.dumps(files))
    for name in ("last", "best"):
        assert same(drltg.transfer.load_agent(run, checkpoint=name).loss.state_dict(), checkpoint(source, name)["loss"])


def test_the_same_networks_give_the_same_bytes(source):
    """A run reproduced bit for bit writes the same file (safetensors orders its metadata entries anew each
    time, so drltg keeps its own in one entry)."""
    weights, info = rundir.load_networks(source)
    assert {networks.encode(weights, **info) for _ in range(20)} == {(source / networks.NETWORKS["last"]).read_bytes()}
