class UsageError(Exception):
    """A mistake the user can fix; the CLI prints it as one sentence and exits with code 2."""
