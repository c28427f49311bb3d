"""The progress bar: shown on a terminal with the rate, silent in a pipe and under CI."""

from __future__ import annotations

import io
import os
import pty
import select

import pytest

from symid import api, progress
from symid.cli import main
from symid.errors import AnalysisError


class Terminal(io.StringIO):
    """A text stream that says it is a terminal."""

    def isatty(self) -> bool:
        return True


def ticking(step: float):
    """A clock that advances `step` seconds at each reading."""
    now = [0.0]

    def clock() -> float:
        now[0] += step
        return now[0]
    return clock


def test_terminal_shows_the_bar_with_its_rate_and_ends_the_line():
    out = Terminal()
    items = list(progress.bar(range(200), 200, "demo", stream=out, environ={}, delay=0, clock=ticking(0.02)))
    assert items == list(range(200))
    text = out.getvalue()
    assert text.startswith("\rdemo ") and text.endswith("\n")
    last = text.rstrip("\n").split("\r")[-1]
    assert "100%" in last and "200/200" in last
    # 200 instants in 201 ticks of 0.02 s: 49.75 instants/s.
    assert "49.75 instants/s" in last
    assert text.count("\r") < 200  # redrawn at most every INTERVAL, not per instant


def test_a_message_after_a_failure_in_the_consumer_starts_on_a_line_of_its_own(capsys, monkeypatch):
    """The consumer fails while the bar is suspended at its yield (a signal
    landing while rows are written): the generator, still referenced by the
    traceback, is not closed yet. The CLI's one-line message must not be
    glued to the bar's line (seen as `...0:19 leftsymid: interrupted`), and
    the bar writes nothing after it when it is closed at last."""
    out = Terminal()
    rows = progress.bar(range(10**6), 10**6, "sweep", stream=out, environ={}, delay=0, clock=ticking(0.2))

    def run(args):  # a subcommand interrupted between two rows
        for k in rows:
            if k == 5:
                raise KeyboardInterrupt
        return 0

    from symid.cli import entry
    status = entry._run(run, None)
    assert status == 130
    text = out.getvalue()
    assert text.endswith("\n") and "6/1000000" in text.rstrip("\n").split("\r")[-1], text
    rows.close()  # the traceback is gone: the generator's finally runs now
    assert out.getvalue() == text, "the bar wrote again after the message"


class InterruptedAtFirstDraw(Terminal):
    """A terminal whose first flush is interrupted: a signal landing while the
    bar's first line is written (the sweep's Ctrl-C test sends it the moment
    it sees that line)."""

    def __init__(self) -> None:
        super().__init__()
        self.flushes = 0

    def flush(self) -> None:
        self.flushes += 1
        if self.flushes == 1:
            raise KeyboardInterrupt


def test_a_signal_during_the_first_draw_still_ends_the_bars_line(capsys):
    """The bar's line counts as open from its first write on: a signal inside
    that write's flush ends it like any later one (it was glued to the
    message, `...0:18 leftsymid: interrupted`, once in a suite run)."""
    out = InterruptedAtFirstDraw()

    def run(args):  # a subcommand whose bar is interrupted while it first draws
        for _ in progress.bar(range(10**6), 10**6, "sweep", stream=out, environ={}, delay=0, clock=ticking(0.2)):
            pass
        return 0

    from symid.cli import entry
    assert entry._run(run, None) == 130
    assert out.getvalue().startswith("\rsweep ") and out.getvalue().endswith("\n"), repr(out.getvalue())


@pytest.mark.parametrize("ci", ["true", "1", "yes"])
def test_ci_keeps_it_silent_even_on_a_terminal(ci):
    out = Terminal()
    assert list(progress.bar(range(50), 50, stream=out, environ={"CI": ci}, delay=0,
                             clock=ticking(0.2))) == list(range(50))
    assert out.getvalue() == ""


def test_an_empty_ci_variable_does_not_count_as_ci():
    assert progress.enabled(Terminal(), {"CI": ""})
    assert progress.enabled(Terminal(), {"CI": "false"})


def test_a_pipe_or_a_file_stays_silent():
    out = io.StringIO()
    assert list(progress.bar(range(50), 50, stream=out, environ={}, delay=0, clock=ticking(0.2))) == list(range(50))
    assert out.getvalue() == ""
    read, write = os.pipe()
    with os.fdopen(read) as r, os.fdopen(write, "w") as w:
        assert not progress.enabled(w, {})


def test_a_quick_run_prints_nothing_before_the_delay():
    out = Terminal()
    list(progress.bar(range(50), 50, stream=out, environ={}, delay=0.5, clock=ticking(0.001)))
    assert out.getvalue() == ""


def test_the_line_is_ended_when_the_solve_fails_part_way():
    def failing():
        yield from range(10)
        raise AnalysisError("Newton did not converge", 0.5, 10)

    out = Terminal()
    with pytest.raises(AnalysisError):
        list(progress.bar(failing(), 100, stream=out, environ={}, delay=0, clock=ticking(0.2)))
    assert out.getvalue().endswith("\n")
    assert "10/100" in out.getvalue().split("\r")[-1]


def test_render_fits_the_width_and_handles_an_unknown_total():
    line = progress.render("slider_crank", 50, 200, 2.0, 60)
    assert len(line) <= 60 and " 25% " in line and "25 instants/s" in line and "0:06 left" in line
    assert progress.render("x", 7, None, 2.0, 80) == "x 7 instants  3.5 instants/s  0:02"


def _read_all(fd: int) -> bytes:
    chunks = []
    while select.select([fd], [], [], 0.2)[0]:
        try:
            data = os.read(fd, 65536)
        except OSError:  # EIO: the other side is closed
            break
        if not data:
            break
        chunks.append(data)
    return b"".join(chunks)


def test_solve_in_a_real_terminal_shows_the_bar_on_stderr(tmp_path, monkeypatch, capsys):
    monkeypatch.delenv("CI", raising=False)
    monkeypatch.setattr(progress, "DELAY", 0.0)
    master, slave = pty.openpty()
    with os.fdopen(slave, "w", encoding="utf-8") as terminal:
        monkeypatch.setattr("sys.stderr", terminal)
        assert main(["solve", str(api.example("slider_crank")), "-o", str(tmp_path / "sc.csv"),
                     "--steps", "21"]) == 0
        terminal.flush()
        shown = _read_all(master).decode("utf-8")
    os.close(master)
    assert "slider_crank" in shown and "100%" in shown and "instants/s" in shown and "21/21" in shown
    assert "instants/s" not in capsys.readouterr().out  # the table's report stays clean on stdout


def test_solve_into_a_pipe_shows_no_bar(tmp_path, monkeypatch):
    monkeypatch.delenv("CI", raising=False)
    monkeypatch.setattr(progress, "DELAY", 0.0)
    read, write = os.pipe()
    with os.fdopen(write, "w") as pipe:
        monkeypatch.setattr("sys.stderr", pipe)
        assert main(["solve", str(api.example("slider_crank")), "-o", str(tmp_path / "sc.csv"),
                     "--steps", "21"]) == 0
    with os.fdopen(read) as r:
        assert r.read() == ""
