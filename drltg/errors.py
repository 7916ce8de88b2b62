class UsageError(ValueError):
    """A mistake the user can fix (a bad value, path or combination), in one sentence.

    A ``ValueError``, so library code catches it like any bad argument; the CLI prints it and exits
    with code 2."""


class RunFailed(RuntimeError):
    """A run that ended without a usable result (its losses diverged): one sentence, exit code 1."""
