"""Errors a user can cause, each with its documented exit status.

The command line turns these into one line on stderr and the exit status;
anything else escaping is a bug in symid, not in the user's input.
"""

from __future__ import annotations

EXIT_OK = 0
EXIT_INPUT = 2
EXIT_ANALYSIS = 3
EXIT_DOES_NOT_FIT = 4  # symid size: a drive does not fit its motor (not an error: a verdict)


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


# Signals the command line's handler has seen and not yet reported. Its
# `Terminated` is raised wherever Python happens to be, which may be a Python
# callback inside C++ that swallows exceptions (CasADi's argument conversion
# does, so `symid solve --backend casadi` once ran on after Ctrl-C); every long
# loop calls `check_signal` between its steps, so a signal is answered at the
# next instant, variant or chunk all the same.
_PENDING: list[int] = []


def note_signal(signum: int) -> None:
    """Record that signal `signum` arrived (the command line's handler)."""
    if signum not in _PENDING:
        _PENDING.append(signum)


def check_signal() -> None:
    """Raise `Terminated` for a signal that arrived but was not reported yet
    (its exception swallowed by C code); nothing when none is pending.
    Called between the steps of every long loop: one list test."""
    if _PENDING:
        raise Terminated(_PENDING[0])


def clear_signals() -> None:
    """Forget the pending signals (the command line reported them)."""
    _PENDING.clear()


def say_kept(interrupt: KeyboardInterrupt, kept: str) -> None:
    """Attach to a Ctrl-C or signal what the interrupted command kept or
    left untouched (`"out.csv not written"`): the command line says it on
    the one line it prints (`symid: interrupted; out.csv not written`)."""
    interrupt.kept = kept  # type: ignore[attr-defined]
