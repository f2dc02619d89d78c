"""plan_benchmark's refusals name its parameters; `dvsot bench` has them name its flags (dvsot.cli.bench.FLAGS)."""

from __future__ import annotations

import pytest

from benchmarks.bench.plan import plan_benchmark
from dvsot.cli.bench import FLAGS
from dvsot.core.errors import UserError

CASES = [  # (plan_benchmark's arguments besides trackers=["rct"], the message by parameter, the message by flag)
    (dict(jobs=0), "jobs must be >= 1, got 0", "--jobs must be >= 1, got 0"),
    (dict(scheduler="bogus"), "scheduler must be local:N", "--scheduler must be local:N"),
    (dict(max_segments=0), "max_segments must be >= 1, got 0", "--max-segments must be >= 1, got 0"),
    (dict(tracker_modules=["no_such_module_x"]), "tracker_modules no_such_module_x: cannot import",
     "--tracker-module no_such_module_x: cannot import"),
    (dict(options=["rct-size=3"]), "options 'rct-size=3': expected TRACKER.KEY=VALUE",
     "--option 'rct-size=3': expected TRACKER.KEY=VALUE"),
    (dict(options=["sctn.fast=false"]), "options 'sctn.fast=false': tracker 'sctn' is not in this run",
     "--option 'sctn.fast=false': tracker 'sctn' is not in this run"),
    (dict(checkpoint="c.pt"),
     "checkpoint c.pt: only used by trackers sctn, sctn_ann, siamfc, goturn, siamrpn, siammask, ocean or automatch",
     "--checkpoint c.pt: only used by --tracker sctn, sctn_ann, siamfc, goturn, siamrpn, siammask, ocean or automatch"),
    (dict(data=None), "or give data", "or give --data"),  # no default data where the run starts
]


@pytest.mark.parametrize("kwargs, by_name, by_flag", CASES, ids=[c[1].split()[0] for c in CASES])
def test_messages_name_parameters_or_the_callers_labels(kwargs, by_name, by_flag, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for labels, words in ((None, by_name), (FLAGS, by_flag)):
        with pytest.raises(UserError) as err:
            plan_benchmark(["rct"], out_dir=tmp_path / "out", labels=labels, **kwargs)
        assert words in str(err.value)
        assert not (tmp_path / "out").exists()
