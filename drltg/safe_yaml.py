"""YAML from files and command lines that may come from anyone: safe types only, each key once, and a
bound on nesting and on the size once aliases are expanded.

PyYAML's safe loader runs no code, but an alias tree of a few hundred bytes (``b: [*a, *a, ...]``, nested)
stands for billions of values, which the first deep copy, validation message or JSON dump expands; and
deep nesting exhausts Python's recursion. Both are refused here in one sentence, before construction.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from drltg.errors import UsageError
from drltg.regular import read_bytes

MAX_DEPTH = 64
"""Most levels of nested lists and mappings."""
MAX_NODES = 100_000
"""Most values, counted with every alias expanded."""


class UniqueKeyLoader(yaml.SafeLoader):
    """``yaml.SafeLoader`` that refuses a mapping with a key twice (plain YAML keeps the last silently)."""

    def construct_mapping(self, node, deep=False):
        seen = set()
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=True)
            if key in seen:
                raise yaml.constructor.ConstructorError(
                    None, None, f"key {key!r} appears twice (line {key_node.start_mark.line + 1})", key_node.start_mark)
            seen.add(key)
        return super().construct_mapping(node, deep)


def _check_size(root: yaml.Node, what: str) -> None:
    """Walk ``root`` as the constructed value would be (aliases expanded), stopping at the first bound."""
    count, stack = 0, [(root, 1)]
    while stack:
        node, depth = stack.pop()
        count += 1
        if depth > MAX_DEPTH:
            raise UsageError(f"{what} nests lists or mappings more than {MAX_DEPTH} levels deep.")
        if count > MAX_NODES:
            raise UsageError(f"{what} holds more than {MAX_NODES:,} values once its aliases are expanded.")
        if isinstance(node, yaml.SequenceNode):
            stack.extend((child, depth + 1) for child in node.value)
        elif isinstance(node, yaml.MappingNode):
            stack.extend((child, depth + 1) for pair in node.value for child in pair)


MAX_FILE_BYTES = 16 * 2**20
"""The largest YAML file read (a run's config is a few kilobytes)."""


def load_file(path, what: str | None = None) -> Any:
    """:func:`load` of the file ``path``: one that is larger than :data:`MAX_FILE_BYTES` or not UTF-8 text is
    one :class:`UsageError` sentence, before it is parsed."""
    path, what = Path(path), what or f"'{path}'"
    try:
        text = read_bytes(path, MAX_FILE_BYTES, "a config").decode("utf-8")
    except UnicodeDecodeError as err:
        raise UsageError(f"{what} is not UTF-8 text (byte {err.start}).") from None
    except OSError as err:
        raise UsageError(f"cannot read {what} ({err.strerror or err}).") from None
    return load(text, what)


def load(text: str, what: str) -> Any:
    """The value of the YAML document ``text`` (``None`` when empty); ``what`` names it in the sentence of a
    :class:`UsageError` (bad YAML, a key twice, too deep, too large)."""
    loader = None
    try:
        loader = UniqueKeyLoader(text)  # reads the first characters: a control character is refused here
        node = loader.get_single_node()
        if node is None:
            return None
        _check_size(node, what)
        return loader.construct_document(node)
    except RecursionError:
        raise UsageError(f"{what} nests lists or mappings more than {MAX_DEPTH} levels deep.") from None
    except yaml.constructor.ConstructorError as err:
        if "appears twice" in str(err.problem):
            raise UsageError(f"{what}: {err.problem}; give each key once.") from None
        raise UsageError(f"{what} is not valid YAML ({err.__class__.__name__}).") from None
    except yaml.YAMLError as err:
        raise UsageError(f"{what} is not valid YAML ({err.__class__.__name__}).") from None
    finally:
        if loader is not None:
            loader.dispose()
