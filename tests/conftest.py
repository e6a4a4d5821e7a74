"""The bad-input catalogue's tally (docs/reliability.md): after a run that included any of its
cases, pytest prints "bad inputs: N tried, M held" (tried: the cases run, skipped ones left
out; held: those that passed)."""

from __future__ import annotations

CATALOGUE = ("tests/blender/test_bad_inputs.py", "tests/pipeline/test_outputs_publish.py")

_outcomes: dict[str, bool] = {}


def pytest_runtest_logreport(report) -> None:
    if not report.nodeid.startswith(CATALOGUE):
        return
    if report.skipped and report.when != "teardown":
        _outcomes.pop(report.nodeid, None)
    elif report.when == "call" or report.failed:  # a failed set-up counts as tried, not held
        _outcomes[report.nodeid] = _outcomes.get(report.nodeid, True) and report.passed


def pytest_terminal_summary(terminalreporter) -> None:
    if _outcomes:
        held = sum(_outcomes.values())
        terminalreporter.write_line(f"bad inputs: {len(_outcomes)} tried, {held} held")
