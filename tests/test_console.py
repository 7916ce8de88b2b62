"""Logs on disk hold no ANSI colour codes; a terminal still gets TorchRL's colours."""
import logging
import os
import pty
import subprocess
import sys

from drltg.training.console import ANSI, PlainUnlessTerminal, plain_unless_terminal

TINY = ["-o", "network.hidden=[16,16]", "-o", "collector.num_envs=4", "-o", "collector.frames_per_batch=16",
        "-o", "collector.init_random_frames=64", "-o", "optim.updates_per_batch=1", "-o", "buffer.batch_size=32",
        "-o", "eval.every=128", "-o", "eval.episodes=2", "-o", "log.tensorboard=false"]


def test_a_redirected_train_writes_no_escape_sequences(tmp_path):
    """``drltg train ... > train.log``: TorchRL's buffer message is there, as plain text."""
    log = tmp_path / "train.log"
    with open(log, "wb") as out:
        done = subprocess.run([sys.executable, "-m", "drltg.cli", "train", "fourrooms/northeast", "--frames", "128",
                               "--run-dir", str(tmp_path / "run"), *TINY], stdout=out, stderr=subprocess.STDOUT,
                              timeout=300)
    text = log.read_bytes()
    assert done.returncode == 0, text[-2000:]
    assert b"[torchrl][INFO]" in text and b"Initialized LazyTensorStorage" in text
    assert b"\x1b" not in text


def _record() -> logging.LogRecord:
    return logging.LogRecord("torchrl", logging.INFO, __file__, 1, "buffer ready", None, None)


class Green(logging.Formatter):
    def format(self, record):
        return f"\x1b[92m{record.levelname}\x1b[0m {record.getMessage()}\x1b[92m [END]\x1b[0m"


def test_the_handler_s_own_format_is_kept_and_its_colours_only_reach_a_terminal(tmp_path):
    master, child = pty.openpty()
    try:
        with open(child, "w", closefd=False) as terminal, open(tmp_path / "f.log", "w") as file:
            for stream, expected in ((terminal, "\x1b[92mINFO\x1b[0m buffer ready\x1b[92m [END]\x1b[0m"),
                                     (file, "INFO buffer ready [END]")):
                handler = logging.StreamHandler(stream)
                handler.setFormatter(Green())
                logger = logging.getLogger(f"drltg-test-{stream.fileno()}")
                logger.addHandler(handler)
                plain_unless_terminal(logger.name)
                plain_unless_terminal(logger.name)  # once: not wrapped twice
                assert isinstance(handler.formatter, PlainUnlessTerminal)
                assert isinstance(handler.formatter.inner, Green)
                assert handler.format(_record()) == expected
                logger.removeHandler(handler)
    finally:
        os.close(master), os.close(child)


def test_every_control_sequence_is_stripped():
    text = "\x1b[1;31mred\x1b[0m \x1b[2K\x1b[?25lbar\x1b[?25h \x1b[38;5;208morange\x1b[m"
    assert ANSI.sub("", text) == "red bar orange"
