"""The command line's progress bar (pipeline/progress.py) against a fake terminal and a fake clock,
and the verbosity switches every command takes (pipeline/command.py)."""

from __future__ import annotations

import argparse
import io

import pytest

from classic_bake.kernels.progress import drain
from classic_bake.pipeline.command import Command, RunContext
from classic_bake.pipeline.progress import (
    NORMAL,
    QUIET,
    VERBOSE,
    ProgressBar,
    clock_text,
    time_left,
)


class Terminal(io.StringIO):
    """A stream that says it is a terminal."""

    def isatty(self):
        return True


class Clock:
    def __init__(self):
        self.now = 100.0

    def __call__(self):
        return self.now


def job(fractions, clock, seconds_per_step=1.0):
    """A step yielding `fractions`, the clock moving `seconds_per_step` before each."""
    for f in fractions:
        clock.now += seconds_per_step
        yield f
    return "result"


def frames(text: str) -> list[str]:
    """The lines a terminal shows one after another (each redraw starts with '\\r')."""
    return [f.rstrip() for f in text.replace("\n", "\r").split("\r") if f.strip()]


def test_clock_text_and_time_left():
    assert [clock_text(s) for s in (0, 7.4, 59.6, 750, 3723)] == [
        "0:00", "0:07", "1:00", "12:30", "1:02:03"]
    assert time_left(0.25, 10.0) == pytest.approx(30.0)  # 10 s for a quarter: 30 s to go
    assert time_left(0.005, 10.0) is None  # under 1%: no estimate
    assert time_left(0.5, 0.1) is None  # under half a second: no estimate


def test_a_terminal_shows_a_bar_with_the_time_left():
    stream, clock = Terminal(), Clock()
    bar = ProgressBar("trace", NORMAL, stream=stream, clock=clock, width=80)
    assert drain(job([0.25, 0.5, 0.75], clock), bar) == "result"
    bar.close()
    shown = frames(stream.getvalue())
    assert shown[0].startswith("trace  25% [") and shown[0].endswith("0:01 elapsed, ~0:03 left")
    assert "50%" in shown[1] and shown[1].endswith("0:02 elapsed, ~0:02 left")
    assert shown[-1].startswith("trace 100% [") and shown[-1].endswith("0:03 elapsed")
    assert "#" * 10 in shown[-1] and "." not in shown[-1].split("]")[0]
    assert stream.getvalue().endswith("\n") and all(len(f) < 80 for f in shown)


def test_redraws_are_limited_to_ten_a_second():
    stream, clock = Terminal(), Clock()
    bar = ProgressBar("radiosity", NORMAL, stream=stream, clock=clock, width=80)
    drain(job([k / 1000 for k in range(1, 1001)], clock, seconds_per_step=0.001), bar)
    assert len(frames(stream.getvalue())) == 10  # 1 s of work: a frame per 0.1 s


def test_not_a_terminal_shows_nothing_unless_verbose():
    for verbosity in (QUIET, NORMAL):
        stream, clock = io.StringIO(), Clock()
        with ProgressBar("trace", verbosity, stream=stream, clock=clock) as bar:
            drain(job([0.5, 1.0], clock), bar)
        assert stream.getvalue() == ""
    stream, clock = io.StringIO(), Clock()
    with ProgressBar("trace", VERBOSE, stream=stream, clock=clock) as bar:
        drain(job([k / 20 for k in range(1, 20)], clock), bar)
    lines = stream.getvalue().splitlines()
    assert [line.split()[1] for line in lines] == [f"{10 * k}%" for k in range(1, 11)]
    assert "\r" not in stream.getvalue() and lines[0] == "trace  10% 0:02 elapsed, ~0:18 left"


def test_quiet_on_a_terminal_shows_nothing():
    stream, clock = Terminal(), Clock()
    with ProgressBar("trace", QUIET, stream=stream, clock=clock) as bar:
        drain(job([0.5, 1.0], clock), bar)
    assert stream.getvalue() == ""


def test_an_interrupted_bar_is_wiped():
    stream, clock = Terminal(), Clock()
    with pytest.raises(KeyboardInterrupt):
        with ProgressBar("trace", NORMAL, stream=stream, clock=clock, width=60) as bar:
            bar(0.3)
            raise KeyboardInterrupt
    text = stream.getvalue()
    assert text.endswith("\r") and "100%" not in text and not text.endswith("\n")


def test_the_width_follows_the_terminal():
    clock = Clock()
    narrow = ProgressBar("shadowmap", NORMAL, stream=Terminal(), clock=clock, width=50)
    wide = ProgressBar("shadowmap", NORMAL, stream=Terminal(), clock=clock, width=200)
    narrow.fraction = wide.fraction = 0.5
    assert len(narrow.line(clock())) <= 49
    assert wide.line(clock()).count("#") == 20  # 40 cells at most, half filled


# --- the verbosity switches and the run context ------------------------------------------------------

def command() -> Command:
    return Command(name="demo-ish", help="", run=lambda ctx: None,
                   add_arguments=lambda p: p.add_argument("--size", type=int, default=3))


def parse(*argv) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    command().add_arguments(parser)
    return parser.parse_args(list(argv))


def test_every_command_takes_quiet_and_verbose():
    assert vars(parse()) == {"size": 3, "quiet": False, "verbose": False}
    assert parse("--quiet").quiet and parse("--verbose", "--size", "4").verbose
    with pytest.raises(SystemExit):
        parse("--quiet", "--verbose")  # one or the other


def test_quiet_silences_messages(capsys):
    RunContext(command(), parse("--quiet"), None, None).say("hello")
    RunContext(command(), parse(), None, None).say("world")
    assert capsys.readouterr().out == "world\n"


def test_a_phase_closes_its_bars(monkeypatch):
    from classic_bake.pipeline import outputs

    stream, clock = Terminal(), Clock()
    monkeypatch.setattr("sys.stderr", stream)
    ctx = RunContext(command(), parse(), None, outputs.PhaseTimer())
    with ctx.phase("bake"):
        bar = ctx.progress()
        bar.clock = clock
        drain(job([0.5], clock), bar)
    assert bar.closed and stream.getvalue().endswith("\n")
    assert frames(stream.getvalue())[-1].startswith("demo-ish 100% [")
    assert "bake" in ctx.timer.seconds
    with pytest.raises(ValueError), ctx.phase("fails"):
        failing = ctx.progress("fails")
        failing(0.2)
        raise ValueError("bad input")
    assert failing.closed and stream.getvalue().endswith("\r")  # wiped for the error line
