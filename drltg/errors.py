import difflib
import re

_CONTROL = re.compile(r"[\x00-\x1f\x7f]")


class UsageError(ValueError):
    """A mistake the user can fix (a bad value, path or combination), in one sentence.

    A ``ValueError``, so library code catches it like any bad argument; the CLI prints it and exits
    with code 2. Control characters from what the user gave (a newline in a key, a NUL byte) are shown
    escaped, so the sentence stays one line."""

    def __init__(self, message: str = "", *args):
        super().__init__(_CONTROL.sub(lambda m: repr(m.group())[1:-1], str(message)), *args)


class ArgumentError(UsageError):
    """A part's argument that breaks the part's rule, as ``"<argument> <rule>"``: a caller that sets the
    argument under another name (a config key) says the sentence in its own words from ``argument`` and
    ``rule``, so the rule is checked once, by the part."""

    def __init__(self, argument: str, rule: str):
        super().__init__(f"{argument} {rule}")
        self.argument, self.rule = argument, rule


class RunFailed(RuntimeError):
    """A run that ended without a usable result (its losses diverged): one sentence, exit code 1."""


def short(value) -> str:
    """``repr(value)`` cut to 60 characters, as an error sentence quotes what it was given."""
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def closest(word, choices) -> str | None:
    """The choice a mistyped ``word`` most likely meant, or None: a near spelling (similarity >= 0.75) or one
    that holds the word (``gpus`` -> ``num_gpus``). A loose match (``name`` -> ``frames``) says little, so a
    message lists the choices instead."""
    word = str(word)
    for choice in difflib.get_close_matches(word, [str(c) for c in choices], n=3):
        if word in choice or choice in word or difflib.SequenceMatcher(None, word, choice).ratio() >= 0.75:
            return choice
    return None
