"""A worker process registers the tasks its parent ships exactly as the parent has them: a Gymnasium task's
``fixed`` fields (its gym id) and its return range included, or every run of it fails in the worker."""
import pickle

import pytest

from drltg.envs import get_task
from drltg.experiments.executor import register


@pytest.mark.parametrize("name", ["pendulum/g15", "fourrooms/northeast", "gridrooms/northeast"])
def test_a_shipped_task_is_registered_with_every_field(name):
    shipped = get_task(name)
    register(pickle.dumps(([shipped], [])))
    assert repr(get_task(name)) == repr(shipped)  # a shipped potential is an equal partial, not the same one
    assert get_task(name).fixed == shipped.fixed
