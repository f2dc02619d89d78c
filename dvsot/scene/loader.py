"""Reading a scene file: YAML 1.2 text (bounded in size and depth, no key given twice), command-line overrides,
validation against dvsot.scene.schema, the checks that need the whole scene, and its mesh and image files.
Every problem is one UserError line naming the file, the field, the YAML line and what is wrong.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from dvsot.core import bounds, yaml12
from dvsot.core.errors import UserError, exception_line
from dvsot.scene.checks import scene_problems
from dvsot.scene.schema import Material, SceneConfig


def _field_loc(loc: tuple) -> tuple:
    """A pydantic error location without its validator and union-member tags ('function-after[..]',
    'constrained-float')."""
    return tuple(p for p in loc if not (isinstance(p, str) and ("-" in p or "[" in p)))


def _chosen_error(errors: list[dict]) -> dict:
    """The error to report: the first, but for a union (one field, an error per member) the member whose type
    matched (a range error, not 'should be a valid number' from the member of another type)."""
    first = _field_loc(errors[0]["loc"])
    same = [e for e in errors if _field_loc(e["loc"])[:len(first)] == first]
    return next((e for e in same if not e["type"].endswith("_type")), errors[0])


def _line_of(node: yaml12.Node | None, loc: tuple) -> int | None:
    """The 1-based YAML line of the field at loc (or of its nearest existing parent)."""
    line = node.start_mark.line + 1 if node is not None else None
    for key in loc:
        if isinstance(node, yaml12.MappingNode):
            found = None
            for k, v in node.value:
                if k.value == key:
                    found = (k, v)
                    break
            if found is None:
                break
            line, node = found[0].start_mark.line + 1, found[1]
        elif isinstance(node, yaml12.SequenceNode) and isinstance(key, int) and key < len(node.value):
            node = node.value[key]
            line = node.start_mark.line + 1
        else:
            break
    return line


def yaml_text_problem(text: str) -> str | None:
    """A message if YAML text is larger than MAX_SCENE_BYTES or nested deeper than MAX_YAML_DEPTH (dvsot.core.bounds),
    or None.

    Runs the YAML scanner (a loop with a stack, no recursion) before any parser that recurses per level.
    """
    tokens = yaml12.tokens
    size = len(text.encode("utf-8", "replace"))
    if size > bounds.MAX_SCENE_BYTES:
        return f"{size} bytes, more than the bound of {bounds.MAX_SCENE_BYTES} bytes (1 MB) for a scene file"
    opening = (tokens.BlockSequenceStartToken, tokens.BlockMappingStartToken, tokens.FlowSequenceStartToken,
               tokens.FlowMappingStartToken)
    closing = (tokens.BlockEndToken, tokens.FlowSequenceEndToken, tokens.FlowMappingEndToken)
    depth = 0
    try:
        for token in yaml12.scan(text):
            if isinstance(token, opening):
                depth += 1
                if depth > bounds.MAX_YAML_DEPTH:
                    return (f"line {token.start_mark.line + 1}: nested more than {bounds.MAX_YAML_DEPTH} levels deep "
                            f"(the bound for a scene file)")
            elif isinstance(token, closing):
                depth -= 1
    except yaml12.YAMLError:
        return None  # a syntax error: the parser reports it with its line
    return None


def yaml_nodes_problem(node: Any) -> str | None:
    """A message if a composed YAML node graph holds more than MAX_YAML_NODES values once aliases are expanded."""
    sizes: dict[int, int] = {}

    def size(n) -> int:  # memoised: an alias shares its anchor's node, counted once per use
        if id(n) not in sizes:
            if isinstance(n, yaml12.MappingNode):
                children = [c for pair in n.value for c in pair]
            elif isinstance(n, yaml12.SequenceNode):
                children = n.value
            else:
                children = []
            sizes[id(n)] = 1 + sum(size(c) for c in children)
        return sizes[id(n)]

    total = size(node) if node is not None else 0
    if total > bounds.MAX_YAML_NODES:
        return (f"{total} values once aliases (*name) are expanded, more than the bound of {bounds.MAX_YAML_NODES} "
                f"for a scene file")
    return None


Locate = Callable[[tuple], "int | None"]  # field path (keys, list indices) -> its 1-based line in the file


def read_yaml(text: str, source: str = "<scene>") -> tuple[Any, Locate]:
    """Parse YAML text as a scene file is read: (data, locate), locate(loc) the line of a field. Raises UserError."""
    problem = yaml_text_problem(text)  # size and depth, before a parser that recurses per level
    if problem:
        raise UserError(f"{source}: {problem}")
    try:
        node = yaml12.compose(text)
        problem = yaml_nodes_problem(node)  # before anything expands the aliases
        if problem:
            raise UserError(f"{source}: {problem}")
        twice = yaml12.duplicate_key(node)  # YAML forbids it; a plain loader would keep the last silently
        if twice:
            key, first, again = twice
            raise UserError(f"{source}:{again}: field '{key}' is given twice (first on line {first})")
        data = yaml12.load(text)
    except yaml12.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f":{mark.line + 1}" if mark else ""
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise UserError(f"{source}{where}: YAML syntax error: {problem}") from None
    return data, lambda loc: _line_of(node, tuple(loc))


def parse_scene(text: str, source: str = "<scene>", base_dir: Path | None = None,
                overrides: dict[str, Any] | None = None) -> SceneConfig:
    """Validate scene YAML text; relative asset paths resolve against base_dir. Raises UserError."""
    data, locate = read_yaml(text, source)
    return validate_scene(data, source, locate, base_dir, overrides)


def validate_scene(data: Any, source: str, locate: Locate, base_dir: Path | None = None,
                   overrides: dict[str, Any] | None = None) -> SceneConfig:
    """Validate scene data read from `source`; errors name the field and its line (from locate). Raises UserError."""
    if not isinstance(data, dict):
        raise UserError(f"{source}: a scene file must be a mapping of fields, got {type(data).__name__}")
    for key, value in (overrides or {}).items():
        _set_path(data, key, value, source, locate)
    try:
        cfg = SceneConfig.model_validate(data)
    except ValidationError as exc:
        err = _chosen_error(exc.errors())
        loc = _field_loc(err["loc"])
        field = ".".join(str(p) for p in loc) or "(top level)"
        msg = err["msg"].removeprefix("Value error, ")
        if err["type"] == "extra_forbidden":
            msg = "unknown field"
        elif loc and loc[0] == "events":  # the simulator's fields: their range and unit
            from dvsot.events.simulator import field_message

            msg = field_message(err)
        if field in (overrides or {}):  # the value came from the command line, not from the file
            raise UserError(f"{source}: field '{field}' = {overrides[field]!r} (an override): {msg}") from None
        line = locate(loc)
        raise UserError(f"{source}{f':{line}' if line else ''}: field '{field}': {msg}") from None
    for loc, msg in scene_problems(cfg):
        line = locate(loc)
        raise UserError(f"{source}{f':{line}' if line else ''}: field '{'.'.join(map(str, loc))}': {msg}")
    _check_assets(cfg, source, base_dir or Path("."), locate)
    return cfg


def yaml_value(text: str) -> Any:
    """One YAML value as a scene file would read it (for KEY=VALUE overrides on a command line)."""
    return yaml12.load(text)


def _set_path(data: dict, dotted: str, value: Any, source: str, locate: Locate) -> None:
    """Set the field `dotted` (a.b.c) to an override's value; UserError if the file has no mapping there."""
    keys = dotted.split(".")
    for i, k in enumerate(keys[:-1]):
        if data.get(k) is None and k not in data:
            data[k] = {}
        data = data[k]
        if not isinstance(data, dict):
            loc = tuple(keys[:i + 1])
            line = locate(loc)
            raise UserError(f"{source}{f':{line}' if line else ''}: field '{'.'.join(loc)}' must be a mapping "
                            f"(to set {dotted} from the command line), got {type(data).__name__}")
    data[keys[-1]] = value


def asset_paths(cfg: SceneConfig) -> list[Path]:
    """The mesh and image files a loaded scene reads (absolute paths)."""
    materials = [cfg.target.material, cfg.background.material] + [o.material for o in cfg.objects]
    meshes = [o.mesh for o in [cfg.target, *cfg.objects] if o.mesh is not None]
    return meshes + [m.texture.path for m in materials if m.texture is not None and m.texture.path is not None]


def _check_assets(cfg: SceneConfig, source: str, base: Path, locate: Locate) -> None:
    """Resolve mesh and image paths against the scene file's folder and read each once: a missing or
    unreadable file is an error here, before anything is rendered (Blender itself only warns)."""
    def fix(obj: Any, attr: str, loc: tuple, read) -> None:
        p = getattr(obj, attr)
        if p is None:
            return
        full = p if p.is_absolute() else (base / p)
        line = locate(loc)
        where = f"{source}{f':{line}' if line else ''}: field '{'.'.join(map(str, loc))}'"
        kind = bounds.file_kind_problem(full)
        if kind:
            raise UserError(f"{where}: " + (f"file not found: {full}" if kind == "no such file" else
                                          f"{full} {kind}, not a regular file"))
        try:
            read(full.resolve())
        except UserError as exc:
            raise UserError(f"{where}: {exc}") from None
        setattr(obj, attr, full.resolve())

    def material(m: Material, loc: tuple) -> None:
        if m.texture is not None:
            fix(m.texture, "path", loc + ("texture", "path"), _read_image)

    from dvsot.scene.shapes import load_mesh_file

    fix(cfg.target, "mesh", ("target", "mesh"), load_mesh_file)
    material(cfg.target.material, ("target", "material"))
    material(cfg.background.material, ("background", "material"))
    for i, o in enumerate(cfg.objects):
        fix(o, "mesh", ("objects", i, "mesh"), load_mesh_file)
        material(o.material, ("objects", i, "material"))


def _read_image(path: Path) -> None:
    """Decode an image texture once (OpenCV; OpenEXR for .exr); UserError if it holds no pixels or more than
    bounds.MAX_TEXTURE_PIXELS (checked from its header, before decoding)."""
    from dvsot.events.frame_sources import image_size

    size = image_size(path)
    if size is not None and size[0] * size[1] > bounds.MAX_TEXTURE_PIXELS:
        raise UserError(f"{path}: image of {size[0]}x{size[1]} pixels, more than the bound of "
                        f"{bounds.MAX_TEXTURE_PIXELS} (8192x8192) for a texture")
    if path.suffix.lower() == ".exr":
        import OpenEXR

        try:
            with OpenEXR.File(str(path)) as f:
                ok = any(part.channels for part in f.parts)
        except Exception as exc:  # OpenEXR raises several kinds for damaged files
            raise UserError(f"{path}: cannot read image ({exception_line(exc, 200, kind=False)})") from None
    else:
        from dvsot.events.frame_sources import imread

        ok = imread(path) is not None
    if not ok:
        raise UserError(f"{path}: cannot read image (not an image file OpenCV or OpenEXR can decode)")


def read_scene_text(path: str | Path, what: str = "scene") -> str:
    """The text of a scene (or template) file: a regular file of at most MAX_SCENE_BYTES; UserError otherwise."""
    p = Path(path)
    kind = bounds.file_kind_problem(p)  # checked first: reading a FIFO would wait forever
    if kind:
        raise UserError(f"{p}: " + (f"no such {what} file" if kind == "no such file" else f"{kind}, not a {what} file"))
    try:
        size = p.stat().st_size
        if size > bounds.MAX_SCENE_BYTES:
            raise UserError(f"{p}: {size} bytes, more than the bound of {bounds.MAX_SCENE_BYTES} bytes (1 MB) "
                            f"for a {what} file")
        return p.read_text()
    except FileNotFoundError:
        raise UserError(f"{p}: no such {what} file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise UserError(f"{p}: cannot read {what} file ({exc})") from None


def load_scene(path: str | Path, overrides: dict[str, Any] | None = None) -> SceneConfig:
    """Read and validate a scene file; every problem raises UserError naming file, field and line."""
    p = Path(path)
    return parse_scene(read_scene_text(p), str(p), p.parent, overrides)
