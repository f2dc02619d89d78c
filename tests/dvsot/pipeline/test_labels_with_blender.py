"""A tiny real render (160x120, 0.2 s): the target's events carry the target's id, the distractor's its own."""

import numpy as np
import pytest
from synthetic import linear_path, tiny_scene

from dvsot.cli import main
from dvsot.dataset import Dataset
from dvsot.events.labels import BACKGROUND_ID, NOISE_ID, TARGET_ID

pytestmark = pytest.mark.blender

SCENE = tiny_scene(
    "labels",
    {"shape": "cube", "size_m": 1.2, "material": {"color": [0.9, 0.9, 0.9]},
     "trajectory": linear_path((-2.5, 0, 0.8), (-1.5, 0, 0.8))},
    objects=[{"name": "ball", "role": "distractor", "shape": "sphere", "size_m": 1.0,
              "material": {"color": [0.8, 0.2, 0.2]}, "trajectory": linear_path((2.0, 0, -0.8), (2.0, 0, 0.2))}],
    sampling={"max_displacement_px": 2.0})


def test_target_events_carry_the_target_id(tmp_path, capsys):
    path = tmp_path / "labels.yaml"
    path.write_text(SCENE)
    out = tmp_path / "labels.h5"
    assert main(["generate", str(path), "-o", str(out), "--quiet"]) == 0
    with Dataset(out) as ds:
        assert [(r["id"], r["name"], r["role"]) for r in ds.objects] == [
            (BACKGROUND_ID, "background", "background"), (TARGET_ID, "target", "target"), (2, "ball", "distractor"),
            (NOISE_ID, "noise", "noise")]
        ev = ds.events(0, ds.duration_us)
        track = ds.boxes()
        # nothing passes in front of the target: all of it visible, never absent
        assert np.all(track.visibility > 0.95) and not ds.segment_absent().any()
        assert np.all(ds.segment_visibility() > 0.95)
    # inside the target's box at either sample around an event, every event is the target's, and no target
    # event lies outside it (the background's own events, from the light the moving objects block, keep id 0)
    # (grown by the 1 px a moving edge's pixel filter reaches: rule 2 of dvsot.events.labels)
    k = np.searchsorted(track.t, ev.t)

    def in_box(grow):
        inside = np.zeros(len(ev), bool)
        for box in (track.xywh[k - 1], track.xywh[k]):
            x, y, w, h = box.T
            ex, ey = ev.x + 0.5, ev.y + 0.5
            inside |= (ex > x - grow) & (ex < x + w + grow) & (ey > y - grow) & (ey < y + h + grow)
        return inside

    target = ev.object == TARGET_ID
    assert in_box(0).sum() > 500
    assert np.all(target[in_box(0)]) and np.all(in_box(1)[target])
    ball = ev.object == 2
    assert ball.sum() > 500 and np.all(ev.x[ball] >= 80)  # the ball moves in the right half
    assert main(["info", str(out)]) == 0
    text = capsys.readouterr().out
    assert "target (target)" in text and "ball (distractor)" in text
