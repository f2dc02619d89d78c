"""The memory a simulation needs at once, estimated from its settings before any work, and the bound it must keep.

Sizes inside every other bound can still exhaust a machine's memory: an 8192x8192 sensor holds some 250 bytes of
simulator state per pixel, and hot pixels firing at 1e7 Hz put tens of millions of events into one interval between
frames, each about 150 bytes on its way through the simulator, the labeller and the writer. The constants below are
measured peaks (tracemalloc and the process's maximum resident size, dvsot 0.x on Linux), rounded up. A run whose
estimate exceeds MEMORY_FRACTION of the memory this process may use (physical memory, or a cgroup's limit when it
is lower) is refused with the estimate, before any frame is read or rendered.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from dvsot.core.errors import UserError

PIXEL_BYTES = 256  # simulator state per pixel: references, thresholds, sensor stages, one frame's log intensities
RENDER_PIXEL_BYTES = 96  # generate's extra per pixel: luma, masks and object ids of a render, Blender's buffers
EVENT_BYTES = 160  # one event of an interval: its columns, the sort and merge copies, the writer's chunk
BASE_BYTES = 300 << 20  # the interpreter, numpy, numba's compiled kernels, HDF5
MEMORY_FRACTION = 0.5  # of usable memory: the rest is the operating system's, the page cache's and other programs'


def usable_memory_bytes() -> int | None:
    """The memory this process may use: physical memory, or the cgroup (v2 or v1) limit when lower; None if unknown."""
    sizes = []
    try:
        sizes.append(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):
        pass
    for limit in ("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory/memory.limit_in_bytes"):
        try:
            text = Path(limit).read_text().strip()
        except OSError:
            continue
        if text.isdigit() and int(text) < 1 << 60:  # "max" or a huge number: no limit
            sizes.append(int(text))
    return min(sizes) if sizes else None


def noise_events(params: Any, width: int, height: int, interval_us: float) -> float:
    """The mean number of noise events (hot pixels, shot noise at its brightest, leak, photoreceptor noise) that
    EventParams `params` draw over a width x height sensor in one interval of interval_us microseconds."""
    pixels, seconds = width * height, interval_us * 1e-6
    hot = params.hot_pixel_fraction * pixels * params.hot_pixel_hz
    shot = params.shot_noise_hz * max(1.0, params.shot_noise_bright_factor) * pixels
    return (hot + shot + (params.leak_hz + params.photoreceptor_noise_hz) * pixels) * seconds


def peak_bytes(params: Any, width: int, height: int, interval_us: float, render: bool = False) -> int:
    """Estimated peak memory (bytes) of simulating a width x height sensor with frames interval_us apart at most."""
    per_pixel = PIXEL_BYTES + (RENDER_PIXEL_BYTES if render else 0)
    return int(BASE_BYTES + per_pixel * width * height + EVENT_BYTES * noise_events(params, width, height, interval_us))


def check_memory(params: Any, width: int, height: int, interval_us: float, what: str, render: bool = False) -> None:
    """UserError (one line, naming `what` and the estimate) if the run would need more than its share of memory;
    a noise rate over the simulator's own bound is refused first, in the simulator's words."""
    from dvsot.events.simulator import noise_rate_problem

    problem = noise_rate_problem(params, width, height, interval_us)
    if problem:
        raise UserError(problem)
    usable = usable_memory_bytes()
    if usable is None:
        return
    need, bound = peak_bytes(params, width, height, interval_us, render), MEMORY_FRACTION * usable
    if need <= bound:
        return
    events = noise_events(params, width, height, interval_us)
    gb = 1 << 30
    raise UserError(f"{what}: {width}x{height} px" + (f" and {events:.3g} noise events between frames "
                    f"{interval_us / 1000:g} ms apart" if events >= 1 else "")
                    + f" need about {need / gb:.1f} GB of memory at once, more than the bound of {bound / gb:.1f} GB "
                    f"({MEMORY_FRACTION:g} of this machine's {usable / gb:.1f} GB); lower the resolution or the "
                    "noise rates")
