"""A networks file is data to check, not to trust: each way of reading one (reuse, ``evaluate``, ``--resume``)
refuses, in one sentence naming the file, a header too large or too deep to parse, a file the manifest does not
list or whose SHA-256 differs, a frame that is no checkpoint's of the run, weights that are not finite, and
tensors that are not exactly the networks they are loaded into; nothing of such a file is loaded."""
import json
import shutil
import struct

import pytest
import torch
from safetensors.torch import save

import drltg.transfer
from drltg.cli import main
from drltg.errors import UsageError
from drltg.store import manifest, networks, rundir
from tests.test_networks import checkpoint, same, source  # noqa: F401 (source: the finished run, a fixture)

ACTOR_IN = "actor_network_params.module.0.module.0.0.weight"
"""The actor's first layer."""


def write(run, name: str, data: bytes, listed: bool = True) -> None:
    """Put ``data`` in place of the run's networks file ``name``, its manifest entry the bytes' SHA-256 (or
    none): what a run altered along with its manifest holds."""
    rel = networks.NETWORKS[name].as_posix()
    (run / rel).write_bytes(data)
    files = manifest.read(run)
    files.pop(rel)
    if listed:
        files[rel] = [manifest.digest(data)]
    (run / manifest.MANIFEST).write_text(manifest.dumps(files))


def crafted(weights: dict, frames=256, updates=7, **meta) -> bytes:
    info = json.dumps({"format": networks.FORMAT, "frames": frames, "updates": updates, **meta})
    return save({k: v.contiguous() for k, v in weights.items()}, metadata={"drltg": info})


def raw(header: bytes, body: bytes = b"") -> bytes:
    return struct.pack("<Q", len(header)) + header + body


@pytest.fixture
def run(source, tmp_path):  # noqa: F811
    return shutil.copytree(source, tmp_path / "src")


@pytest.fixture
def weights(source):  # noqa: F811
    return rundir.load_networks(source, "best")[0]


def refused(run, name: str, *fragments: str) -> None:
    """Every reader of the networks refuses ``name`` in one sentence holding each fragment."""
    sentences = []
    for read in (lambda: rundir.load_networks(run, name), lambda: drltg.transfer.load_agent(run, checkpoint=name),
                 lambda: drltg.transfer.load_from_run(drltg.transfer.load_agent(run, checkpoint="last" if name ==
                                                                                 "best" else "best").loss, run,
                                                      checkpoint=name)):
        with pytest.raises(UsageError) as err:
            read()
        sentences.append(str(err.value))
    for text in sentences:
        assert "\n" not in text and str(run / networks.NETWORKS[name]) in text, text
        assert all(f in text for f in fragments), (text, fragments)


def one_line(capsys, code: int) -> str:
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and "Traceback" not in err, err
    return err


DEEP = b'{"__metadata__": {"drltg": "{}"}, "a": ' + b"[" * 200_000 + b"]" * 200_000 + b"}"


def test_a_header_nested_200000_deep_is_refused_without_parsing_it(run, capsys):
    write(run, "best", raw(DEEP))
    refused(run, "best", "is not a drltg networks file (safetensors with drltg's header).")
    err = one_line(capsys, main(["evaluate", str(run), "--checkpoint", "best", "--episodes", "1"]))
    assert err.endswith("best.safetensors' is not a drltg networks file (safetensors with drltg's header).")


def test_the_depth_is_counted_outside_strings():
    text = json.dumps({"__metadata__": {"drltg": "[" * 100}, "x": [[[[1]]]]})
    assert networks._shallow_json(text)["__metadata__"]["drltg"] == "[" * 100
    with pytest.raises(ValueError):
        networks._shallow_json("[" * (networks.MAX_DEPTH + 1) + "]" * (networks.MAX_DEPTH + 1))


@pytest.mark.parametrize("size", [2**40, networks.MAX_HEADER_BYTES + 1])
def test_a_header_length_over_the_limit_is_refused_before_it_is_read(run, size):
    data = struct.pack("<Q", size) + b"{" * 64
    write(run, "last", data)
    refused(run, "last", f"its header would be {size:,} bytes, more than the file holds or the 16 MB")


def test_a_file_too_short_for_a_header_is_refused(run):
    write(run, "last", b"\x01\x02")
    refused(run, "last", "it is 2 bytes long, too short for the header's length.")


def test_resume_writes_a_deep_or_changed_networks_file_again_from_its_checkpoint(run, monkeypatch):
    """``--resume`` compares each networks file with its checkpoint before training on: a file it cannot
    trust is never parsed but written again from the checkpoint, which was checked against the manifest."""
    write(run, "best", raw(DEEP))
    changed = raw(DEEP + b" ")
    (run / networks.NETWORKS["last"]).write_bytes(changed)  # its digest no longer matches: never parsed
    parsed = []
    real = networks.header
    monkeypatch.setattr(networks, "header", lambda data, *a, **k: parsed.append(bytes(data)) or real(data, *a, **k))
    (run / rundir.SUMMARY).unlink()
    assert main(["train", "--resume", "--run-dir", str(run), "--no-progress"]) == 0
    assert raw(DEEP) in parsed and changed not in parsed
    for name in ("last", "best"):
        ckpt = checkpoint(run, name)
        assert (run / networks.NETWORKS[name]).read_bytes() == networks.encode(ckpt["loss"], ckpt["frames"],
                                                                               ckpt["updates"])
        manifest.verify(run, networks.NETWORKS[name].as_posix())


def test_a_changed_file_is_not_parsed(run, monkeypatch):
    (run / networks.NETWORKS["best"]).write_bytes(raw(DEEP))
    monkeypatch.setattr(networks, "header", lambda *a, **k: pytest.fail("a file of another SHA-256 was parsed"))
    assert networks.read_header(run, "best") is None
    with pytest.raises(UsageError, match="best.safetensors': it does not match its SHA-256 in"):
        rundir.load_networks(run, "best")


def test_a_networks_file_the_manifest_does_not_list_is_not_read(run, weights, capsys):
    write(run, "best", crafted({k: torch.full_like(v, float("nan")) if v.is_floating_point() else v
                                for k, v in weights.items()}), listed=False)
    refused(run, "best", "manifest.json does not list it, so nothing says it holds the run's networks; resume the "
                         "run to write it again, or train the run again.")
    err = one_line(capsys, main(["evaluate", str(run), "--checkpoint", "best", "--episodes", "1"]))
    assert "best.safetensors': " in err and "does not list it" in err and "return" not in err
    assert networks.read_header(run, "best") is None  # --resume writes it again


def test_a_run_without_a_manifest_is_read_as_it_is(run, weights):
    """As every file of a run written before drltg kept a manifest, checked for what it holds only."""
    (run / manifest.MANIFEST).unlink()
    assert same(rundir.load_networks(run, "best")[0], weights)


@pytest.mark.parametrize("value", [float("nan"), float("inf"), -float("inf")])
def test_weights_that_are_not_finite_are_refused(run, weights, value, capsys):
    bad = dict(weights)
    bad[ACTOR_IN] = bad[ACTOR_IN].clone()
    bad[ACTOR_IN][0, 0] = value
    write(run, "best", crafted(bad))
    refused(run, "best", f"holds NaN or infinite values in {ACTOR_IN}; no trained network holds them")
    err = one_line(capsys, main(["evaluate", str(run), "--checkpoint", "best", "--episodes", "1"]))
    assert "NaN or infinite values" in err


@pytest.mark.parametrize(("field", "value"), [("frames", 10**30), ("frames", 1e30), ("frames", -5), ("frames", 257),
                                              ("frames", True), ("frames", "64"), ("updates", -1), ("updates", 0.5)])
def test_a_frame_or_update_count_that_is_no_checkpoint_s_is_refused(run, weights, field, value, capsys):
    write(run, "best", crafted(weights, **{field: value}))
    bound = "0 to the run's budget of 256" if field == "frames" else "0 or more"
    refused(run, "best", f"gives its {field} as {value!r}, not a whole number from {bound}; it holds no checkpoint "
                         "of this run.")
    err = one_line(capsys, main(["evaluate", str(run), "--checkpoint", "best", "--episodes", "1"]))
    assert f"gives its {field} as {value!r}" in err


def test_the_budget_itself_is_a_checkpoint_s_frame(run, weights):
    write(run, "best", crafted(weights, frames=256))
    assert rundir.load_networks(run, "best")[1] == {"frames": 256, "updates": 7}


def mismatched(weights: dict, how: str) -> tuple[dict, str]:
    bad = dict(weights)
    if how == "int64":
        bad[ACTOR_IN] = bad[ACTOR_IN].round().to(torch.int64)
        return bad, f"{ACTOR_IN} is int64 {list(weights[ACTOR_IN].shape)} there, float32 "
    if how == "bool":
        bad[ACTOR_IN] = bad[ACTOR_IN] > 0
        return bad, f"{ACTOR_IN} is bool {list(weights[ACTOR_IN].shape)} there, float32 "
    if how == "extra":
        bad["actor_network_params.module.0.module.9.weight"] = torch.zeros(2)
        return bad, "it holds actor_network_params.module.0.module.9.weight besides"
    if how == "missing":
        del bad[ACTOR_IN]
        return bad, f"it lacks {ACTOR_IN}"
    rows, cols = weights[ACTOR_IN].shape
    bad[ACTOR_IN] = torch.zeros(rows, cols + 3)
    return bad, f"{ACTOR_IN} is float32 [{rows}, {cols + 3}] there, float32 [{rows}, {cols}] here"


@pytest.mark.parametrize("how", ["int64", "bool", "extra", "missing", "first layer"])
def test_tensors_that_are_not_the_learner_s_networks_are_refused(run, weights, how, capsys):
    bad, reason = mismatched(weights, how)
    write(run, "best", crafted(bad))
    for loader in ("load_agent", "load_actor", "load_critic"):
        with pytest.raises(UsageError) as err:
            getattr(drltg.transfer, loader)(run, checkpoint="best")
        text = str(err.value)
        assert text.startswith(f"'{run / networks.NETWORKS['best']}' does not fit the sac learner its config.yaml "
                               f"describes ({reason}") and text.endswith(").") and "\n" not in text, text
    err = one_line(capsys, main(["evaluate", str(run), "--checkpoint", "best", "--episodes", "1"]))
    assert "does not fit the sac learner" in err
    err = one_line(capsys, main(["train", "fourrooms/northeast-shifted", "--frames", "32", "--no-progress",
                                 "--run-dir", str(run.parent / "t"), "-o", "transfer.method=policy-reuse",
                                 "-o", f"transfer.source={run}", "-o", "transfer.source_checkpoint=best"]))
    assert "does not fit the sac learner" in err
    assert not (run.parent / "t").exists()


def test_mismatch_names_the_first_difference_and_none_for_an_exact_fit(weights):
    bad, reason = mismatched(weights, "extra")
    assert networks.mismatch(weights, bad).startswith("it holds ")
    assert networks.mismatch(weights, dict(weights)) is None


def test_nothing_of_a_refused_file_is_loaded(run, weights):
    target = drltg.transfer.load_agent(run, checkpoint="last")
    before = {k: v.clone() for k, v in target.loss.state_dict().items()}
    bad = {k: torch.full_like(v, float("nan")) if v.is_floating_point() else v for k, v in weights.items()}
    write(run, "best", crafted(bad))
    with pytest.raises(UsageError, match="NaN or infinite"):
        drltg.transfer.load_from_run(target.loss, run, checkpoint="best")
    assert same(target.loss.state_dict(), before)


@pytest.mark.parametrize("how", ["extra", "first layer", "int64"])
def test_drltg_video_refuses_networks_that_do_not_fit_in_one_sentence(run, weights, how, capsys):
    """An extra key or a wrong first layer crashed ``drltg video`` inside load_state_dict; an int64 weight
    was cast without a word."""
    bad, reason = mismatched(weights, how)
    write(run, "last", crafted(bad))
    err = one_line(capsys, main(["video", str(run), "--episodes", "1", "--max-steps", "2",
                                 "--out", str(run.parent / "video")]))
    assert f"the networks of '{run}' do not fit the sac learner its config.yaml describes ({reason}" in err, err
    assert not (run.parent / "video").exists()
