"""check_stream, the streaming settings' check before any tracking: the query rate's bounds, latency models and
profiles, and every tracker of the run having a cost under each declared model."""

from __future__ import annotations

import math

import pytest

from benchmarks.bench.stream_options import check_stream
from dvsot.core.errors import UserError

LABELS = {"latency": "--latency", "query_hz": "--query-hz", "window": "--stream-window", "protocol": "--protocol"}


@pytest.mark.parametrize("rate", [1.0, 1e6])
def test_the_query_rate_bounds_are_accepted(rate):
    assert check_stream("stream", {"query_hz": rate}, ["rct"], [])["query_hz"] == rate


@pytest.mark.parametrize("rate", [0.999, 1e6 + 1, -5.0, 0.0, math.nan, math.inf])
def test_a_query_rate_outside_1_hz_to_1_mhz_is_refused(rate):
    with pytest.raises(UserError, match=r"^--query-hz \S+: outside 1\.\.1e\+06 Hz$"):
        check_stream("stream", {"query_hz": rate}, ["rct"], [], LABELS)


@pytest.mark.parametrize("spec, words", [("declared:", "unknown latency model"), ("declared:gpu", "unknown hardware"),
                                         ("measured:2", "unknown latency model"), ("Declared:cpu", "unknown latency")])
def test_unknown_models_and_profiles_are_refused_naming_the_option(spec, words):
    with pytest.raises(UserError, match=f"^--latency {spec}: {words}"):
        check_stream("stream", {"latency": ["declared:cpu", spec]}, ["siamfc"], [], LABELS)


@pytest.mark.parametrize("trackers, latency", [
    (["siamfc", "kcf"], "declared:loihi"), (["sctn", "csrt"], "declared:cpu"), (["mil", "sctn_ann"], "declared:cpu"),
])
def test_the_tracker_without_a_declared_cost_is_named_among_others(trackers, latency):
    lacking = next(t for t in trackers if t in ("kcf", "csrt", "mil"))
    with pytest.raises(UserError, match=f"^--latency {latency}: tracker '{lacking}' has no latency under it"):
        check_stream("stream", {"latency": ["scaled:2", latency]}, trackers, [], LABELS)
    # the same trackers under measured and scaled models pass: only a declared model needs a cost
    assert check_stream("stream", {"latency": ["measured", "scaled:2"]}, trackers, [], LABELS) is not None
