class UsageError(ValueError):
    """A mistake the user can fix (a bad value, path or combination), in one sentence.

    A ``ValueError``, so library code catches it like any bad argument; the CLI prints it and exits
    with code 2."""
