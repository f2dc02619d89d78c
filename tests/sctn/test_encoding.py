"""Events to input spikes: the pixel, step and channel of each event on a box's canvas and on a search region."""

import numpy as np
import torch

from dvsot.events import EventBatch
from sctn.encoding import encode_boxes, encode_region
from sctn.network import NetworkConfig

torch.set_num_threads(1)


def test_encoding_places_events_at_the_right_pixel_step_and_channel():
    ev = EventBatch(np.array([50, 52, 10], np.uint16), np.array([40, 41, 10], np.uint16),
                    np.array([1_000, 3_500, 2_000]), np.array([1, 0, 1], np.uint8))
    x = encode_boxes(ev, 0, np.array([[40, 30, 20, 20], [0, 0, 400, 300]]), NetworkConfig(input_size=107, steps=10))
    assert x.shape == (2, 10, 2, 107, 107)
    # box 0 centred at (50, 40): pixel centre (50.5, 40.5) -> canvas (54, 54) at step 1, ON;
    # (52.5, 41.5) -> (56, 55) at step 3, OFF; (10, 10) is outside box 0
    assert x[0, 1, 1, 54, 54] == 1 and x[0, 3, 0, 55, 56] == 1 and x[0].sum() == 2
    # box 1 is 400 px wide: scaled by 107/400 around its centre (200, 150)
    u = int(np.floor((10.5 - 200) * 107 / 400 + 53.5))
    v = int(np.floor((10.5 - 150) * 107 / 400 + 53.5))
    assert x[1, 2, 1, v, u] == 1 and x[1].sum() == 3
    r = encode_region(ev, 0, np.array([0.0, 0.0]), 1.0, (60, 60))
    assert r[0, 1, 1, 40, 50] == 1 and r.sum() == 3
