"""The lifecycle of the run directories that train together: one run, or the runs of a seed group.

    with RunSession(cfgs, dirs, resume=resume) as session:
        if session.finished: ...                  # every run is complete: nothing to write
        ... build agents, envs, transfers (nothing is written yet: a bad config leaves no trace) ...
        session.restore(agents, buffers)          # the checkpoints' networks, optimizers and replay
        session.claim()                           # new folders made and locked, or logs cut back
        writers = session.writers(transfers)
        frames, updates = session.position()      # where the loop starts, the random state restored
        ... run_loop(...) ...

Checks come first: a new run refuses a folder that holds anything; a resumed one needs its saved
config to match and its checkpoint, evaluations and logs to agree. Each directory is locked while the
session writes it. If a new run fails before its first checkpoint, what it wrote is removed, so the same
command can be run again; a run that diverged keeps its record.
"""
from __future__ import annotations

import contextlib
import os
import shutil
from pathlib import Path

import torch

from drltg.config import RunConfig, config_changes
from drltg.errors import UsageError
from drltg.store import manifest, rundir
from drltg.store.rundir import CHECKPOINT, CONFIG, EVAL, RunWriter, is_complete, read_eval_csv
from drltg.training import best, health
from drltg.training.replay import load_buffer_state

TRAINING_STATE = {"frames", "updates", "optimizer", "buffer", "rng"}


class RunSession(contextlib.ExitStack):
    """Owns ``dirs`` (one per config of ``cfgs``) from the first check to the last write."""

    def __init__(self, cfgs: list[RunConfig], dirs: list[Path], *, resume: bool):
        super().__init__()
        self.cfgs, self.dirs, self.resume = cfgs, dirs, resume
        self.states: list[tuple[dict | None, list[dict]]] = [(None, []) for _ in dirs]
        self.created: list[bool] = []
        self.finished = self.mixed = False

    def __enter__(self) -> RunSession:
        super().__enter__()
        try:
            self._open()
        except BaseException:
            self.close()
            raise
        return self

    def __exit__(self, kind, err, tb) -> bool:
        if err is not None and not self.resume and not isinstance(err, health.Diverged):
            for d, new in zip(self.dirs, self.created):
                if not (d / CHECKPOINT).is_file():
                    remove_start(d, new)
        return super().__exit__(kind, err, tb)

    def _open(self) -> None:
        if self.resume and all(d.is_dir() and any(d.iterdir()) and not rundir.entries(d) for d in self.dirs):
            self.resume = False  # only a killed write's temporary file or lock: killed before its config landed
        if not self.resume:
            for d in self.dirs:
                refuse_existing(d)
            return
        for c, d in zip(self.cfgs, self.dirs):
            rundir.check_contents(d)
            if not (d / CONFIG).is_file():
                raise UsageError(f"cannot resume: '{d}' holds no {CONFIG} (is it a drltg run directory?).")
            check_saved_config(c, d)
        if all(is_complete(d) for d in self.dirs):  # nothing to write: finished runs may sit in a read-only archive
            for d in self.dirs:
                if os.access(d, os.W_OK) and (rundir.unlisted(d) or (d / rundir.LOCK).exists()):
                    complete_manifest(d)  # killed before its final manifest or before its lock was removed
            self.finished = True
            return
        for d in self.dirs:
            self.enter_context(rundir.lock(d))
        if all(is_complete(d) for d in self.dirs):  # finished by their previous owner meanwhile
            self.finished = True
            return
        self.states = [resume_state(c, d) for c, d in zip(self.cfgs, self.dirs)]
        for d in self.dirs:
            rundir.remove_temporaries(d)
        frames = {None if ckpt is None else ckpt["frames"] for ckpt, _ in self.states}
        self.mixed = any(is_complete(d) for d in self.dirs) or len(frames) > 1

    @property
    def checkpoints(self) -> list[dict | None]:
        return [ckpt for ckpt, _ in self.states]

    def restore(self, agents, buffers, transfers=None) -> None:
        """Load each run's checkpoint (if resuming from one) into its agent's loss and optimizer, its
        replay buffer and its transfer's ``state`` (a curriculum's stage); a checkpoint of another config is
        one sentence."""
        transfers = transfers if transfers is not None else [None] * len(agents)
        for agent, buffer, transfer, ckpt, d in zip(agents, buffers, transfers, self.checkpoints, self.dirs):
            if ckpt is None:
                continue
            try:
                agent.loss.load_state_dict(ckpt["loss"])
                agent.optimizer.load_state_dict(ckpt["optimizer"])
                load_buffer_state(buffer, ckpt["buffer"])
                if transfer is not None and transfer.state is not None and "transfer" in ckpt:
                    transfer.state.load_state_dict(ckpt["transfer"])
            except (KeyError, IndexError, RuntimeError, ValueError) as err:
                raise UsageError(
                    f"checkpoint '{d / CHECKPOINT}' does not fit the run's config ({type(err).__name__})."
                ) from None

    def claim(self) -> None:
        """Make and lock the new runs' folders (refusing one another process started meanwhile), or cut a
        resumed run's logs back to its checkpoint."""
        if self.resume:
            for d, ckpt in zip(self.dirs, self.checkpoints):
                rundir.truncate_logs(d, ckpt["frames"] if ckpt is not None else -1, self.cfgs[0].log.tensorboard)
            return
        for d in self.dirs:
            new = not d.exists()
            try:
                d.mkdir(parents=True, exist_ok=True)
            except OSError as err:
                raise UsageError(f"cannot create --run-dir '{d}' ({err.strerror}).") from None
            self.enter_context(rundir.lock(d))
            refuse_existing(d)  # another process started it first: none of its files are ours to remove
            rundir.remove_temporaries(d)
            self.created.append(new)

    def writers(self, transfers) -> list[RunWriter]:
        """One writer per run, its evaluations up to the checkpoint kept, its transfer's files written."""
        writers = [RunWriter(d, c, rows) for d, c, (_, rows) in zip(self.dirs, self.cfgs, self.states)]
        for writer, transfer in zip(writers, transfers):
            writer.start(transfer.files)
        return writers

    def position(self) -> tuple[int, int]:
        """The frames and updates the loop starts from; on resume, torch's random state is the checkpoint's."""
        ckpt = self.checkpoints[0]
        if ckpt is None:
            return 0, 0
        torch.set_rng_state(ckpt["rng"])
        return ckpt["frames"], ckpt["updates"]


def complete_manifest(run_dir: Path) -> None:
    """Write the final manifest of a finished run a kill left without one, under its lock, once every file
    it lists still matches its digest."""
    with rundir.lock(run_dir):
        for name in manifest.read(run_dir):
            manifest.verify(run_dir, name)
        rundir.remove_temporaries(run_dir)
        rundir.finalize_manifest(run_dir)


def refuse_existing(run_dir: Path) -> None:
    if rundir.entries(run_dir):
        raise UsageError(
            f"run directory '{run_dir}' already exists; pass --resume to continue it or choose another --run-dir."
        )


def check_saved_config(cfg: RunConfig, run_dir: Path) -> None:
    saved = rundir.read_config(run_dir)
    changed = config_changes(saved if isinstance(saved, dict) else {},
                             rundir.absolute_source(cfg.model_dump(), Path.cwd()))
    if changed:
        raise UsageError(f"cannot resume '{run_dir}': the config differs from the saved one in {', '.join(changed)}.")


def resume_state(cfg: RunConfig, run_dir: Path) -> tuple[dict | None, list[dict]]:
    """The checkpoint to continue from (``None``: start over) and the evaluations up to it."""
    if not (run_dir / CHECKPOINT).is_file():
        listed = manifest.read(run_dir).get(CHECKPOINT.as_posix(), [])
        killed_first_write = len(listed) == 1 and any((run_dir / CHECKPOINT.parent).glob(f".{CHECKPOINT.name}.*.tmp"))
        if listed and not killed_first_write:  # (a kill inside the first write: the checkpoint was never written)
            raise UsageError(f"cannot resume '{run_dir}': its {CHECKPOINT.as_posix()} is missing though its manifest "
                             "lists it, so the run would start over from frame 0; restore the checkpoint or start the "
                             "run again in another --run-dir.")
        return None, []
    ckpt = rundir.load_checkpoint(run_dir, map_location=cfg.device)
    if not TRAINING_STATE <= set(ckpt):
        raise UsageError(f"cannot resume '{run_dir}': its checkpoint is not a training checkpoint of drltg train.")
    frames, updates = ckpt["frames"], ckpt["updates"]
    for name, value, most in (("frames", frames, cfg.frames), ("updates", updates, None)):
        if not isinstance(value, int) or isinstance(value, bool) or value < 0 or (most is not None and value > most):
            bound = f"0 to the budget of {most}" if most is not None else "0 or more"
            raise UsageError(f"cannot resume '{run_dir}': its checkpoint's {name} is {value!r}, not a whole number "
                             f"from {bound}; it is not this run's checkpoint.")
    if not (run_dir / EVAL).is_file():
        raise UsageError(
            f"cannot resume '{run_dir}': its {EVAL} is missing, so the curve up to the checkpoint at frame "
            f"{frames} is lost; start the run again in another --run-dir."
        )
    manifest.verify(run_dir, EVAL)  # the curve is carried forward: an edited one must not be
    rows = [r for r in read_eval_csv(run_dir / EVAL) if r["frames"] <= frames]
    found, expected = [r["frames"] for r in rows], ckpt.get("evaluations", [0])
    missing = sorted(set(expected) - set(found))
    if missing:
        raise UsageError(
            f"cannot resume '{run_dir}': {EVAL} lacks the evaluations at frames {missing} before the checkpoint "
            f"at frame {frames}; restore it or start the run again in another --run-dir."
        )
    if len(found) != len(set(found)):
        raise UsageError(
            f"cannot resume '{run_dir}': {EVAL} repeats frames before the checkpoint at frame {frames}; restore "
            "it or start the run again in another --run-dir."
        )
    best.check_resume(cfg, run_dir, ckpt, rows)
    for name in ("last", "best"):
        rundir.sync_networks(run_dir, name, ckpt if name == "last" else None)
    return ckpt, rows


def remove_start(run_dir: Path, created: bool) -> None:
    """Remove what a failed start wrote, so that the same command can be run again."""
    if created:
        shutil.rmtree(run_dir, ignore_errors=True)
        return
    for path in rundir.entries(run_dir):
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path, ignore_errors=True)
        else:
            path.unlink(missing_ok=True)
