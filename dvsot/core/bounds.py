"""Bounds on input and the checks every stage shares: file kinds, value ranges, sensor and preview sizes.

Every bound on what a file or a flag can make dvsot allocate lives here, so each error can name it.
"""

from __future__ import annotations

import os
import stat

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
