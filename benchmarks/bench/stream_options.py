"""The streaming protocol's settings of a benchmark run (`dvsot bench --protocol stream`), checked before any
tracking: latency models, query rate, window, predictive rows."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from dvsot.core.errors import label


def stream_models(stream: Mapping) -> list:
    """The latency models of a streaming run's settings (default: measured), each once."""
    from benchmarks.evaluation.latency import parse_latency

    models = [m for spec in (stream.get("latency") or ["measured"]) for m in parse_latency(spec)]
    return list(dict.fromkeys(models))


def check_stream(protocol: str, stream: Mapping | None, trackers: list[str], videos: Sequence[str],
                 labels: Mapping[str, str] | None = None) -> dict | None:
    """The streaming settings checked ({latency, query_hz, window, predictive}, defaults filled), None for another
    protocol; UserError naming the setting: a streaming setting without protocol stream, an unknown latency model
    or hardware profile, a query rate outside 1 Hz..1 MHz, an unknown window, a tracker with no declared latency."""
    from benchmarks.evaluation.instant_truth import MAX_QUERY_HZ, MIN_QUERY_HZ
    from benchmarks.evaluation.latency import check_declared, parse_latency
    from benchmarks.evaluation.stream import DEFAULT_QUERY_HZ, WINDOWS
    from benchmarks.trackers import tracker_class
    from dvsot.core.errors import UserError

    # a setting left at its default is None, False or empty (0 is a value: a query rate to refuse)
    given = {k: v for k, v in (stream or {}).items()
             if v is not None and v is not False and not (isinstance(v, (list, tuple)) and not v)}
    if protocol != "stream":
        if given:
            key = next(iter(given))
            raise UserError(f"{label(key, labels)}: only with {label('protocol', labels)} stream")
        return None
    if videos:
        raise UserError(f"{label('videos', labels)} {videos[0]}: not made by {label('protocol', labels)} stream")
    specs = list(given.get("latency") or ["measured"])
    models = [m for spec in specs for m in parse_latency(spec, label("latency", labels))]
    query_hz = float(given.get("query_hz", DEFAULT_QUERY_HZ))
    if not MIN_QUERY_HZ <= query_hz <= MAX_QUERY_HZ:
        raise UserError(f"{label('query_hz', labels)} {query_hz:g}: outside {MIN_QUERY_HZ:g}..{MAX_QUERY_HZ:g} Hz")
    window = given.get("window", "last")
    if window not in WINDOWS:
        raise UserError(f"{label('window', labels)} {window}: not one of {', '.join(WINDOWS)}")
    check_declared(models, {t: tracker_class(t) for t in trackers}, label("latency", labels))
    return {"latency": specs, "query_hz": query_hz, "window": window, "predictive": bool(given.get("predictive"))}
