"""Event frames, boxes and GIF/MP4 previews from a tiny hand-made dataset file."""

import numpy as np
import pytest
from PIL import Image

from dvsot.dataset import DatasetWriter
from dvsot.dataset.preview import GT_COLOUR, OFF_COLOUR, ON_COLOUR, PALETTE, draw_box, event_frame, write_preview
from dvsot.events import EventBatch


def _batch(x, y, t, p):
    return EventBatch(np.array(x, np.uint16), np.array(y, np.uint16), np.array(t, np.int64), np.array(p, np.uint8))


def test_event_frame_colours_the_last_polarity_per_pixel():
    img = event_frame(_batch([1, 3, 3, 0], [0, 2, 2, 1], [0, 1, 2, 3], [1, 1, 0, 0]), 4, 3)
    assert img.shape == (3, 4, 3) and img.dtype == np.uint8
    np.testing.assert_array_equal(img[0, 1], ON_COLOUR)
    np.testing.assert_array_equal(img[2, 3], OFF_COLOUR)  # ON then OFF at the same pixel: the last wins
    np.testing.assert_array_equal(img[1, 0], OFF_COLOUR)
    assert (img[0, 0] == 255).all() and (img.reshape(-1, 3) == 255).all(axis=1).sum() == 12 - 3
    dark = event_frame(EventBatch.empty(), 4, 3, background="dark")
    assert (dark < 50).all()
    with pytest.raises(ValueError):
        event_frame(_batch([4], [0], [0], [1]), 4, 3)


def test_draw_box_covers_the_half_open_rectangle_and_skips_nan():
    img = np.zeros((20, 20, 3), np.uint8)
    draw_box(img, [2, 3, 5, 4], (0, 255, 0))
    ys, xs = np.nonzero(img[:, :, 1])
    assert (xs.min(), xs.max(), ys.min(), ys.max()) == (2, 6, 3, 6)  # last covered pixel is x + w - 1
    assert img[4:6, 3:6].sum() == 0  # outline only
    before = img.copy()
    draw_box(img, [np.nan] * 4, (255, 0, 0))
    draw_box(img, [1, 1, 0, 5], (255, 0, 0))
    np.testing.assert_array_equal(img, before)


def _tiny_dataset(path):
    """Three 10 ms segments of a 96x64 sensor: events inside a box that moves 4 px right per segment."""
    with DatasetWriter(path, 96, 64, 10_000, {"name": "tiny", "split": "test"}) as w:
        for k in range(3):
            x0 = 4 + 4 * k
            xs, ys = np.meshgrid(np.arange(x0, x0 + 8), np.arange(36, 44))
            n = xs.size
            t = np.sort(np.linspace(k * 10_000 + 100, k * 10_000 + 9_000, n).astype(np.int64))
            w.append_events(_batch(xs.ravel(), ys.ravel(), t, np.arange(n) % 2))
        w.append_boxes(np.array([0, 10_000, 20_000, 30_000]),
                       np.array([[0, 36, 8, 8], [4, 36, 8, 8], [8, 36, 8, 8], [12, 36, 8, 8]], float))
        w.close(30_000)
    return path


def test_gif_preview_has_one_frame_per_segment_with_boxes(tmp_path):
    ds = _tiny_dataset(tmp_path / "tiny.h5")
    pred = np.array([[60, 30, 6, 6]] * 3, float)
    out = write_preview(ds, tmp_path / "sub" / "tiny.gif", {"tracker": pred}, fps=20)
    assert out.exists() and not list(out.parent.glob(".*tmp*"))
    with Image.open(out) as im:
        assert im.n_frames == 3 and im.size == (96, 64)
        assert im.info["duration"] == 50
        im.seek(1)
        rgb = np.asarray(im.convert("RGB")).astype(int)
    # ground truth of segment 1 is the box at 20 ms: x in [8, 16), drawn green at its left edge x = 8
    assert np.abs(rgb[40, 8] - GT_COLOUR).sum() < 60 and np.abs(rgb[40, 15] - GT_COLOUR).sum() < 60
    assert np.abs(rgb[30, 62] - PALETTE[0]).sum() < 60  # the tracker's box top edge (y = 30, x = 60..65)
    assert (rgb[50, 80] > 230).all()  # background stays white
    # pixels that fired in segment 1 (x in [8, 16)) are red or blue
    r, g, b = rgb[40, 12]
    assert max(r, b) > 150 and g < 120


def test_preview_rejects_bad_tracks_and_suffixes_and_writes_mp4(tmp_path):
    ds = _tiny_dataset(tmp_path / "tiny.h5")
    with pytest.raises(ValueError, match="one per segment"):
        write_preview(ds, tmp_path / "x.gif", {"tracker": np.zeros((4, 4))})
    # a track of the first segments only (a limited benchmark run) is drawn where it exists
    short = write_preview(ds, tmp_path / "short.gif", {"tracker": np.array([[60, 30, 6, 6]], float)})
    with Image.open(short) as im:
        first = np.asarray(im.convert("RGB")).astype(int)
        im.seek(2)
        last = np.asarray(im.convert("RGB")).astype(int)
    assert np.abs(first[30, 62] - PALETTE[0]).sum() < 60 and (last[30, 62] > 230).all()
    with pytest.raises(ValueError, match="gif or .mp4"):
        write_preview(ds, tmp_path / "x.png")
    with pytest.raises(ValueError, match="no segments"):
        write_preview(ds, tmp_path / "x.gif", start=5)
    assert not (tmp_path / "x.gif").exists()
    mp4 = write_preview(ds, tmp_path / "tiny.mp4", background="dark")
    assert mp4.stat().st_size > 0
