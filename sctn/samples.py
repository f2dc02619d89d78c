"""MDNet-style box samples around a box (pixels, xywh): gaussian, uniform and whole-image, with IoU filters.

After py-MDNet's SampleGenerator: for "gaussian", the centre moves by trans * mean(w, h) * N(0, 1)
(clipped to +-1 ... as a multiple of the range) and the size by scale ** (0.5 N(0, 1)), clipped;
"uniform" draws both offsets uniformly in [-1, 1]; "whole" places a box of the same size range
anywhere in the image. Boxes are kept inside the image (w, h >= 4 px). `draw_samples` repeats
vectorised draws until n boxes satisfy the IoU range.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dvsot.dataset.boxes import iou_xywh

MIN_SIZE = 4.0


@dataclass(frozen=True)
class SampleSpec:
    """How to draw: kind (gaussian | uniform | whole), translation range (x mean size), scale base, IoU range."""

    kind: str
    n: int
    trans: float
    scale: float
    iou_range: tuple[float, float] = (0.0, 1.0)


# The paper's numbers (§2.4): training, fine-tuning on a test sequence's first segment, tracking.
TRAIN = (SampleSpec("uniform", 20, 0.3, 1.3, (0.7, 1.0)), SampleSpec("uniform", 40, 1.5, 1.6, (0.0, 0.5)))
FINETUNE = (SampleSpec("gaussian", 500, 0.1, 1.3, (0.7, 1.0)), SampleSpec("uniform", 1000, 1.5, 1.6, (0.0, 0.5)),
            SampleSpec("whole", 1000, 0.0, 1.3, (0.0, 0.5)))
TRACK = SampleSpec("gaussian", 256, 0.6, 1.05)


def propose(rng: np.random.Generator, box: np.ndarray, n: int, kind: str, trans: float, scale: float,
            image_wh: tuple[int, int]) -> np.ndarray:
    """n raw boxes (N, 4) of one kind around `box`, clipped inside the image."""
    b = np.asarray(box, np.float64)
    w_img, h_img = image_wh
    cx, cy = b[0] + b[2] / 2, b[1] + b[3] / 2
    size = (b[2] + b[3]) / 2
    if kind == "gaussian":
        dxy = np.clip(0.5 * rng.standard_normal((n, 2)), -1, 1) * trans * size
        ds = scale ** np.clip(0.5 * rng.standard_normal((n, 1)), -1, 1)
    elif kind == "uniform":
        dxy = rng.uniform(-1, 1, (n, 2)) * trans * size
        ds = scale ** rng.uniform(-1, 1, (n, 1))
    elif kind == "whole":
        ds = scale ** rng.uniform(-1, 1, (n, 1))
        wh = np.maximum(b[2:] * ds, MIN_SIZE)
        xy = rng.uniform(0, 1, (n, 2)) * np.maximum(np.array([w_img, h_img]) - wh, 0)
        return np.concatenate([xy, wh], axis=1)
    else:
        raise ValueError(f"unknown sample kind {kind!r}")
    wh = np.clip(b[2:] * ds, MIN_SIZE, [w_img, h_img])
    centre = np.array([cx, cy]) + dxy
    xy = np.clip(centre - wh / 2, 0, np.array([w_img, h_img]) - wh)
    return np.concatenate([xy, wh], axis=1)


def draw_samples(rng: np.random.Generator, box: np.ndarray, spec: SampleSpec, image_wh: tuple[int, int],
                 max_rounds: int = 50) -> np.ndarray:
    """spec.n boxes (float32 xywh) whose IoU with `box` lies in spec.iou_range; raises ValueError if impossible."""
    lo, hi = spec.iou_range
    found: list[np.ndarray] = []
    count = 0
    for _ in range(max_rounds):
        cand = propose(rng, box, max(2 * spec.n, 64), spec.kind, spec.trans, spec.scale, image_wh)
        iou = iou_xywh(cand, box[None, :])
        ok = cand[(iou >= lo) & (iou <= hi)]
        found.append(ok)
        count += len(ok)
        if count >= spec.n:
            return np.concatenate(found)[: spec.n].astype(np.float32)
    raise ValueError(f"could not draw {spec.n} {spec.kind} samples with IoU in [{lo}, {hi}] around {box.tolist()}"
                     f" (got {count})")


def labelled_samples(rng: np.random.Generator, box: np.ndarray, specs: tuple[SampleSpec, ...],
                     image_wh: tuple[int, int]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Boxes (N, 4), their IoU with `box` and a positive flag (IoU range starting at >= 0.5) for a set of specs."""
    boxes, pos = [], []
    for spec in specs:
        s = draw_samples(rng, box, spec, image_wh)
        boxes.append(s)
        pos.append(np.full(len(s), spec.iou_range[0] >= 0.5))
    boxes = np.concatenate(boxes)
    return boxes, iou_xywh(boxes, box[None, :]).astype(np.float32), np.concatenate(pos)
