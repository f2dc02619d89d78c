"""YAML 1.2 for scene files and --option values, via ruamel.yaml (safe types only, pure-Python parser).

YAML 1.2's core schema has none of YAML 1.1's traps: `010` is ten (octal is `0o10`), `1:30` is a
string (no base-60 numbers), `on`, `no`, `y` are strings (only true/false are booleans), and
`1e-3` is a number. A key given twice in one mapping is an error naming both lines, found on the
composed node graph (so before anything is constructed); node marks give every field's line.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

from ruamel.yaml import YAML, nodes, tokens
from ruamel.yaml.error import MarkedYAMLError, YAMLError

__all__ = ["MappingNode", "SequenceNode", "ScalarNode", "YAMLError", "MarkedYAMLError", "compose", "load",
           "scan", "duplicate_key", "tokens"]

MappingNode, SequenceNode, ScalarNode, Node = nodes.MappingNode, nodes.SequenceNode, nodes.ScalarNode, nodes.Node


def _yaml() -> YAML:
    """A fresh YAML 1.2 safe loader (ruamel's loaders keep state: one per call is thread-safe)."""
    y = YAML(typ="safe", pure=True)
    y.version = (1, 2)
    return y


def compose(text: str) -> Node | None:
    """The node graph of one YAML document (None for an empty one); aliases share their anchor's node."""
    return _yaml().compose(text)


def load(text: str) -> Any:
    """The Python value of one YAML document (dicts, lists, str, int, float, bool, None)."""
    return _yaml().load(text)


def scan(text: str) -> Iterator:
    """The tokens of a YAML text (no recursion: a loop with a stack), each with its start_mark."""
    return _yaml().scan(text)


def duplicate_key(node: Node | None) -> tuple[str, int, int] | None:
    """(key, first line, second line), 1-based, of the first key given twice in one mapping, or None."""
    seen_nodes: set[int] = set()
    stack = [node] if node is not None else []
    while stack:
        n = stack.pop()
        if id(n) in seen_nodes:
            continue
        seen_nodes.add(id(n))
        if isinstance(n, MappingNode):
            first: dict[tuple, int] = {}
            for key, _ in n.value:
                if isinstance(key, ScalarNode):
                    ident = (str(key.tag), key.value)
                    if ident in first:
                        return str(key.value), first[ident], key.start_mark.line + 1
                    first[ident] = key.start_mark.line + 1
            stack.extend(c for pair in reversed(n.value) for c in reversed(pair))  # document order
        elif isinstance(n, SequenceNode):
            stack.extend(reversed(n.value))
    return None
