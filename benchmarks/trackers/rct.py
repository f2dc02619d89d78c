"""`rct`: an event-by-event rectangular cluster tracker after Delbruck (2007) / jAER's RectangularClusterTracker.

Written from the description of jAER's `net.sf.jaer.eventprocessing.tracking.RectangularClusterTracker`
(read for its semantics and default values; no code is copied). Per event, in time order:

1. **Assignment.** The event goes to the first cluster in list order (the oldest; or the nearest, with
   `use_nearest_cluster`) whose rectangle contains it: |x - cx| < rX and |y - cy| < rY, where (cx, cy) is
   the cluster's centre predicted forward by its velocity since its last update, rX = r / aspect_ratio,
   rY = r * aspect_ratio. With `surround_inhibition` the capture rectangle is `surround` times larger,
   and events in that ring (outside r) *reduce* the mass by `surround_inhibition_cost`.
2. **Seeding.** An event that no cluster takes starts a new cluster (radius r, mass 1) unless there are
   already `max_num_clusters`; then it is dropped.
3. **Update.** The cluster centre moves towards the event by `mixing_factor` (c <- (1-m) c + m e); the
   mass decays exponentially with `cluster_mass_decay_tau_us` since the cluster's last event and is
   incremented by 1.

Every `update_interval_us` of event time (jAER's FilterChain.updateIntervalMs) the cluster list is updated:
prune (mass decayed below `threshold_mass_for_visible_cluster` once the cluster has lived at least one
mass time constant, or centre off the array), merge (Manhattan distance of centres < r1 + r2, unless both
are visible with valid velocities more than `vel_ang_diff_deg_to_not_merge` apart; the merged cluster
takes the stronger cluster's centre, velocity, radius and id, and the sum of masses), move clusters by
their velocity, append a path point and estimate velocity from the last path points holding at least
`threshold_mass_for_visible_cluster` events, low-pass filtered with `velocity_tau_ms`, and mark
clusters visible when they hold that many events and that much mass.

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

Not implemented (all off by default in jAER): dynamic size / aspect ratio / angle, elliptical clusters,
highway perspective, smooth move, the 4x4-pixel "fast cluster finder" cache (a speed-up that may send an
event to a cluster whose centre lies in the same 4x4 cell). Small deliberate differences: the velocity
prediction in the containment test uses the predicted centre (jAER adds v*dt to the offset, a sign
slip); a cluster is visible when it has *at least* the threshold of events and of mass; merging sums the
masses decayed to the same time.

**Benchmark adaptation** (not part of jAER): the tracker is initialised with a ground-truth box. After
each segment the visible clusters (at the segment's end time) are candidates; each gives a box centred
on the cluster centre (+0.5 px: pixel i covers [i, i+1)) whose size is the init box's (`box_size="init"`)
or the cluster's rectangle 2rX x 2rY (`box_size="cluster"`). The target is the candidate with the highest
IoU with the previous target box; if none overlaps it, the previous box is kept. With
`radius_from_box=True` the cluster radius is half the larger side of the init box instead of
`cluster_size` (off by default). Cluster state carries over across segments and across
re-initialisations on contiguous segments (the tracker sees one event stream); a non-contiguous init
starts from an empty cluster list.

**Speed.** Per-event processing is sequential by nature. Here events are processed in chunks
speculatively: all events of a chunk are assigned using the cluster state at the chunk's start, the
exact per-event trajectories of the cluster centres (an exponential moving average per cluster) are then
computed in closed form with cumulative sums, and each event's assignment is re-checked against the
state just before it. The chunk is committed up to the first event whose assignment differs (or that
would seed a cluster), and processing resumes there. The result is identical to one-event-at-a-time
processing; a chunk costs a few (chunk x clusters) numpy operations.
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from benchmarks.trackers import register
from benchmarks.trackers.base import Tracker
from dvsot.boxes import iou_xywh
from dvsot.dataset import Segment
from dvsot.events import EventBatch

_NEVER = np.iinfo(np.int64).min // 4  # "no event yet" timestamp, far enough from overflow in differences


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


class ClusterSet:
    """The clusters of one event stream, as parallel numpy arrays in list order (oldest first)."""

    def __init__(self, params: RCTParams, width: int, height: int, radius: float) -> None:
        self.p = params
        self.width, self.height = int(width), int(height)
        self.radius0 = float(radius)
        self._next_id = 0
        self._next_update: int | None = None
        self._chunk = 64
        a = 1.0 - params.mixing_factor
        # a**-n must stay finite in float64 for every n within one chunk.
        self._chunk_max = int(max(16, min(4096, 600.0 / -math.log(a))))
        z = np.zeros
        self.loc = z((0, 2))            # centre, pixel-index coordinates
        self.vel = z((0, 2))            # pixels per microsecond
        self.vel_valid = z(0, bool)
        self.mass = z(0)                # mass right after the last event
        self.last_event = z(0, np.int64)
        self.last_update = z(0, np.int64)
        self.birth = z(0, np.int64)
        self.num_events = z(0, np.int64)
        self.prev_num_events = z(0, np.int64)
        self.ids = z(0, np.int64)
        self.radius = z(0)
        self.visible = z(0, bool)
        self.vf_time = z(0, np.int64)   # low-pass filter state of the velocity
        self.vf_init = z(0, bool)
        self.paths: list[list[tuple[float, float, int, int]]] = []

    @property
    def n(self) -> int:
        return int(self.loc.shape[0])

    # ---- cluster list edits -------------------------------------------------------------------------

    def _append(self, loc, vel, vel_valid, mass, last_event, last_update, birth, num_events, prev_num,
                cid, radius, visible, vf_time, vf_init, path) -> None:
        self.loc = np.vstack([self.loc, np.asarray(loc, float).reshape(1, 2)])
        self.vel = np.vstack([self.vel, np.asarray(vel, float).reshape(1, 2)])
        self.vel_valid = np.append(self.vel_valid, bool(vel_valid))
        self.mass = np.append(self.mass, float(mass))
        self.last_event = np.append(self.last_event, np.int64(last_event))
        self.last_update = np.append(self.last_update, np.int64(last_update))
        self.birth = np.append(self.birth, np.int64(birth))
        self.num_events = np.append(self.num_events, np.int64(num_events))
        self.prev_num_events = np.append(self.prev_num_events, np.int64(prev_num))
        self.ids = np.append(self.ids, np.int64(cid))
        self.radius = np.append(self.radius, float(radius))
        self.visible = np.append(self.visible, bool(visible))
        self.vf_time = np.append(self.vf_time, np.int64(vf_time))
        self.vf_init = np.append(self.vf_init, bool(vf_init))
        self.paths.append(path)

    def spawn(self, x: float, y: float, t: int) -> None:
        """Start a cluster at an event (pixels, microseconds) with mass 1 and the default radius."""
        self._next_id += 1
        self._append((x, y), (0.0, 0.0), False, 1.0, t, t, t, 1, 0, self._next_id, self.radius0, False,
                     t, False, [])

    def _keep(self, keep: np.ndarray) -> None:
        for name in ("loc", "vel", "vel_valid", "mass", "last_event", "last_update", "birth", "num_events",
                     "prev_num_events", "ids", "radius", "visible", "vf_time", "vf_init"):
            setattr(self, name, getattr(self, name)[keep])
        self.paths = [p for p, k in zip(self.paths, keep) if k]

    def mass_at(self, t: int) -> np.ndarray:
        """Each cluster's mass decayed to time t (microseconds)."""
        dt = (self.last_event - np.int64(t)).astype(float)
        return self.mass * np.exp(np.minimum(dt, 0.0) / self.p.cluster_mass_decay_tau_us)

    def visible_at(self, t: int) -> np.ndarray:
        """Which clusters have enough events, mass (and speed) at time t to count as visible."""
        thr = self.p.threshold_mass_for_visible_cluster
        vis = (self.num_events >= thr) & (self.mass_at(t) >= thr)
        if self.p.use_velocity and self.p.threshold_velocity_for_visible_cluster > 0:
            speed_pps = np.hypot(self.vel[:, 0], self.vel[:, 1]) * 1e6
            vis &= speed_pps >= self.p.threshold_velocity_for_visible_cluster
        return vis

    def centres_at(self, t: int) -> np.ndarray:
        """Cluster centres (pixel-index coordinates) predicted to time t by their velocities."""
        if not self.p.use_velocity:
            return self.loc.copy()
        dt = np.maximum(np.int64(t) - self.last_update, 0).astype(float)
        gain = np.where(self.vel_valid, dt * self.p.predictive_velocity_factor, 0.0)
        return self.loc + self.vel * gain[:, None]

    # ---- per-event processing -----------------------------------------------------------------------

    def feed(self, x: np.ndarray, y: np.ndarray, t: np.ndarray) -> None:
        """Process time-ordered events (pixels, microseconds), with cluster-list updates on schedule."""
        n = len(t)
        pos = 0
        while pos < n:
            if self._next_update is None:
                self._next_update = int(t[pos]) + self.p.update_interval_us
            idx = int(np.searchsorted(t, self._next_update, side="left"))
            idx = max(idx, pos)
            if idx >= n:
                self._run(x[pos:], y[pos:], t[pos:])
                break
            # jAER calls the update after the first event at or past the scheduled time.
            self._run(x[pos:idx + 1], y[pos:idx + 1], t[pos:idx + 1])
            self.update_list(int(t[idx]))
            self._next_update = int(t[idx]) + self.p.update_interval_us
            pos = idx + 1

    def _assign(self, X, Y, T, LX, LY, LU) -> np.ndarray:
        """Cluster index per event (-1: none) given centres LX, LY and last-update times LU, (k|1, C)."""
        p = self.p
        if p.use_velocity:
            gain = (T[:, None] - LU).astype(float) * p.predictive_velocity_factor
            gain = np.where(self.vel_valid[None, :], np.maximum(gain, 0.0), 0.0)
            LX = LX + self.vel[None, :, 0] * gain
            LY = LY + self.vel[None, :, 1] * gain
        s = p.surround if p.surround_inhibition else 1.0
        rx = self.radius / p.aspect_ratio * s
        ry = self.radius * p.aspect_ratio * s
        dx = np.abs(X[:, None] - LX)
        dy = np.abs(Y[:, None] - LY)
        inside = (dx < rx[None, :]) & (dy < ry[None, :])
        anyin = inside.any(axis=1)
        if p.use_nearest_cluster:
            idx = np.argmin(np.where(inside, dx + dy, np.inf), axis=1)
        else:
            idx = np.argmax(inside, axis=1)
        return np.where(anyin, idx, -1)

    def _trajectories(self, X, Y, T, A):
        """Centres (x, y), last-update times and event counts of every cluster before each row, given
        the assignment A; row k (one past the last) is the state after the whole chunk."""
        C = self.n
        m = self.p.mixing_factor
        a = 1.0 - m
        onehot = A[:, None] == np.arange(C)[None, :]
        cnt = np.cumsum(onehot, axis=0)                       # events of each cluster up to and incl. row
        n_before = np.vstack([np.zeros((1, C), np.int64), cnt])
        # c_n = a^n c_0 + m sum_j a^(n-j) e_j, evaluated for all rows at once with cumulative sums
        w = np.where(onehot, a ** (-cnt.astype(float)), 0.0)
        sx = np.vstack([np.zeros((1, C)), np.cumsum(w * X[:, None], axis=0)])
        sy = np.vstack([np.zeros((1, C)), np.cumsum(w * Y[:, None], axis=0)])
        an = a ** n_before.astype(float)
        LX = an * (self.loc[None, :, 0] + m * sx)
        LY = an * (self.loc[None, :, 1] + m * sy)
        tm = np.where(onehot, T[:, None], _NEVER)
        LU = np.maximum(np.vstack([self.last_update[None, :], np.maximum.accumulate(tm, axis=0)]),
                        self.last_update[None, :])
        return LX, LY, LU, n_before

    def _run(self, x: np.ndarray, y: np.ndarray, t: np.ndarray) -> None:
        """Process events between two list updates, speculatively in chunks (exact, see module doc)."""
        p = self.p
        tau = p.cluster_mass_decay_tau_us
        n = len(t)
        i = 0
        while i < n:
            C = self.n
            if C == 0:
                self.spawn(float(x[i]), float(y[i]), int(t[i]))
                i += 1
                continue
            j = min(n, i + self._chunk)
            X = x[i:j].astype(float)
            Y = y[i:j].astype(float)
            T = t[i:j]
            # keep exp((t - T0) / tau) small within a chunk
            j2 = int(np.searchsorted(T, T[0] + int(50 * tau), side="right"))
            X, Y, T = X[:j2], Y[:j2], T[:j2]
            A = self._assign(X, Y, T, self.loc[None, :, 0], self.loc[None, :, 1], self.last_update[None, :])
            if C < p.max_num_clusters:
                free = np.flatnonzero(A < 0)
                if free.size:
                    if free[0] == 0:
                        self.spawn(float(X[0]), float(Y[0]), int(T[0]))
                        i += 1
                        continue
                    k = int(free[0])
                    X, Y, T, A = X[:k], Y[:k], T[:k], A[:k]
            k = len(T)
            LX, LY, LU, n_before = self._trajectories(X, Y, T, A)
            A2 = self._assign(X, Y, T, LX[:-1], LY[:-1], LU[:-1])
            bad = np.flatnonzero(A2 != A)
            ok = int(bad[0]) if bad.size else k   # rows [0, ok) are verified exact; row 0 always is
            # commit rows [0, ok)
            sel = A[:ok]
            rows = np.arange(ok)
            has = sel >= 0
            if p.surround_inhibition and ok:
                cx = LX[rows, np.maximum(sel, 0)]
                cy = LY[rows, np.maximum(sel, 0)]
                rx = self.radius[np.maximum(sel, 0)] / p.aspect_ratio
                ry = self.radius[np.maximum(sel, 0)] * p.aspect_ratio
                core = (np.abs(X[:ok] - cx) < rx) & (np.abs(Y[:ok] - cy) < ry)
                inc = np.where(core, 1.0, -p.surround_inhibition_cost)
            else:
                inc = np.ones(ok)
            T0 = int(T[0])
            gain = np.zeros(C)
            np.add.at(gain, sel[has], inc[has] * np.exp((T[:ok][has] - T0) / tau))
            touched = n_before[ok] > 0
            new_last = LU[ok]
            g0 = self.mass * np.exp(np.minimum(self.last_event - T0, 0) / tau)
            new_mass = (g0 + gain) * np.exp(-(new_last - T0) / tau)
            self.mass = np.where(touched, new_mass, self.mass)
            self.last_event = np.where(touched, new_last, self.last_event)
            self.last_update = np.where(touched, new_last, self.last_update)
            self.num_events = self.num_events + n_before[ok]
            self.loc = np.stack([LX[ok], LY[ok]], axis=1)
            i += ok
            self._chunk = min(self._chunk_max, self._chunk * 2) if ok == k else max(16, 2 * ok)

    # ---- list update ---------------------------------------------------------------------------------

    def update_list(self, t: int) -> None:
        """Prune, merge, move by velocity, update paths and velocities, and mark visibility at time t."""
        self._prune(t)
        self._merge()
        p = self.p
        if p.use_velocity and self.n:
            dt = (np.int64(t) - self.last_update).astype(float)
            move = self.vel_valid & (dt > 0)
            self.loc = self.loc + np.where(move, dt * p.predictive_velocity_factor, 0.0)[:, None] * self.vel
            self.last_update = np.where(move, np.int64(t), self.last_update)
        for c in range(self.n):
            self._update_path(c, t)
        self.visible = self.visible_at(t)

    def _prune(self, t: int) -> None:
        if not self.n:
            return
        p = self.p
        since = np.int64(t) - self.last_event
        lifetime = np.where(np.int64(t) > self.last_event, np.int64(t) - self.birth, self.last_update - self.birth)
        weak = ((lifetime == 0) | (lifetime >= p.cluster_mass_decay_tau_us)) & (
            self.mass_at(t) < p.threshold_mass_for_visible_cluster)
        drop = (weak | (since < 0)) & (since != 0)
        if p.enable_cluster_exit_purging:
            lx = np.trunc(self.loc[:, 0])
            ly = np.trunc(self.loc[:, 1])
            drop |= (lx <= 0) | (lx >= self.width) | (ly <= 0) | (ly >= self.height)
        if drop.any():
            self._keep(~drop)

    def _merge(self) -> None:
        p = self.p
        if p.dont_merge_ever:
            return
        limit = math.radians(p.vel_ang_diff_deg_to_not_merge)
        while self.n > 1:
            d = np.abs(self.loc[:, None, :] - self.loc[None, :, :]).sum(axis=2)
            overlap = d < (self.radius[:, None] + self.radius[None, :])
            if limit > 0:
                s = np.hypot(self.vel[:, 0], self.vel[:, 1])
                both = self.visible & self.vel_valid & (s > 0)
                with np.errstate(invalid="ignore", divide="ignore"):
                    cos = (self.vel @ self.vel.T) / (s[:, None] * s[None, :])
                angle = np.arccos(np.clip(np.nan_to_num(cos, nan=1.0), -1, 1))
                overlap &= ~(both[:, None] & both[None, :] & (angle > limit))
            overlap = np.triu(overlap, k=1)
            if not overlap.any():
                return
            i, j = (int(v) for v in np.argwhere(overlap)[0])  # first pair in list order, as jAER
            self._merge_pair(i, j)

    def _merge_pair(self, i: int, j: int) -> None:
        strong = i if self.mass[i] > self.mass[j] else j
        last = int(max(self.last_event[i], self.last_event[j]))
        tau = self.p.cluster_mass_decay_tau_us
        mass = float(sum(self.mass[c] * math.exp(min(0, int(self.last_event[c]) - last) / tau) for c in (i, j)))
        s = strong
        args = (self.loc[s].copy(), self.vel[s].copy(), self.vel_valid[s], mass, last, last, self.birth[s],
                int(self.num_events[i] + self.num_events[j]), int(self.prev_num_events[s]), self.ids[s],
                self.radius[s], bool(self.visible[i] or self.visible[j]), self.vf_time[s], self.vf_init[s],
                list(self.paths[s]))
        keep = np.ones(self.n, bool)
        keep[[i, j]] = False
        self._keep(keep)
        self._append(*args)

    def _update_path(self, c: int, t: int) -> None:
        p = self.p
        new = int(self.num_events[c] - self.prev_num_events[c])
        if new == 0:
            return
        path = self.paths[c]
        path.append((float(self.loc[c, 0]), float(self.loc[c, 1]), int(t), new))
        self.prev_num_events[c] = self.num_events[c]
        if len(path) > p.path_length:
            del path[0]
        if not p.use_velocity or len(path) < 2:
            return
        last = path[-1]
        count = last[3]
        k = len(path) - 2
        first = path[k]
        while count < p.threshold_mass_for_visible_cluster and k > 0:
            count += first[3]
            k -= 1
            first = path[k]
        if count < p.threshold_mass_for_visible_cluster or last[2] == first[2]:
            return
        dt = float(last[2] - first[2])
        v = np.array([(last[0] - first[0]) / dt, (last[1] - first[1]) / dt])
        # first-order low-pass of the velocity, time step capped at one time constant (jAER LowpassFilter)
        now = int(self.last_event[c])
        if not self.vf_init[c] or p.velocity_tau_ms == 0:
            self.vel[c] = v
            self.vf_init[c] = True
        else:
            frac = min(1.0, max(0, now - int(self.vf_time[c])) / (p.velocity_tau_ms * 1000.0))
            self.vel[c] = self.vel[c] + (v - self.vel[c]) * frac
        self.vf_time[c] = now
        if p.friction_tau_ms is not None:
            self.vel[c] = self.vel[c] * math.exp(-dt / (p.friction_tau_ms * 1000.0))
        self.vel_valid[c] = True


@register("rct")
class RCTTracker(Tracker):
    """Rectangular cluster tracker (Delbruck 2007 / jAER) with IoU-based target selection."""

    name = "rct"

    def __init__(self, **options) -> None:
        self.params = RCTParams(**options)
        self.clusters: ClusterSet | None = None
        self._box = np.full(4, np.nan, np.float32)
        self._size = np.zeros(2)
        self._t_end: int | None = None
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
        dims = (int(width), int(height))
        contiguous = (self.clusters is not None and self._dims == dims and self._t_end == int(segment.t0_us))
        self._dims = dims
        if self.params.radius_from_box:
            radius = float(max(box[2], box[3])) / 2.0
        else:
            radius = self.params.cluster_size * max(dims)
        if not contiguous or self.clusters.radius0 != radius:
            self.clusters = ClusterSet(self.params, dims[0], dims[1], radius)
        self._feed(segment.events)
        self._t_end = int(segment.t1_us)
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
        self._t_end = int(segment.t1_us)
        boxes = self.candidate_boxes(int(segment.t1_us))
        if len(boxes):
            scores = iou_xywh(boxes, self._box[None, :])
            best = int(np.argmax(scores))
            if scores[best] > 0:
                self._box = boxes[best]
        return self._box.copy()
