"""A child started as a user's shell starts it: SIGINT, SIGTERM and SIGHUP at
their defaults, whatever the test run inherited (a background job of a
non-interactive shell ignores SIGINT, nohup ignores SIGHUP; symid leaves an
ignored signal ignored, as it should)."""

from __future__ import annotations

import signal


def default_signals() -> None:
    """`preexec_fn` of a child that is to answer the signals a test sends it."""
    for s in (signal.SIGTERM, signal.SIGHUP, signal.SIGINT):
        signal.signal(s, signal.SIG_DFL)
