"""Latency models of the streaming evaluation, each named in every result it gives.

- `measured`: the wall time of each call on this machine (the machine is recorded: `machine()`).
- `scaled:F[,F...]`: measured times F (STARE's hardware simulator); several factors give a curve of score
  against F, and the factor at which a tracker falls to half its latency-free score.
- `declared:PROFILE`: the operations a tracker counts for each call (`Tracker.energy_per_segment` /
  `energy_per_init`: synaptic ACs, MACs, neuron state updates, activations) times the profile's time per
  operation (PROFILES). Deterministic: the same run gives the same windows, answers and scores bit for bit.
  A tracker that counts none of the profile's operations (`Tracker.operations` empty) is refused before any
  tracking.
- `free` (internal): latency 0 and a call at every segment end, the latency-free reference.
"""

from __future__ import annotations

from dataclasses import dataclass

from dvsot.core.errors import UserError

FREE = "free"
KINDS = ("measured", "scaled", "declared")

# seconds per operation. cpu: one operation per ns (a single core's order of magnitude); loihi: a neuromorphic
# core after Davies et al. 2018 (IEEE Micro 38(1), "Loihi", Table 1: a synaptic spike operation in ~3.5 ns, a
# neuron update in ~5 ns) and its 128 cores sharing a call's operations evenly (LANES): assumptions, not
# measurements (docs/benchmarks.md). An operation a profile has no time for (None) runs on its HOST's profile: a
# neuromorphic chip's dense arithmetic (an ANN's MACs, fine-tuning's backward pass) is done by the computer it is
# attached to.
PROFILES: dict[str, dict[str, float | None]] = {
    "cpu": {"ac_ops": 1e-9, "mac_ops": 1e-9, "state_updates": 1e-9, "activations": 1e-9},
    "loihi": {"ac_ops": 3.5e-9, "mac_ops": None, "state_updates": 5e-9, "activations": None},
}
HOST = {"loihi": "cpu"}
LANES = {"cpu": 1, "loihi": 128}  # operations done at once: a profile's own operations are divided among them


@dataclass(frozen=True)
class LatencyModel:
    """One latency model: kind (measured, scaled, declared or free), the scale factor, the hardware profile."""

    kind: str
    factor: float = 1.0
    profile: str | None = None

    @property
    def name(self) -> str:
        """The model as results name it: measured, scaled:F, declared:PROFILE or free."""
        if self.kind == "scaled":
            return f"scaled:{self.factor:g}"
        if self.kind == "declared":
            return f"declared:{self.profile}"
        return self.kind

    def latency_s(self, wall_s: float, tracker, init: bool) -> float:
        """The latency (seconds) of the call just made: wall_s as measured, scaled, or the declared cost of the
        operations the tracker counted for it."""
        if self.kind == FREE:
            return 0.0
        if self.kind == "measured":
            return float(wall_s)
        if self.kind == "scaled":
            return float(wall_s) * self.factor
        counts = tracker.energy_per_init() if init else tracker.energy_per_segment()
        if not counts:
            raise RuntimeError(f"{getattr(tracker, 'name', type(tracker).__name__)} counted no operations for a "
                               f"call, which latency {self.name} needs")
        return declared_seconds(counts, self.profile)


def declared_seconds(counts: dict, profile: str) -> float:
    """Seconds of a call's operations (counts: {operation: number}) on a hardware profile of PROFILES."""
    total = 0.0
    for name in (profile, HOST.get(profile)):
        if name is None:
            continue
        own = 0.0
        for op in sorted(PROFILES[name]):
            n = float(counts.get(op, 0.0) or 0.0)
            t = PROFILES[name][op]
            if n and t is not None and (name == profile or PROFILES[profile].get(op) is None):
                own += n * t
        total += own / LANES[name]
    return total


def _times(profile: str) -> dict[str, float]:
    """Seconds per operation of a profile, the operations it has no time for taken from its host's."""
    own = PROFILES[profile]
    host = _times(HOST[profile]) if profile in HOST else {}
    return {op: t if t is not None else host[op] for op, t in own.items() if t is not None or op in host}


def free_model() -> LatencyModel:
    """The latency-free reference model."""
    return LatencyModel(FREE)


def parse_latency(spec: str, flag: str = "latency") -> list[LatencyModel]:
    """The models of one --latency value (scaled:F1,F2 gives one per factor); UserError naming flag otherwise."""
    kind, _, arg = str(spec).partition(":")
    if kind == "measured" and not arg:
        return [LatencyModel("measured")]
    if kind == "scaled" and arg:
        out = []
        for part in arg.split(","):
            try:
                f = float(part)
            except ValueError:
                f = float("nan")
            if not 0 < f <= 1e6:
                raise UserError(f"{flag} {spec}: scale factor {part!r} is not a number in (0, 1e6]")
            out.append(LatencyModel("scaled", f))
        return out
    if kind == "declared" and arg:
        if arg not in PROFILES:
            raise UserError(f"{flag} {spec}: unknown hardware profile '{arg}' (known: {', '.join(PROFILES)})")
        return [LatencyModel("declared", profile=arg)]
    raise UserError(f"{flag} {spec}: unknown latency model (use measured, scaled:F[,F...] or declared:PROFILE with "
                    f"PROFILE one of {', '.join(PROFILES)})")


def check_declared(models: list[LatencyModel], trackers: dict[str, type], flag: str = "latency") -> None:
    """UserError before any tracking if a declared model meets a tracker that counts none of its profile's
    operations (trackers: {name: class}; the class's `operations`)."""
    for m in models:
        if m.kind != "declared":
            continue
        timed = set(_times(m.profile))
        for name, cls in trackers.items():
            ops = set(getattr(cls, "operations", ()))
            if not ops & timed:
                have = f"counts {', '.join(sorted(ops))}" if ops else "counts no operations"
                raise UserError(f"{flag} {m.name}: tracker '{name}' has no latency under it ({have}; the profile "
                                f"times {', '.join(sorted(timed))})")


def machine() -> dict:
    """The machine a measured latency comes from: host name, CPU model, threads available and torch's threads."""
    import os
    import platform
    import sys

    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as f:
            cpu = next((ln.split(":", 1)[1].strip() for ln in f if ln.startswith("model name")), cpu)
    except OSError:
        pass
    torch = sys.modules.get("torch")
    return {"node": platform.node(), "cpu": cpu, "threads": len(os.sched_getaffinity(0))
            if hasattr(os, "sched_getaffinity") else os.cpu_count(),
            "torch_threads": torch.get_num_threads() if torch is not None else None}
