"""Scene templates: scene files whose values may be distributions, drawn into concrete scenes (blender_scenes/README.md).

Wherever the scene schema takes a number, a vector or a choice, a template may give
  {uniform: [lo, hi]}                 a real number in [lo, hi] (lo, hi may be vectors of one length)
  {normal: [mu, sigma]}               optionally with clip: [lo, hi]
  {choice: [a, b, ...]}               one of the values (each may hold distributions), optionally weights: [...]
In a list (objects, lights, keyframes) an item {count: N, each: ITEM} stands for N items drawn one by one
(N a whole number or a distribution of whole numbers). A trajectory may be {random_walk: {...}} instead of
keyframes (dvsot.walk). Variant i of a template whose master seed is S gets the scene seed variant_seed(S, i);
each draw's generator derives from that seed and the drawn field's path, so variant 17 is the same on any
machine and a distribution added elsewhere changes no other draw.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import ValidationError

from dvsot.config import Locate, SceneConfig, read_scene_text, read_yaml, validate_scene
from dvsot.errors import UserError
from dvsot.events import EventParams
from dvsot.walk import expand_walks
from dvsot.yamltext import to_yaml

KINDS = {"uniform": set(), "normal": {"clip"}, "choice": {"weights"}}
MAX_COUNT = 1000
_CENTRE = (("<centre>",), 0)  # a probe of no distribution: every one at its centre


def variant_seed(master: int, index: int) -> int:
    """Scene seed of variant `index` of a template whose master seed is `master` (0 <= seed < 2**63)."""
    digest = hashlib.sha256(f"dvsot-variant:{master}:{index}".encode()).digest()
    return int.from_bytes(digest[:8], "little") >> 1


def variant_name(name: str, index: int) -> str:
    """The scene name (and output stem) of variant `index`."""
    return f"{name}_{index:05d}"


@dataclass
class Variant:
    """One concrete scene drawn from a template."""

    index: int
    seed: int
    name: str
    scene: dict                       # scene-file data, no distribution left
    drawn: dict[str, Any]             # field path -> drawn value (a choice of a mapping: its option index)
    origin: dict[tuple, tuple] = field(repr=False, default_factory=dict)  # scene path -> template path

    def text(self, source: str) -> str:
        """The concrete scene as a scene file (YAML), headed by where it came from."""
        return f"# variant {self.index} of {source}, seed {self.seed}\n" + to_yaml(self.scene)


@dataclass
class Template:
    """A template file read and checked: its data, where it came from and how to find a field's line."""

    data: dict
    source: str
    locate: Locate
    base_dir: Path

    @property
    def name(self) -> str:
        return str(self.data.get("name", "variant"))

    @property
    def master_seed(self) -> int:
        return int(self.data.get("seed", 0))


# -- drawing -----------------------------------------------------------------------------------------


@dataclass
class _Ctx:
    template: Template
    seed: int
    probe: tuple | None = None        # (template path, option index): every other distribution at its centre
    drawn: dict = field(default_factory=dict)
    origin: dict = field(default_factory=dict)

    def rng(self, spath: tuple, salt: str = "") -> np.random.Generator:
        key = f"{self.seed}:{salt}:{'.'.join(map(str, spath))}".encode()
        return np.random.default_rng(int.from_bytes(hashlib.sha256(key).digest()[:8], "little"))

    def fail(self, tpath: tuple, msg: str) -> UserError:
        line = self.template.locate(tpath)
        return UserError(f"{self.template.source}{f':{line}' if line else ''}: field '{_dotted(tpath)}': {msg}")


def _dotted(path: tuple) -> str:
    return ".".join(map(str, path)) or "(top level)"


def _kind(node: Any) -> str | None:
    """The distribution kind of a node, or None when it is a plain value."""
    if not isinstance(node, dict):
        return None
    kinds = [k for k in node if k in KINDS]
    return kinds[0] if kinds else None


def _number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _numbers(ctx: _Ctx, v: Any, tpath: tuple, what: str) -> np.ndarray:
    """A number or a non-empty list of numbers, as a float array (0-d or 1-d)."""
    if _number(v):
        return np.asarray(float(v))
    if isinstance(v, list) and v and all(_number(x) for x in v):
        return np.asarray(v, np.float64)
    raise ctx.fail(tpath, f"{what} must be a number or a list of numbers, got {v!r}")


def _pair(ctx: _Ctx, node: dict, key: str, tpath: tuple, names: str) -> tuple[np.ndarray, np.ndarray]:
    v = node[key]
    if not (isinstance(v, list) and len(v) == 2):
        raise ctx.fail(tpath + (key,), f"{key} needs [{names}], got {v!r}")
    a, b = (_numbers(ctx, x, tpath + (key, i), f"{key}'s {n}") for i, (x, n) in enumerate(zip(v, names.split(", "))))
    if a.shape and b.shape and a.shape != b.shape:
        raise ctx.fail(tpath + (key,), f"{key}'s {names} must have one length, got {v!r}")
    return a, b


def _check_keys(ctx: _Ctx, node: dict, kind: str, tpath: tuple) -> None:
    extra = [k for k in node if k != kind and k not in KINDS[kind]]
    if extra:
        allowed = ", ".join(sorted(KINDS[kind])) or "nothing"
        raise ctx.fail(tpath + (extra[0],), f"unknown key beside {kind} ({allowed} allowed)")


def _as_value(x: np.ndarray) -> float | list[float]:
    """Plain numbers at 6 significant digits: what the variant's scene file holds is exactly what was drawn."""
    return float(f"{float(x):.6g}") if x.ndim == 0 else [float(f"{float(v):.6g}") for v in x]


def _real(ctx: _Ctx, node: dict, kind: str, tpath: tuple, spath: tuple) -> Any:
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
    ctx.drawn[_dotted(spath)] = value
    return value


def _choice(ctx: _Ctx, node: dict, tpath: tuple, spath: tuple) -> Any:
    opts = node["choice"]
    if not (isinstance(opts, list) and opts):
        raise ctx.fail(tpath + ("choice",), f"choice needs a non-empty list of values, got {opts!r}")
    weights = node.get("weights")
    p = None
    if weights is not None:
        if not (isinstance(weights, list) and len(weights) == len(opts) and all(_number(w) and w >= 0 for w in weights)
                and sum(weights) > 0):
            raise ctx.fail(tpath + ("weights",), f"weights must be {len(opts)} numbers >= 0, not all 0, got {weights!r}")
        p = np.asarray(weights, np.float64) / sum(weights)
    if ctx.probe is None:
        m = int(ctx.rng(spath).choice(len(opts), p=p))
    elif ctx.probe[0] == tpath:
        m = ctx.probe[1]
    else:  # a probe inside one option takes that option
        inner = [i for i in range(len(opts)) if ctx.probe[0][:len(tpath) + 2] == tpath + ("choice", i)]
        m = inner[0] if inner else 0
    ctx.drawn[_dotted(spath)] = opts[m] if _plain(opts[m]) else {"choice": m}
    return _resolve(ctx, opts[m], tpath + ("choice", m), spath)


def _plain(v: Any) -> bool:
    return not isinstance(v, (dict, list)) or (isinstance(v, list) and all(not isinstance(x, (dict, list)) for x in v))


def _count(ctx: _Ctx, node: Any, tpath: tuple, spath: tuple) -> int:
    """A count of list items: a whole number in [0, MAX_COUNT], fixed or drawn (uniform over whole numbers)."""
    kind = _kind(node)
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
    ctx.drawn[_dotted(spath[:-1]) + f".count@{tpath[-2]}"] = n
    return n


def _resolve(ctx: _Ctx, node: Any, tpath: tuple, spath: tuple) -> Any:
    """The node with every distribution drawn and every counted list item expanded."""
    ctx.origin[spath] = tpath
    kind = _kind(node)
    if kind is not None:
        _check_keys(ctx, node, kind, tpath)
        return _choice(ctx, node, tpath, spath) if kind == "choice" else _real(ctx, node, kind, tpath, spath)
    if isinstance(node, dict):
        if "count" in node or "each" in node:
            raise ctx.fail(tpath, "count/each stands for list items: use it as an item of a list")
        return {k: _resolve(ctx, v, tpath + (k,), spath + (k,)) for k, v in node.items()}
    if isinstance(node, list):
        out: list = []
        for j, item in enumerate(node):
            if isinstance(item, dict) and ("count" in item or "each" in item):
                if set(item) != {"count", "each"}:
                    raise ctx.fail(tpath + (j,), "a counted item has exactly two keys, count and each")
                for _ in range(_count(ctx, item["count"], tpath + (j, "count"), spath + (len(out),))):
                    out.append(_resolve(ctx, item["each"], tpath + (j, "each"), spath + (len(out),)))
            else:
                out.append(_resolve(ctx, item, tpath + (j,), spath + (len(out),)))
        return out
    return node


def _distributions(node: Any, tpath: tuple = ()) -> list[tuple[tuple, int]]:
    """Every distribution and count in a template: (template path, number of probe options)."""
    found: list = []
    kind = _kind(node)
    if kind == "choice" and isinstance(node["choice"], list):
        found.append((tpath, len(node["choice"])))
        for m, opt in enumerate(node["choice"]):
            found += _distributions(opt, tpath + ("choice", m))
    elif kind is not None:
        found.append((tpath, 3 if kind == "normal" and "clip" in node else 1 if kind == "normal" else 2))
    elif isinstance(node, dict):
        for k, v in node.items():
            if k == "count" and "each" in node:
                c = _kind(v)
                n = 0 if c is None else len(v[c]) if c == "choice" and isinstance(v[c], list) else 2
                found += [(tpath + ("count",), n)] if n else []
            else:
                found += _distributions(v, tpath + (k,))
    elif isinstance(node, list):
        for j, item in enumerate(node):
            found += _distributions(item, tpath + (j,))
    return found


def _draw(tpl: Template, index: int | None, probe: tuple | None = None) -> Variant:
    seed = variant_seed(tpl.master_seed, index if index is not None else 0)
    ctx = _Ctx(tpl, seed, probe)
    scene = {k: _resolve(ctx, v, (k,), (k,)) for k, v in tpl.data.items()}
    name = variant_name(tpl.name, index if index is not None else 0)
    scene["name"], scene["seed"] = name, seed
    expand_walks(scene, lambda spath: ctx.rng(spath, "walk"), lambda spath, msg: ctx.fail(_origin(ctx.origin, spath), msg),
                 ctx.origin)
    return Variant(index if index is not None else 0, seed, name, scene, ctx.drawn, ctx.origin)


def _origin(origin: dict, spath: tuple) -> tuple:
    """The template path a scene path came from (through its longest recorded prefix)."""
    for n in range(len(spath), -1, -1):
        if spath[:n] in origin:
            return origin[spath[:n]] + tuple(spath[n:])
    return tuple(spath)


# -- reading and checking ------------------------------------------------------------------------


def read_template(path: str | Path) -> Template:
    """Read a template (or scene) file and check its distributions; UserError naming file, line and field."""
    p = Path(path)
    data, locate = read_yaml(read_scene_text(p, "template"), str(p))
    if not isinstance(data, dict):
        raise UserError(f"{p}: a template file must be a mapping of fields, got {type(data).__name__}")
    tpl = Template(data, str(p), locate, p.parent.resolve())
    for key, pattern in (("seed", "a whole number"), ("name", "a name")):
        if _kind(data.get(key)) is not None or isinstance(data.get(key), (dict, list)):
            line = locate((key,))
            raise UserError(f"{p}{f':{line}' if line else ''}: field '{key}': the template's {key} is {pattern}, "
                            "not drawn (each variant's seed derives from it)")
    check_template(tpl)
    return tpl


def check_template(tpl: Template) -> None:
    """Validate the scene at every bound and choice option of each distribution (the rest at their centres)."""
    validate_variant(tpl, _draw(tpl, None, probe=_CENTRE))
    for tpath, n in _distributions(tpl.data):
        for k in range(n):
            v = _draw(tpl, None, probe=(tpath, k))
            try:
                SceneConfig.model_validate(v.scene)
            except ValidationError:
                validate_variant(tpl, v, note=_probe_note(tpl.data, tpath, k), check_assets=False)


def _probe_note(data: Any, tpath: tuple, k: int) -> str:
    """What a probe set: '(when target.size_m is its lo 0)', '(when objects.0.each.shape is 'torso')'."""
    node = data
    for key in tpath:
        node = node[key]
    kind = _kind(node) or "count"
    if kind == "choice":
        opt = node["choice"][k]
        return f"(when {_dotted(tpath)} is {opt!r})" if _plain(opt) else f"(when {_dotted(tpath)} is option {k + 1})"
    spec = node.get(kind) if kind != "count" else None
    names = {"uniform": ["lo", "hi"], "normal": ["mean", "clip lo", "clip hi"]}.get(kind, ["option"])
    bound = spec[k] if kind == "uniform" else node.get("clip", [None, None])[k - 1] if k else spec[0] if spec else ""
    return f"(when {_dotted(tpath)} is its {names[min(k, len(names) - 1)]} {bound})".replace(" )", ")")


def validate_variant(tpl: Template, v: Variant, overrides: dict | None = None, note: str = "",
                     check_assets: bool = True) -> SceneConfig:
    """Validate a drawn scene; an error names the template's file, line and field. Raises UserError."""
    def locate(loc: tuple) -> int | None:
        return tpl.locate(_origin(v.origin, tuple(loc)))

    try:
        _unknown_kind(tpl, v, locate)
        if check_assets:
            return validate_scene(_copy(v.scene), tpl.source, locate, tpl.base_dir, overrides)
        try:
            return SceneConfig.model_validate(_copy(v.scene))
        except ValidationError:
            validate_scene(_copy(v.scene), tpl.source, locate, tpl.base_dir, overrides)  # raises its one-line form
            raise
    except UserError as exc:
        raise UserError(f"{exc} {note}".strip()) from None


def _unknown_kind(tpl: Template, v: Variant, locate: Locate) -> None:
    """A one-key mapping where the schema wants a value is a misspelt distribution: say so."""
    for prefix, check in (((), lambda: SceneConfig.model_validate(_copy(v.scene))),
                          (("events",), lambda: EventParams(**(v.scene.get("events") or {})))):
        try:
            check()
        except (ValidationError, TypeError) as exc:
            if not isinstance(exc, ValidationError):
                continue
            err = exc.errors()[0]
            if err["type"] in ("extra_forbidden", "missing"):
                continue
            loc, node = (), v.scene
            for key in prefix + tuple(err["loc"]):
                if isinstance(node, dict) and key in node:
                    node, loc = node[key], loc + (key,)
                elif isinstance(node, list) and isinstance(key, int) and key < len(node):
                    node, loc = node[key], loc + (key,)
                else:
                    break
            if isinstance(node, dict) and len(node) == 1 and isinstance(next(iter(node.values())), list):
                line = locate(loc)
                raise UserError(f"{tpl.source}{f':{line}' if line else ''}: field '{_dotted(loc)}': unknown "
                                f"distribution '{next(iter(node))}' (uniform, normal or choice)")


def _copy(data: Any) -> Any:
    if isinstance(data, dict):
        return {k: _copy(v) for k, v in data.items()}
    if isinstance(data, list):
        return [_copy(v) for v in data]
    return data


def draw_variants(tpl: Template, count: int, first: int = 0) -> list[Variant]:
    """Variants first..first+count-1 of a checked template."""
    return [_draw(tpl, i) for i in range(first, first + count)]


def is_template(data: Any) -> bool:
    """Whether scene data holds a distribution, a counted list item or a random walk anywhere."""
    if isinstance(data, dict):
        return (_kind(data) is not None or {"count", "each"} <= set(data) or "random_walk" in data
                or any(is_template(v) for v in data.values()))
    return isinstance(data, list) and any(is_template(v) for v in data)
