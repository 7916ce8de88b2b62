from pathlib import Path

import pytest

DATA = Path(__file__).resolve().parent / "data"


@pytest.fixture(scope="session")
def sb3_runs() -> Path:
    """Real Stable-Baselines3 logs shipped with the suite (origin and licence: data/README.md)."""
    return DATA / "sb3_runs"
