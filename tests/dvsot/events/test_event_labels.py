"""Per-event object labels (dvsot.events.labels) on a synthetic moving square, against closed-form events."""

from __future__ import annotations

import numpy as np
import pytest

from dvsot.events import EventParams, EventSimulator
from dvsot.events.labels import (
    BACKGROUND_ID,
    NOISE_ID,
    TARGET_ID,
    EventLabeller,
    LabelledFrame,
    event_objects,
    object_table,
)

W, H = 32, 20
DT = 1000  # us between samples
C = 0.2  # contrast threshold (log intensity)
SQUARE_L, DISTRACTOR_L = 0.6, 1.2  # log intensities: 3 thresholds apart from the background (0) and each other
ROWS = slice(7, 13)
DISTRACTOR_ID = 2


def square_x0(k: int) -> int:
    """Left column of the square at sample k: 3 px to the right per sample."""
    return 2 + 3 * k


def scene(k: int, distractor: bool) -> tuple[np.ndarray, np.ndarray]:
    """(log intensity, object ids) at sample k: the square (target) in front of a still distractor on background 0."""
    level = np.zeros((H, W))
    ids = np.zeros((H, W), np.uint8)
    if distractor:
        level[4:16, 14:30], ids[4:16, 14:30] = DISTRACTOR_L, DISTRACTOR_ID
    x0 = square_x0(k)
    level[ROWS, x0:x0 + 6], ids[ROWS, x0:x0 + 6] = SQUARE_L, TARGET_ID
    return level, ids


def expected_events(samples: int, distractor: bool) -> list[tuple[int, int, int, int]]:
    """(t, y, x, id) of every event in closed form: a pixel whose level changes by n thresholds between samples
    fires n times, at t0 + j/n of the interval (j = 1..n); its id by the rule of dvsot.events.labels."""
    out = []
    for k in range(1, samples):
        (l0, a), (l1, b) = scene(k - 1, distractor), scene(k, distractor)
        for y, x in zip(*np.nonzero(l0 != l1)):
            n = int(round(abs(l1[y, x] - l0[y, x]) / C))
            for j in range(1, n + 1):
                t = (k - 1) * DT + int(round(j * DT / n))
                if a[y, x] == BACKGROUND_ID or b[y, x] == BACKGROUND_ID:
                    label = max(a[y, x], b[y, x])  # the object whose boundary moved over the pixel
                else:
                    label = a[y, x] if j / n < 0.5 else b[y, x]  # the nearer sample
                out.append((t, int(y), int(x), int(label)))
    return sorted(out)


def simulate(samples: int, distractor: bool, params: EventParams | None = None):
    sim = EventSimulator(W, H, params or EventParams(cp=C, cn=C), seed=3)
    labeller = EventLabeller(W, H)
    batches = []
    for k in range(samples):
        level, ids = scene(k, distractor)
        batches.append(labeller.label(sim.step(level, k * DT, is_log=True), ids, k * DT))
    from dvsot.events import EventBatch

    return EventBatch.concatenate(batches)


@pytest.mark.parametrize("distractor", [False, True])
def test_moving_square_labels_match_closed_form(distractor):
    batch = simulate(6, distractor)
    got = sorted(zip(batch.t.tolist(), batch.y.tolist(), batch.x.tolist(), batch.object.tolist()))
    assert got == expected_events(6, distractor)


def test_square_over_background_is_all_target():
    batch = simulate(6, distractor=False)
    # 5 intervals x (leading + trailing edge: 2 x 3 columns x 6 rows) x 3 crossings
    assert len(batch) == 5 * 2 * 3 * 6 * 3
    assert np.all(batch.object == TARGET_ID)


def test_square_over_distractor_splits_by_nearer_sample():
    batch = simulate(6, distractor=True)
    # interval 4 -> 5 (x0 14 -> 17): columns 14..16 go target -> distractor (1.2 - 0.6: 3 ON crossings at 1/3,
    # 2/3, 1 of the interval: target, distractor, distractor); columns 20..22 distractor -> target (3 OFF: distractor,
    # target, target)
    sel = (batch.t > 4 * DT) & (batch.t <= 5 * DT)
    for cols, ids in ((range(14, 17), [TARGET_ID, DISTRACTOR_ID, DISTRACTOR_ID]),
                      (range(20, 23), [DISTRACTOR_ID, TARGET_ID, TARGET_ID])):
        m = sel & np.isin(batch.x, list(cols))
        order = np.lexsort((batch.t[m], batch.x[m], batch.y[m]))
        got = batch.object[m][order].reshape(-1, 3)  # per pixel, its 3 events in time order
        assert got.shape[0] == 3 * 6
        assert (got == ids).all()
        assert np.array_equal(np.unique(batch.t[m]), 4 * DT + np.array([333, 667, 1000]))


def test_midpoint_goes_to_the_later_sample_and_noise_gets_its_id():
    before = np.array([[1, 2, 0]], np.uint8)
    after = np.array([[2, 1, 3]], np.uint8)
    x = np.array([0, 0, 0, 1, 2, 2])
    t = np.array([499, 500, 501, 10, 1, 2])
    signal = np.array([True, True, True, True, True, False])
    ids = event_objects(x, np.zeros_like(x), t, signal, 0, 1000, before, after)
    assert ids.tolist() == [1, 2, 2, 2, 3, NOISE_ID]


def test_noise_events_carry_the_noise_id():
    batch = simulate(4, distractor=False, params=EventParams(cp=C, cn=C, shot_noise_hz=2000.0))
    assert not batch.signal.all()
    assert np.all(batch.object[~batch.signal] == NOISE_ID)
    assert np.all(batch.object[batch.signal] == TARGET_ID)


def test_labelled_file_round_trip(tmp_path):
    from dvsot.dataset import Dataset
    from dvsot.pipeline.sequence import write_sequence

    frames = [LabelledFrame(*scene(k, True)) for k in range(6)]
    table = object_table([("box", "distractor")])
    sim = EventSimulator(W, H, EventParams(cp=C, cn=C), seed=3)
    path, counts = write_sequence(tmp_path / "sq.h5", frames, np.arange(6) * DT, sim, {}, 1000,
                                  is_log=True, objects=table)
    want = expected_events(6, True)
    with Dataset(path) as ds:
        assert ds.objects == table
        batch = ds.events(0, ds.duration_us)
        assert sorted(zip(batch.t.tolist(), batch.y.tolist(), batch.x.tolist(), batch.object.tolist())) == want
        shares = ds.object_counts()
        assert shares[TARGET_ID] == sum(1 for e in want if e[3] == TARGET_ID)
        assert shares[DISTRACTOR_ID] == sum(1 for e in want if e[3] == DISTRACTOR_ID)
        assert shares[BACKGROUND_ID] == 0 and shares[NOISE_ID] == 0


def test_frames_labelled_all_or_none(tmp_path):
    from dvsot.core.errors import UserError
    from dvsot.pipeline.sequence import write_sequence

    frames = [LabelledFrame(*scene(0, False)), scene(1, False)[0]]
    sim = EventSimulator(W, H, EventParams(cp=C, cn=C))
    with pytest.raises(UserError, match="every frame comes with object labels or none"):
        write_sequence(tmp_path / "x.h5", frames, [0, DT], sim, {}, 1000, is_log=True, objects=object_table())
    assert not (tmp_path / "x.h5").exists()


def _labelled_file(tmp_path):
    from dvsot.pipeline.sequence import write_sequence

    frames = [LabelledFrame(*scene(k, True)) for k in range(4)]
    sim = EventSimulator(W, H, EventParams(cp=C, cn=C), seed=3)
    path, _ = write_sequence(tmp_path / "sq.h5", frames, np.arange(4) * DT, sim, {}, 1000, is_log=True,
                             objects=object_table([("box", "distractor")]))
    return path


@pytest.mark.parametrize("change, message", [
    (lambda col: np.where(col == TARGET_ID, 7, col), r"/events/object holds id 7 \(\d+ events\), which /objects/id"),
    (lambda col: col[:-1], r"/events/object has \d+ rows, /events/t has \d+"),
])
def test_label_column_disagreeing_with_its_table_is_refused_on_open(tmp_path, change, message):
    import h5py

    from dvsot.core.errors import UserError
    from dvsot.dataset import Dataset

    path = _labelled_file(tmp_path)
    with h5py.File(path, "r+") as f:
        col = change(f["events/object"][()]).astype(np.uint8)
        del f["events/object"]
        f["events"].create_dataset("object", data=col)
    with pytest.raises(UserError) as err:
        Dataset(path)
    text = str(err.value)
    assert "\n" not in text and text.startswith(f"{path}: damaged dvsot file (")
    import re

    assert re.search(message, text)


def test_unlabelled_files_load_without_labels(tmp_path):
    from dvsot.dataset import Dataset
    from dvsot.pipeline.sequence import write_sequence

    sim = EventSimulator(W, H, EventParams(cp=C, cn=C), seed=3)
    path, _ = write_sequence(tmp_path / "plain.h5", [scene(k, False)[0] for k in range(3)], np.arange(3) * DT, sim,
                             {}, 1000, is_log=True)
    with Dataset(path) as ds:
        assert ds.objects is None and ds.object_counts() is None
        assert ds.events(0, ds.duration_us).object is None


def test_background_pixel_beside_a_moving_edge_takes_the_moved_object():
    # column 1 goes background -> target (the edge arrives); column 3 is background at both samples but next to
    # it (the renderer's pixel filter changes its intensity); column 5 is background with no change next to it
    before = np.zeros((3, 7), np.uint8)
    after = before.copy()
    after[:, 1:3] = TARGET_ID
    before[:, 6], after[:, 6] = 2, 2  # a still object: no boundary moved beside column 5
    x = np.array([3, 3, 5, 0])
    y = np.array([1, 0, 1, 2])
    ids = event_objects(x, y, np.array([100, 900, 500, 500]), None, 0, 1000, before, after)
    assert ids.tolist() == [TARGET_ID, TARGET_ID, BACKGROUND_ID, TARGET_ID]


def test_info_gives_each_objects_share(tmp_path, capsys):
    from dvsot.cli import main
    from dvsot.dataset.info import dataset_info

    path = _labelled_file(tmp_path)
    info = dataset_info(path)
    shares = {row["name"]: row["share"] for row in info["objects"]}
    assert sum(shares.values()) == pytest.approx(1.0)
    assert shares["target"] > 0 and shares["box"] > 0 and shares["noise"] == 0
    assert main(["info", str(path)]) == 0
    assert "1 target (target)" in capsys.readouterr().out


def test_label_column_without_its_table_is_refused(tmp_path):
    import h5py

    from dvsot.core.errors import UserError
    from dvsot.dataset import Dataset

    path = _labelled_file(tmp_path)
    with h5py.File(path, "r+") as f:
        del f["objects/role"]
    with pytest.raises(UserError, match=r"sq\.h5: damaged dvsot file \(missing /objects/role"):
        Dataset(path)
