"""When training validates and when it also scores tracking: the two periods need not divide each other."""

from types import SimpleNamespace

import pytest

from sctn.training.loop import Validation


def run_schedule(val_every: int, arscore_every: int, steps: int) -> list[tuple[int, bool]]:
    """(step, has a tracking score) of every validation entry, as fit makes them (the last step validated twice)."""
    history = {"train_loss": [], "val": []}
    calls = []
    v = Validation(
        SimpleNamespace(eval=lambda: None),
        SimpleNamespace(val_arscore_every=arscore_every),
        history,
        lambda: {},
        lambda model: calls.append(len(history["train_loss"])) or {"arscore": 0.5},
    )
    for step in range(1, steps + 1):
        history["train_loss"].append(0.0)
        if step % val_every == 0:
            history["val"].append({**v(), "step": step})
    history["val"].append({**v(), "step": steps})
    history["steps"] = steps
    v.score_last()
    assert len(calls) == len(set(calls))  # each step scored at most once
    return [(e["step"], "arscore" in e) for e in history["val"]]


@pytest.mark.parametrize("val_every, arscore_every, steps, scored", [
    (100, 500, 1200, [500, 1000, 1200]),   # a multiple: scored on it
    (100, 540, 1200, [600, 1100, 1200]),   # not a multiple: the first validation after each multiple of 540
    (3, 4, 12, [6, 9, 12]),
    (1, 2, 3, [2, 3]),                     # the end always scored
])
def test_tracking_is_scored_at_the_first_validation_after_each_period(val_every, arscore_every, steps, scored):
    entries = run_schedule(val_every, arscore_every, steps)
    assert sorted({s for s, has in entries if has}) == scored
    assert entries[-1][1]  # the final entry carries the score, also when its step was scored already
