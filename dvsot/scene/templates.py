"""Scene templates: scene files whose values may be distributions, drawn into concrete scenes
(blender_scenes/README.md).

Wherever the scene schema takes a number, a vector or a choice, a template may give
  {uniform: [lo, hi]}                 a real number in [lo, hi] (lo, hi may be vectors of one length)
  {normal: [mu, sigma]}               optionally with clip: [lo, hi]
  {choice: [a, b, ...]}               one of the values (each may hold distributions), optionally weights: [...]
In a list (objects, lights, keyframes) an item {count: N, each: ITEM} stands for N items drawn one by one
(N a whole number or a distribution of whole numbers). A trajectory may be {random_walk: {...}} instead of
keyframes (dvsot.scene.random_walk). Variant i of a template whose master seed is S gets the scene seed
variant_seed(S, i); each draw's generator derives from that seed and the drawn field's path, so variant 17 is
the same on any machine and a distribution added elsewhere changes no other draw. Drawing the distributions is
dvsot.scene.distributions' job; this module reads and checks templates and makes their variants.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from dvsot.core.errors import UserError
from dvsot.events import EventParams
from dvsot.scene import Locate, SceneConfig, read_scene_text, read_yaml, validate_scene
from dvsot.scene.distributions import CENTRE, DrawContext, distributions, dotted, is_plain, kind_of, resolve
from dvsot.scene.random_walk import expand_walks
from dvsot.scene.yaml_write import to_yaml


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



def _draw(tpl: Template, index: int | None, probe: tuple | None = None) -> Variant:
    seed = variant_seed(tpl.master_seed, index if index is not None else 0)
    ctx = DrawContext(tpl.source, tpl.locate, seed, probe)
    scene = {k: resolve(ctx, v, (k,), (k,)) for k, v in tpl.data.items()}
    name = variant_name(tpl.name, index if index is not None else 0)
    scene["name"], scene["seed"] = name, seed
    expand_walks(
        scene,
        lambda spath: ctx.rng(spath, "walk"),
        lambda spath, msg: ctx.fail(_origin(ctx.origin, spath), msg),
        ctx.origin,
    )
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
        if kind_of(data.get(key)) is not None or isinstance(data.get(key), (dict, list)):
            line = locate((key,))
            raise UserError(f"{p}{f':{line}' if line else ''}: field '{key}': the template's {key} is {pattern}, "
                            "not drawn (each variant's seed derives from it)")
    check_template(tpl)
    return tpl


def check_template(tpl: Template) -> None:
    """Validate the scene at every bound and choice option of each distribution (the rest at their centres)."""
    validate_variant(tpl, _draw(tpl, None, probe=CENTRE))
    for tpath, n in distributions(tpl.data):
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
    kind = kind_of(node) or "count"
    if kind == "choice":
        opt = node["choice"][k]
        return f"(when {dotted(tpath)} is {opt!r})" if is_plain(opt) else f"(when {dotted(tpath)} is option {k + 1})"
    spec = node.get(kind) if kind != "count" else None
    names = {"uniform": ["lo", "hi"], "normal": ["mean", "clip lo", "clip hi"]}.get(kind, ["option"])
    bound = spec[k] if kind == "uniform" else node.get("clip", [None, None])[k - 1] if k else spec[0] if spec else ""
    return f"(when {dotted(tpath)} is its {names[min(k, len(names) - 1)]} {bound})".replace(" )", ")")


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
                raise UserError(f"{tpl.source}{f':{line}' if line else ''}: field '{dotted(loc)}': unknown "
                                f"distribution '{next(iter(node))}' (uniform, normal or choice)") from None


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
        return (kind_of(data) is not None or {"count", "each"} <= set(data) or "random_walk" in data
                or any(is_template(v) for v in data.values()))
    return isinstance(data, list) and any(is_template(v) for v in data)
