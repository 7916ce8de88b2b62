import re

_CONTROL = re.compile(r"[\x00-\x1f\x7f]")


class UsageError(ValueError):
    """A mistake the user can fix (a bad value, path or combination), in one sentence.

    A ``ValueError``, so library code catches it like any bad argument; the CLI prints it and exits
    with code 2. Control characters from what the user gave (a newline in a key, a NUL byte) are shown
    escaped, so the sentence stays one line."""

    def __init__(self, message: str = "", *args):
        super().__init__(_CONTROL.sub(lambda m: repr(m.group())[1:-1], str(message)), *args)


class RunFailed(RuntimeError):
    """A run that ended without a usable result (its losses diverged): one sentence, exit code 1."""
