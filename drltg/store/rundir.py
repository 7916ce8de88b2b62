"""A run directory on disk: its file names, atomic writes, its owner lock, eval.csv and log truncation.

    config.yaml          the resolved config; `drltg train --config config.yaml` reproduces the run
    eval.csv             frames,return_mean,return_std,episodes[,success_rate,lifted_rate,pushed_rate]  (one row per
                         evaluation; a rate column the earlier rows of a resumed run lack is empty there)
    logs/csv/, logs/tensorboard/   training scalars (TorchRL CSVLogger + TensorboardLogger)
    checkpoints/last.pt  weights, optimizer, replay buffer and RNG state (for --resume)
    checkpoints/last.safetensors   the networks of last.pt alone, saved with it: what reusing the run as a
                         source reads (drltg.store.networks)
    checkpoints/best.safetensors   the networks of the best evaluation so far (drltg.training.best)
    checkpoints/best.pt  with checkpoint.keep_best: the whole checkpoint of that evaluation
    model_reuse.txt      what model reuse loaded (model-reuse runs)
    summary.json         the run is finished when it exists: status complete (or diverged, with the reason)
    manifest.json        SHA-256 of the checkpoints and eval.csv, and when the run ends (written last) of
                         every file: a changed or damaged file is refused (drltg.store.manifest)
    .drltg.lock          pid, host and start time of the process writing the directory, while it runs

Every file is written through a temporary file in the same folder and a rename (:mod:`drltg.store.atomic`),
so a reader never sees half a file and a failed write leaves the previous version. Experiment and sweep folders
are owned through the same lock.
"""
from __future__ import annotations

import csv
import io
import os
import pickle
from pathlib import Path
from typing import Any

from drltg.errors import UsageError
from drltg.regular import MAX_LOG_BYTES, MAX_META_BYTES, read_bytes
from drltg.store import manifest, networks
from drltg.store.atomic import atomic_path, atomic_write, refuse_special, write_directory, write_files
from drltg.store.lock import LOCK, lock

CONFIG = "config.yaml"
EVAL = "eval.csv"
SUMMARY = "summary.json"
COMPLETE, DIVERGED = "complete", "diverged"
"""summary.json's ``status`` of a run that finished, and of one whose losses diverged."""
CHECKPOINT = Path("checkpoints") / "last.pt"
BEST = Path("checkpoints") / "best.pt"
CHECKPOINTS = {"last": CHECKPOINT, "best": BEST}
"""A run's checkpoints by the name ``--checkpoint`` and ``transfer.source_checkpoint`` give them."""
LOGS = "logs"
MODEL_REUSE = "model_reuse.txt"
EPISODE_FLAGS = ("success", "lifted", "pushed")
"""Boolean env outputs an evaluation counts as "ever true in the episode": eval.csv's ``<flag>_rate``."""
EVAL_COLUMNS = ["frames", "return_mean", "return_std", "episodes", *(f"{flag}_rate" for flag in EPISODE_FLAGS),
                "unfinished"]
"""eval.csv's columns, those a run has in this order; ``unfinished``: episodes cut at the evaluation's step limit."""


__all__ = ["atomic_write", "atomic_torch_save", "atomic_path", "write_files", "write_directory", "read_eval_csv",
           "write_eval_csv", "read_config", "write_config", "absolute_source", "is_complete", "check_directory",
           "check_contents", "refuse_special", "refuse_links", "lock",
           "load_checkpoint", "load_networks", "checkpoint_path", "missing_checkpoint", "truncate_logs", "RunWriter"]


# ------------------------------------------------------------------------------------------ config
DEMONSTRATOR = "demonstrator:"
"""``transfer.source=demonstrator:TASK`` names the scripted policy of TASK, not a run directory."""


def absolute_source(cfg: dict, base: Path) -> dict:
    """``cfg`` (the mapping a config file holds) with a relative ``transfer.source`` read as relative to
    ``base`` (a run directory, or the folder of a config file); a demonstrator or an absolute path stays as
    it is."""
    section = cfg.get("transfer") if isinstance(cfg, dict) else None
    source = section.get("source") if isinstance(section, dict) else None
    if not isinstance(source, str) or source.startswith(DEMONSTRATOR) or Path(source).expanduser().is_absolute():
        return cfg
    return {**cfg, "transfer": {**section, "source": os.path.normpath(Path(base).resolve() / source)}}


def read_config(run_dir: str | Path):
    """A run's ``config.yaml``, its ``transfer.source`` as an absolute path (bad YAML: :class:`UsageError`)."""
    from drltg import safe_yaml

    run_dir = Path(run_dir)
    return absolute_source(safe_yaml.load_file(run_dir / CONFIG), run_dir)


def write_config(run_dir: str | Path, cfg: Any) -> None:
    """Write ``config.yaml`` (a :class:`drltg.config.RunConfig`'s values, in its order) atomically, with
    ``transfer.source`` relative to the run directory: a folder holding runs and their sources (an
    experiment, a sweep) can be moved and resumed."""
    import yaml

    run_dir = Path(run_dir)
    data = cfg.model_dump()
    source = data["transfer"]["source"]
    if isinstance(source, str) and not source.startswith(DEMONSTRATOR):
        data["transfer"]["source"] = os.path.relpath(Path(source).expanduser().resolve(), run_dir.resolve())
    atomic_write(run_dir / CONFIG, yaml.safe_dump(data, sort_keys=False))


# ------------------------------------------------------------------------------------- run files
def check_contents(run_dir: str | Path) -> None:
    """Refuse a run directory that holds anything but regular files and folders: a symbolic link (its
    ``logs`` pointing at a user's data, its ``eval.csv`` at a file the manifest does not cover), a FIFO, a
    device or a socket. Reading or rewriting a run then never reaches outside it, nor blocks on a pipe.
    The directory itself may be reached through a link (``runs/latest``); what it holds may not."""
    import stat

    root = Path(run_dir)
    for folder, dirs, files in os.walk(root, followlinks=False):
        for name in sorted(dirs + files):
            path = Path(folder) / name
            try:
                mode = os.lstat(path).st_mode
            except FileNotFoundError:  # removed meanwhile (a temporary file renamed)
                continue
            if stat.S_ISREG(mode) or stat.S_ISDIR(mode):
                continue
            kind = ("a symbolic link" if stat.S_ISLNK(mode) else "a FIFO" if stat.S_ISFIFO(mode) else
                    "a socket" if stat.S_ISSOCK(mode) else "a device")
            raise UsageError(f"run directory '{run_dir}' holds {kind}, '{path.relative_to(root).as_posix()}'; a run "
                             "holds regular files and folders only, and drltg follows nothing out of it: replace it "
                             "with the file it stands for.")


def atomic_torch_save(obj, path: str | Path) -> None:
    """``torch.save`` atomically; a run's checkpoint with its digest in the run's manifest."""
    import torch

    buf = io.BytesIO()
    torch.save(obj, buf)
    path = Path(path)
    for name in CHECKPOINTS.values():
        if path.as_posix().endswith(name.as_posix()):
            write_tracked(path.parents[1], name.as_posix(), buf.getvalue())
            return
    atomic_write(path, buf.getvalue())


def write_tracked(run_dir: str | Path, name: str, data: bytes) -> None:
    """Write ``run_dir/name`` atomically with its digest in ``manifest.json``: both the old and the new
    digest are accepted while the file is replaced, so a kill at any moment leaves a file it accepts."""
    run_dir = Path(run_dir)
    files, new = manifest.read(run_dir), manifest.digest(data)
    if not (run_dir / name).exists():  # a first write: a kill before the file lands leaves no entry naming it
        atomic_write(run_dir / name, data)
        atomic_write(run_dir / manifest.MANIFEST, manifest.dumps({**files, name: [new]}))
        return
    files[name] = [new, *[d for d in files.get(name, [])[:1] if d != new]]
    atomic_write(run_dir / manifest.MANIFEST, manifest.dumps(files))
    atomic_write(run_dir / name, data)
    if len(files[name]) > 1:
        files[name] = [new]
        atomic_write(run_dir / manifest.MANIFEST, manifest.dumps(files))


def unlisted(run_dir: str | Path) -> list[str]:
    """The files of a finished run its manifest does not list (a kill between ``summary.json`` and the final
    manifest leaves most of them out)."""
    run_dir = Path(run_dir)
    listed = manifest.read(run_dir)
    return [p.relative_to(run_dir).as_posix() for p in sorted(run_dir.rglob("*"))
            if p.is_file() and p.name != manifest.MANIFEST and not p.name.startswith(".")
            and p.relative_to(run_dir).as_posix() not in listed]


def finalize_manifest(run_dir: str | Path) -> None:
    """Record every file of a finished run in ``manifest.json`` (written last: after ``summary.json``)."""
    run_dir = Path(run_dir)
    files = {p.relative_to(run_dir).as_posix(): [manifest.digest(p)] for p in sorted(run_dir.rglob("*"))
             if p.is_file() and p.name != manifest.MANIFEST and not p.name.startswith(".")}
    atomic_write(run_dir / manifest.MANIFEST, manifest.dumps(files))


# ---------------------------------------------------------------------------------------- eval.csv
def write_eval_csv(path: str | Path, rows: list[dict]) -> None:
    columns = [c for c in EVAL_COLUMNS if any(c in r for r in rows)]
    out = io.StringIO()
    writer = csv.DictWriter(out, fieldnames=columns, restval="", extrasaction="ignore", lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    write_tracked(Path(path).parent, Path(path).name, out.getvalue().encode())


def read_eval_csv(path: str | Path) -> list[dict]:
    """The rows of a run's eval.csv; a truncated or foreign file is one :class:`UsageError` sentence."""
    path = Path(path)
    try:
        text = read_bytes(path, MAX_LOG_BYTES, "an eval.csv").decode("utf-8-sig")
    except FileNotFoundError:
        raise UsageError(f"'{path}' is missing.") from None
    except UnicodeDecodeError:
        raise UsageError(f"'{path}' is not a text file.") from None
    reader = csv.DictReader(io.StringIO(text))
    if reader.fieldnames is None or "frames" not in reader.fieldnames:
        raise UsageError(f"'{path}' is not a drltg eval.csv (no 'frames' column).")
    rows = []
    try:
        if not text.endswith("\n"):  # every write ends with a newline
            raise ValueError
        for row in reader:
            if None in row or None in row.values():
                raise ValueError
            rows.append({k: _cell(k, v) for k, v in row.items() if not (v == "" and _optional(k))})
    except ValueError:
        raise UsageError(f"'{path}' is truncated or malformed at line {max(reader.line_num, 1)}.") from None
    return rows


def frames_evaluated(run: str | Path) -> int:
    """The frames of a run's last evaluation (0 before the first, or when eval.csv is unreadable);
    a stopped run resumes from its last checkpoint, at or before that frame."""
    try:
        rows = read_eval_csv(Path(run) / EVAL)
    except (OSError, UsageError):
        return 0
    return rows[-1]["frames"] if rows else 0


def _optional(column: str) -> bool:
    """A column a row may leave empty (written before the run reported it, or nothing to report)."""
    return column.endswith("_rate") or column == "unfinished"


def _cell(column: str, text: str) -> int | float:
    return int(text) if column in ("frames", "episodes", "unfinished") else float(text)


def is_complete(run_dir: str | Path) -> bool:
    """Whether the run finished (``summary.json`` is written last), as ``complete`` or ``diverged``."""
    return (Path(run_dir) / SUMMARY).is_file()


def summary_status(run_dir: str | Path) -> tuple[str, str] | None:
    """``(status, reason)`` from a finished run's ``summary.json`` (``complete`` when it names none, as
    older runs' do); ``None`` for a run that has not finished."""
    import json

    path = Path(run_dir) / SUMMARY
    try:
        summary = json.loads(read_bytes(path, MAX_META_BYTES, "a summary"))
    except FileNotFoundError:
        return None
    except (OSError, ValueError):
        return "unreadable", f"'{path}' is not readable JSON"
    if not isinstance(summary, dict):
        return "unreadable", f"'{path}' holds no JSON object"
    try:
        manifest.verify(run_dir, SUMMARY)
    except UsageError as err:
        return "unreadable", str(err)
    return str(summary.get("status", COMPLETE)), str(summary.get("reason", ""))


# ---------------------------------------------------------------------------------------- ownership
def check_directory(path: str | Path, option: str) -> Path:
    """``path`` resolved; refuse one that exists but is not a directory, or whose name is not UTF-8
    (the logs, TensorBoard's included, write it as UTF-8 text)."""
    try:
        str(path).encode("utf-8")
    except UnicodeEncodeError:
        shown = os.fsencode(str(path)).decode("utf-8", "backslashreplace")
        raise UsageError(f"{option} '{shown}' is not valid UTF-8; choose a name in UTF-8.") from None
    path = Path(path).expanduser().resolve()
    refuse_special(path, option)
    if path.exists() and not path.is_dir():
        raise UsageError(f"{option} '{path}' is a file, not a directory; choose another {option}.")
    return path


def refuse_links(root: Path, folders=(), files=()) -> None:
    """Refuse, in one sentence, a link at or above any of ``folders`` and ``files`` inside ``root`` (an
    experiment's or a sweep's folder, whose runs, logs and reports are written inside it and never through a
    link to elsewhere), and anything on the way that is not what drltg keeps there: a file where a folder
    belongs or the reverse, a FIFO, a device or a socket."""
    import stat

    seen: set[Path] = set()
    for path, is_file in [*((Path(f), False) for f in folders), *((Path(f), True) for f in files)]:
        part = root
        for name in path.relative_to(root).parts:
            part = part / name
            if part in seen:
                continue
            seen.add(part)
            try:
                mode = os.lstat(part).st_mode
            except FileNotFoundError:
                break
            if stat.S_ISLNK(mode):
                raise UsageError(f"'{part}' is a link; drltg writes an experiment's runs, logs and reports inside "
                                 "its folder and never through a link, so move the link away.")
            wants_file = is_file and part == path
            if stat.S_ISDIR(mode) == wants_file or not (stat.S_ISDIR(mode) or stat.S_ISREG(mode)):
                kind = ("a folder" if stat.S_ISDIR(mode) else "a file" if stat.S_ISREG(mode) else "a FIFO"
                        if stat.S_ISFIFO(mode) else "a socket" if stat.S_ISSOCK(mode) else "a device")
                raise UsageError(f"'{part}' is {kind} where drltg keeps {'a file' if wants_file else 'a folder'}; "
                                 "move it away.")


def refuse_run_directory(path: Path, option: str) -> None:
    """Refuse a folder of many runs (``--out`` of an experiment or a sweep) that is itself one run."""
    if (path / CONFIG).is_file() or (path / SUMMARY).is_file():
        raise UsageError(f"{option} '{path}' is the run directory of one run (it holds {CONFIG}); choose a new "
                         f"or an experiment's folder.")


def check_name_lengths(path: Path, what: str) -> None:
    """Refuse a path the file system cannot create: a component longer than its NAME_MAX or a whole path
    longer than PATH_MAX (e.g. a sweep variant named by many grid values)."""
    existing = next(p for p in (path, *path.parents) if p.exists())
    try:
        name_max, path_max = (os.pathconf(existing, n) for n in ("PC_NAME_MAX", "PC_PATH_MAX"))
    except (OSError, ValueError):
        name_max, path_max = 255, 4096
    for part in path.parts:
        if len(os.fsencode(part)) > name_max:
            raise UsageError(f"{what} '{path}' has a name of {len(os.fsencode(part))} bytes, more than the "
                             f"{name_max} the file system allows: '{part[:40]}...'; use shorter names or values.")
    if len(os.fsencode(str(path))) >= path_max:
        raise UsageError(f"{what} '{path}' is {len(os.fsencode(str(path)))} bytes long, more than the {path_max} "
                         "the file system allows; choose a shorter --out.")


def entries(directory: Path) -> list[Path]:
    """What ``directory`` holds besides its lock and the temporary files of killed writes (nothing when it
    does not exist)."""
    if not directory.is_dir():
        return []
    return [p for p in directory.iterdir() if p.name != LOCK and not _temporary(p)]


def _temporary(path: Path) -> bool:
    """A file :func:`atomic_path` was writing when it was killed: ``.NAME.XXXXXXXX.tmp``."""
    return path.name.startswith(".") and path.name.endswith(".tmp") and path.is_file() and not path.is_symlink()


def remove_temporaries(run_dir: Path) -> None:
    """Remove the temporary files killed writes left in a run (the run's owner holds its lock)."""
    for folder in (run_dir, run_dir / "checkpoints"):
        if folder.is_dir():
            for path in folder.iterdir():
                if _temporary(path):
                    path.unlink(missing_ok=True)


# -------------------------------------------------------------------------------------- checkpoint
def checkpoint_path(name: str) -> Path:
    """``checkpoints/last.pt`` or ``checkpoints/best.pt`` for ``last`` or ``best``."""
    if name not in CHECKPOINTS:
        raise UsageError(f"a run's checkpoint is {' or '.join(CHECKPOINTS)}, not {name!r}.")
    return CHECKPOINTS[name]


def missing_checkpoint(run_dir: str | Path, name: str = "last") -> str:
    """The sentence for a run that lacks checkpoint ``name`` (what to do depends on which one)."""
    if name == "best":
        return (f"'{run_dir}' holds no best networks ({networks.NETWORKS['best'].as_posix()}, nor {BEST.as_posix()}): "
                "a run keeps them from its first evaluation on, which runs of earlier drltg versions did only with "
                "-o checkpoint.keep_best=true; use its last checkpoint.")
    return f"'{run_dir}' holds no {CHECKPOINT.as_posix()}; train the run first or fix the path."


def _refused_object(err: Exception) -> str:
    """What torch's restricted unpickler refused, e.g. ``GLOBAL builtins.exec``."""
    import re

    found = re.search(r"Unsupported global: (GLOBAL \S+)|Unsupported operand (\S+)", str(err))
    return next((g for g in found.groups() if g), "") if found else "an object it does not allow"


def load_checkpoint(run_dir: str | Path, map_location="cpu", mmap: bool = False, checkpoint: str = "last") -> dict:
    """``checkpoints/last.pt`` (or ``best.pt``: ``checkpoint="best"``) of a run; a missing, truncated or foreign
    file is one :class:`UsageError` sentence.

    A run may come from someone else, so its checkpoint is checked against the manifest's SHA-256 first and
    then read with ``torch.load(weights_only=True)``: torch's restricted unpickler rebuilds tensors, dicts,
    lists, numbers and strings only, and refuses any other object, so no code in the file can run."""
    import torch

    name = checkpoint_path(checkpoint)
    path = Path(run_dir) / name
    check_contents(run_dir)
    if not path.is_file():
        raise UsageError(missing_checkpoint(run_dir, checkpoint))
    manifest.verify(run_dir, name.as_posix())
    try:
        ckpt = torch.load(path, map_location=map_location, weights_only=True, mmap=mmap)
    except pickle.UnpicklingError as err:
        raise UsageError(f"refused checkpoint '{path}': it holds an object other than tensors and plain data "
                         f"({_refused_object(err)}), and a checkpoint is never allowed to run code.") from None
    except Exception as err:  # a truncated or foreign file surfaces as one of many library errors
        raise UsageError(f"cannot read checkpoint '{path}' ({type(err).__name__}); is it truncated?") from None
    if not isinstance(ckpt, dict) or "loss" not in ckpt:
        raise UsageError(f"checkpoint '{path}' has no 'loss' entry; is it a drltg training checkpoint?")
    return ckpt


def has_networks(run_dir: str | Path, checkpoint: str = "last") -> bool:
    """Whether :func:`load_networks` finds the networks of ``checkpoint``: its networks file, or for a run
    written before drltg saved one, the checkpoint itself."""
    run = Path(run_dir)
    return (run / networks.NETWORKS[checkpoint]).is_file() or (
        (run / checkpoint_path(checkpoint)).is_file() and not networks.listed(run, checkpoint))


def load_networks(run_dir: str | Path, checkpoint: str = "last", map_location="cpu") -> tuple[dict, dict]:
    """``(loss state dict, {"frames", "updates"})``: the networks of a run's ``checkpoint`` (``last`` or
    ``best``) from ``checkpoints/<checkpoint>.safetensors`` (:mod:`drltg.store.networks`), never from the
    training checkpoint. A run written before drltg saved networks files has none, and its manifest does
    not list one: its networks are read from the checkpoint's ``"loss"`` entry instead, as data only
    (:func:`load_checkpoint`); that is the only path on which reusing a run opens its checkpoint."""
    run = Path(run_dir)
    check_contents(run)
    ckpt_name = checkpoint_path(checkpoint)  # refuses a name other than last or best
    name = networks.NETWORKS[checkpoint]
    if (run / name).is_file():
        return networks.load(run, checkpoint, map_location, _frame_budget(run))
    if networks.listed(run, checkpoint):
        raise UsageError(f"'{run_dir}' holds no {name.as_posix()} though its manifest lists it; restore the file, "
                         "or train the run again.")
    if not (run / ckpt_name).is_file():
        raise UsageError(missing_checkpoint(run_dir, checkpoint))
    ckpt = load_checkpoint(run, map_location=map_location, mmap=True, checkpoint=checkpoint)
    return ckpt["loss"], {"frames": ckpt.get("frames"), "updates": ckpt.get("updates")}


def _frame_budget(run: Path) -> int | None:
    """The run's ``frames`` from its ``config.yaml``, which no checkpoint of it passes; ``None`` where the
    config gives none (rebuilding the run refuses such a config, in its own words)."""
    try:
        frames = read_config(run).get("frames")
    except (OSError, UsageError, AttributeError):
        return None
    return frames if type(frames) is int else None


def sync_networks(run_dir: str | Path, checkpoint: str, ckpt: dict | None = None) -> None:
    """Make the networks file of ``checkpoint`` hold its checkpoint's networks, as a resumed run starts.
    Each checkpoint is written before its networks file, so a kill between the two leaves the file of an
    earlier checkpoint (or none); ``last``'s is written again at the next checkpoint, but ``best``'s only at
    the next improvement, so both are compared here (``frames`` and ``updates``) and rewritten where they
    differ. ``ckpt``: the checkpoint already loaded, if any."""
    run = Path(run_dir)
    if not (run / checkpoint_path(checkpoint)).is_file():
        return
    ckpt = ckpt if ckpt is not None else load_checkpoint(run, mmap=True, checkpoint=checkpoint)
    saved = networks.read_header(run, checkpoint)
    if saved != {"frames": ckpt["frames"], "updates": ckpt["updates"]}:
        write_tracked(run, networks.NETWORKS[checkpoint].as_posix(),
                      networks.encode(ckpt["loss"], ckpt["frames"], ckpt["updates"]))


# -------------------------------------------------------------------------------------------- logs
def truncate_logs(run_dir: str | Path, frame: int, tensorboard: bool = False) -> None:
    """Drop every logged scalar after ``frame`` (CSVLogger files and TensorBoard event files).

    A resumed run logs again from its checkpoint's frame; without this the logs would hold those
    steps twice and their curves would run backwards. A resume from a checkpoint (``frame >= 0``) whose
    logs are gone (``logs/csv``, or ``logs/tensorboard`` where the run writes it) is refused: its logs
    would start mid-run.
    """
    logs = Path(run_dir) / LOGS
    needed = [logs / "csv", *[logs / "tensorboard"] * tensorboard]
    lost = [f"{LOGS}/"] if not logs.is_dir() else [p.relative_to(run_dir).as_posix() for p in needed if not p.is_dir()]
    if frame >= 0 and lost:
        folders = f"{' and '.join(lost)} folder{'s are' if len(lost) > 1 else ' is'}"
        raise UsageError(f"cannot resume '{run_dir}': its {folders} missing, so the training "
                         f"scalars up to the checkpoint at frame {frame} are lost; restore it or start the run again "
                         "in another --run-dir.")
    for path in sorted((logs / "csv").rglob("*.csv")):
        _truncate_csv(path, frame)
    for path in sorted((logs / "tensorboard").rglob("*tfevents*")):
        _truncate_events(path, frame)


def _truncate_csv(path: Path, frame: int) -> None:
    text = path.read_text(errors="replace")
    kept = []
    for line in text.splitlines(keepends=True):
        step = line.split(",", 1)[0]
        if line.endswith("\n") and step.strip().lstrip("-").isdigit() and int(step) <= frame:
            kept.append(line)
    if "".join(kept) != text:
        atomic_write(path, "".join(kept))


def _truncate_events(path: Path, frame: int) -> None:
    from tensorboard.backend.event_processing.event_file_loader import RawEventFileLoader
    from tensorboard.compat.proto.event_pb2 import Event
    from tensorboard.summary.writer.record_writer import RecordWriter

    records = list(RawEventFileLoader(str(path)).Load())
    kept = [r for r in records if Event.FromString(r).step <= frame]
    if len(kept) == len(records) and path.stat().st_size == sum(len(r) + 16 for r in records):
        return
    with atomic_path(path) as tmp, open(tmp, "wb") as f:
        writer = RecordWriter(f)
        for record in kept:
            writer.write(record)
        f.flush()


# -------------------------------------------------------------------------------------------- writer
class RunWriter:
    """What one run writes while it trains, in the order the training loop reports it: the config at
    the start, a row of eval.csv per evaluation, scalars to the loggers, checkpoints, and summary.json
    last. The loop computes; this object is the only one that touches the directory's files.

    Args:
        run_dir: the run directory (created and locked by the caller).
        cfg: the resolved config (:class:`drltg.config.RunConfig`), written as config.yaml and summarised in
            summary.json.
        rows: the evaluations kept from before a resumed checkpoint (``[]`` for a new run).
    """

    def __init__(self, run_dir: str | Path, cfg: Any, rows: list[dict] | None = None):
        self.run_dir = Path(run_dir)
        self.cfg = cfg
        self.rows = list(rows or [])
        self.loggers: list = []

    def start(self, files: dict[str, str | bytes] | None = None) -> None:
        """Write the config (and a method's own ``files``) and open the loggers."""
        from torchrl.record.loggers import CSVLogger, TensorboardLogger

        write_files(self.run_dir, files or {})
        write_config(self.run_dir, self.cfg)
        self.loggers = [CSVLogger("csv", log_dir=str(self.run_dir / LOGS))]
        if self.cfg.log.tensorboard:
            self.loggers.append(TensorboardLogger("tensorboard", log_dir=str(self.run_dir / LOGS)))

    def log(self, metrics: dict, step: int) -> None:
        """Each scalar to every logger; a write the system refuses (a full disk, a folder made read-only) is
        one :class:`UsageError` sentence, as every other file of the run's is."""
        try:
            for logger in self.loggers:
                for k, v in metrics.items():
                    logger.log_scalar(k, float(v), step=step)
        except OSError as err:
            raise UsageError(f"cannot write the training logs in '{self.run_dir / LOGS}' "
                             f"({err.strerror or err}).") from None

    def evaluation(self, row: dict) -> None:
        """Append an evaluation (``{"frames": ..., "return_mean": ...}``) to eval.csv and the loggers."""
        self.rows.append(row)
        write_eval_csv(self.run_dir / EVAL, self.rows)
        self.log({f"eval/{k}": v for k, v in row.items() if k != "frames"}, row["frames"])

    def checkpoint(self, state: dict, frames: int, updates: int, *, last: bool = True, best: bool = False) -> None:
        """Save ``state`` (weights, optimiser, buffer, RNG) with the counters a resume needs, as ``last.pt``
        and its networks alone after it (``last.safetensors``); for the best evaluation so far
        (:mod:`drltg.training.best`), its networks as ``best.safetensors`` after those, and with
        ``checkpoint.keep_best`` the same content as ``last.pt`` as ``best.pt`` before them."""
        evaluations = [r["frames"] for r in self.rows]
        weights = networks.encode(state["loss"], frames, updates)
        for name in ["last"] * last + ["best"] * best:
            if name == "last" or self.cfg.checkpoint.keep_best:
                atomic_torch_save({**state, "frames": frames, "updates": updates, "evaluations": evaluations},
                                  self.run_dir / CHECKPOINTS[name])
            write_tracked(self.run_dir, networks.NETWORKS[name].as_posix(), weights)

    def finish(self, frames: int, updates: int, wall: float, timed_frames: int, extra: dict | None = None) -> None:
        """Write summary.json: the run is complete. ``wall`` is the time of the last start (a resumed run's
        earlier starts are not in it), which trained ``timed_frames`` of the ``frames``."""
        import json

        summary = {
            "status": COMPLETE,
            "task": self.cfg.task,
            "algo": self.cfg.algo,
            "seed": self.cfg.seed,
            "frames": frames,
            "updates": updates,
            "wall_time_s": round(wall, 2),
            "timed_frames": timed_frames,
            "frames_per_s": round(timed_frames / max(wall, 1e-9), 1),
            "final_eval": self.rows[-1],
            **({"note": "no update was made: every frame lay within the random warm-up "
                        "(collector.init_random_frames)"} if updates == 0 else {}),
            **(extra or {}),
        }
        atomic_write(self.run_dir / SUMMARY, json.dumps(summary, indent=2) + "\n")
        finalize_manifest(self.run_dir)

    def close(self) -> None:
        from torchrl.record.loggers import TensorboardLogger

        for logger in self.loggers:
            if isinstance(logger, TensorboardLogger):
                logger.experiment.close()
