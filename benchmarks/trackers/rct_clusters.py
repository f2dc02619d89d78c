"""The cluster list of jAER's RectangularClusterTracker (Delbruck 2007) for one event stream, one structured
array of cluster states; the tracker and its parameters are benchmarks.trackers.rct.

Semantics from jAER's description (no code copied; see benchmarks.trackers.rct). Per event, in time order:

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

Not implemented (all off by default in jAER): dynamic size / aspect ratio / angle, elliptical clusters,
highway perspective, smooth move, the 4x4-pixel "fast cluster finder" cache (a speed-up that may send an
event to a cluster whose centre lies in the same 4x4 cell). Small deliberate differences: the velocity
prediction in the containment test uses the predicted centre (jAER adds v*dt to the offset, a sign
slip); a cluster is visible when it has *at least* the threshold of events and of mass; merging sums the
masses decayed to the same time.

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
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # the parameters' model lives with the tracker, which imports this module
    from benchmarks.trackers.rct import RCTParams

_NEVER = np.iinfo(np.int64).min // 4  # "no event yet" timestamp, far enough from overflow in differences


# One cluster's state: one row of ClusterSet.c (a numpy structured array, list order = oldest first).
CLUSTER = np.dtype([
    ("loc", np.float64, (2,)),      # centre, pixel-index coordinates
    ("vel", np.float64, (2,)),      # pixels per microsecond
    ("vel_valid", bool),
    ("mass", np.float64),           # mass right after the last event
    ("last_event", np.int64),       # microseconds
    ("last_update", np.int64),
    ("birth", np.int64),
    ("num_events", np.int64),
    ("prev_num_events", np.int64),  # num_events at the last path point
    ("ids", np.int64),
    ("radius", np.float64),         # pixels
    ("visible", bool),
    ("vf_time", np.int64),          # low-pass filter state of the velocity
    ("vf_init", bool),
    ("paths", object),              # list of path points (x, y, t_us, new events)
])
_FIELDS = frozenset(CLUSTER.names)


class ClusterSet:
    """The clusters of one event stream: one structured array `c` (dtype CLUSTER) in list order (oldest first).

    Each field reads as an attribute (`cs.mass` is the view `cs.c["mass"]`, a property made from CLUSTER);
    writes go through `c`."""

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
        self.c = np.zeros(0, CLUSTER)

    def __setattr__(self, name: str, value) -> None:
        if name in _FIELDS:  # an attribute would shadow the field and fall out of step with c
            raise AttributeError(f"cluster field {name!r} is written through ClusterSet.c")
        super().__setattr__(name, value)

    @property
    def n(self) -> int:
        return len(self.c)

    # ---- cluster list edits -------------------------------------------------------------------------

    def _append(self, cluster: np.ndarray) -> None:
        """Add one cluster (a CLUSTER record) at the end of the list."""
        self.c = np.concatenate([self.c, np.asarray(cluster, CLUSTER).reshape(1)])

    def spawn(self, x: float, y: float, t: int) -> None:
        """Start a cluster at an event (pixels, microseconds) with mass 1 and the default radius."""
        self._next_id += 1
        cluster = np.zeros(1, CLUSTER)
        cluster["loc"] = (x, y)
        cluster["mass"] = 1.0
        cluster["last_event"] = cluster["last_update"] = cluster["birth"] = cluster["vf_time"] = t
        cluster["num_events"] = 1
        cluster["ids"] = self._next_id
        cluster["radius"] = self.radius0
        cluster["paths"][0] = []
        self._append(cluster)

    def _keep(self, keep: np.ndarray) -> None:
        """Keep the clusters where keep (bool per cluster) is true, in order."""
        self.c = self.c[keep]

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

    def _chunk_state(self) -> tuple[np.ndarray, ...]:
        """(x, y, last_update, vx, vy, vel_valid, radius) per cluster: contiguous copies of the fields a chunk
        reads, taken once per chunk (the structured array's fields are strided views)."""
        c = self.c
        loc, vel = c["loc"], c["vel"]
        return (loc[:, 0].copy(), loc[:, 1].copy(), c["last_update"].copy(), vel[:, 0].copy(), vel[:, 1].copy(),
                c["vel_valid"].copy(), c["radius"].copy())

    def _assign(self, X, Y, T, LX, LY, LU, state: tuple[np.ndarray, ...]) -> np.ndarray:
        """Cluster index per event (-1: none) given centres LX, LY and last-update times LU, (k|1, C), and the
        chunk's velocities and radii (state, from _chunk_state)."""
        p = self.p
        _, _, _, vx, vy, vel_valid, radius = state
        if p.use_velocity:
            gain = (T[:, None] - LU).astype(float) * p.predictive_velocity_factor
            gain = np.where(vel_valid[None, :], np.maximum(gain, 0.0), 0.0)
            LX = LX + vx[None, :] * gain
            LY = LY + vy[None, :] * gain
        s = p.surround if p.surround_inhibition else 1.0
        rx = radius / p.aspect_ratio * s
        ry = radius * p.aspect_ratio * s
        dx = np.abs(X[:, None] - LX)
        dy = np.abs(Y[:, None] - LY)
        inside = (dx < rx[None, :]) & (dy < ry[None, :])
        anyin = inside.any(axis=1)
        if p.use_nearest_cluster:
            idx = np.argmin(np.where(inside, dx + dy, np.inf), axis=1)
        else:
            idx = np.argmax(inside, axis=1)
        return np.where(anyin, idx, -1)

    def _trajectories(self, X, Y, T, A, state: tuple[np.ndarray, ...]):
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
        x0, y0, last_update = state[:3]
        LX = an * (x0[None, :] + m * sx)
        LY = an * (y0[None, :] + m * sy)
        tm = np.where(onehot, T[:, None], _NEVER)
        LU = np.maximum(np.vstack([last_update[None, :], np.maximum.accumulate(tm, axis=0)]), last_update[None, :])
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
            state = self._chunk_state()
            A = self._assign(X, Y, T, state[0][None, :], state[1][None, :], state[2][None, :], state)
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
            LX, LY, LU, n_before = self._trajectories(X, Y, T, A, state)
            A2 = self._assign(X, Y, T, LX[:-1], LY[:-1], LU[:-1], state)
            bad = np.flatnonzero(A2 != A)
            ok = int(bad[0]) if bad.size else k   # rows [0, ok) are verified exact; row 0 always is
            # commit rows [0, ok)
            sel = A[:ok]
            rows = np.arange(ok)
            has = sel >= 0
            if p.surround_inhibition and ok:
                cx = LX[rows, np.maximum(sel, 0)]
                cy = LY[rows, np.maximum(sel, 0)]
                rx = state[6][np.maximum(sel, 0)] / p.aspect_ratio
                ry = state[6][np.maximum(sel, 0)] * p.aspect_ratio
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
            c = self.c
            c["mass"] = np.where(touched, new_mass, c["mass"])
            c["last_event"] = np.where(touched, new_last, c["last_event"])
            c["last_update"] = np.where(touched, new_last, c["last_update"])
            c["num_events"] = c["num_events"] + n_before[ok]
            c["loc"] = np.stack([LX[ok], LY[ok]], axis=1)
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
            self.c["loc"] = self.loc + np.where(move, dt * p.predictive_velocity_factor, 0.0)[:, None] * self.vel
            self.c["last_update"] = np.where(move, np.int64(t), self.last_update)
        for c in range(self.n):
            self._update_path(c, t)
        self.c["visible"] = self.visible_at(t)

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
        """Replace clusters i and j by one at the end of the list: the stronger's state, the summed masses
        (decayed to the later last event) and event counts, visible if either was."""
        c = self.c
        strong = i if c["mass"][i] > c["mass"][j] else j
        last = int(max(c["last_event"][i], c["last_event"][j]))
        tau = self.p.cluster_mass_decay_tau_us
        merged = c[strong:strong + 1].copy()
        merged["mass"] = float(sum(c["mass"][k] * math.exp(min(0, int(c["last_event"][k]) - last) / tau)
                                   for k in (i, j)))
        merged["last_event"] = merged["last_update"] = last
        merged["num_events"] = int(c["num_events"][i] + c["num_events"][j])
        merged["visible"] = bool(c["visible"][i] or c["visible"][j])
        merged["paths"][0] = list(c["paths"][strong])
        keep = np.ones(self.n, bool)
        keep[[i, j]] = False
        self._keep(keep)
        self._append(merged)

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


def _field(name: str) -> property:
    """A read-only property giving the field `name` of every cluster, as a view into ClusterSet.c."""
    return property(lambda self: self.c[name], doc=f"cluster field {name!r} (a view into c)")


for _name in CLUSTER.names:
    setattr(ClusterSet, _name, _field(_name))
