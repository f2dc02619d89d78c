"""The distributions of a scene template (dvsot.scene.templates): uniform, normal and choice values and item counts,
each drawn with a generator seeded from the variant's seed and the field's path, or probed at one bound or option
(the rest at their centres) to check a template."""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from dvsot.core.errors import UserError
from dvsot.scene import Locate

KINDS = {"uniform": set(), "normal": {"clip"}, "choice": {"weights"}}
MAX_COUNT = 1000
CENTRE = (("<centre>",), 0)  # a probe of no distribution: every one at its centre


@dataclass
class DrawContext:
    """One variant's draw: the template's source and field lines (for errors), the variant's seed, the probe,
    and what was drawn (field path -> value) and where each scene path came from (scene path -> template path)."""

    source: str
    locate: Locate
    seed: int
    probe: tuple | None = None        # (template path, option index): every other distribution at its centre
    drawn: dict = field(default_factory=dict)
    origin: dict = field(default_factory=dict)

    def rng(self, spath: tuple, salt: str = "") -> np.random.Generator:
        """The generator of the draw at scene path spath (salt: a second stream for the same path)."""
        key = f"{self.seed}:{salt}:{'.'.join(map(str, spath))}".encode()
        return np.random.default_rng(int.from_bytes(hashlib.sha256(key).digest()[:8], "little"))

    def fail(self, tpath: tuple, msg: str) -> UserError:
        """The error for the template field at tpath, naming its file and line."""
        line = self.locate(tpath)
        return UserError(f"{self.source}{f':{line}' if line else ''}: field '{dotted(tpath)}': {msg}")


def dotted(path: tuple) -> str:
    """A field path as text: 'objects.0.size_m'."""
    return ".".join(map(str, path)) or "(top level)"


def kind_of(node: Any) -> str | None:
    """The distribution kind of a node, or None when it is a plain value."""
    if not isinstance(node, dict):
        return None
    kinds = [k for k in node if k in KINDS]
    return kinds[0] if kinds else None


def _number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _numbers(ctx: DrawContext, v: Any, tpath: tuple, what: str) -> np.ndarray:
    """A number or a non-empty list of numbers, as a float array (0-d or 1-d)."""
    if _number(v):
        return np.asarray(float(v))
    if isinstance(v, list) and v and all(_number(x) for x in v):
        return np.asarray(v, np.float64)
    raise ctx.fail(tpath, f"{what} must be a number or a list of numbers, got {v!r}")


def _pair(ctx: DrawContext, node: dict, key: str, tpath: tuple, names: str) -> tuple[np.ndarray, np.ndarray]:
    v = node[key]
    if not (isinstance(v, list) and len(v) == 2):
        raise ctx.fail(tpath + (key,), f"{key} needs [{names}], got {v!r}")
    a, b = (_numbers(ctx, x, tpath + (key, i), f"{key}'s {n}") for i, (x, n) in enumerate(zip(v, names.split(", "))))
    if a.shape and b.shape and a.shape != b.shape:
        raise ctx.fail(tpath + (key,), f"{key}'s {names} must have one length, got {v!r}")
    return a, b


def _check_keys(ctx: DrawContext, node: dict, kind: str, tpath: tuple) -> None:
    extra = [k for k in node if k != kind and k not in KINDS[kind]]
    if extra:
        allowed = ", ".join(sorted(KINDS[kind])) or "nothing"
        raise ctx.fail(tpath + (extra[0],), f"unknown key beside {kind} ({allowed} allowed)")


def _as_value(x: np.ndarray) -> float | list[float]:
    """Plain numbers at 6 significant digits: what the variant's scene file holds is exactly what was drawn."""
    return float(f"{float(x):.6g}") if x.ndim == 0 else [float(f"{float(v):.6g}") for v in x]


def _real(ctx: DrawContext, node: dict, kind: str, tpath: tuple, spath: tuple) -> Any:
    """Draw (or probe) a uniform or normal distribution."""
    if kind == "uniform":
        lo, hi = _pair(ctx, node, "uniform", tpath, "lo, hi")
        if np.any(lo > hi):
            raise ctx.fail(tpath + ("uniform",), f"uniform needs lo <= hi, got {node['uniform']!r}")
        options, centre = [lo, hi], (lo + hi) / 2
        draw = lambda rng: rng.uniform(lo, hi)  # noqa: E731
        clip = (lo, hi)
    else:
        mu, sigma = _pair(ctx, node, "normal", tpath, "mu, sigma")
        if np.any(sigma < 0):
            raise ctx.fail(tpath + ("normal",), f"normal needs sigma >= 0, got {node['normal']!r}")
        clip = None
        if "clip" in node:
            clip = _pair(ctx, node, "clip", tpath, "lo, hi")
            if np.any(clip[0] > clip[1]):
                raise ctx.fail(tpath + ("clip",), f"clip needs lo <= hi, got {node['clip']!r}")
        centre = mu if clip is None else np.clip(mu, *clip)
        options = [centre] + ([] if clip is None else [np.broadcast_to(c, np.broadcast(mu, sigma).shape) for c in clip])
        draw = lambda rng: rng.normal(mu, sigma)  # noqa: E731
    if ctx.probe is None:
        x = draw(ctx.rng(spath))
    else:
        x = options[ctx.probe[1]] if ctx.probe[0] == tpath else centre
    x = np.asarray(x, np.float64)
    value = _as_value(x)
    if clip is not None:  # rounding to 6 digits may not step outside the bounds
        value = _as_value(np.clip(np.asarray(value), *clip))
    ctx.drawn[dotted(spath)] = value
    return value


def _choice(ctx: DrawContext, node: dict, tpath: tuple, spath: tuple) -> Any:
    opts = node["choice"]
    if not (isinstance(opts, list) and opts):
        raise ctx.fail(tpath + ("choice",), f"choice needs a non-empty list of values, got {opts!r}")
    weights = node.get("weights")
    p = None
    if weights is not None:
        if not (isinstance(weights, list) and len(weights) == len(opts) and all(_number(w) and w >= 0 for w in weights)
                and sum(weights) > 0):
            raise ctx.fail(
                tpath + ("weights",), f"weights must be {len(opts)} numbers >= 0, not all 0, got {weights!r}"
            )
        p = np.asarray(weights, np.float64) / sum(weights)
    if ctx.probe is None:
        m = int(ctx.rng(spath).choice(len(opts), p=p))
    elif ctx.probe[0] == tpath:
        m = ctx.probe[1]
    else:  # a probe inside one option takes that option
        inner = [i for i in range(len(opts)) if ctx.probe[0][:len(tpath) + 2] == tpath + ("choice", i)]
        m = inner[0] if inner else 0
    ctx.drawn[dotted(spath)] = opts[m] if is_plain(opts[m]) else {"choice": m}
    return resolve(ctx, opts[m], tpath + ("choice", m), spath)


def is_plain(v: Any) -> bool:
    return not isinstance(v, (dict, list)) or (isinstance(v, list) and all(not isinstance(x, (dict, list)) for x in v))


def _count(ctx: DrawContext, node: Any, tpath: tuple, spath: tuple) -> int:
    """A count of list items: a whole number in [0, MAX_COUNT], fixed or drawn (uniform over whole numbers)."""
    kind = kind_of(node)
    if kind is None:
        if not (isinstance(node, int) and not isinstance(node, bool) and 0 <= node <= MAX_COUNT):
            raise ctx.fail(tpath, f"count must be a whole number in 0..{MAX_COUNT} or a distribution, got {node!r}")
        return node
    _check_keys(ctx, node, kind, tpath)
    if kind == "uniform":
        lo, hi = _pair(ctx, node, "uniform", tpath, "lo, hi")
        if lo.ndim or not (float(lo).is_integer() and float(hi).is_integer() and 0 <= lo <= hi <= MAX_COUNT):
            raise ctx.fail(tpath + ("uniform",), f"a count's uniform needs whole numbers 0 <= lo <= hi <= {MAX_COUNT}, "
                                                 f"got {node['uniform']!r}")
        options, centre = [int(lo), int(hi)], int(hi)
        draw = lambda rng: int(rng.integers(int(lo), int(hi) + 1))  # noqa: E731
    elif kind == "choice":
        opts = node["choice"]
        if not (isinstance(opts, list) and opts and all(isinstance(n, int) and not isinstance(n, bool)
                                                         and 0 <= n <= MAX_COUNT for n in opts)):
            raise ctx.fail(tpath + ("choice",), f"a count's choice needs whole numbers in 0..{MAX_COUNT}, got {opts!r}")
        options, centre = list(opts), max(opts)
        draw = lambda rng: int(rng.choice(opts))  # noqa: E731
    else:
        raise ctx.fail(tpath + (kind,), "a count is drawn by uniform (whole numbers) or choice, not normal")
    if ctx.probe is None:
        n = draw(ctx.rng(spath, "count"))
    else:
        n = options[ctx.probe[1]] if ctx.probe[0] == tpath else centre
    ctx.drawn[dotted(spath[:-1]) + f".count@{tpath[-2]}"] = n
    return n


def resolve(ctx: DrawContext, node: Any, tpath: tuple, spath: tuple) -> Any:
    """The node with every distribution drawn and every counted list item expanded."""
    ctx.origin[spath] = tpath
    kind = kind_of(node)
    if kind is not None:
        _check_keys(ctx, node, kind, tpath)
        return _choice(ctx, node, tpath, spath) if kind == "choice" else _real(ctx, node, kind, tpath, spath)
    if isinstance(node, dict):
        if "count" in node or "each" in node:
            raise ctx.fail(tpath, "count/each stands for list items: use it as an item of a list")
        return {k: resolve(ctx, v, tpath + (k,), spath + (k,)) for k, v in node.items()}
    if isinstance(node, list):
        out: list = []
        for j, item in enumerate(node):
            if isinstance(item, dict) and ("count" in item or "each" in item):
                if set(item) != {"count", "each"}:
                    raise ctx.fail(tpath + (j,), "a counted item has exactly two keys, count and each")
                for _ in range(_count(ctx, item["count"], tpath + (j, "count"), spath + (len(out),))):
                    out.append(resolve(ctx, item["each"], tpath + (j, "each"), spath + (len(out),)))
            else:
                out.append(resolve(ctx, item, tpath + (j,), spath + (len(out),)))
        return out
    return node


def distributions(node: Any, tpath: tuple = ()) -> list[tuple[tuple, int]]:
    """Every distribution and count in a template: (template path, number of probe options)."""
    found: list = []
    kind = kind_of(node)
    if kind == "choice" and isinstance(node["choice"], list):
        found.append((tpath, len(node["choice"])))
        for m, opt in enumerate(node["choice"]):
            found += distributions(opt, tpath + ("choice", m))
    elif kind is not None:
        found.append((tpath, 3 if kind == "normal" and "clip" in node else 1 if kind == "normal" else 2))
    elif isinstance(node, dict):
        for k, v in node.items():
            if k == "count" and "each" in node:
                c = kind_of(v)
                n = 0 if c is None else len(v[c]) if c == "choice" and isinstance(v[c], list) else 2
                found += [(tpath + ("count",), n)] if n else []
            else:
                found += distributions(v, tpath + (k,))
    elif isinstance(node, list):
        for j, item in enumerate(node):
            found += distributions(item, tpath + (j,))
    return found

