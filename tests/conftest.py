"""Test-wide set-up: the shared helpers beside this file (synthetic.py) import as top-level modules,
`--cpu-durations N` lists the tests that cost the most CPU time, and `refuse_calls` makes named functions fail a
test if they run."""

import sys
from pathlib import Path

import pytest

HELPERS = str(Path(__file__).resolve().parent)
if HELPERS not in sys.path:
    sys.path.insert(0, HELPERS)



@pytest.fixture
def refuse_calls(monkeypatch: pytest.MonkeyPatch):
    """A function taking dotted names of functions: each then fails the test, naming itself, if it is called."""
    def refuse(*targets: str) -> None:
        for target in targets:
            def boom(*args, _target: str = target, **kwargs):
                raise AssertionError(f"{_target} was called")
            monkeypatch.setattr(target, boom)
    return refuse


_CPU_START = pytest.StashKey[float]()
_CPU_ROWS: list[tuple[float, str]] = []  # (CPU seconds, test id), in the process that prints the summary


def pytest_addoption(parser: pytest.Parser) -> None:
    """The --cpu-durations option."""
    parser.addoption("--cpu-durations", type=int, default=None, metavar="N",
                     help="list the N tests that used the most CPU seconds (this process and its finished children, "
                          "setup to teardown): a cost a busy machine does not inflate, unlike --durations")


def _cpu_seconds() -> float:
    """CPU seconds (user + system) of this process and of its children that have been waited for."""
    import resource

    own, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item: pytest.Item, nextitem: pytest.Item | None):
    """Note the CPU clock as a test's setup begins."""
    item.stash[_CPU_START] = _cpu_seconds()
    yield


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo):
    """With --cpu-durations, the teardown report carries the test's CPU seconds from setup to teardown."""
    outcome = yield
    report = outcome.get_result()
    if call.when == "teardown" and item.config.getoption("cpu_durations") is not None:
        # a user property travels with the report, so pytest-xdist's workers hand it to the controller
        report.user_properties.append(("cpu_s", _cpu_seconds() - item.stash[_CPU_START]))


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    """Collect each test's CPU seconds (in the controller too, under pytest-xdist)."""
    for name, value in report.user_properties:
        if name == "cpu_s" and report.when == "teardown":
            _CPU_ROWS.append((value, report.nodeid))


def pytest_terminal_summary(terminalreporter, config: pytest.Config) -> None:
    """Print the total CPU seconds and the N most costly tests (every test for N = 0)."""
    n = config.getoption("cpu_durations")
    if n is None or not _CPU_ROWS:
        return
    total = sum(c for c, _ in _CPU_ROWS)
    terminalreporter.write_sep("=", f"CPU time: {total:.1f} s over {len(_CPU_ROWS)} tests; the most costly")
    for cpu, nodeid in sorted(_CPU_ROWS, reverse=True)[:n or None]:
        terminalreporter.write_line(f"{cpu:8.2f}s cpu  {nodeid}")
