"""Random-walk trajectories for scene templates: {random_walk: {...}} drawn into keyframes (metres, seconds, degrees).

The walk moves in one plane (x-z by default: the plane facing a camera on the -y axis) at a speed drawn
per step from [lo, hi] m/s, its heading turning at a rate drawn per step from [-turn_deg_s, turn_deg_s],
reflected at the walls of an optional box. Each step ends in a keyframe, so between keyframes the
object moves at the drawn speed (less across a wall it bounced off) when the interpolation is linear;
smooth interpolation (the default) rounds the corners.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Annotated, Literal

import numpy as np
from pydantic import Field, ValidationError, model_validator

from dvsot.core.errors import UserError
from dvsot.core.strict import Float, Strict
from dvsot.scene import Vec3

_PLANES = {"xz": (0, 2), "xy": (0, 1), "yz": (1, 2)}
MAX_STEPS = 100_000


class RandomWalk(Strict):
    """A random walk's parameters (the values of {random_walk: ...} after the template's draws)."""

    start: Vec3
    speed_mps: tuple[Annotated[Float, Field(ge=0)], Annotated[Float, Field(ge=0)]]
    turn_deg_s: Float = Field(90.0, ge=0, description="largest turn rate of the heading, degrees per second")
    step_s: Float = Field(0.1, gt=0, description="time between keyframes, seconds")
    plane: Literal["xz", "xy", "yz"] = "xz"
    heading_deg: Float | None = Field(None, description="first heading in the plane (0 = +first axis); None: drawn")
    bounds: tuple[Vec3, Vec3] | None = Field(None, description="[lo corner, hi corner] of the box the walk stays in")
    rotation_deg: Vec3 | None = None
    spin_deg_s: Vec3 | None = Field(None, description="constant rotation rate added to rotation_deg, degrees/s")
    look_at: Vec3 | None = None

    @model_validator(mode="after")
    def _consistent(self) -> RandomWalk:
        if self.speed_mps[0] > self.speed_mps[1]:
            raise ValueError(f"speed_mps needs [lo, hi] with lo <= hi, got {list(self.speed_mps)}")
        if self.look_at is not None and (self.rotation_deg is not None or self.spin_deg_s is not None):
            raise ValueError("give look_at or rotation_deg/spin_deg_s, not both")
        if self.bounds is not None:
            lo, hi = np.asarray(self.bounds[0]), np.asarray(self.bounds[1])
            if np.any(lo > hi):
                raise ValueError("bounds needs [lo corner, hi corner] with lo <= hi on every axis")
            if np.any(np.asarray(self.start) < lo) or np.any(np.asarray(self.start) > hi):
                raise ValueError("start lies outside bounds")
        return self


def random_walk(walk: RandomWalk, duration_s: float, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Keyframe times (s, (K,)) and locations (m, (K, 3)) of a random walk over [0, duration_s]."""
    n = max(1, math.ceil(duration_s / walk.step_s - 1e-6))  # no sliver of a last step
    times = np.minimum(np.arange(n + 1) * walk.step_s, duration_s)
    a, b = _PLANES[walk.plane]
    speeds = rng.uniform(walk.speed_mps[0], walk.speed_mps[1], n)
    turns = np.radians(rng.uniform(-walk.turn_deg_s, walk.turn_deg_s, n))
    heading = math.radians(walk.heading_deg) if walk.heading_deg is not None else rng.uniform(0, 2 * math.pi)
    lo, hi = (np.asarray(walk.bounds[0]), np.asarray(walk.bounds[1])) if walk.bounds else (None, None)
    pos = np.empty((n + 1, 3))
    pos[0] = walk.start
    for k in range(n):  # a few hundred steps at most per scene; each depends on the last
        dt = times[k + 1] - times[k]
        heading += turns[k] * dt
        p = pos[k].copy()
        p[a] += speeds[k] * dt * math.cos(heading)
        p[b] += speeds[k] * dt * math.sin(heading)
        if lo is not None:  # mirror at a wall, heading with it
            if p[a] < lo[a] or p[a] > hi[a]:
                p[a] = 2 * (lo[a] if p[a] < lo[a] else hi[a]) - p[a]
                heading = math.pi - heading
            if p[b] < lo[b] or p[b] > hi[b]:
                p[b] = 2 * (lo[b] if p[b] < lo[b] else hi[b]) - p[b]
                heading = -heading
            p = np.clip(p, lo, hi)  # a step longer than the box
        pos[k + 1] = p
    return times, pos


def _six(x: float) -> float:
    return float(f"{float(x):.6g}")


def walk_keyframes(walk: RandomWalk, duration_s: float, rng: np.random.Generator) -> list[dict]:
    """The random walk as scene-file keyframes (t, location and rotation_deg or look_at)."""
    times, pos = random_walk(walk, duration_s, rng)
    keys = []
    for t, p in zip(times, pos):
        key: dict = {"t": _six(t), "location": [_six(v) for v in p]}
        if walk.look_at is not None:
            key["look_at"] = list(walk.look_at)
        elif walk.rotation_deg is not None or walk.spin_deg_s is not None:
            r0 = np.asarray(walk.rotation_deg or (0.0, 0.0, 0.0))
            key["rotation_deg"] = [_six(v) for v in r0 + np.asarray(walk.spin_deg_s or (0.0, 0.0, 0.0)) * t]
        keys.append(key)
    return keys


def expand_walks(scene: dict, rng_for: Callable[[tuple], np.random.Generator],
                 fail: Callable[[tuple, str], UserError], origin: dict) -> None:
    """Replace each trajectory's random_walk (camera, target, objects) by its keyframes, in place."""
    places = [("camera",), ("target", "trajectory")]
    places += [("objects", i, "trajectory") for i in range(len(scene.get("objects") or []))]
    for place in places:
        traj = scene
        for key in place:
            traj = traj.get(key) if isinstance(traj, dict) else traj[key] if isinstance(traj, list) else None
        if not (isinstance(traj, dict) and "random_walk" in traj):
            continue
        if "keyframes" in traj:
            raise fail(place + ("random_walk",), "give keyframes or random_walk, not both")
        spec = traj.pop("random_walk")
        try:
            walk = RandomWalk.model_validate(spec)
        except ValidationError as exc:
            err = exc.errors()[0]
            loc = tuple(err["loc"])
            msg = "unknown field" if err["type"] == "extra_forbidden" else err["msg"].removeprefix("Value error, ")
            raise fail(place + ("random_walk",) + loc, msg) from None
        duration = scene.get("duration_s")
        if not (isinstance(duration, (int, float)) and not isinstance(duration, bool) and 0 < duration <= 600):
            raise fail(("duration_s",), f"a random_walk needs duration_s as a number of seconds, got {duration!r}")
        if duration / walk.step_s > MAX_STEPS:
            raise fail(place + ("random_walk", "step_s"), f"more than {MAX_STEPS} steps over duration_s")
        traj["keyframes"] = walk_keyframes(walk, float(duration), rng_for(place))
        origin[place + ("keyframes",)] = origin.get(place + ("random_walk",), place + ("random_walk",))
