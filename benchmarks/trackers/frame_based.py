"""Frame-based baselines: each segment becomes an ATSLTD frame (paper eq. 11), then an OpenCV tracker runs.

The paper compares SCTN with Siamese-network trackers (SiamRPN, SiamMask, Ocean, AutoMatch, GOTURN) run
on ATSLTD frames. Their weights cannot be downloaded here, so OpenCV's conventional trackers stand in
for them: `csrt` (discriminative correlation filter with channel and spatial reliability),
`kcf` (kernelised correlation filter) and `mil` (multiple-instance learning), all with OpenCV's
default parameters (opencv-contrib 4.11, `cv2.TrackerCSRT_create` etc.).

Per segment: frame = ATSLTD of the segment's events (3 channels, divisor = the segment's length);
`init` initialises the OpenCV tracker with the ground-truth box on the init segment's frame;
`update` returns the tracker's box, or the previous box when the tracker reports a loss.

OpenCV's trackers draw from process-wide random state: MIL picks its Haar features with the C library's `rand()`,
and `cv::theRNG()` is shared by everything in a thread. Every `init` seeds both (`OPENCV_SEED`), so a result depends
on the sequence alone, not on which trackers ran before in the same worker.
"""

from __future__ import annotations

import ctypes
import threading
from collections.abc import Callable

import cv2
import numpy as np

from benchmarks.trackers import register
from benchmarks.trackers.atsltd import atsltd_frame_bgr
from benchmarks.trackers.base import Tracker
from dvsot.dataset import Segment

OPENCV_SEED = 0  # the seed of the random state every OpenCV tracker starts from at each (re-)initialisation
_LIBC = ctypes.CDLL(None)  # the process's C library: the rand() OpenCV's MIL calls
_SEEDED_INIT = threading.Lock()  # rand() is one state per process: seeding and drawing from it are not interleaved


def reseed_opencv(seed: int = OPENCV_SEED) -> None:
    """Seed the random state OpenCV's trackers draw from: the C library's rand() and this thread's cv::theRNG()."""
    _LIBC.srand(ctypes.c_uint(seed))
    cv2.setRNGSeed(seed)


def _opencv_rect(box_xywh: np.ndarray, width: int, height: int) -> tuple[int, int, int, int]:
    """An integer (x, y, w, h) rectangle inside the image for OpenCV, from a float xywh box (pixels)."""
    x0, y0, w, h = (float(v) for v in box_xywh)
    x1, y1 = x0 + w, y0 + h
    x0, y0 = max(0.0, x0), max(0.0, y0)
    x1, y1 = min(float(width), x1), min(float(height), y1)
    ix0, iy0 = int(np.floor(x0)), int(np.floor(y0))
    ix0, iy0 = min(ix0, width - 1), min(iy0, height - 1)
    iw = max(1, int(np.ceil(x1)) - ix0)
    ih = max(1, int(np.ceil(y1)) - iy0)
    return ix0, iy0, min(iw, width - ix0), min(ih, height - iy0)


class OpenCVFrameTracker(Tracker):
    """An OpenCV single-object tracker on ATSLTD frames; subclasses name the OpenCV factory."""

    name = "opencv"
    factory: Callable[[], object] | None = None

    def __init__(self) -> None:
        self._tracker = None
        self._box = np.full(4, np.nan, np.float32)
        self._width = 0
        self._height = 0

    def _frame(self, segment: Segment) -> np.ndarray:
        window = max(1, int(segment.t1_us) - int(segment.t0_us))
        return atsltd_frame_bgr(segment.events, self._width, self._height, window)

    def init(self, segment: Segment, box_xywh: np.ndarray, width: int, height: int) -> None:
        """Start tracking box_xywh (pixels) on the ATSLTD frame of the init segment."""
        box = np.asarray(box_xywh, dtype=np.float32).reshape(4)
        if not np.all(np.isfinite(box)) or box[2] <= 0 or box[3] <= 0:
            raise ValueError(f"{self.name}: cannot initialise on an absent or empty box {box.tolist()}")
        self._width, self._height = int(width), int(height)
        frame = self._frame(segment)
        with _SEEDED_INIT:
            reseed_opencv()
            self._tracker = type(self).factory()
            self._tracker.init(frame, _opencv_rect(box, self._width, self._height))
        self._box = box.copy()

    def update(self, segment: Segment) -> np.ndarray:
        """The box (xywh pixels) at the end of this segment; the previous box if OpenCV reports a loss."""
        if self._tracker is None:
            raise RuntimeError(f"{self.name}: update() before init()")
        ok, rect = self._tracker.update(self._frame(segment))
        if ok:
            candidate = np.asarray(rect, dtype=np.float32).reshape(4)
            if np.all(np.isfinite(candidate)) and candidate[2] > 0 and candidate[3] > 0:
                self._box = candidate
        return self._box.copy()


@register("csrt")
class CSRTTracker(OpenCVFrameTracker):
    """OpenCV CSRT on ATSLTD frames."""

    name = "csrt"
    factory = staticmethod(cv2.TrackerCSRT_create)


@register("kcf")
class KCFTracker(OpenCVFrameTracker):
    """OpenCV KCF on ATSLTD frames."""

    name = "kcf"
    factory = staticmethod(cv2.TrackerKCF_create)


@register("mil")
class MILTracker(OpenCVFrameTracker):
    """OpenCV MIL on ATSLTD frames."""

    name = "mil"
    factory = staticmethod(cv2.TrackerMIL_create)
