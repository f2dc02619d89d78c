"""Scene data (dicts, lists, plain values) written back as scene-file text: block YAML, short parts in flow style."""

from __future__ import annotations

import json
import re
from typing import Any

_PLAIN = re.compile(r"^[A-Za-z_][A-Za-z0-9_.\-/]*$")
_RESERVED = {"true", "false", "yes", "no", "on", "off", "null", "y", "n", "~"}


def _scalar(v: Any) -> str:
    if v is None:
        return "null"
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    s = str(v)
    return s if _PLAIN.match(s) and s.lower() not in _RESERVED else json.dumps(s)


def _flow(v: Any) -> str:
    if isinstance(v, dict):
        return "{" + ", ".join(f"{_scalar(k)}: {_flow(x)}" for k, x in v.items()) + "}"
    if isinstance(v, list):
        return "[" + ", ".join(_flow(x) for x in v) + "]"
    return _scalar(v)


def to_yaml(data: Any, indent: int = 0) -> str:
    """Scene data as block YAML, short lists and mappings of plain values in flow style (a scene file)."""
    pad = " " * indent
    if isinstance(data, dict):
        lines = []
        for k, v in data.items():
            if isinstance(v, (dict, list)) and v and len(_flow(v)) > 100:
                lines.append(f"{pad}{_scalar(k)}:\n{to_yaml(v, indent + 2)}")
            else:
                lines.append(f"{pad}{_scalar(k)}: {_flow(v)}")
        return "\n".join(lines) + ("\n" if indent == 0 else "")
    if isinstance(data, list):
        return "\n".join(f"{pad}- {_flow(v)}" if len(_flow(v)) <= 100 or not isinstance(v, dict)
                         else f"{pad}-\n{to_yaml(v, indent + 2)}" for v in data)
    return pad + _scalar(data)
