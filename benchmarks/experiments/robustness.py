"""ARscore per tracker against the sensor model: one sequence's kept frames re-simulated under presets and noise rates.

    python -m benchmarks.experiments.robustness SEQUENCE.h5 FRAMES_DIR --tracker rct [--tracker sctn ...]
        [--preset ideal --preset davis346 ...] [--noise-hz preset 0 1 5 ...] [--event-seed 1 2 3]
        [--picture-segment N] [--out DIR] [--max-segments N] [--jobs N]

FRAMES_DIR holds the sequence's rendered luma frames (`dvsot generate SCENE --keep-frames FRAMES_DIR`: one
NNNNNN.npy per render sample, linear intensity); SEQUENCE.h5 is the file that run wrote, whose /boxes hold
the sample times and the ground truth, and the digest of the frames it was rendered from (frames of another
sequence are refused before any work). Each variant (every --preset, default ideal, times every
--noise-hz, the shot-noise rate in events per pixel per second that overrides the preset's, or the word
`preset` for the preset's own; default: the preset's own; a value given twice is refused, and a rate is written
in NAME exactly, e.g. _noise0.1234561) re-simulates the frames into OUT/NAME.h5 with
each --event-seed (default: the sequence's own event seed; with several, NAME ends in _seedN), and every
tracker runs on every variant (AR protocol). Written to OUT (default runs/robustness-<name>):
robustness.csv (one row per variant and seed: preset, seed, set and measured noise rate, events, A, R,
ARscore per tracker), robustness.md (per variant: ARscore per tracker, the mean and the sample standard
deviation over the seeds when there are several), robustness.png (ARscore per tracker against the measured
noise rate, one marker per preset, bars of one standard deviation over seeds) and, with
--picture-segment N, segment.png: that segment's events under every variant of the first seed side by side.
OUT holds one run's files: they are staged and renamed into place together at the end with run.json (the
run's manifest), the previous run's files that this one does not write removed in the same commit; an
interrupted or failed run leaves OUT as it was, and an OUT that holds other files is refused before any work.
"""

from __future__ import annotations

import argparse
import csv
import sys
import time
from pathlib import Path

import numpy as np

MANIFEST = "run.json"  # the run's manifest in OUT (dvsot.runtime.outputs): its files' sizes and SHA-256, written last
TABLE_FILES = ("robustness.csv", "robustness.md", "robustness.png")
PICTURE_FILE = "segment.png"


def resimulate(sequence: str | Path, frames_dir: str | Path, output: str | Path, values: dict,
               seed: int | None = None) -> dict:
    """The kept frames of a sequence through the simulator with EventParams values into a new dataset file (same
    times and boxes; the sequence's event seed unless `seed` is given); {events, noise_events, noise_hz
    (measured, per pixel per second), duration_s, seed}."""
    from dvsot.core.errors import UserError
    from dvsot.dataset import Dataset
    from dvsot.events import EventParams, EventSimulator
    from dvsot.pipeline.kept_frames import DIGEST_ATTR as KEPT_DIGEST_ATTR
    from dvsot.pipeline.kept_frames import FrameDigest, frames_problem, load_frame
    from dvsot.pipeline.sequence import write_sequence
    from dvsot.runtime.outputs import readable

    with Dataset(sequence) as ds:
        track, attrs = ds.boxes(), dict(ds.attrs)
        width, height, segment_us, duration_us = ds.width, ds.height, ds.segment_us, ds.duration_us
    files = kept_frames(sequence, frames_dir, len(track.t))
    recorded = attrs.get(KEPT_DIGEST_ATTR)
    params = EventParams.parse(values, "robustness variant")
    if seed is None:
        seed = int(attrs.get("event_seed", attrs.get("seed", 0)))
    from dvsot.events.memory import check_memory

    check_memory(params, width, height, float(np.diff(track.t).max()) if len(track.t) > 1 else 0.0, str(sequence))
    sim = EventSimulator(width, height, params, seed)
    out_attrs = {"name": attrs.get("name", Path(sequence).stem), "split": attrs.get("split", ""),
                 "source": str(frames_dir), "simulator": params.model_dump(), "event_seed": seed,
                 "generator": "benchmarks.experiments.robustness"}
    digest = FrameDigest()

    def frames():
        """Each kept frame in turn; at the end, UserError unless they are the frames the sequence recorded."""
        for f in files:
            frame = load_frame(f)
            digest.update(frame)
            yield frame
        if recorded is not None and digest.hexdigest() != recorded:  # before the file is renamed into place
            raise UserError(f"{frames_dir}: {frames_problem(files, recorded)} of {sequence}")

    path, counts = write_sequence(output, frames(), track.t, sim, out_attrs, segment_us, source=str(frames_dir),
                                  boxes=lambda: (track.t, track.xywh, track.xywh_visible))
    noise = 0
    with Dataset(readable(path)) as ds:  # inside a run: the staged file, renamed into place at the run's end
        for batch in ds.chunks():
            noise += 0 if batch.signal is None else int(np.count_nonzero(~batch.signal))
    seconds = max(int(track.t[-1]) + 1, duration_us) / 1e6
    return {"events": counts.events, "noise_events": noise, "noise_hz": noise / (width * height) / seconds,
            "duration_s": seconds, "seed": seed}


def check_frames(sequence: str | Path, frames_dir: str | Path) -> list[Path]:
    """The kept frames of a sequence, checked before any work: one per render sample, each a numeric frame, and
    together the frames whose digest the sequence recorded (files written before the digest: not checkable)."""
    from dvsot.core.errors import UserError
    from dvsot.dataset import Dataset
    from dvsot.pipeline.kept_frames import DIGEST_ATTR as KEPT_DIGEST_ATTR
    from dvsot.pipeline.kept_frames import frames_problem

    with Dataset(sequence) as ds:
        samples, recorded = len(ds.boxes().t), ds.attrs.get(KEPT_DIGEST_ATTR)
    files = kept_frames(sequence, frames_dir, samples)
    if recorded is not None and not isinstance(recorded, str):
        raise UserError(f"{sequence}: root attribute '{KEPT_DIGEST_ATTR}' is {type(recorded).__name__}, "
                        "expected a SHA-256 as text")
    problem = frames_problem(files, recorded)
    if problem:
        raise UserError(f"{frames_dir}: {problem} of {sequence}")
    return files


def kept_frames(sequence: str | Path, frames_dir: str | Path, samples: int | None = None) -> list[Path]:
    """The kept frames of a sequence (FRAMES_DIR/NNNNNN.npy, in order); UserError unless there is one per render
    sample of the sequence (`samples`, else read from its /boxes)."""
    from dvsot.core.bounds import file_kind_problem
    from dvsot.core.errors import UserError

    problem = file_kind_problem(frames_dir)
    if problem != "is a directory":
        what = "no such directory" if problem == "no such file" else problem or "is a file"
        raise UserError(f"{frames_dir}: {what}, not the directory of kept frames")

    if samples is None:
        from dvsot.dataset import Dataset

        with Dataset(sequence) as ds:
            samples = len(ds.boxes().t)
    from dvsot.runtime.inputs import regular_input

    files = [regular_input(f, "a kept frame") for f in sorted(Path(frames_dir).glob("*.npy"))]  # a FIFO: no wait
    if len(files) != samples:
        raise UserError(f"{frames_dir}: {len(files)} frames (.npy), but {sequence} has {samples} render samples")
    return files


def exact_number(value: float) -> str:
    """A float as short text that reads back as the same float ('200', '0.1234561', '1e-07'), for names."""
    short = f"{value:g}"
    return short if float(short) == value else repr(float(value))


def variant_name(preset: str, rate: float | None) -> str:
    """A variant's name: the preset, with _noiseR when a shot-noise rate overrides the preset's (R exact)."""
    return preset if rate is None else f"{preset}_noise{exact_number(rate)}"


def _no_repeats(flag: str, values: list | None) -> None:
    """UserError naming the flag if a value is given twice: two variants would be one file and one table row."""
    from dvsot.core.errors import UserError

    seen = set()
    for v in values or []:
        if v in seen:
            shown = "preset" if v is None else v if isinstance(v, str) else exact_number(v) if isinstance(v, float) \
                else str(v)
            raise UserError(f"{flag}: {shown} is given twice; each variant is run once")
        seen.add(v)


def variants(presets: list[str], noise_hz: list[float | None] | None,
             seeds: list[int] | None) -> list[tuple[str, str, float | None, int | None, str]]:
    """(variant name, preset, noise rate or None, seed or None, file name) for every variant and seed, in sweep
    order."""
    from dvsot.core.errors import UserError

    for flag, values in (("--preset", presets), ("--noise-hz", noise_hz), ("--event-seed", seeds)):
        _no_repeats(flag, values)
    out = []
    for preset in presets:
        for rate in (noise_hz if noise_hz else [None]):
            name = variant_name(preset, rate)
            for seed in (seeds if seeds else [None]):
                out.append((name, preset, rate, seed,
                            f"{name}.h5" if seed is None or len(seeds) == 1 else f"{name}_seed{seed}.h5"))
    files: dict[str, str] = {}
    for _, _, _, _, file_name in out:  # names differ in case only: one file on a case-folding disk
        other = files.setdefault(file_name.casefold(), file_name)
        if other != file_name or sum(v[-1] == file_name for v in out) > 1:
            raise UserError(f"variants {other!r} and {file_name!r} would write one file; give each variant once")
    return out


def output_names(presets: list[str], noise_hz: list[float | None] | None, seeds: list[int] | None,
                 picture: bool) -> list[str]:
    """Every file a run writes in OUT: the variants' dataset files, the tables, the picture if asked, the manifest."""
    return ([v[-1] for v in variants(presets, noise_hz, seeds)] + list(TABLE_FILES)
            + ([PICTURE_FILE] if picture else []) + [MANIFEST])


def sweep(sequence: str | Path, frames_dir: str | Path, trackers: list[str], presets: list[str],
          noise_hz: list[float | None] | None, out_dir: str | Path, max_segments: int | None = None,
          jobs: int = 1, seeds: list[int] | None = None) -> list[dict]:
    """Every (preset, noise rate, seed) variant re-simulated and tracked; one row each (see the module docstring).
    A noise rate of None keeps the preset's own; seeds None: the sequence's own event seed."""
    from benchmarks.evaluation.metrics import scores
    from benchmarks.evaluation.runner import benchmark
    from dvsot.events import EventParams
    from dvsot.runtime.outputs import readable

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    rows = []
    for name, preset, rate, seed, file_name in variants(presets, noise_hz, seeds):
        values = {"preset": preset} if rate is None else {"preset": preset, "shot_noise_hz": rate}
        file = out_dir / file_name
        stats = resimulate(sequence, frames_dir, file, values, seed)
        row = {"variant": name, "preset": preset, "seed": stats["seed"], "file": file.name,
               "set_shot_noise_hz": EventParams.parse(values, "robustness variant").shot_noise_hz,
               "measured_noise_hz": round(stats["noise_hz"], 4), "events": stats["events"]}
        for result in benchmark(trackers, [readable(file)], jobs=jobs, max_segments=max_segments):
            s = scores(result.iou)
            row[f"{result.tracker}_A"] = round(s.accuracy, 4)
            row[f"{result.tracker}_R"] = round(s.robustness, 4)
            row[f"{result.tracker}_ARscore"] = round(s.arscore, 4)
            if result.error:
                row[f"{result.tracker}_error"] = result.error
        rows.append(row)
    return rows


def run(sequence: str | Path, frames_dir: str | Path, trackers: list[str], presets: list[str],
        noise_hz: list[float | None] | None, out_dir: str | Path, max_segments: int | None = None, jobs: int = 1,
        seeds: list[int] | None = None, picture_segment: int | None = None) -> list[dict]:
    """A whole sweep into out_dir as one run (see the module docstring): OUT checked first (UserError if it holds
    other files), every file staged, all renamed into place together with the manifest at the end; the rows."""
    from dvsot.runtime.outputs import owned_run, readable

    out = Path(out_dir)
    output_names(presets, noise_hz, seeds, picture_segment is not None)  # repeated variants: refused before work
    check_frames(sequence, frames_dir)
    with owned_run(out, "--out", output_names(presets, noise_hz, seeds, picture_segment is not None), MANIFEST):
        rows = sweep(sequence, frames_dir, trackers, presets, noise_hz, out, max_segments, jobs, seeds)
        write_outputs(rows, trackers, out, Path(sequence).stem)
        if picture_segment is not None:
            first = {}
            for row in rows:
                first.setdefault(row["variant"], readable(out / row["file"]))
            picture(first, picture_segment, out / PICTURE_FILE, f"{Path(sequence).stem}, segment {picture_segment}")
    return rows


def check_segment(sequence: str | Path, segment: int, flag: str) -> None:
    """UserError naming the flag unless `segment` is a segment of the dataset file `sequence`."""
    from dvsot.core.errors import UserError
    from dvsot.dataset import Dataset

    with Dataset(sequence) as ds:
        if not 0 <= segment < ds.num_segments:
            raise UserError(f"{flag}: {segment} is not a segment of {sequence} (0..{ds.num_segments - 1})")


def picture(files: dict[str, Path], segment: int, out_png: Path, title: str) -> Path:
    """One segment's events in each of the files side by side ({panel label: dataset file}); UserError if a file
    does not have that segment or the files' sensors differ."""
    from benchmarks.analysis.pictures import plot_segment_side_by_side
    from dvsot.core.errors import UserError

    try:
        return plot_segment_side_by_side(files, segment, out_png, title=title)
    except ValueError as exc:
        raise UserError(str(exc)) from None


def summarise(rows: list[dict], trackers: list[str]) -> list[dict]:
    """One row per variant, in first-seen order: seeds, mean measured noise rate and events, and per tracker the
    mean ARscore and its sample standard deviation over the variant's seeds (NaN with one seed)."""
    out = []
    for name in dict.fromkeys(r["variant"] for r in rows):
        group = [r for r in rows if r["variant"] == name]
        row = {"variant": name, "preset": group[0]["preset"], "seeds": len(group),
               "set_shot_noise_hz": group[0]["set_shot_noise_hz"],
               "measured_noise_hz": float(np.mean([r["measured_noise_hz"] for r in group])),
               "events": float(np.mean([r["events"] for r in group]))}
        for t in trackers:
            values = np.array([r.get(f"{t}_ARscore", np.nan) for r in group], float)
            row[f"{t}_ARscore"] = float(np.mean(values))
            row[f"{t}_ARscore_std"] = float(np.std(values, ddof=1)) if len(values) > 1 else float("nan")
        out.append(row)
    return out


def write_outputs(rows: list[dict], trackers: list[str], out_dir: Path, title: str) -> None:
    """robustness.csv (every row), robustness.md and robustness.png (per variant, over its seeds) in out_dir."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from benchmarks.analysis.pictures import save_figure
    from dvsot.runtime.outputs import replacing

    out_dir = Path(out_dir)
    keys = list(dict.fromkeys(k for row in rows for k in row))
    with replacing(out_dir / "robustness.csv") as tmp, open(tmp, "w", newline="") as f:
        w = csv.DictWriter(f, keys)
        w.writeheader()
        w.writerows(rows)
    summary = summarise(rows, trackers)
    several = any(r["seeds"] > 1 for r in summary)
    head = ["variant", "set shot noise, Hz", "measured noise, Hz/px", "events"] + [f"{t} ARscore" for t in trackers]
    if several:
        head.insert(1, "seeds")
    lines = [f"# Robustness: {title}", "", "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for row in summary:
        cells = [row["variant"], f"{row['set_shot_noise_hz']:g}", f"{row['measured_noise_hz']:.4g}",
                 f"{row['events']:,.0f}"]
        for t in trackers:
            mean, std = row[f"{t}_ARscore"], row[f"{t}_ARscore_std"]
            cells.append(f"{mean:.3f} ± {std:.3f}" if several and np.isfinite(std) else f"{mean:.3f}")
        if several:
            cells.insert(1, str(row["seeds"]))
        lines.append("| " + " | ".join(cells) + " |")
    if several:
        lines += ["", "ARscore: mean ± sample standard deviation over the event seeds."]
    with replacing(out_dir / "robustness.md") as tmp:
        Path(tmp).write_text("\n".join(lines) + "\n")
    fig, ax = plt.subplots(figsize=(6.4, 4))
    markers = dict(zip(dict.fromkeys(r["preset"] for r in summary), "osD^v<>ph*"))
    colours = plt.get_cmap("tab10")
    for k, t in enumerate(trackers):
        for preset, marker in markers.items():
            pts = sorted((r["measured_noise_hz"], r[f"{t}_ARscore"], r[f"{t}_ARscore_std"])
                         for r in summary if r["preset"] == preset)
            ax.errorbar([p[0] for p in pts], [p[1] for p in pts], yerr=[np.nan_to_num(p[2]) for p in pts],
                        marker=marker, color=colours(k % 10), capsize=2, lw=1, label=f"{t} ({preset})")
    ax.set_xscale("symlog", linthresh=0.1)
    ax.set_xlabel("noise events per pixel per second (measured)")
    ax.set_ylabel("ARscore")
    ax.set_title(title)
    ax.legend(fontsize=6, ncol=len(trackers))
    ax.grid(alpha=0.3)
    fig.tight_layout()
    save_figure(fig, out_dir / "robustness.png", dpi=100)


def noise_rate(text: str) -> float | None:
    """A --noise-hz value: a rate in events per pixel per second (>= 0), or `preset` (None: the preset's own)."""
    if text == "preset":
        return None
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"{text!r} is neither a rate (events per pixel per second) nor 'preset'"
        ) from None
    if not 0 <= value < float("inf"):
        raise argparse.ArgumentTypeError(f"{text}: a shot-noise rate is finite and >= 0 events per pixel per second")
    return value


def event_seed(text: str) -> int:
    """An --event-seed value: an integer 0..2**63-1."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer seed") from None
    if not 0 <= value < 2**63:
        raise argparse.ArgumentTypeError(f"{text}: an event seed lies in 0..2**63-1")
    return value


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("sequence", help="the dataset file `dvsot generate --keep-frames` wrote")
    parser.add_argument("frames", help="the kept frames directory (NNNNNN.npy per render sample)")
    parser.add_argument("--tracker", action="append", required=True)
    parser.add_argument("--preset", action="append", default=[], help="sensor preset (repeatable; default ideal)")
    parser.add_argument("--noise-hz", type=noise_rate, nargs="+",
                        help="shot-noise rates, events per pixel per second, or 'preset' for the preset's own")
    parser.add_argument("--event-seed", type=event_seed, nargs="+", help="event seeds (default: the sequence's own)")
    parser.add_argument("--picture-segment", type=int, help="also write segment.png: this segment under every variant")
    parser.add_argument("--out", help="output directory (default runs/robustness-<name>-<time>)")
    parser.add_argument("--max-segments", type=int)
    parser.add_argument("--jobs", type=int, default=1)
    args = parser.parse_args()
    status = _guarded(lambda: _main(args))
    if status:
        raise SystemExit(status)


def _main(args: argparse.Namespace) -> None:
    """The sweep the parsed flags ask for, its table printed."""
    if args.picture_segment is not None:  # checked before the sweep: a bad segment wastes no run
        check_segment(args.sequence, args.picture_segment, "--picture-segment")
    out = Path(args.out or f"runs/robustness-{Path(args.sequence).stem}-{time.strftime('%Y%m%d-%H%M%S')}")
    run(args.sequence, args.frames, args.tracker, args.preset or ["ideal"], args.noise_hz, out,
        args.max_segments, args.jobs, args.event_seed, args.picture_segment)
    print((out / "robustness.md").read_text())


def _guarded(work) -> int:
    """Run work() as dvsot's commands run: bad input one line and 2, a refused write one line and 1, SIGINT and
    SIGTERM one line and 128 + the signal (the run's staged files removed as the exception unwinds), a signal
    after the final renames reported as such with the run's own status."""
    import signal

    from dvsot.core.errors import RunError, UserError
    from dvsot.runtime import interrupts
    from dvsot.runtime.outputs import disk_error

    prog = "benchmarks.experiments.robustness"
    saved = interrupts.install()
    interrupted = False
    try:
        work()
        if interrupts.late():
            print(f"{prog}: done; {signal.Signals(interrupts.late()).name} arrived after its outputs were written",
                  file=sys.stderr)
        return 0
    except UserError as exc:
        print(f"{prog}: error: {exc}", file=sys.stderr)
        return 2
    except RunError as exc:
        print(f"{prog}: failed: {exc}", file=sys.stderr)
        return 1
    except (OSError, RuntimeError) as exc:  # h5py words a full disk as a RuntimeError
        reason = disk_error(exc)
        if reason is None:
            raise
        print(f"{prog}: failed: {getattr(exc, 'filename', None) or 'an output'}: cannot write ({reason}); "
              "nothing was replaced",
              file=sys.stderr)
        return 1
    except BaseException as caught:
        status = None if isinstance(caught, SystemExit) else interrupts.stopped_status(caught, prog)
        if status is None:
            raise
        interrupted = True
        return status
    finally:
        interrupts.restore(saved)
        if interrupted:
            interrupts.quiet_exit()


if __name__ == "__main__":
    main()
