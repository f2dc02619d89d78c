"""Background threads of the simulate pipeline: ordered writer thread, read-ahead decoding, their failures."""

from __future__ import annotations

import threading
import time

import cv2
import numpy as np
import pytest

import dvsot
from dvsot.core.errors import RunError, UserError
from dvsot.dataset import DatasetWriter, open_dataset
from dvsot.events import EventParams, EventSimulator, log_intensity
from dvsot.events.frame_sources import open_frames
from dvsot.runtime.threads import OrderedWorker, read_ahead


def test_ordered_worker_runs_calls_in_order_and_raises_the_first_failure_in_the_caller():
    seen: list[int] = []
    worker = OrderedWorker("test", depth=2)
    for i in range(20):
        worker.submit(seen.append, i)
    worker.wait()
    assert seen == list(range(20))

    def boom(_: int) -> None:
        raise OSError("disk full")

    worker.submit(boom, 0)
    worker.submit(seen.append, 99)  # dropped: it comes after the failure
    with pytest.raises(OSError, match="disk full"):
        worker.wait()
    assert 99 not in seen
    with pytest.raises(OSError, match="disk full"):
        worker.submit(seen.append, 100)
    worker.stop()
    assert not any(t.name == "test" for t in threading.enumerate())


def test_read_ahead_keeps_order_bounds_the_lead_and_raises_at_the_failing_item():
    started: list[int] = []

    def load(i: int) -> int:
        started.append(i)
        time.sleep(0.001 * (i % 3))  # later items can finish first
        if i == 7:
            raise UserError("frame 7: cannot read image")
        return i * i

    gen = read_ahead(load, range(20), workers=3, ahead=4)
    assert [next(gen) for _ in range(3)] == [0, 1, 4]
    assert max(started) <= 3 + 4  # never more than `ahead` items beyond the one handed out
    with pytest.raises(UserError, match="frame 7"):
        list(gen)


def write_pngs(folder, n: int = 12, w: int = 64, h: int = 48) -> None:
    rng = np.random.default_rng(0)
    base = rng.integers(0, 256, (h, w + n), np.uint8)
    folder.mkdir()
    for i in range(n):
        cv2.imwrite(str(folder / f"{i:04d}.png"), np.ascontiguousarray(base[:, i:i + w]))


def test_threaded_decoding_gives_the_frames_of_sequential_decoding_and_names_a_bad_file(tmp_path):
    write_pngs(tmp_path / "f")
    src = open_frames(tmp_path / "f")
    threaded, plain = list(src.frames(workers=3)), list(src.frames(workers=0))
    assert len(threaded) == 12 and all(np.array_equal(a, b) for a, b in zip(threaded, plain))
    # log frames (8-bit: a table lookup on the decoding thread) hold exactly what the simulator computes
    logs = list(src.log_frames(1e-3))
    assert all(np.array_equal(a, log_intensity(b, 1e-3).reshape(b.shape)) for a, b in zip(logs, plain))
    for name, img in (("deep", np.arange(64 * 48, dtype=np.uint16).reshape(48, 64) * 21),
                      ("colour", np.random.default_rng(1).integers(0, 256, (48, 64, 3), np.uint8))):
        (tmp_path / name).mkdir()
        cv2.imwrite(str(tmp_path / name / "0.png"), img)
        one = open_frames(tmp_path / name)
        (linear,), (logged,) = list(one.frames()), list(one.log_frames(1e-3))
        assert np.array_equal(logged, log_intensity(linear, 1e-3).reshape(linear.shape)), name
    (tmp_path / "f" / "0005.png").write_bytes(b"not a png")
    with pytest.raises(UserError, match="0005.png: cannot read image"):
        list(open_frames(tmp_path / "f").frames())


def test_simulate_frames_writes_what_the_simulator_gives_and_a_failed_write_leaves_no_file(tmp_path, monkeypatch):
    write_pngs(tmp_path / "f", n=30)
    src = open_frames(tmp_path / "f")
    t_us = np.arange(30) * 1_000
    params = EventParams(sigma_cp=0.03, sigma_cn=0.03)
    with DatasetWriter(tmp_path / "a.h5", src.width, src.height) as w:
        counts = dvsot.simulate_frames(src.frames(), t_us, EventSimulator(src.width, src.height, params, 3), w)
        w.close(int(t_us[-1]) + 1)
    sim = EventSimulator(src.width, src.height, params, 3)
    want = [sim.step(f, int(t)) for f, t in zip(src.frames(workers=0), t_us)]
    with open_dataset(tmp_path / "a.h5") as ds:
        got = ds.events(0, ds.duration_us)
    assert counts.frames == 30 and counts.events == len(got) == sum(len(b) for b in want) > 1000
    assert np.array_equal(got.t, np.concatenate([b.t for b in want]))
    assert np.array_equal(got.x, np.concatenate([b.x for b in want]))

    monkeypatch.setattr("dvsot.dataset.writer._EVENT_CHUNK", 256)  # several chunks, written by the writer thread

    def full_disk(self, n0, n1, columns):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(DatasetWriter, "_write_columns", full_disk)
    with pytest.raises(RunError, match="No space left"):
        with DatasetWriter(tmp_path / "b.h5", src.width, src.height) as w:
            dvsot.simulate_frames(src.frames(), t_us, EventSimulator(src.width, src.height, params, 3), w)
            w.close(int(t_us[-1]) + 1)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.h5", "f"]
