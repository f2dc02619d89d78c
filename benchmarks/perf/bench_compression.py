"""Size and read speed of dataset files with gzip level 1 against LZF (and no compression); print a table.

    python -m benchmarks.perf.bench_compression [FILE.h5 ...] [--repeat 3]

Each file (default: data/dvsot21/*.h5) is rewritten into a temporary directory once per compression
with dvsot's own writer (same events, boxes and chunking), then read back best of `--repeat` times in
two ways (and the rewrite timed, which includes reading the source): every event column whole (a full scan, what
`dvsot info` does) and every 10 ms segment in order (what bench and train do). Sizes are whole files in MB (10^6 bytes).
"""

from __future__ import annotations

import argparse
import glob
import tempfile
import time
from pathlib import Path

from dvsot.core.errors import UserError
from dvsot.dataset import COMPRESSIONS, Dataset, DatasetWriter


def rewrite(src: Path, dst: Path, compression: str | None) -> None:
    """Copy the events and box track of `src` into a new file `dst` written with `compression`."""
    with Dataset(src) as ds, DatasetWriter(dst, ds.width, ds.height, ds.segment_us, compression=compression,
                                           t_offset_us=ds.t_offset_us) as w:
        for batch in ds.chunks():
            w.append_events(batch)
        track = ds.boxes()
        w.append_boxes(track.t, track.xywh, track.xywh_visible)
        w.close(ds.duration_us)


def best_of(repeat: int, fn) -> float:
    """The shortest wall time (seconds) of `repeat` calls of fn."""
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return min(times)


def full_scan(path: Path) -> None:
    with Dataset(path) as ds:
        for _ in ds.chunks():
            pass


def segment_scan(path: Path) -> None:
    with Dataset(path) as ds:
        for _ in ds.segments():
            pass


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("files", nargs="*")
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    files = [Path(f) for f in (args.files or sorted(glob.glob("data/dvsot21/*.h5")))]
    if not files:
        raise SystemExit("no dataset files (give some, or render data/dvsot21 first)")
    names = [c for c in COMPRESSIONS if c is not None] + [None]
    print("| file | events | compression | size MB | rewrite s | full scan s | all segments s |")
    print("|---|---|---|---|---|---|---|")
    totals = {c: 0 for c in names}
    with tempfile.TemporaryDirectory(prefix="dvsot-compression-") as tmp:
        for src in files:
            with Dataset(src) as ds:
                n = ds.num_events
            for c in names:
                dst = Path(tmp) / f"{c}-{src.name}"
                start = time.perf_counter()
                try:
                    rewrite(src, dst, c)
                except UserError as exc:  # a damaged source: say so and go on with the others
                    print(f"| {src.stem} | {n:,} | skipped: {exc} |||||", flush=True)
                    break
                wrote = time.perf_counter() - start
                size = dst.stat().st_size
                totals[c] += size
                full, seg = (
                    best_of(args.repeat, lambda dst=dst: full_scan(dst)),
                    best_of(args.repeat, lambda dst=dst: segment_scan(dst)),
                )
                print(
                    f"| {src.stem} | {n:,} | {c or 'none'} | {size / 1e6:.2f} | {wrote:.3f} | {full:.3f} | {seg:.3f} |",
                    flush=True,
                )
                dst.unlink()
    print()
    print("total MB: " + ", ".join(f"{c or 'none'} {totals[c] / 1e6:.2f}" for c in names))


if __name__ == "__main__":
    main()
