"""The `ideal` sensor model gives the events of the ESIM-style simulator bit for bit (digests taken before the
sensor stages existed), on linear, log and 8-bit coded frames, with mismatch, refractory period and noise."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest

from dvsot.events import CodedFrame, EventParams, EventSimulator, log_intensity

W, H, N_FRAMES = 64, 48, 24


def codes_sequence() -> list[np.ndarray]:
    """8-bit frames: a random texture shifted one pixel a frame, its brightness stepped every eighth frame."""
    rng = np.random.default_rng(1234)
    tex = rng.integers(20, 200, size=(H, 2 * W)).astype(np.int64)
    tex = (tex + np.roll(tex, 1, axis=1) + np.roll(tex, 1, axis=0)) // 3  # some spatial correlation
    frames = []
    for k in range(N_FRAMES):
        gain = 4 + (k // 8)  # 4/4, 5/4, 6/4
        frames.append(np.clip(tex[:, k:k + W] * gain // 4, 0, 255).astype(np.uint8))
    return frames


def times_us() -> list[int]:
    return [int(1000 * k + 37 * (k % 3)) for k in range(N_FRAMES)]


def digest(batches) -> str:
    h = hashlib.sha256()
    for b in batches:
        for col in (b.x, b.y, b.t, b.p, b.signal):
            h.update(np.ascontiguousarray(col).tobytes())
    return h.hexdigest()


CASES = {
    "plain": dict(),
    "mismatch_refractory": dict(sigma_cp=0.03, sigma_cn=0.04, refractory_us=300.0),
    "noise": dict(cp=0.15, cn=0.25, shot_noise_hz=40.0, leak_hz=15.0),
    "per_interval": dict(sigma_cp=0.05, sigma_cn=0.05, mismatch="per_interval"),
}
KINDS = ("linear", "log", "coded")

# sha256 of x, y, t, p, signal of every batch, from the simulator before the sensor stages were added
REFERENCE = {
    "mismatch_refractory": "ba476a201db66819b3b38542954c299c54580e8e7aba32c705b8c2e69b8d6fac",
    "noise": "8c5c30d4fae600359345d09e97ad740d2f3c800a007fc6e12b814ab57fd1822f",
    "per_interval": "d69837fbb5ee2ad983f3a19bf87d24cffef611ca6291931cad47a8836fd051d9",
    "plain": "feceee469efc6efae4b60369c61392604ecc39cd3b518e1dda25469a9add1046",
}
# the same for the /events columns of `dvsot simulate` on the frames as a .npy stack (case "noise", seed 7)
FILE_REFERENCE = "d140abf561c1d66e082fdd9d6b3aaffebf793cc1a1a5cf9333e751a19a04d9c0"


def run(case: str, kind: str, params_cls=EventParams) -> str:
    params = params_cls(**CASES[case])
    sim = EventSimulator(W, H, params, seed=7)
    table = log_intensity(np.arange(256, dtype=np.float32).reshape(1, -1) / 255.0, params.log_eps)
    out = []
    for frame, t in zip(codes_sequence(), times_us()):
        if kind == "linear":
            out.append(sim.step(frame.astype(np.float32) / np.float32(255.0), t))
        elif kind == "log":
            out.append(sim.step(np.take(table, frame), t, is_log=True))
        else:
            out.append(sim.step(CodedFrame(frame, table), t))
    return digest(out)


@pytest.mark.parametrize("case", sorted(CASES))
@pytest.mark.parametrize("kind", KINDS)
def test_ideal_model_gives_todays_events(case, kind):
    assert run(case, kind) == REFERENCE[case]


def simulate_digest(tmp_path, **params) -> str:
    import h5py

    from dvsot.pipeline.simulate import simulate_file

    stack = tmp_path / "frames.npy"
    np.save(stack, np.stack(codes_sequence()).astype(np.float32) / np.float32(255.0))
    (tmp_path / "t.txt").write_text("".join(f"{t / 1e6:.6f}\n" for t in times_us()))
    out = tmp_path / "out.h5"
    simulate_file(stack, out, EventParams(**{**CASES["noise"], **params}), 7, timestamps=tmp_path / "t.txt")
    h = hashlib.sha256()
    with h5py.File(out, "r") as f:
        for name in ("x", "y", "t", "p", "signal"):
            h.update(np.ascontiguousarray(f["events"][name][:]).tobytes())
        assert "noise_kind" not in f["events"]  # the ideal model's files keep today's layout
    return h.hexdigest()


def test_ideal_model_gives_todays_file(tmp_path):
    assert simulate_digest(tmp_path) == FILE_REFERENCE
