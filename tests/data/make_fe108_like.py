"""Write tests/data/fe108_like.aedat4 with dv-processing, as an FE108 recording is laid out: an event track and
an APS frame track on one epoch clock (run with a Python that has dv-processing; the test only reads the file).

    python tests/data/make_fe108_like.py tests/data/fe108_like.aedat4
"""

from __future__ import annotations

import sys

import dv_processing as dv
import numpy as np

W, H = 64, 48
START = 1_600_000_000_000_000  # epoch microseconds, as a DAVIS346 recording has
FRAME_US = 50_000  # 20 APS frames per second
FRAMES = 6


def main(path: str) -> None:
    rng = np.random.default_rng(108)
    config = dv.io.MonoCameraWriter.Config("DAVIS346_fixture")
    config.addEventStream((W, H))
    config.addFrameStream((W, H))
    writer = dv.io.MonoCameraWriter(path, config)
    for k in range(FRAMES):
        t0 = START + k * FRAME_US
        n = 200
        t = np.sort(rng.integers(t0, t0 + FRAME_US, n))
        store = dv.EventStore()
        for ti, xi, yi, pi in zip(t, rng.integers(0, W, n), rng.integers(0, H, n), rng.integers(0, 2, n)):
            store.push_back(int(ti), int(xi), int(yi), bool(pi))
        writer.writeEvents(store)
        image = np.full((H, W), 40 + 30 * k, np.uint8)
        writer.writeFrame(dv.Frame(t0 + 1_000, image))  # the frame's timestamp: 1 ms into its period
    del writer  # closes the file


if __name__ == "__main__":
    main(sys.argv[1])
