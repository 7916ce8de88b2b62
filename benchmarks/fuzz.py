"""``python -m benchmarks.fuzz [--examples N]``: the properties of ``tests/test_fuzz.py`` (``-o`` overrides,
sweep specs, report inputs: a result or one sentence, never another exception) with many more examples
than ``make test`` runs. Prints one JSON object (slow: minutes; not a test)."""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

from benchmarks.common import REPO


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--examples", type=int, default=2000, help="examples per property (make test runs 60)")
    args = p.parse_args()
    start = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "tests/test_fuzz.py"],
                          cwd=REPO, env={**os.environ, "DRLTG_FUZZ_EXAMPLES": str(args.examples)},
                          capture_output=True, text=True)
    print(json.dumps({"suite": "fuzz", "examples_per_property": args.examples, "passed": proc.returncode == 0,
                      "wall_s": round(time.perf_counter() - start, 1),
                      "summary": next((line for line in reversed(proc.stdout.splitlines())
                                       if " passed" in line or " failed" in line), "")}, indent=2))
    if proc.returncode:
        print(proc.stdout[-4000:], file=sys.stderr)
    return proc.returncode


if __name__ == "__main__":
    sys.exit(main())
