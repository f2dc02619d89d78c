"""Checks of input shared by readers and writers: file kinds, box values, the root-attribute digest, size bounds.

Every bound on what a file or a flag can make dvsot allocate lives here, so each error can name it.
"""

from __future__ import annotations

import hashlib
import json
import os
import stat
from typing import Any

import numpy as np

# Size bounds (each error message names the one it hits)
MAX_DURATION_S = 3600  # one dataset file covers at most an hour: ms_to_idx <= 29 MB
MAX_DURATION_US = MAX_DURATION_S * 1_000_000
MIN_SEGMENT_US = 1000  # segments of at least 1 ms: at most 3.6 million per file
MAX_SENSOR_PIXELS = 8192 * 8192  # width x height of a file, as a scene file's sensor allows
MAX_WINDOW_EVENTS = 1 << 26  # events one time window (a segment) may load at once: 67 million, 0.9 GB
MAX_BOX_ROWS = 1 << 24  # rendered box samples per file (16.7 million, 512 MB for both tracks)
MAX_SCENE_BYTES = 1 << 20  # a scene file (1 MB; it is stored verbatim in every dataset file)
MAX_YAML_DEPTH = 64  # nesting of mappings and lists in a YAML text
MAX_YAML_NODES = 1_000_000  # values in a YAML text once aliases are expanded
MAX_TEXT_ATTR_BYTES = 16 * MAX_SCENE_BYTES  # one text root attribute of a dataset file (a scene, its resolved JSON)
MIN_BOX_SIDE_PX = 0.01  # a box narrower or lower than this is no box (rendered boxes are whole pixels)
MAX_CONTRAST = 100.0  # event thresholds, log intensity: float32 intensities span less than 180 in log
MAX_SEGMENT_US = MAX_DURATION_US  # a segment is at most a whole file
MAX_TEXTURE_PIXELS = 8192 * 8192  # an image texture (decoded whole by OpenCV, then by Blender: 1 GB as float RGBA)
MAX_VARIANTS = 100_000  # scenes drawn from one template in one run (each a task and a manifest record)
MAX_WORKERS = 256  # processes of one run: --jobs, local:N
MAX_THREADS = 1024  # torch CPU threads
MAX_TAIL_STEPS = 1000  # SCTN's empty steps after its 10 ms window: every sample's tensors grow with them
MAX_LEARNING_RATE = 1.0  # Adam's rate: far above it the weights overflow float32 at the first step
MAX_PREVIEW_BYTES = 2 << 30  # the RGB frames of one preview GIF/MP4, held in memory until written

DIGEST_ATTR = "attrs_sha256"  # root attribute: SHA-256 of the other root attributes' canonical JSON

_KINDS = ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO (named pipe)"), (stat.S_ISCHR, "a character device"),
          (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"))


def file_kind_problem(path: str | os.PathLike) -> str | None:
    """Why path is not a regular file one can read ("no such file", "is a directory", ...), or None."""
    try:
        mode = os.stat(path).st_mode
    except (FileNotFoundError, NotADirectoryError):
        return "no such file"
    except OSError as exc:
        return f"cannot be examined ({exc.strerror or exc})"
    if stat.S_ISREG(mode):
        return None
    return "is " + next((word for test, word in _KINDS if test(mode)), "not a regular file")


def box_problem(xywh: np.ndarray, width: int, height: int, row_name=lambda i: f"row {i}") -> str | None:
    """What is wrong with (N, 4) boxes (xywh pixels) on a width x height sensor, or None.

    A box is four NaNs (no target) or finite with w, h >= MIN_BOX_SIDE_PX, inside the sensor widened by its
    own size on every side ([-width, 2 width] x [-height, 2 height]): further out, nothing of it can be seen.
    """
    b = np.asarray(xywh, np.float64).reshape(-1, 4)
    absent = np.isnan(b).all(axis=1)
    with np.errstate(invalid="ignore"):
        bad = ~absent & (~np.isfinite(b).all(axis=1) | (b[:, 2] < MIN_BOX_SIDE_PX) | (b[:, 3] < MIN_BOX_SIDE_PX)
                         | (b[:, 0] < -width) | (b[:, 1] < -height)
                         | (b[:, 0] + b[:, 2] > 2 * width) | (b[:, 1] + b[:, 3] > 2 * height))
    if not bad.any():
        return None
    i = int(np.flatnonzero(bad)[0])
    x, y, w, h = (f"{v:g}" for v in b[i])
    return (f"{row_name(i)} is x={x} y={y} w={w} h={h}; a box is finite with w, h >= {MIN_BOX_SIDE_PX:g} px and inside "
            f"[{-width}, {2 * width}] x [{-height}, {2 * height}] px (the {width}x{height} sensor and its own size "
            f"around it), or four NaNs for no target")


def _canonical(value: Any) -> Any:
    """A JSON-serialisable form of an attribute value that numpy or h5py handed back."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, bytes):
        return value.decode("utf-8", "replace")
    return str(value)


def attrs_digest(attrs: dict[str, Any]) -> str:
    """SHA-256 (hex) of the canonical JSON (sorted keys, no spaces) of decoded root attributes, the digest itself left out."""
    body = {k: v for k, v in attrs.items() if k != DIGEST_ATTR}
    text = json.dumps(body, sort_keys=True, separators=(",", ":"), ensure_ascii=True, default=_canonical)
    return hashlib.sha256(text.encode("ascii")).hexdigest()


def digest_problem(attrs: dict[str, Any]) -> str | None:
    """What is wrong with the root attributes' digest, or None (also when there is none: files before it)."""
    stored = attrs.get(DIGEST_ATTR)
    if stored is None:
        return None
    if stored != attrs_digest(attrs):
        return (f"the root attributes do not match their SHA-256 in root attribute '{DIGEST_ATTR}' "
                f"(an attribute was changed or corrupted after the file was written)")
    return None


def rows_problem(name: str, rows: int, bound: int, why: str) -> str | None:
    """A message if dataset /name has more than `bound` rows (a bound on what one file can make us read), or None."""
    if rows > bound:
        return f"/{name} has {rows} rows, more than the bound of {bound} ({why})"
    return None


def range_problem(name: str, value: float, low: float, high: float, unit: str = "") -> str | None:
    """A one-line message if value is not finite or outside [low, high] (high: a bound of this module), or None."""
    import math

    def num(v: float) -> str:
        return (f"{v:g}" if isinstance(v, float) else str(v)) + (f" {unit}" if unit else "")

    if isinstance(value, float) and not math.isfinite(value):
        return f"{name} must be a finite number in {num(low)}..{num(high)}, got {value}"
    if value < low:
        return f"{name} must be >= {num(low)}, got {num(value)}"
    if value > high:
        return f"{name} must be <= {num(high)} (the bound), got {num(value)}"
    return None


def sensor_size_problem(width: int, height: int) -> str | None:
    """What is wrong with a sensor size (pixels) for a dataset file, or None: each side 1..2**16 (x and y are
    stored as u2), at most MAX_SENSOR_PIXELS in all."""
    side = 1 << 16
    if not (0 < width <= side and 0 < height <= side):
        return f"width and height must lie in 1..{side}, got {width}x{height}"
    if width * height > MAX_SENSOR_PIXELS:
        return (f"{width}x{height} is {width * height} pixels, more than the bound of {MAX_SENSOR_PIXELS} "
                f"(8192x8192) for a sensor")
    return None


def preview_problem(width: int, height: int, frames: int) -> str | None:
    """A message if `frames` RGB frames of width x height pixels exceed MAX_PREVIEW_BYTES, or None."""
    need = 3 * int(width) * int(height) * int(frames)
    if need > MAX_PREVIEW_BYTES:
        return (f"{frames} frames of {width}x{height} px need {need / 2**30:.1f} GiB, more than the bound of "
                f"{MAX_PREVIEW_BYTES / 2**30:g} GiB for a preview")
    return None


def yaml_text_problem(text: str) -> str | None:
    """A message if YAML text is larger than MAX_SCENE_BYTES or nested deeper than MAX_YAML_DEPTH, or None.

    Runs the YAML scanner (a loop with a stack, no recursion) before any parser that recurses per level.
    """
    from dvsot import yaml12 as yamlio
    from dvsot.yaml12 import tokens

    size = len(text.encode("utf-8", "replace"))
    if size > MAX_SCENE_BYTES:
        return f"{size} bytes, more than the bound of {MAX_SCENE_BYTES} bytes (1 MB) for a scene file"
    opening = (tokens.BlockSequenceStartToken, tokens.BlockMappingStartToken, tokens.FlowSequenceStartToken,
               tokens.FlowMappingStartToken)
    closing = (tokens.BlockEndToken, tokens.FlowSequenceEndToken, tokens.FlowMappingEndToken)
    depth = 0
    try:
        for token in yamlio.scan(text):
            if isinstance(token, opening):
                depth += 1
                if depth > MAX_YAML_DEPTH:
                    return (f"line {token.start_mark.line + 1}: nested more than {MAX_YAML_DEPTH} levels deep "
                            f"(the bound for a scene file)")
            elif isinstance(token, closing):
                depth -= 1
    except yamlio.YAMLError:
        return None  # a syntax error: the parser reports it with its line
    return None


def yaml_nodes_problem(node: Any) -> str | None:
    """A message if a composed YAML node graph holds more than MAX_YAML_NODES values once aliases are expanded."""
    from dvsot.yaml12 import MappingNode, SequenceNode

    sizes: dict[int, int] = {}

    def size(n) -> int:  # memoised: an alias shares its anchor's node, counted once per use
        if id(n) not in sizes:
            if isinstance(n, MappingNode):
                children = [c for pair in n.value for c in pair]
            elif isinstance(n, SequenceNode):
                children = n.value
            else:
                children = []
            sizes[id(n)] = 1 + sum(size(c) for c in children)
        return sizes[id(n)]

    total = size(node) if node is not None else 0
    if total > MAX_YAML_NODES:
        return (f"{total} values once aliases (*name) are expanded, more than the bound of {MAX_YAML_NODES} "
                f"for a scene file")
    return None
