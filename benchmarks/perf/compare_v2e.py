"""dvsot's sensor model beside v2e's emulator on the same frames with matched parameters; print JSON figures.

    python -m benchmarks.perf.compare_v2e --v2e-python PY --v2e-src DIR [--width 160 --height 120 --frames 100]

v2e (SensorsINI/v2e, its v2ecore.emulator.EventEmulator) runs in its own Python (PY, a venv with torch,
outside this repository) with its source DIR first on the path; this script runs its own file there with
--v2e-side. Both get the same 8-bit frames (DN 25-240, so v2e's lin-log is in its log part) and times:

- totals: a random texture drifting 0.5 px a frame at 1 kHz, thresholds 0.2/0.2, no mismatch, no noise;
  once without and once with a 100 Hz low-pass (dvsot: lowpass_order 1, dark_intensity 20/255: v2e's
  inten01 = (DN + 20) / 275). Printed: events, ON fraction, and dvsot's ratio to v2e (goal: within 5 %).
- noise: static uniform frames at three intensities, shot noise 5 Hz with v2e's intensity factor 0.25
  (dvsot: shot_noise_bright_factor 0.25), 0.5 s at 1 kHz. Every event is noise; printed: each side's rate
  per pixel against the set rate 5 * ((0.25 - 1) * inten01 + 1) Hz (goal: within 5 %).
- step: uniform frames stepping up by 3x at three intensities, 100 Hz low-pass, frames every 100 us;
  printed: the time of each ON event after the step (microseconds), v2e's and dvsot's, and the largest
  difference (goal: within one frame interval). v2e stamps an interval's only event at its end, dvsot
  at the interpolated crossing, so dvsot's are earlier by up to one interval.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

SHOT_HZ, SHOT_FACTOR, CUTOFF_HZ, DARK = 5.0, 0.25, 100.0, 20.0 / 255.0
NOISE_DN = (30, 120, 240)
STEP_DN = (25, 60, 80)


def _v2e_side(spec_path: str) -> None:
    """Run v2e's EventEmulator on every experiment of the spec (in v2e's Python); events saved as (t s, x, y, p)."""
    import logging

    from v2ecore.emulator import EventEmulator

    logging.disable(logging.WARNING)
    spec = json.loads(Path(spec_path).read_text())
    data = np.load(spec["frames"])
    out = {}
    for name, kw in spec["v2e"].items():
        emu = EventEmulator(device="cpu", seed=1, output_folder=None, **kw)
        parts = []
        for frame, t in zip(data[name], data[name + "_t"]):
            ev = emu.generate_events(frame, float(t))
            if ev is not None and len(ev):
                parts.append(np.asarray(ev, np.float64))
        out[name] = np.concatenate(parts) if parts else np.zeros((0, 4))
    np.savez(spec["out"], **out)


def inputs(width: int, height: int, n_frames: int) -> tuple[dict, dict, dict]:
    """(frames and times in seconds by experiment, v2e's parameters, dvsot's EventParams values)."""
    rng = np.random.default_rng(5)
    tex = rng.uniform(0, 1, (height // 4 + 2, width // 4 + n_frames // 8 + 3))
    tex = np.kron(tex, np.ones((4, 4)))  # 4-px blocks, drifting half a pixel a frame (interpolated)
    frames, v2e, dvs = {}, {}, {}
    x = np.arange(width)
    drift = []
    for k in range(n_frames):
        s = 0.5 * k
        i, f = int(s), s - int(s)
        img = (1 - f) * tex[:height, i + x] + f * tex[:height, i + 1 + x]
        drift.append(np.rint(25 + 215 * img).astype(np.uint8))
    ideal_v2e = dict(pos_thres=0.2, neg_thres=0.2, sigma_thres=0.0, cutoff_hz=0.0, leak_rate_hz=0.0,
                     shot_noise_rate_hz=0.0, refractory_period_s=0.0)
    ideal_dvs = dict(cp=0.2, cn=0.2, log_eps=1e-6)
    for name, cutoff in (("totals", 0.0), ("totals_lowpass", CUTOFF_HZ)):
        frames[name], frames[name + "_t"] = np.stack(drift), np.arange(n_frames) * 1e-3
        v2e[name] = {**ideal_v2e, "cutoff_hz": cutoff}
        dvs[name] = {**ideal_dvs, **(dict(lowpass_order=1, lowpass_cutoff_hz=cutoff, dark_intensity=DARK)
                                     if cutoff else {})}
    for dn in NOISE_DN:
        name = f"noise_{dn}"
        frames[name], frames[name + "_t"] = np.full((501, 64, 64), dn, np.uint8), np.arange(501) * 1e-3
        v2e[name] = {**ideal_v2e, "shot_noise_rate_hz": SHOT_HZ}
        dvs[name] = {**ideal_dvs, "shot_noise_hz": SHOT_HZ, "shot_noise_bright_factor": SHOT_FACTOR,
                     "dark_intensity": DARK}
    for dn in STEP_DN:
        name = f"step_{dn}"
        values = np.where(np.arange(501) < 10, dn, 3 * dn).astype(np.uint8)  # the step in frame 10 (1 ms)
        frames[name] = np.broadcast_to(values[:, None, None], (501, 4, 4)).copy()
        frames[name + "_t"] = np.arange(501) * 1e-4
        v2e[name] = {**ideal_v2e, "cutoff_hz": CUTOFF_HZ}
        dvs[name] = {**ideal_dvs, "lowpass_order": 1, "lowpass_cutoff_hz": CUTOFF_HZ, "dark_intensity": DARK}
    return frames, v2e, dvs


def run_dvsot(frames: np.ndarray, t_s: np.ndarray, values: dict) -> np.ndarray:
    """dvsot's events on 8-bit frames (linear I = DN / 255) as rows (t s, x, y, p +-1)."""
    from dvsot.events import EventParams, EventSimulator
    from dvsot.events.batch import EventBatch

    sim = EventSimulator(frames.shape[2], frames.shape[1], EventParams(**values), seed=1)
    batches = [sim.step(f.astype(np.float32) / np.float32(255.0), int(round(t * 1e6))) for f, t in zip(frames, t_s)]
    ev = EventBatch.concatenate(batches)
    return np.stack([ev.t / 1e6, ev.x, ev.y, np.where(ev.p == 1, 1, -1)], axis=1).astype(np.float64)


def summarise(v2e: dict, dvs: dict, frames: dict) -> dict:
    """The figures: totals and ON fractions, noise rates against the set rate, step responses."""
    out: dict = {}
    for name in ("totals", "totals_lowpass"):
        a, b = v2e[name], dvs[name]
        on_a, on_b = float(np.mean(a[:, 3] > 0)), float(np.mean(b[:, 3] > 0))
        out[name] = {"v2e_events": len(a), "dvsot_events": len(b), "dvsot_over_v2e": round(len(b) / len(a), 4),
                     "v2e_on_fraction": round(on_a, 4), "dvsot_on_fraction": round(on_b, 4),
                     "on_off_ratio_dvsot_over_v2e": round((on_b / (1 - on_b)) / (on_a / (1 - on_a)), 4)}
    for dn in NOISE_DN:
        name = f"noise_{dn}"
        n_pix, seconds = frames[name].shape[1] * frames[name].shape[2], float(frames[name + "_t"][-1])
        inten01 = (dn + 20) / 275
        want = SHOT_HZ * ((SHOT_FACTOR - 1) * inten01 + 1)
        rate_a, rate_b = len(v2e[name]) / n_pix / seconds, len(dvs[name]) / n_pix / seconds
        out[name] = {"set_hz": round(want, 4), "v2e_hz": round(rate_a, 4), "dvsot_hz": round(rate_b, 4),
                     "v2e_over_set": round(rate_a / want, 4), "dvsot_over_set": round(rate_b / want, 4),
                     "dvsot_on_fraction": round(float(np.mean(dvs[name][:, 3] > 0)), 4)}
    for dn in STEP_DN:
        name = f"step_{dn}"
        t_step = float(frames[name + "_t"][10])
        rows = []
        for ev in (v2e[name], dvs[name]):
            on = ev[(ev[:, 1] == 0) & (ev[:, 2] == 0) & (ev[:, 3] > 0)]
            rows.append(np.rint((on[:, 0] - t_step) * 1e6).astype(int))
        k = min(len(rows[0]), len(rows[1]))
        diff = np.abs(rows[0][:k] - rows[1][:k])
        out[name] = {"frame_interval_us": 100, "v2e_on_us": rows[0].tolist(), "dvsot_on_us": rows[1].tolist(),
                     "max_difference_us": int(diff.max()) if k else None}
    return out


def main() -> None:
    if len(sys.argv) == 3 and sys.argv[1] == "--v2e-side":
        _v2e_side(sys.argv[2])
        return
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--v2e-python", required=True, help="a Python with v2e's requirements (torch, ...)")
    parser.add_argument("--v2e-src", required=True, help="v2e's source tree (holds v2ecore/)")
    parser.add_argument("--width", type=int, default=160)
    parser.add_argument("--height", type=int, default=120)
    parser.add_argument("--frames", type=int, default=100, help="frames of the drifting texture, 1 ms apart")
    args = parser.parse_args()
    frames, v2e_params, dvs_params = inputs(args.width, args.height, args.frames)
    with tempfile.TemporaryDirectory() as tmp:
        np.savez(f"{tmp}/frames.npz", **frames)
        spec = {"frames": f"{tmp}/frames.npz", "out": f"{tmp}/v2e.npz", "v2e": v2e_params}
        Path(f"{tmp}/spec.json").write_text(json.dumps(spec))
        env = {**os.environ, "PYTHONPATH": str(Path(args.v2e_src).resolve())}
        subprocess.run([args.v2e_python, str(Path(__file__).resolve()), "--v2e-side", f"{tmp}/spec.json"], env=env,
                       check=True, cwd=tmp)
        v2e = dict(np.load(f"{tmp}/v2e.npz"))
    dvs = {name: run_dvsot(frames[name], frames[name + "_t"], values) for name, values in dvs_params.items()}
    print(json.dumps(summarise(v2e, dvs, frames), indent=1))


if __name__ == "__main__":
    main()
