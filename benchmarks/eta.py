"""How right a sweep's time left was: from a log of its progress lines, each stamped with the Unix time.

``python -m benchmarks.eta LOG``: LOG holds ``<unix seconds> sweep: D of T frames ...`` lines, as a command's
plain progress lines (every 30 s where no terminal draws a bar) come out of::

    drltg bench tune ... 2>&1 | while IFS= read -r l; do printf '%s %s\\n' "$(date -u +%s)" "$l"; done

For each line with frames counted it prints the share done, the time the rest actually took (the end
extrapolated from the last two lines to the total, the start 30 s before the first line) and two estimates of
it with their ratio to it: the rate since the start (the time left drltg showed before) and the rate since the
first line that counted frames (what :class:`drltg.training.progress.Progress` shows now, counting from its
first count).
"""
from __future__ import annotations

import re
import sys

LINE = re.compile(r"^(\d+) \w+: ([\d,]+) of ([\d,]+) frames")


def points(text: str) -> list[tuple[int, int, int]]:
    """``(unix seconds, frames done, total)`` of each progress line."""
    found = (LINE.match(line) for line in text.splitlines())
    return [(int(m[1]), int(m[2].replace(",", "")), int(m[3].replace(",", ""))) for m in found if m]


def table(pts: list[tuple[int, int, int]]) -> list[dict]:
    start = pts[0][0] - 30
    (ta, da, total), (tb, db, _) = pts[-2], pts[-1]
    end = tb + (total - db) * (tb - ta) / (db - da)
    first = next(p for p in pts if p[1] > 0)
    rows = []
    for t, done, _ in pts:
        if done <= first[1]:
            continue
        actual = end - t
        since_start = (total - done) * (t - start) / done
        since_first = (total - done) * (t - first[0]) / (done - first[1])
        rows.append({"share": round(done / total, 2), "actual_s": round(actual),
                     "since_start_s": round(since_start), "since_start_ratio": round(since_start / actual, 2),
                     "since_first_s": round(since_first), "since_first_ratio": round(since_first / actual, 2)})
    return rows


def main(path: str) -> None:
    print("| done | time it took | rate since the start | ratio | rate since the first count | ratio |")
    print("|---|---|---|---|---|---|")
    for r in table(points(open(path).read())):
        print(f"| {r['share']:.2f} | {r['actual_s']} s | {r['since_start_s']} s | {r['since_start_ratio']:.2f}x "
              f"| {r['since_first_s']} s | {r['since_first_ratio']:.2f}x |")


if __name__ == "__main__":
    main(sys.argv[1])
