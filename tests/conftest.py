import signal
from pathlib import Path

import pytest

# Ctrl-C raises KeyboardInterrupt in the tests of stopped runs, as in a terminal, also when the suite itself
# was started in the background, where SIGINT comes ignored (a run keeps it ignored: tests/test_train.py).
signal.signal(signal.SIGINT, signal.default_int_handler)

DATA = Path(__file__).resolve().parent / "data"


@pytest.fixture(scope="session")
def sb3_runs() -> Path:
    """Real Stable-Baselines3 logs shipped with the suite (origin and licence: data/README.md)."""
    return DATA / "sb3_runs"


@pytest.fixture(scope="session")
def page_size():
    """A one-page PDF's page size in points (72 to the inch), read from its MediaBox."""
    import re

    def read(pdf: Path) -> tuple[float, float]:
        found = re.findall(rb"/MediaBox\s*\[\s*([-\d. ]+)\]", pdf.read_bytes())
        assert len(found) == 1, found
        x0, y0, x1, y1 = (float(v) for v in found[0].split())
        return x1 - x0, y1 - y0

    return read
