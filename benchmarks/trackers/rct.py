"""`rct`: an event-by-event rectangular cluster tracker after Delbruck (2007) / jAER's RectangularClusterTracker.

Written from the description of jAER's `net.sf.jaer.eventprocessing.tracking.RectangularClusterTracker`
(read for its semantics and default values; no code is copied). The cluster list (assignment, seeding,
updates, pruning, merging, velocities) is benchmarks.trackers.rct_clusters.

Defaults (jAER's, as its preferences initialise them; `initDefaults` overrides two field defaults):

| parameter | default | jAER name |
|---|---|---|
| cluster_size | 0.15 (radius = 0.15 * max(width, height), 96 px on 640x480) | clusterSize |
| aspect_ratio | 1.0 | aspectRatio |
| mixing_factor | 0.05 | mixingFactor |
| surround | 2.0 | surround |
| surround_inhibition | False (cost 1.0) | surroundInhibitionEnabled / surroundInhibitionCost |
| threshold_mass_for_visible_cluster | 30 | thresholdMassForVisibleCluster |
| threshold_velocity_for_visible_cluster | 0 px/s | thresholdVelocityForVisibleCluster |
| cluster_mass_decay_tau_us | 10000 | clusterMassDecayTauUs |
| max_num_clusters | 10 | maxNumClusters |
| use_nearest_cluster | False | useNearestCluster |
| use_velocity | True | useVelocity |
| predictive_velocity_factor | 1.0 | predictiveVelocityFactor |
| velocity_tau_ms | 100 | velocityTauMs |
| friction_tau_ms | None (off) | frictionTauMs (NaN) |
| vel_ang_diff_deg_to_not_merge | 60 | velAngDiffDegToNotMerge |
| dont_merge_ever | False | dontMergeEver |
| enable_cluster_exit_purging | True | enableClusterExitPurging |
| update_interval_us | 25000 | FilterChain.updateIntervalMs = 25 |

**Benchmark adaptation** (not part of jAER): the tracker is initialised with a ground-truth box. After
each segment the visible clusters (at the segment's end time) are candidates; each gives a box centred
on the cluster centre (+0.5 px: pixel i covers [i, i+1)) whose size is the init box's (`box_size="init"`)
or the cluster's rectangle 2rX x 2rY (`box_size="cluster"`). The target is the candidate with the highest
IoU with the previous target box; if none overlaps it, the previous box is kept. With
`radius_from_box=True` the cluster radius is half the larger side of the init box instead of
`cluster_size` (off by default). Cluster state carries over across segments; every initialisation,
the protocol's re-initialisations included, starts from an empty cluster list, as a new tracker does.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from benchmarks.trackers import register
from benchmarks.trackers.base import Tracker
from benchmarks.trackers.rct_clusters import ClusterSet
from dvsot.dataset import Segment
from dvsot.dataset.boxes import iou_xywh
from dvsot.events import EventBatch

__all__ = ["ClusterSet", "RCTParams", "RCTTracker"]


class RCTParams(BaseModel):
    """Parameters of the rectangular cluster tracker (jAER defaults; see the module docstring)."""

    model_config = ConfigDict(extra="forbid")

    cluster_size: float = Field(0.15, gt=0, le=1)
    aspect_ratio: float = Field(1.0, gt=0)
    mixing_factor: float = Field(0.05, gt=0, le=0.5)
    surround: float = Field(2.0, ge=1)
    surround_inhibition: bool = False
    surround_inhibition_cost: float = Field(1.0, ge=0)
    threshold_mass_for_visible_cluster: float = Field(30.0, ge=0)
    threshold_velocity_for_visible_cluster: float = Field(0.0, ge=0)
    cluster_mass_decay_tau_us: float = Field(10_000.0, gt=0)
    max_num_clusters: int = Field(10, ge=1)
    use_nearest_cluster: bool = False
    use_velocity: bool = True
    predictive_velocity_factor: float = 1.0
    velocity_tau_ms: float = Field(100.0, ge=0)
    friction_tau_ms: float | None = None
    vel_ang_diff_deg_to_not_merge: float = 60.0
    dont_merge_ever: bool = False
    enable_cluster_exit_purging: bool = True
    update_interval_us: int = Field(25_000, gt=0)
    path_length: int = Field(100, ge=2)
    box_size: Literal["init", "cluster"] = "init"
    radius_from_box: bool = False



@register("rct")
class RCTTracker(Tracker):
    """Rectangular cluster tracker (Delbruck 2007 / jAER) with IoU-based target selection."""

    name = "rct"

    def __init__(self, **options) -> None:
        self.params = RCTParams(**options)
        self.clusters: ClusterSet | None = None
        self._box = np.full(4, np.nan, np.float32)
        self._size = np.zeros(2)
        self._dims = (0, 0)

    def _feed(self, events: EventBatch) -> None:
        x = np.asarray(events.x, dtype=np.int64)
        y = np.asarray(events.y, dtype=np.int64)
        t = np.asarray(events.t, dtype=np.int64)
        w, h = self._dims
        keep = (x < w) & (y < h)
        if not keep.all():
            x, y, t = x[keep], y[keep], t[keep]
        if len(t) > 1 and np.any(np.diff(t) < 0):
            order = np.argsort(t, kind="stable")
            x, y, t = x[order], y[order], t[order]
        self.clusters.feed(x, y, t)

    def init(self, segment: Segment, box_xywh: np.ndarray, width: int, height: int) -> None:
        """Take the ground-truth box (xywh pixels) as the target and feed the init segment's events."""
        box = np.asarray(box_xywh, dtype=np.float32).reshape(4)
        if not np.all(np.isfinite(box)) or box[2] <= 0 or box[3] <= 0:
            raise ValueError(f"rct: cannot initialise on an absent or empty box {box.tolist()}")
        self._dims = (int(width), int(height))
        if self.params.radius_from_box:
            radius = float(max(box[2], box[3])) / 2.0
        else:
            radius = self.params.cluster_size * max(self._dims)
        self.clusters = ClusterSet(self.params, self._dims[0], self._dims[1], radius)  # a new tracker's: empty
        self._feed(segment.events)
        self._box = box.copy()
        self._size = box[2:].astype(float)

    def candidate_boxes(self, t_us: int) -> np.ndarray:
        """Boxes (N,4 xywh pixels) of the clusters visible at t_us, sized per `box_size`."""
        cs = self.clusters
        vis = cs.visible_at(t_us)
        centres = cs.centres_at(t_us)[vis] + 0.5
        if self.params.box_size == "init":
            size = np.broadcast_to(self._size, centres.shape)
        else:
            r = cs.radius[vis]
            size = np.stack([2 * r / self.params.aspect_ratio, 2 * r * self.params.aspect_ratio], axis=1)
        return np.concatenate([centres - size / 2, size], axis=1).astype(np.float32)

    def update(self, segment: Segment) -> np.ndarray:
        """Feed the segment's events; the target box (xywh pixels) at the segment's end."""
        if self.clusters is None:
            raise RuntimeError("rct: update() before init()")
        self._feed(segment.events)
        boxes = self.candidate_boxes(int(segment.t1_us))
        if len(boxes):
            scores = iou_xywh(boxes, self._box[None, :])
            best = int(np.argmax(scores))
            if scores[best] > 0:
                self._box = boxes[best]
        return self._box.copy()
