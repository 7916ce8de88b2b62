"""Progress of long work, counted in frames: a tqdm bar on a terminal, a plain line every half minute elsewhere.

A log file or a CI job gets no bar (tqdm draws none when stderr is not a terminal), so :class:`Progress`
prints ``experiment: 120,000 of 420,000 frames (29%), 1,234 frames/s, about 4 min left; runs 3/21`` there
every :data:`PLAIN_EVERY` seconds. The rate is the frames counted since the first count over the time since
it, so the time left counts every frame, not only evaluations, and leaves out the start-up before any frame
(imports, builds, SF-GPI's psi): measured on a bench tune whose first frame came 271 s into 735, the time left
from the start's rate was 1.6x to 5.7x the time it took from 11% of the frames on; from the first count's rate
0.75x to 1.00x (benchmarks/README.md, "Time left").
"""
from __future__ import annotations

import sys
import time
from typing import Callable

from tqdm.auto import tqdm

PLAIN_EVERY = 30.0
"""Seconds between two plain progress lines where no bar is drawn."""


def duration(seconds: float) -> str:
    """``42 s``, ``7 min``, ``2.5 h``."""
    if seconds < 90:
        return f"{seconds:.0f} s"
    if seconds < 5400:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"


class Progress:
    """Frames done of ``total``: ``update(n)`` adds ``n`` and calls ``on_update`` with the frames done;
    ``note`` is shown after the count."""

    def __init__(self, total: int, *, initial: int = 0, desc: str = "frames", enabled: bool = True, file=None,
                 on_update: Callable[[int], None] | None = None):
        self.file = file or sys.stderr
        self.bar = tqdm(total=total, initial=initial, unit="frame", desc=desc, dynamic_ncols=True, smoothing=0.05,
                        file=self.file, disable=None if enabled else True)  # None: a bar on a terminal only
        self.plain = enabled and self.bar.disable
        self.total, self.done, self.desc, self.note = total, initial, desc, ""
        self.last = time.monotonic()
        self.on_update = on_update
        self.first: tuple[float, int] | None = None  # (when, frames done) at the first count

    def update(self, n: int) -> None:
        self.done += n
        if self.first is None and n > 0:
            self.first = (time.monotonic(), self.done)
        self.bar.update(n)
        if self.on_update is not None:
            self.on_update(self.done)
        self._line_if_due()

    def set_note(self, note: str) -> None:
        self.note = note
        self.bar.set_postfix_str(note, refresh=False)

    def line(self) -> str:
        """The plain line: frames, share, rate and time left (from the second count on)."""
        rate = 0.0
        if self.first is not None and time.monotonic() > self.first[0]:
            rate = (self.done - self.first[1]) / (time.monotonic() - self.first[0])
        text = f"{self.desc}: {self.done:,} of {self.total:,} frames ({100 * self.done / max(self.total, 1):.0f}%)"
        if rate > 0:
            text += f", {rate:,.0f} frames/s, about {duration(max(self.total - self.done, 0) / rate)} left"
        return text + (f"; {self.note}" if self.note else "")

    def print_line(self) -> None:
        self.last = time.monotonic()
        print(self.line(), file=self.file, flush=True)

    def refresh(self) -> None:
        self._line_if_due()
        self.bar.refresh()

    def _line_if_due(self) -> None:
        if self.plain and time.monotonic() - self.last >= PLAIN_EVERY:
            self.print_line()

    def close(self) -> None:
        self.bar.close()
