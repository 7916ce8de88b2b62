"""Keep a finished source run: ``python results/manipulation/keep_source.py RUN_DIR DEST_DIR``.

Its config, curve and summary, and of ``checkpoints/last.pt`` (and ``best.pt``, where kept) the learner's
weights alone: without the replay buffer and optimiser state (about 420 MB on Lift) DEST_DIR serves as
``transfer.source`` but cannot be resumed.
"""
import shutil
import sys
from pathlib import Path

import torch

from drltg.errors import UsageError


def keep_source(run: Path, dest: Path) -> None:
    if not (run / "summary.json").is_file():
        raise UsageError(f"{run} has no summary.json: only a finished run is kept as a source.")
    (dest / "checkpoints").mkdir(parents=True, exist_ok=True)
    for name in ("config.yaml", "eval.csv", "summary.json"):
        shutil.copyfile(run / name, dest / name)
    for name in ("last.pt", "best.pt"):
        if name == "last.pt" or (run / "checkpoints" / name).is_file():
            ckpt = torch.load(run / "checkpoints" / name, map_location="cpu", weights_only=True, mmap=True)
            tmp = dest / "checkpoints" / f"{name}.tmp"
            torch.save({"loss": ckpt["loss"], "frames": ckpt["frames"]}, tmp)
            tmp.replace(dest / "checkpoints" / name)


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    try:
        keep_source(Path(sys.argv[1]), Path(sys.argv[2]))
    except UsageError as e:
        print(f"keep_source: error: {e}", file=sys.stderr)
        sys.exit(2)
