"""Frame sources for `dvsot simulate`: image directories, video files and .npy stacks, as linear luma frames.

8-bit images are read as I/255 and 16-bit as I/65535 (ESIM reads 8-bit frames as I/255 too);
``srgb=True`` first undoes the sRGB transfer curve. Float images (EXR, .npy) are taken as linear
intensity. Colour becomes luma with Rec. 709 weights (applied after linearisation when asked).
Frames are produced lazily, one at a time.
"""

from __future__ import annotations

import os
import threading

os.environ.setdefault("OPENCV_IO_ENABLE_OPENEXR", "1")  # must be set before cv2 is imported
# AV_LOG_QUIET: ffmpeg's own notes on a bad video ("moov atom not found") would precede our one-line error.
# OpenCV reads this once, when it first opens a video, so it cannot be scoped like the log level below.
os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import cv2
import numpy as np

from dvsot.core.bounds import MAX_SENSOR_PIXELS, file_kind_problem
from dvsot.core.errors import UserError
from dvsot.events import CodedFrame, log_intensity
from dvsot.runtime.threads import read_ahead

IMAGE_SUFFIXES = {".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp", ".exr"}
VIDEO_SUFFIXES = {".mp4", ".avi", ".mov", ".mkv", ".webm", ".m4v", ".mpg", ".mpeg"}
_LUMA_BGR = np.array([0.0722, 0.7152, 0.2126], np.float32)  # Rec. 709, in OpenCV's B, G, R order


_quiet_lock = threading.Lock()
_quiet_depth = [0, 0]  # callers inside _quiet_opencv (from any thread), and the log level to restore


@contextmanager
def _quiet_opencv() -> Iterator[None]:
    """OpenCV logs errors only inside: its decoder warnings would precede our one-line error.

    The log level is process-wide and decoding threads overlap: the first to enter sets it, the last
    to leave restores it.
    """
    with _quiet_lock:
        if _quiet_depth[0] == 0:
            _quiet_depth[1] = cv2.getLogLevel()
            cv2.setLogLevel(2)  # LOG_LEVEL_ERROR
        _quiet_depth[0] += 1
    try:
        yield
    finally:
        with _quiet_lock:
            _quiet_depth[0] -= 1
            if _quiet_depth[0] == 0:
                cv2.setLogLevel(_quiet_depth[1])


def imread(path: Path) -> np.ndarray | None:
    """cv2.imread (any depth, channels kept) without OpenCV's warnings; None if the file cannot be decoded."""
    with _quiet_opencv():
        return cv2.imread(str(path), cv2.IMREAD_UNCHANGED)


_pillow_lock = threading.Lock()


def image_size(path: Path) -> tuple[int, int] | None:
    """(width, height) in pixels from an image file's header, its pixels not decoded (Pillow; OpenEXR for .exr);
    None when the header is not one they read (OpenCV's decoder then decides)."""
    try:
        if path.suffix.lower() == ".exr":
            import OpenEXR

            with OpenEXR.File(str(path), header_only=True) as f:
                return max(p.width() for p in f.parts), max(p.height() for p in f.parts)
        from PIL import Image

        with _pillow_lock:  # decoding threads call this too; Pillow's limit is one global
            limit, Image.MAX_IMAGE_PIXELS = Image.MAX_IMAGE_PIXELS, None  # the bound is ours: Pillow's hides the size
            try:
                with Image.open(path) as im:  # reads the header only
                    return im.size
            finally:
                Image.MAX_IMAGE_PIXELS = limit
    except Exception:  # not an image Pillow or OpenEXR knows, or a damaged header
        return None


def srgb_to_linear(v: np.ndarray) -> np.ndarray:
    """Undo the sRGB transfer curve on values in [0, 1]."""
    return np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4).astype(np.float32)


def to_linear_luma(img: np.ndarray, srgb: bool = False) -> np.ndarray:
    """An image as float32 linear luma: integer types scaled to [0, 1], colour (BGR[A]) weighted by Rec. 709."""
    if img.dtype == np.uint8:
        v = img.astype(np.float32) / 255.0
    elif img.dtype == np.uint16:
        v = img.astype(np.float32) / 65535.0
    elif img.dtype.kind == "f":
        v = img.astype(np.float32)
    else:
        raise UserError(f"unsupported pixel type {img.dtype}")
    if srgb:
        v = srgb_to_linear(np.clip(v, 0.0, 1.0))
    if v.ndim == 3:
        v = v[..., :3] @ _LUMA_BGR if v.shape[2] >= 3 else v[..., 0]
    return np.ascontiguousarray(v, dtype=np.float32)


@dataclass
class FrameSource:
    """A lazily read sequence of frames: count, size, native rate (fps, or None) and the frames themselves."""

    path: Path
    count: int
    width: int
    height: int
    fps: float | None
    srgb: bool = False

    def frames(self, workers: int = 2) -> Iterator[np.ndarray]:
        """Yield (height, width) float32 linear-luma frames in order, decoded up to a few frames ahead by threads."""
        if self.path.is_dir():
            yield from read_ahead(self._image, _image_files(self.path), workers=max(1, workers),
                                  ahead=2 * max(1, workers))
        elif self.path.suffix.lower() == ".npy":
            stack = np.load(self.path, mmap_mode="r")
            for i in range(stack.shape[0]):
                yield np.asarray(stack[i], dtype=np.float32)
        else:
            yield from self._video(ahead=workers > 0)

    def log_frames(self, log_eps: float, workers: int = 2, coded: bool = False) -> Iterator[np.ndarray | CodedFrame]:
        """Yield (height, width) float64 log intensities log(I + log_eps) of the frames, computed on decoding threads.

        Single-channel 8/16-bit images are looked up in a table of their 256/65536 values, which holds
        exactly what dvsot.events.log_intensity computes from the linear frame. With coded=True they come
        as CodedFrames instead (the decoded image and that table: the simulator reads a byte or two a pixel).
        """
        if self.path.is_dir():
            yield from read_ahead(lambda p: self._image(p, log_eps, coded), _image_files(self.path),
                                  workers=max(1, workers), ahead=2 * max(1, workers))
            return
        for i, frame in enumerate(self.frames(workers)):
            try:
                yield log_intensity(frame, log_eps).reshape(self.height, self.width)
            except UserError as exc:
                raise UserError(f"{self.path}: frame {i}: {exc}") from None

    def _image(self, p: Path, log_eps: float | None = None, coded: bool = False) -> np.ndarray | CodedFrame:
        """One image file as a linear-luma frame or as log intensities (on a decoding thread: OpenCV releases the
        GIL)."""
        size = image_size(p)  # the header first: a frame of another size is not decoded
        if size is not None and size != (self.width, self.height):
            raise UserError(f"{p}: image is {size[0]}x{size[1]}, the first was {self.width}x{self.height}")
        img = imread(p)
        if img is None:
            raise UserError(f"{p}: cannot read image")
        if img.shape[:2] != (self.height, self.width):
            raise UserError(f"{p}: image is {img.shape[1]}x{img.shape[0]}, the first was {self.width}x{self.height}")
        if log_eps is not None and img.ndim == 2 and img.dtype in (np.uint8, np.uint16):
            table = _log_table(img.dtype.str, log_eps, self.srgb)
            if coded:
                return CodedFrame(img, table)
            if img.dtype == np.uint8:  # OpenCV's table lookup: 3x numpy's take, and it releases the GIL
                return cv2.LUT(img, table.reshape(1, -1))
            return np.take(table, img)
        frame = to_linear_luma(img, self.srgb and img.dtype != np.float32)
        if log_eps is None:
            return frame
        try:
            return log_intensity(frame, log_eps).reshape(self.height, self.width)
        except UserError as exc:
            raise UserError(f"{p}: {exc}") from None

    def _video(self, ahead: bool) -> Iterator[np.ndarray]:
        cap = cv2.VideoCapture(str(self.path))

        def read(_: int) -> np.ndarray | None:  # one thread: the capture is read in order
            ok, img = cap.read()
            return to_linear_luma(img, self.srgb) if ok else None

        frames = read_ahead(read, range(self.count), workers=1, ahead=4) if ahead else map(read, range(self.count))
        try:
            for frame in frames:
                if frame is None:
                    break
                yield frame
        finally:
            if ahead:
                frames.close()  # waits for the read-ahead thread before the capture is released
            cap.release()


@lru_cache(maxsize=4)
def _log_table(dtype: str, log_eps: float, srgb: bool = False) -> np.ndarray:
    """log(I + log_eps) of every value of an 8- or 16-bit single-channel image, as log_intensity computes it."""
    values = np.arange(np.iinfo(np.dtype(dtype)).max + 1, dtype=np.dtype(dtype)).reshape(1, -1)
    return log_intensity(to_linear_luma(values, srgb), log_eps)


def _image_files(directory: Path) -> list[Path]:
    files = sorted(p for p in directory.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES)
    for p in files:
        kind = file_kind_problem(p)  # a FIFO named like an image would block the decoder
        if kind:
            raise UserError(f"{p}: {kind}, not an image file")
    return files


def open_frames(path: str | os.PathLike, srgb: bool = False) -> FrameSource:
    """Open a directory of images, a video file or a .npy (T, H, W) stack; bad input raises UserError."""
    p = Path(path)
    if not p.exists():
        raise UserError(f"{p}: no such file or directory")
    kind = None if p.is_dir() else file_kind_problem(p)  # before opening: a FIFO would block the readers
    if kind:
        raise UserError(f"{p}: {kind}, not an image directory, video or .npy file")
    if p.is_dir():
        files = _image_files(p)
        if not files:
            raise UserError(f"{p}: no images ({', '.join(sorted(IMAGE_SUFFIXES))}) in this directory")
        size = image_size(files[0])
        if size is not None and size[0] * size[1] > MAX_SENSOR_PIXELS:  # before decoding it
            raise UserError(f"{files[0]}: image of {size[0]}x{size[1]} pixels, more than the bound of "
                            f"{MAX_SENSOR_PIXELS} (8192x8192) for a frame")
        first = imread(files[0])
        if first is None:
            raise UserError(f"{files[0]}: cannot read image")
        h, w = first.shape[:2]
        return FrameSource(p, len(files), w, h, None, srgb)
    if p.suffix.lower() == ".npy":
        try:
            stack = np.load(p, mmap_mode="r")
        except (ValueError, OSError) as exc:
            raise UserError(f"{p}: not a readable .npy file ({exc})") from None
        if stack.ndim != 3 or stack.dtype.kind not in "fiu":
            raise UserError(f"{p}: expected a (T, H, W) array of real numbers, got {stack.dtype} {stack.shape}")
        if stack.shape[1] == 0 or stack.shape[2] == 0:
            raise UserError(f"{p}: frames are {stack.shape[2]}x{stack.shape[1]} pixels (shape {stack.shape})")
        return FrameSource(p, int(stack.shape[0]), int(stack.shape[2]), int(stack.shape[1]), None, srgb)
    if p.suffix.lower() in VIDEO_SUFFIXES:
        with _quiet_opencv():
            cap = cv2.VideoCapture(str(p))
        try:
            if not cap.isOpened():
                raise UserError(f"{p}: cannot open video")
            count = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
            w, h = int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
            fps = float(cap.get(cv2.CAP_PROP_FPS)) or None
        finally:
            cap.release()
        if count <= 0 or w <= 0 or h <= 0:
            raise UserError(f"{p}: video has no frames")
        return FrameSource(p, count, w, h, fps, srgb)
    raise UserError(f"{p}: not an image directory, a video ({', '.join(sorted(VIDEO_SUFFIXES))}) or a .npy stack")
