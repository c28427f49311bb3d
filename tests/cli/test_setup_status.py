"""The setup status line: on a terminal past a delay, with the stage and the
elapsed time; nothing in a pipe, under CI, or for a quick setup."""

from __future__ import annotations

import io
import time

from symid import progress


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_status_shows_the_stage_and_elapsed_time_then_the_total() -> None:
    out = Terminal()
    with progress.status("symid: setting up", stream=out, environ={}, delay=0.05, interval=0.02):
        progress.stage("deriving")
        time.sleep(0.2)
        progress.stage("compiling")
        time.sleep(0.2)
    text = out.getvalue()
    assert "symid: setting up: deriving... " in text and "symid: setting up: compiling... " in text
    assert text.rstrip().split("\r")[-1].startswith("symid: setting up: done in ")
    assert text.endswith("\n")


def test_status_is_silent_for_a_quick_setup() -> None:
    out = Terminal()
    with progress.status("symid: setting up", stream=out, environ={}, delay=5.0):
        progress.stage("deriving")
    assert out.getvalue() == ""


def test_status_is_silent_in_a_pipe_and_under_ci() -> None:
    for out, env in ((io.StringIO(), {}), (Terminal(), {"CI": "true"})):
        with progress.status("symid: setting up", stream=out, environ=env, delay=0.0, interval=0.01):
            time.sleep(0.05)
        assert out.getvalue() == ""
