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
