"""The scene file's `events:` block is as strict as the rest of the schema: no strings or flags for numbers."""

from pathlib import Path

import pytest

from dvsot.core.errors import UserError
from dvsot.scene import load_scene
from tests.synthetic import MINIMAL_SCENE


@pytest.mark.parametrize("events, field", [
    ("{cp: true}", "events.cp"),
    ('{cp: "0.2"}', "events.cp"),
    ("{lowpass_order: true, lowpass_cutoff_hz: 100}", "events.lowpass_order"),
    ("{readout_fifo_events: 3.0}", "events.readout_fifo_events"),
    ('{hot_pixel_hz: "1e3"}', "events.hot_pixel_hz"),
])
def test_events_block_refuses_coercion(tmp_path: Path, events: str, field: str) -> None:
    path = tmp_path / "s.yaml"
    path.write_text(MINIMAL_SCENE + f"events: {events}\n")
    with pytest.raises(UserError, match=rf"s\.yaml:\d+: field '{field}'"):
        load_scene(path)


def test_events_block_takes_numbers_and_an_int_for_a_float(tmp_path: Path) -> None:
    path = tmp_path / "s.yaml"
    path.write_text(MINIMAL_SCENE + "events: {cp: 1, cn: 0.3, lowpass_order: 1, lowpass_cutoff_hz: 200}\n")
    cfg = load_scene(path)
    assert (cfg.events.cp, cfg.events.cn, cfg.events.lowpass_order) == (1.0, 0.3, 1)


@pytest.mark.parametrize("block, field", [('render: {specular: "false"}', "render.specular"),
                                          ("render: {persistent_data: 0}", "render.persistent_data")])
def test_render_flags_are_flags(tmp_path: Path, block: str, field: str) -> None:
    path = tmp_path / "s.yaml"
    path.write_text(MINIMAL_SCENE + block + "\n")
    with pytest.raises(UserError, match=rf"s\.yaml:\d+: field '{field}'"):
        load_scene(path)
