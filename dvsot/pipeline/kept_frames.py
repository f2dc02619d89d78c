"""The digest of a sequence's kept frames (`dvsot generate --keep-frames`), recorded in its dataset file.

A tool that re-simulates a sequence from its kept frames (benchmarks.experiments.robustness) checks the frames
it is given against this digest, so another sequence's frames of the same count are not scored against these
boxes. The digest covers each frame's dtype, shape and values in render order, not the .npy container.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

import numpy as np

from dvsot.core.errors import UserError

DIGEST_ATTR = "kept_frames_sha256"  # root attribute of a dataset file whose frames were kept


class FrameDigest:
    """SHA-256 over frames in order: each frame's dtype, shape and C-order bytes."""

    def __init__(self) -> None:
        self._h = hashlib.sha256()

    def update(self, frame: np.ndarray) -> None:
        """Add the next frame (any numeric array)."""
        a = np.ascontiguousarray(frame)
        self._h.update(f"{a.dtype.str}{a.shape}".encode("ascii"))
        self._h.update(a.tobytes())

    def hexdigest(self) -> str:
        """The digest of the frames added so far (hex)."""
        return self._h.hexdigest()


def load_frame(path: str | os.PathLike) -> np.ndarray:
    """One kept frame (.npy of real numbers, 2-D luma); UserError naming the file otherwise (no pickled objects)."""
    from dvsot.core.bounds import file_kind_problem

    p = Path(path)
    problem = file_kind_problem(p)
    if problem:
        raise UserError(f"{p}: {problem}")
    try:
        a = np.load(p, allow_pickle=False)
    except (ValueError, OSError, EOFError) as exc:
        raise UserError(f"{p}: not a numeric .npy frame ({' '.join(str(exc).split()) or type(exc).__name__})") from None
    if a.dtype.kind not in "biuf" or a.ndim != 2:
        raise UserError(f"{p}: a kept frame is a 2-D array of real numbers, got {a.dtype} of shape {a.shape}")
    return a


def frames_problem(files: list[Path], recorded: str | None) -> str | None:
    """Why the frame files are not the frames whose digest is `recorded` (one line), or None (also with none
    recorded)."""
    if recorded is None:
        return None
    digest = FrameDigest()
    for f in files:
        digest.update(load_frame(f))
    if digest.hexdigest() != recorded:
        return (f"these {len(files)} frames are not the ones this sequence was rendered from (their SHA-256 differs "
                f"from root attribute '{DIGEST_ATTR}')")
    return None
