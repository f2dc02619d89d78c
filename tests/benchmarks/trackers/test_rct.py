"""RCT: cluster semantics by hand, chunked processing equals event-by-event, tracking a moving blob in noise."""

import math

import numpy as np
import pytest
from pydantic import ValidationError

from benchmarks.trackers.rct import ClusterSet, RCTParams, RCTTracker
from dvsot.dataset import Segment
from dvsot.dataset.boxes import iou_xywh
from dvsot.events import EventBatch

W, H = 640, 480


def moving_square(n_seg=30, size=40, v=(800.0, 300.0), start=(100.0, 100.0), obj_rate=3000,
                  noise_rate=500, seed=0, seg_us=10_000):
    """Segments of events on the outline of a moving square plus uniform noise; GT box at each end."""
    rng = np.random.default_rng(seed)
    segs = []
    for i in range(n_seg):
        t0 = i * seg_us
        to = np.sort(rng.integers(t0, t0 + seg_us, obj_rate))
        cx = start[0] + v[0] * to / 1e6
        cy = start[1] + v[1] * to / 1e6
        side = rng.integers(0, 4, obj_rate)
        u = rng.uniform(-0.5, 0.5, obj_rate) * size
        ox = np.where(side == 0, -size / 2, np.where(side == 1, size / 2, u))
        oy = np.where(side == 2, -size / 2, np.where(side == 3, size / 2, u))
        x = np.clip(np.round(cx + ox), 0, W - 1)
        y = np.clip(np.round(cy + oy), 0, H - 1)
        tn = rng.integers(t0, t0 + seg_us, noise_rate)
        t = np.concatenate([to, tn])
        order = np.argsort(t, kind="stable")
        xs = np.concatenate([x, rng.integers(0, W, noise_rate)])[order].astype(np.uint16)
        ys = np.concatenate([y, rng.integers(0, H, noise_rate)])[order].astype(np.uint16)
        ev = EventBatch(xs, ys, t[order].astype(np.int64), rng.integers(0, 2, len(t)).astype(np.uint8))
        t1 = t0 + seg_us
        c = (start[0] + v[0] * t1 / 1e6 + 0.5, start[1] + v[1] * t1 / 1e6 + 0.5)
        segs.append(Segment(i, t0, t1, ev, np.array([c[0] - size / 2, c[1] - size / 2, size, size], np.float32)))
    return segs


def test_one_event_moves_centre_by_mixing_factor_and_adds_decayed_mass():
    cs = ClusterSet(RCTParams(), W, H, radius=20.0)
    cs.feed(np.array([10]), np.array([10]), np.array([1000]))
    assert cs.n == 1 and cs.mass[0] == 1.0
    cs.feed(np.array([20]), np.array([14]), np.array([6000]))
    assert cs.n == 1
    np.testing.assert_allclose(cs.loc[0], [10 + 0.05 * 10, 10 + 0.05 * 4])
    assert cs.mass[0] == pytest.approx(1 + math.exp(-5000 / 10_000))
    assert cs.num_events[0] == 2
    # outside the 20 px rectangle: a second cluster is seeded
    cs.feed(np.array([60]), np.array([10]), np.array([7000]))
    assert cs.n == 2 and tuple(cs.loc[1]) == (60.0, 10.0)


def test_overlapping_clusters_merge_into_the_stronger_one():
    cs = ClusterSet(RCTParams(), W, H, radius=20.0)
    xs = np.array([100] * 5 + [130] * 2)
    cs.feed(xs, np.full(7, 100), np.arange(7, dtype=np.int64) * 10)
    assert cs.n == 2
    strong_id = cs.ids[0]
    cs._merge()  # Manhattan distance 30 < 20 + 20
    assert cs.n == 1 and cs.ids[0] == strong_id and cs.num_events[0] == 7
    assert cs.loc[0, 0] == pytest.approx(100.0)


def test_unsupported_cluster_is_pruned():
    cs = ClusterSet(RCTParams(), W, H, radius=20.0)
    t = np.arange(40, dtype=np.int64) * 100
    cs.feed(np.full(40, 200), np.full(40, 200), t)
    cs.update_list(int(t[-1]) + 1)
    assert cs.n == 1 and cs.visible[0]
    cs.update_list(int(t[-1]) + 30_000)   # three mass time constants later: mass ~ 40 * e^-3 < 30
    assert cs.n == 0


def test_chunked_processing_equals_event_by_event():
    segs = moving_square(n_seg=6, obj_rate=2000, noise_rate=1500, seed=3)
    ev = EventBatch.concatenate([s.events for s in segs])
    x, y, t = ev.x.astype(np.int64), ev.y.astype(np.int64), ev.t
    fast = ClusterSet(RCTParams(), W, H, radius=40.0)
    slow = ClusterSet(RCTParams(), W, H, radius=40.0)
    slow._chunk = slow._chunk_max = 1
    fast.feed(x, y, t)
    slow.feed(x, y, t)
    assert fast.n == slow.n > 1
    np.testing.assert_array_equal(fast.ids, slow.ids)
    np.testing.assert_array_equal(fast.num_events, slow.num_events)
    np.testing.assert_allclose(fast.loc, slow.loc, rtol=0, atol=1e-6)
    np.testing.assert_allclose(fast.mass, slow.mass, rtol=1e-9)
    np.testing.assert_allclose(fast.vel, slow.vel, rtol=1e-6, atol=1e-12)


def test_follows_moving_blob_in_uniform_noise_deterministically():
    segs = moving_square(n_seg=30)
    runs = []
    for _ in range(2):
        tr = RCTTracker()
        tr.init(segs[0], segs[0].box, W, H)
        runs.append(np.array([tr.update(s) for s in segs[1:]]))
    np.testing.assert_array_equal(runs[0], runs[1])
    ious = iou_xywh(runs[0], np.array([s.box for s in segs[1:]]))
    assert ious.mean() > 0.6, ious
    assert (ious >= 0.5).mean() >= 0.9, ious   # RCT would count as failing in at most 10% of segments
    # the box really moved with the blob (about 8 px per segment to the right)
    assert runs[0][-1, 0] - segs[0].box[0] > 150


def test_box_size_modes_and_options():
    segs = moving_square(n_seg=4)
    tr = RCTTracker(box_size="cluster", cluster_size=0.05)
    tr.init(segs[0], segs[0].box, W, H)
    box = tr.update(segs[1])
    np.testing.assert_allclose(box[2:], [64, 64])   # 2 * 0.05 * 640
    with pytest.raises(ValidationError, match="no_such_option"):
        RCTTracker(no_such_option=1)
    with pytest.raises(ValueError):
        RCTTracker().init(segs[0], np.full(4, np.nan), W, H)
