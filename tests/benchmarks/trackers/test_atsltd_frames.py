"""ATSLTD frame of paper eq. 11 on a hand-made event list."""

import numpy as np

from benchmarks.trackers.atsltd import atsltd_frame, atsltd_frame_bgr
from dvsot.events import EventBatch


def _events(rows):
    rows = np.array(rows, dtype=np.int64)
    return EventBatch(rows[:, 0].astype(np.uint16), rows[:, 1].astype(np.uint16), rows[:, 2],
                      rows[:, 3].astype(np.uint8))


# x, y, t (us), p; the segment starts at 100_000 us, the earliest event is at 101_000 us.
EVENTS = _events([
    (0, 0, 101_000, 1),   # the earliest event: t* = 0 -> 0
    (1, 1, 101_000, 0),   # overwritten by the later event at the same pixel
    (2, 1, 103_500, 1),   # t* = 2.5 ms -> 255 * 2.5 / 10 = 63.75 -> 64
    (1, 1, 106_000, 1),   # t* = 5 ms -> 127.5 -> 128 (round half up)
    (3, 2, 110_999, 0),   # t* = 9.999 ms -> 254.97 -> 255
])


def test_eq11_values_by_hand():
    frame = atsltd_frame(EVENTS, width=5, height=3, window_us=10_000)
    expected = np.zeros((3, 5), np.uint8)
    expected[1, 2] = 64
    expected[1, 1] = 128
    expected[2, 3] = 255
    assert frame.dtype == np.uint8 and frame.shape == (3, 5)
    np.testing.assert_array_equal(frame, expected)


def test_latest_event_wins_regardless_of_input_order():
    order = np.array([3, 0, 4, 2, 1])
    frame = atsltd_frame(EVENTS.select(order), 5, 3, 10_000)
    assert frame[1, 1] == 128


def test_window_generalises_the_divisor():
    frame = atsltd_frame(EVENTS, 5, 3, window_us=20_000)
    assert frame[1, 1] == 64       # 255 * 5 / 20 = 63.75
    assert frame[2, 3] == 127      # 255 * 9.999 / 20 = 127.49


def test_empty_and_bgr():
    assert not atsltd_frame(EventBatch.empty(), 4, 2).any()
    bgr = atsltd_frame_bgr(EVENTS, 5, 3)
    assert bgr.shape == (3, 5, 3)
    np.testing.assert_array_equal(bgr[:, :, 0], atsltd_frame(EVENTS, 5, 3))
    np.testing.assert_array_equal(bgr[:, :, 2], bgr[:, :, 1])
