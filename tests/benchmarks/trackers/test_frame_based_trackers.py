"""csrt / kcf / mil on ATSLTD frames follow a synthetic moving square drawn as events."""

import numpy as np
import pytest

from benchmarks.trackers.frame_based import CSRTTracker, KCFTracker, MILTracker, _opencv_rect
from dvsot.dataset import Segment
from dvsot.dataset.boxes import iou_xywh
from dvsot.events import EventBatch

W, H = 320, 240


def moving_square(n_seg=15, size=40, v=(500.0, 200.0), start=(60.0, 60.0), obj_rate=3000, noise_rate=200,
                  seed=1, seg_us=10_000):
    """Segments of events on the outline of a moving square plus uniform noise; GT box at each end."""
    rng = np.random.default_rng(seed)
    segs = []
    for i in range(n_seg):
        t0 = i * seg_us
        t = np.sort(rng.integers(t0, t0 + seg_us, obj_rate + noise_rate))
        obj = rng.random(len(t)) < obj_rate / (obj_rate + noise_rate)
        cx = start[0] + v[0] * t / 1e6
        cy = start[1] + v[1] * t / 1e6
        side = rng.integers(0, 4, len(t))
        u = rng.uniform(-0.5, 0.5, len(t)) * size
        ox = np.where(side == 0, -size / 2, np.where(side == 1, size / 2, u))
        oy = np.where(side == 2, -size / 2, np.where(side == 3, size / 2, u))
        x = np.where(obj, np.clip(np.round(cx + ox), 0, W - 1), rng.integers(0, W, len(t)))
        y = np.where(obj, np.clip(np.round(cy + oy), 0, H - 1), rng.integers(0, H, len(t)))
        ev = EventBatch(x.astype(np.uint16), y.astype(np.uint16), t.astype(np.int64),
                        np.ones(len(t), np.uint8))
        t1 = t0 + seg_us
        c = (start[0] + v[0] * t1 / 1e6 + 0.5, start[1] + v[1] * t1 / 1e6 + 0.5)
        segs.append(Segment(i, t0, t1, ev, np.array([c[0] - size / 2, c[1] - size / 2, size, size], np.float32)))
    return segs


@pytest.mark.parametrize("cls", [CSRTTracker, KCFTracker, MILTracker])
def test_follows_moving_square(cls):
    segs = moving_square()
    tr = cls()
    tr.init(segs[0], segs[0].box, W, H)
    boxes = np.array([tr.update(s) for s in segs[1:]])
    assert boxes.shape == (len(segs) - 1, 4) and boxes.dtype == np.float32
    ious = iou_xywh(boxes, np.array([s.box for s in segs[1:]]))
    assert ious.mean() > 0.45, (cls.name, ious)
    assert boxes[-1, 0] - segs[0].box[0] > 40, (cls.name, boxes[-1])  # it moved right with the square


def test_rect_is_clipped_to_the_image_and_never_empty():
    assert _opencv_rect(np.array([-5.5, 10.2, 20.0, 5.0]), 100, 50) == (0, 10, 15, 6)
    assert _opencv_rect(np.array([98.0, 48.0, 10.0, 10.0]), 100, 50) == (98, 48, 2, 2)
    assert _opencv_rect(np.array([150.0, 10.0, 10.0, 10.0]), 100, 50)[2] >= 1


def test_rejects_absent_box_and_update_before_init():
    segs = moving_square(n_seg=1)
    with pytest.raises(ValueError):
        CSRTTracker().init(segs[0], np.full(4, np.nan), W, H)
    with pytest.raises(RuntimeError):
        KCFTracker().update(segs[0])
