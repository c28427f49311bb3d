"""Errors a user can cause, each with its documented exit status.

The command line turns these into one line on stderr and the exit status;
anything else escaping is a bug in symid, not in the user's input.
"""

from __future__ import annotations

EXIT_OK = 0
EXIT_INPUT = 2
EXIT_ANALYSIS = 3


class SymidError(Exception):
    """Base of every error caused by the user's input or mechanism."""

    exit_status = 1


class InputError(SymidError):
    """The input is wrong: file, key, value, expression, name or count.

    Args:
        message: what is wrong, naming the file and key where known.
    """

    exit_status = EXIT_INPUT


class AnalysisError(SymidError):
    """The analysis failed: Newton did not converge or `Phi_q` is singular.

    Attributes:
        time: the instant at which it stopped (None when not time-specific).
        solved: how many output instants were solved before it stopped.
    """

    exit_status = EXIT_ANALYSIS

    def __init__(self, message: str, time: float | None = None, solved: int = 0) -> None:
        super().__init__(message)
        self.time = time
        self.solved = solved


EXIT_SIGNAL_BASE = 128  # a run ended by signal N exits 128 + N, as a shell reports it


class Terminated(KeyboardInterrupt):
    """SIGTERM or SIGHUP arrived: raised by the command line's handler, so the
    same cleanup as for Ctrl-C (SIGINT) runs (temporary files removed).

    Attributes:
        signum: the signal's number; the exit status is 128 + signum.
    """

    def __init__(self, signum: int) -> None:
        super().__init__(signum)
        self.signum = signum


def say_kept(interrupt: KeyboardInterrupt, kept: str) -> None:
    """Attach to a Ctrl-C or signal what the interrupted command kept or
    left untouched (`"out.csv not written"`): the command line says it on
    the one line it prints (`symid: interrupted; out.csv not written`)."""
    interrupt.kept = kept  # type: ignore[attr-defined]
