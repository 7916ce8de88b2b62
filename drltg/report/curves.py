"""Learning curves from run directories and foreign logs, as :class:`Curve` objects.

A curve is one run's evaluation return against environment frames. Readers (``FORMATS``):

``drltg``
    a drltg run directory: ``eval.csv`` (``frames,return_mean,...``; ``--tag`` picks another column,
    e.g. ``success_rate``); the task comes from ``config.yaml``'s ``task`` key.
``sb3``
    Stable-Baselines3 ``progress.csv``: x = ``time/total_timesteps``, y = ``eval/mean_reward``
    (or ``--tag``); rows whose y cell is empty (training rows) are skipped. The same reader takes the
    three-column ``Wall time,time/total_timesteps,eval/mean_reward`` logs.
``sb3-monitor``
    Stable-Baselines3 ``*monitor.csv`` files (one per environment, ``0.monitor.csv`` ... as
    ``make_vec_env`` names them, merged by wall time; a folder of other names is refused): x = cumulative
    episode length ``l``, y = episode return ``r``. These are *training* episodes, so they are noisier
    than evaluation curves.
``tensorboard``
    ``events.out.tfevents.*`` files; the scalar tag is ``--tag`` (default: the first of
    ``DEFAULT_TAGS`` present).
``csvlogger``
    TorchRL ``CSVLogger`` scalars: ``<exp>/scalars/<tag>.csv`` with header-less ``step,value`` lines.

A path may be a file, a run directory, a directory holding several runs (found recursively; one run
per seed), or a glob. A directory that holds several kinds of log is read once, in the order above.
Every curve is checked: no empty file, finite values only, strictly increasing frames. A bad input
raises :class:`~drltg.errors.UsageError` with one sentence naming the file and the problem.
"""
from __future__ import annotations

import glob as _glob
import io
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable, Sequence

import numpy as np
import pandas as pd

from drltg.errors import UsageError
from drltg.regular import MAX_LOG_BYTES, open_regular, read_bytes
from drltg.store.rundir import EVAL

FORMATS = ("auto", "drltg", "sb3", "sb3-monitor", "tensorboard", "csvlogger")
DEFAULT_TAGS = ("eval/return_mean", "eval/mean_reward", "eval/reward")

_SB3_X = "time/total_timesteps"
_SB3_Y = "eval/mean_reward"


@dataclass
class Curve:
    """One run's learning curve: ``values[i]`` is the evaluation return after ``frames[i]`` frames."""

    frames: np.ndarray
    values: np.ndarray
    source: Path
    label: str
    task: str | None = None
    config: dict | None = None  # the run's config.yaml, for drltg runs

    def __post_init__(self):
        self.frames = np.asarray(self.frames, dtype=np.float64)
        self.values = np.asarray(self.values, dtype=np.float64)
        self.source = Path(self.source)

    def __len__(self) -> int:
        return len(self.frames)


def read_curves(
    paths: str | Path | Iterable[str | Path],
    *,
    format: str = "auto",
    tag: str | None = None,
) -> list[Curve]:
    """Read every run named by ``paths`` (files, run directories, directories of runs, globs)."""
    if format not in FORMATS:
        raise UsageError(f"unknown log format '{format}'; choose one of {', '.join(FORMATS)}.")
    if isinstance(paths, (str, Path)):
        paths = [paths]
    curves: list[Curve] = []
    for path in paths:
        for target in _expand(str(path)):
            curves.extend(_read_path(target, format, tag))
    if not curves:
        raise UsageError(f"no runs found in {', '.join(map(str, paths))}.")
    return curves


def _expand(pattern: str) -> list[Path]:
    if any(c in pattern for c in "*?[") and not Path(pattern).exists():
        matches = sorted(_glob.glob(pattern))
        if not matches:
            raise UsageError(f"the pattern '{pattern}' matches no file or directory.")
        return [Path(m) for m in matches]
    path = Path(pattern)
    if not path.exists():
        raise UsageError(f"'{path}' does not exist.")
    return [path]


def _read_path(path: Path, format: str, tag: str | None) -> list[Curve]:
    if path.is_file():
        return [_read_file(path, format, tag)]
    if not path.is_dir():
        raise UsageError(f"'{path}' is neither a log file nor a directory of runs.")
    runs = find_runs(path, format)
    if not runs:
        raise UsageError(
            f"directory '{path}' holds no runs (no eval.csv, progress.csv, *monitor.csv, "
            "TensorBoard event file or CSVLogger scalars/ folder)."
        )
    return [read_run(run, format=format, tag=tag) for run in runs]


def run_format(directory: Path) -> str | None:
    """The log format a directory holds as a single run, or None if it holds none."""
    d = Path(directory)
    if (d / EVAL).is_file():
        return "drltg"
    if (d / "progress.csv").is_file():
        return "sb3"
    if any(d.glob("*monitor.csv")):
        return "sb3-monitor"
    if any(d.glob("events.out.tfevents.*")):
        return "tensorboard"
    if (d / "scalars").is_dir():
        return "csvlogger"
    return None


def _has_format(directory: Path, format: str) -> bool:
    if format == "auto":
        return run_format(directory) is not None
    d = Path(directory)
    return {
        "drltg": lambda: (d / EVAL).is_file(),
        "sb3": lambda: (d / "progress.csv").is_file(),
        "sb3-monitor": lambda: any(d.glob("*monitor.csv")),
        "tensorboard": lambda: any(d.glob("events.out.tfevents.*")),
        "csvlogger": lambda: (d / "scalars").is_dir(),
    }[format]()


def find_runs(directory: str | Path, format: str = "auto") -> list[Path]:
    """Run directories at or below ``directory`` (sorted; a run's own subfolders are not searched, nor is a
    folder reached through a symbolic link: a link to ``..`` or ``/`` would make the search endless or read
    the whole machine)."""
    directory = Path(directory)
    if _has_format(directory, format):
        return [directory]
    runs: list[Path] = []
    for child in sorted(p for p in directory.iterdir() if p.is_dir() and not p.is_symlink()):
        runs.extend(find_runs(child, format))
    return runs


def read_run(directory: str | Path, *, format: str = "auto", tag: str | None = None) -> Curve:
    """Read one run directory."""
    d = Path(directory)
    fmt = run_format(d) if format == "auto" else format
    if fmt is None:
        raise UsageError(f"directory '{d}' holds no run.")
    owner = _owner(d)
    config = _config_of(owner)
    label = owner.resolve().name
    log = {"drltg": d / EVAL, "sb3": d / "progress.csv", "sb3-monitor": _one_runs_monitors(d),
           "tensorboard": d, "csvlogger": d / "scalars"}[fmt]
    curve = _read(fmt, log, tag)
    curve.label, curve.config = label, config
    curve.task = _task_in(config)
    return curve


def _one_runs_monitors(directory: Path) -> list[Path]:
    """The ``*monitor.csv`` files of a run directory, which are one run's environments only as SB3's
    ``make_vec_env(monitor_dir=...)`` names them, ``0.monitor.csv`` to ``<n-1>.monitor.csv`` (or a single
    file): other names may be several runs' files in one folder, which merged would be one run, silently."""
    files = sorted(directory.glob("*monitor.csv"))
    ranks = sorted(f.name.removesuffix(".monitor.csv") for f in files)
    if len(files) > 1 and ranks != sorted(map(str, range(len(files)))):
        names = ", ".join(f.name for f in files[:3]) + (f" and {len(files) - 3} more" if len(files) > 3 else "")
        raise UsageError(f"'{directory}' holds {len(files)} monitor files ({names}) not named as one run's "
                         "environments (0.monitor.csv, 1.monitor.csv, ...); put each run's in its own folder, or pass "
                         f"the files ('{directory}/*monitor.csv') to read each as a run.")
    return files


def _read_file(path: Path, format: str, tag: str | None) -> Curve:
    name = path.name
    if format == "auto":
        if name == EVAL:
            format = "drltg"
        elif name.endswith("monitor.csv"):
            format = "sb3-monitor"
        elif name.startswith("events.out.tfevents"):
            format = "tensorboard"
        elif name.endswith(".csv"):
            format = "csvlogger" if _headerless(path) else "sb3"
        else:
            raise UsageError(f"cannot tell the log format of '{path}'; pass --format.")
    curve = _read(format, [path] if format == "sb3-monitor" else path, tag)
    owner = _owner(path.parent)
    curve.config = _config_of(owner)
    curve.task = _task_in(curve.config)
    if owner != path.parent.resolve():
        curve.label = owner.name
    return curve


def _read(fmt: str, log, tag: str | None) -> Curve:
    """One log of format ``fmt``: its file, its folder (TensorBoard, CSVLogger ``scalars/``) or, for
    ``sb3-monitor``, its list of files."""
    if fmt == "drltg":
        return read_eval_csv(log, column=tag or "return_mean")
    if fmt == "sb3":
        return read_sb3_progress(log, column=tag or _SB3_Y)
    if fmt == "sb3-monitor":
        return read_sb3_monitor(log, column=tag or "r")
    if fmt == "tensorboard":
        return read_tensorboard(log, tag=tag)
    return read_csvlogger(log, tag=tag)


def _owner(directory: Path, levels: int = 3) -> Path:
    """The run a log folder belongs to: the nearest of it and its parents holding a ``config.yaml``
    (a drltg run keeps its logger files in ``logs/csv`` and ``logs/tensorboard``)."""
    d = Path(directory).resolve()
    for candidate in [d, *d.parents][:levels + 1]:
        if (candidate / "config.yaml").is_file():
            return candidate
    return d


def _config_of(directory: Path) -> dict | None:
    """The run's ``config.yaml`` as a dict (``{}`` when it holds no mapping), None without one."""
    config = Path(directory) / "config.yaml"
    if not config.is_file():
        return None
    _verify(config)
    from drltg import safe_yaml

    data = safe_yaml.load_file(config)
    return data if isinstance(data, dict) else {}


def _task_in(config: dict | None) -> str | None:
    task = (config or {}).get("task")
    return str(task) if task is not None else None


# ----------------------------------------------------------------------------------------- readers
MAX_COLUMNS = 10_000
"""The most columns a CSV log may have (SB3's progress.csv has a few dozen)."""


def _lines(path: Path) -> list[tuple[int, str]]:
    """The non-blank lines of a text file, with their line numbers (a byte-order mark is dropped); a file
    larger than :data:`MAX_LOG_BYTES` is refused before it is read."""
    try:
        text = read_bytes(path, MAX_LOG_BYTES, "a log of evaluations").decode("utf-8-sig")
    except UnicodeDecodeError:
        raise UsageError(f"'{path}' is not a text file.") from None
    lines = [(i, line) for i, line in enumerate(text.splitlines(), start=1) if line.strip()]
    if not lines:
        raise UsageError(f"'{path}' is empty.")
    if not text.endswith(("\n", "\r")):
        raise UsageError(f"'{path}' line {lines[-1][0]} is torn: the file ends without a newline, as one cut while "
                         "being written does; let the run finish, or remove that line.")
    _verify(Path(path))
    return lines


def _verify(path: Path) -> None:
    """Refuse a file of a drltg run whose ``manifest.json`` records another digest for it."""
    from drltg.store import manifest

    folder = path.parent.resolve()
    for run in [folder, *folder.parents][:6]:  # logs/csv/scalars/<group>/<tag>.csv lies 4 folders down
        if (run / manifest.MANIFEST).is_file():
            if path.is_symlink():  # its digest would be checked for a file the manifest does not cover
                raise UsageError(f"'{path}' is a symbolic link inside the run '{run}'; a run's files are read where "
                                 "they lie: replace the link with the file it stands for.")
            manifest.verify(run, (folder / path.name).relative_to(run).as_posix())
            return


def _table(path: Path, comment: str | None = None,
           columns: Sequence[str] | None = None) -> tuple[pd.DataFrame, np.ndarray]:
    """A CSV file's cells as strings, and each row's line number in the file (for the error sentences).

    pandas parses the non-blank lines after any leading ``comment`` lines: quoted cells are unquoted. The
    first of them is the header, or, for a header-less file of ``columns`` (CSVLogger's ``step,value``),
    the first row. A row with another number of cells is refused."""
    lines = _lines(path)
    while comment and lines and lines[0][1].startswith(comment):
        lines.pop(0)
    if not lines:
        raise UsageError(f"'{path}' has no header.")
    numbers = np.asarray([i for i, _ in lines])
    if lines[0][1].count(",") >= MAX_COLUMNS:
        raise UsageError(f"'{path}' line {lines[0][0]} has more than {MAX_COLUMNS:,} cells; a log of evaluations has "
                         "a few dozen columns.")

    def misfit(line: int, cells: int, expected: int) -> UsageError:
        if columns:
            return UsageError(f"'{path}' line {line} is not a '{','.join(columns)}' pair.")
        return UsageError(f"'{path}' line {line} has {cells} cells, but the header has {expected}.")

    try:
        table = pd.read_csv(io.StringIO("\n".join(line for _, line in lines)), header=None, dtype=str,
                            keep_default_na=False, engine="python")
    except pd.errors.ParserError as err:
        found = re.search(r"Expected (\d+) fields in line (\d+), saw (\d+)", str(err))
        if found is None:
            raise UsageError(f"'{path}' is not a readable CSV file ({err}).") from None
        expected, line, saw = map(int, found.groups())
        raise misfit(int(numbers[line - 1]), saw, expected) from None
    if columns is None:
        header, table, numbers = table.iloc[0], table.iloc[1:], numbers[1:]
        table.columns = [str(c).strip() for c in header]
        twice = sorted({c for c in table.columns if list(table.columns).count(c) > 1})
        if twice:  # which of the two would be read is a guess
            raise UsageError(f"'{path}' names the column '{twice[0]}' twice in its header; keep one.")
        if table.empty:
            raise UsageError(f"'{path}' has a header but no rows.")
    counts = table.notna().sum(axis=1).to_numpy()
    wrong = np.flatnonzero(counts != (len(columns) if columns else table.shape[1]))
    if wrong.size:
        raise misfit(int(numbers[wrong[0]]), int(counts[wrong[0]]), table.shape[1])
    if columns:
        table.columns = list(columns)
    return table, numbers


def _headerless(path: Path) -> bool:
    """Whether the first line of ``path`` holds numbers only (a CSVLogger file) rather than a header."""
    first = pd.read_csv(io.StringIO(_lines(path)[0][1]), header=None, dtype=str, keep_default_na=False)
    return bool(pd.to_numeric(first.iloc[0].str.strip(), errors="coerce").notna().all())


def _column(path: Path, table: pd.DataFrame, name: str) -> pd.Series:
    """The cells of the first column called ``name``, stripped."""
    if name not in table.columns:
        raise UsageError(f"'{path}' has no column '{name}' (columns: {', '.join(table.columns)}).")
    return table.iloc[:, list(table.columns).index(name)].str.strip()


def _floats(cells: pd.Series) -> np.ndarray:
    """Cells as floats, NaN where a cell is no number (pandas finds those; Python's own conversion gives the
    values, exact to the last digit, where pandas' faster parser may round)."""
    values = np.full(len(cells), np.nan)
    numeric = pd.to_numeric(cells, errors="coerce").notna().to_numpy()
    values[numeric] = cells[numeric].astype(np.float64)
    return values


def _numbers(path: Path, lines: np.ndarray, columns: Sequence[tuple[str, pd.Series]]) -> list[np.ndarray]:
    """Each column as floats. The first row with a cell that is empty, not a number or not finite is one
    sentence naming its line, column and cell (an empty cell first, then in the order given)."""
    values = [_floats(cells) for _, cells in columns]
    bad = np.logical_or.reduce([~np.isfinite(v) for v in values])
    if bad.any():
        i = int(np.argmax(bad))
        wrong = [(n, c.iloc[i]) for (n, c), v in zip(columns, values) if not np.isfinite(v[i])]
        name, cell = next(((n, c) for n, c in wrong if c == ""), wrong[0])
        if cell == "":
            raise UsageError(f"'{path}' line {lines[i]}: column '{name}' is empty.")
        if cell.lower().lstrip("+-") in ("nan", "inf", "infinity"):
            raise UsageError(f"'{path}' line {lines[i]}: column '{name}' holds the non-finite value {cell}.")
        raise UsageError(f"'{path}' line {lines[i]}: column '{name}' holds '{cell}', not a number.")
    return values


def _columns_xy(path: Path, x_name: str, y_name: str, *, skip_empty_y: bool) -> tuple[np.ndarray, np.ndarray, list]:
    table, lines = _table(path)
    x, y = _column(path, table, x_name), _column(path, table, y_name)
    if skip_empty_y:
        keep = (y != "").to_numpy()
        x, y, lines = x[keep], y[keep], lines[keep]
        if not keep.any():
            raise UsageError(f"'{path}' has no values in column '{y_name}'.")
    xs, ys = _numbers(path, lines, [(x_name, x), (y_name, y)])
    return xs, ys, list(lines)


def _checked(path: Path, frames, values, where: Sequence | None = None, what: str = "line") -> Curve:
    """A curve whose frames strictly increase and whose values are finite."""
    frames, values = np.asarray(frames, np.float64), np.asarray(values, np.float64)
    if frames.size == 0:
        raise UsageError(f"'{path}' holds no evaluations.")
    bad = np.flatnonzero(~np.isfinite(frames) | ~np.isfinite(values))
    if bad.size:
        i = bad[0]
        at = f" at {what} {where[i]}" if where is not None else ""
        raise UsageError(f"'{path}' holds a non-finite value{at} (frame {frames[i]:g}, value {values[i]:g}).")
    if frames[0] < 0:
        at = f" at {what} {where[0]}" if where is not None else ""
        raise UsageError(f"'{path}' counts a negative number of frames{at} ({frames[0]:g}); a learning curve "
                         "starts at frame 0 or later.")
    steps = np.diff(frames)
    if (steps <= 0).any():
        i = int(np.flatnonzero(steps <= 0)[0]) + 1
        at = f" at {what} {where[i]}" if where is not None else ""
        kind = "appears twice" if steps[i - 1] == 0 else f"comes after frame {frames[i - 1]:g}"
        raise UsageError(f"'{path}': frame {frames[i]:g}{at} {kind}; frames must strictly increase.")
    return Curve(frames, values, Path(path), Path(path).parent.name or Path(path).name)


def read_eval_csv(path: str | Path, column: str = "return_mean") -> Curve:
    """A drltg ``eval.csv`` (``frames`` against ``column``)."""
    path = Path(path)
    x, y, lines = _columns_xy(path, "frames", column, skip_empty_y=False)
    return _checked(path, x, y, lines)


def read_sb3_progress(path: str | Path, column: str = _SB3_Y, x_column: str = _SB3_X) -> Curve:
    """A Stable-Baselines3 ``progress.csv``; training rows (empty ``column`` cell) are skipped."""
    path = Path(path)
    x, y, lines = _columns_xy(path, x_column, column, skip_empty_y=True)
    return _checked(path, x, y, lines)


def read_sb3_monitor(paths: Sequence[str | Path], column: str = "r") -> Curve:
    """Stable-Baselines3 ``monitor.csv`` files (a ``#{json}`` line, then ``r,l,t``), merged by wall time.

    x is the cumulative episode length, as in SB3's own ``load_results``/``ts2xy``.
    """
    files = []
    for path in map(Path, paths):
        table, lines = _table(path, comment="#")
        files.append(_numbers(path, lines, [(name, _column(path, table, name)) for name in ("t", "l", column)]))
    t, lengths, y = (np.concatenate(parts) for parts in zip(*files))
    order = np.argsort(t, kind="stable")
    source = Path(paths[0]) if len(paths) == 1 else Path(paths[0]).parent
    return _checked(source, np.cumsum(lengths[order]), y[order], None)


def read_tensorboard(path: str | Path, tag: str | None = None) -> Curve:
    """Scalars of ``tag`` from a TensorBoard event file, or from all event files of a directory."""
    from tensorboard.backend.event_processing import event_accumulator as ea

    path = Path(path)
    for file in [path] if path.is_file() else sorted(path.rglob("*tfevents*")):
        _check_records(file)
    acc = ea.EventAccumulator(str(path), size_guidance={ea.SCALARS: 0, ea.TENSORS: 0})
    try:
        acc.Reload()
    except Exception as err:  # a corrupt record surfaces as a library-specific error
        raise UsageError(f"'{path}' is not a readable TensorBoard event file ({err}).") from None
    tags = acc.Tags()
    scalar_tags, tensor_tags = list(tags.get("scalars", [])), list(tags.get("tensors", []))
    if not scalar_tags and not tensor_tags:
        raise UsageError(f"'{path}' holds no scalar in any TensorBoard event file.")
    tag = tag or _default_tag(path, scalar_tags + tensor_tags)
    if tag in scalar_tags:
        events = acc.Scalars(tag)
        steps, values = [e.step for e in events], [e.value for e in events]
    elif tag in tensor_tags:
        from tensorboard.util import tensor_util

        events = acc.Tensors(tag)
        steps = [e.step for e in events]
        values = [float(tensor_util.make_ndarray(e.tensor_proto)) for e in events]
    else:
        raise UsageError(
            f"'{path}' has no scalar tag '{tag}' (tags: {', '.join(sorted(scalar_tags + tensor_tags))})."
        )
    return _checked(path, steps, values, list(range(len(steps))), what="event")


def _check_records(file: Path) -> None:
    """Refuse an event file with a record that fails its CRC (TensorBoard itself would stop reading there
    without a word, and the curve would end early); a torn last record, as a killed run leaves, is left out
    as TensorBoard does."""
    from tensorboard.compat.tensorflow_stub import errors
    from tensorboard.compat.tensorflow_stub.pywrap_tensorflow import PyRecordReader_New

    _verify(file)
    _check_record_sizes(file)
    reader, record = PyRecordReader_New(str(file), 0, None, None), 0
    while True:
        try:
            reader.GetNext()
        except errors.OutOfRangeError:
            return
        except errors.DataLossError as err:
            if "truncated" in str(err).lower():
                return
            raise UsageError(f"'{file}' is a corrupt TensorBoard event file: record {record} fails its CRC check; "
                             "restore it or leave the run out.") from None
        record += 1


def _check_record_sizes(file: Path) -> None:
    """Walk the records' length headers (TFRecord: an 8-byte length, its 4-byte CRC, the data, its 4-byte
    CRC) before TensorBoard reads them: a file above :data:`MAX_LOG_BYTES`, or a record declaring more bytes
    than that, is refused, where the reader would first try to allocate it."""
    import struct

    with open_regular(file) as f:
        size = os.fstat(f.fileno()).st_size
        if size > MAX_LOG_BYTES:
            raise UsageError(f"'{file}' holds {size / 2**20:,.0f} MB, more than the {MAX_LOG_BYTES // 2**20} MB a "
                             "run's event file takes; is it a learning curve?")
        position, record = 0, 0
        while position + 12 <= size:
            f.seek(position)
            (length,) = struct.unpack("<Q", f.read(8))
            if length > MAX_LOG_BYTES:
                raise UsageError(f"'{file}' is a corrupt TensorBoard event file: record {record} declares {length:,} "
                                 "bytes; restore it or leave the run out.")
            position, record = position + 16 + length, record + 1


def read_csvlogger(path: str | Path, tag: str | None = None) -> Curve:
    """TorchRL ``CSVLogger`` scalars: ``path`` is a ``scalars/`` folder (``tag`` picks the file) or a file."""
    path = Path(path)
    if path.is_dir():
        found = sorted(p.relative_to(path).with_suffix("").as_posix() for p in path.rglob("*.csv"))
        if not found:
            raise UsageError(f"'{path}' holds no CSVLogger scalar file.")
        tag = tag or _default_tag(path, found)
        if tag not in found:
            raise UsageError(f"'{path}' has no scalar '{tag}' (scalars: {', '.join(found)}).")
        path = path / f"{tag}.csv"
    table, lines = _table(Path(path), columns=("step", "value"))
    steps, values = _numbers(path, lines, [(name, table[name].str.strip()) for name in ("step", "value")])
    return _checked(path, steps, values, list(lines))


def _default_tag(path: Path, available: Sequence[str]) -> str:
    for tag in DEFAULT_TAGS:
        if tag in available:
            return tag
    raise UsageError(
        f"'{path}' has none of the default tags {', '.join(DEFAULT_TAGS)}; choose one with --tag "
        f"(available: {', '.join(sorted(available))})."
    )
