"""What training prints: colour for a terminal, plain text for a file.

TorchRL's logger colours every line with ANSI escape codes (``\\x1b[92m...``) whatever its stream is, so a run's
log (a sweep's ``logs/*.log``, ``drltg train > train.log``) filled with them. :func:`plain_unless_terminal` keeps
each of its handlers' formats and strips the codes wherever the handler's stream is no terminal."""
from __future__ import annotations

import logging
import re

ANSI = re.compile(r"\x1b\[[0-?]*[ -/]*[@-~]")
"""An ANSI control sequence (ECMA-48 CSI: ESC [, parameters, intermediates, a final byte), colours included."""


class PlainUnlessTerminal(logging.Formatter):
    """``inner``'s text, without ANSI sequences unless ``handler`` writes to a terminal (checked per record: a
    worker points its stdout at a log file after the handler was made)."""

    def __init__(self, inner: logging.Formatter | None, handler: logging.Handler):
        super().__init__()
        self.inner, self.handler = inner or logging.Formatter(), handler

    def format(self, record: logging.LogRecord) -> str:
        text = self.inner.format(record)
        return text if _is_terminal(getattr(self.handler, "stream", None)) else ANSI.sub("", text)


def _is_terminal(stream) -> bool:
    try:
        return bool(stream is not None and stream.isatty())
    except (ValueError, OSError):  # a closed stream
        return False


def plain_unless_terminal(name: str = "torchrl") -> None:
    """Wrap the formatter of every handler of the logger ``name`` in :class:`PlainUnlessTerminal` (once)."""
    for handler in logging.getLogger(name).handlers:
        if not isinstance(handler.formatter, PlainUnlessTerminal):
            handler.setFormatter(PlainUnlessTerminal(handler.formatter, handler))
