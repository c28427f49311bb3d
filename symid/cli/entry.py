"""The command line: the parser, its subcommands (one module each, see
`symid.cli.commands`) and how every fault ends: a thin layer over `symid.api`.

Exit status: 0 success, 2 input error or unusable resource (an output that
cannot be written: disk full, file-size limit, permissions), 3 analysis
failed, 4 `symid size` found a drive that does not fit, 128 + N ended by
signal N (130 SIGINT, 143 SIGTERM, 129 SIGHUP, 141 a closed stdout pipe). Errors are one line on stderr, never a traceback.
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
from types import FrameType
from typing import Any, Callable, NoReturn, Sequence

from symid import progress
from symid.cli.options import Parser, UsageError
from symid.errors import (EXIT_INPUT, EXIT_SIGNAL_BASE, AnalysisError, SymidError, Terminated, check_signal,
                          clear_signals, note_signal)
from symid.text import number


def version() -> str:
    """The installed distribution's version (a checkout run without installing: unknown)."""
    from importlib.metadata import PackageNotFoundError
    from importlib.metadata import version as dist_version

    try:
        return dist_version("symid")
    except PackageNotFoundError:
        return "unknown (not installed)"


class _Version(argparse.Action):
    """`--version`, looked up only when asked: importlib.metadata reads every
    installed distribution, a tenth of a second of every command otherwise."""

    def __init__(self, option_strings: Sequence[str], dest: str = argparse.SUPPRESS,
                 default: str = argparse.SUPPRESS, help: str = "show program's version number and exit") -> None:
        super().__init__(option_strings, dest=dest, default=default, nargs=0, help=help)

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace, values: Any,
                 option_string: str | None = None) -> None:
        sys.stdout.write(f"symid {version()}\n")
        parser.exit()


def build_parser() -> argparse.ArgumentParser:
    """The whole command line: `symid` and every subcommand."""
    parser = Parser(prog="symid", description="Planar multibody inverse dynamics, derived by sympy.",
                     epilog="start with: symid example slider_crank; symid help format; "
                            "symid solve --help")
    parser.add_argument("--version", action=_Version)
    sub = parser.add_subparsers(dest="command", required=True, parser_class=Parser, metavar="COMMAND")

    from importlib import import_module

    from symid.cli.commands import MODULES

    for module in MODULES:
        import_module(module).register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except UsageError as exc:  # one line said; --help and --version still end by SystemExit
        return int(exc.code)  # type: ignore[arg-type]
    run: Callable[[argparse.Namespace], int] = args.run
    previous = _catch_signals()
    try:
        return _run(run, args)
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
        clear_signals()


def command() -> NoReturn:
    """The `symid` program (`python -m symid` and the installed script): `main`, then `leave`."""
    leave(main())


def leave(status: int) -> NoReturn:
    """End the process with `status`, skipping the interpreter's teardown.

    Freeing every object of sympy and numpy at exit takes a quarter of a
    second (0.25 s of a 1.8 s cached sweep), after the command is done. The
    exit handlers (`atexit`: e.g. removing a private temporary cache) still
    run and the standard streams are flushed; with another thread still
    alive, a profiler or tracer at work, or a stream that cannot be flushed,
    the normal exit runs instead.
    """
    import atexit
    import threading

    try:
        sys.stdout.flush()
        sys.stderr.flush()
    except (OSError, ValueError):  # reported by the normal exit, as before
        raise SystemExit(status) from None
    atexit._run_exitfuncs()
    if threading.active_count() > 1 or not isinstance(status, int) or sys.getprofile() or sys.gettrace():
        raise SystemExit(status)  # threads to join, or a profiler (cProfile) with results to write
    os._exit(status)


def _run(run: Callable[[argparse.Namespace], int], args: argparse.Namespace) -> int:
    """Run a subcommand; turn every fault into one line and its exit status."""
    try:
        try:
            status = run(args)
        except Exception:
            check_signal()  # an error a signal caused inside C code (its exception swallowed): the signal's
            raise
        finally:
            progress.end_lines()  # a bar whose generator is not yet closed ends its line before any message
        sys.stdout.flush()  # a closed pipe is found here, not at exit where it would be printed
        return status
    except SymidError as exc:
        message = str(exc)
        file = getattr(args, "file", None)
        if isinstance(exc, AnalysisError) and file and not message.startswith(str(file)):
            where = f"t = {number(exc.time)}: " if exc.time is not None else ""
            message = f"{file}: {where}{message}"
        print(f"symid: {message}", file=sys.stderr)
        return exc.exit_status
    except BrokenPipeError:
        # The reader of stdout (`| head -1`) has all it wanted: end quietly, as a
        # program killed by SIGPIPE would, and keep Python from reporting the
        # unflushed rest at exit.
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
        return EXIT_SIGNAL_BASE + signal.SIGPIPE
    except KeyboardInterrupt as exc:  # Ctrl-C, or a signal made `Terminated`
        signum = exc.signum if isinstance(exc, Terminated) else signal.SIGINT
        said = "interrupted" if signum == signal.SIGINT else f"terminated by {signal.Signals(signum).name}"
        kept = getattr(exc, "kept", None)
        print(f"symid: {said}{f'; {kept}' if kept else ''}", file=sys.stderr)
        return EXIT_SIGNAL_BASE + signum
    except MemoryError:
        print("symid: out of memory", file=sys.stderr)
        return EXIT_INPUT
    except OSError as exc:  # a machine fault no layer below named: still one line
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"symid: {where}{exc.strerror or exc}", file=sys.stderr)
        return EXIT_INPUT


# what signal.signal takes and returns
_Handler = Callable[[int, FrameType | None], Any] | int | signal.Handlers | None


def _raise_terminated(signum: int, frame: FrameType | None) -> None:
    note_signal(signum)  # kept: C code that swallows the exception below leaves it to `check_signal`
    raise Terminated(signum)


def _catch_signals() -> dict[int, _Handler]:
    """SIGTERM, SIGHUP and SIGINT raise `Terminated` (unless ignored, as under nohup);
    SIGXFSZ is ignored, so a file-size limit fails the write (EFBIG) instead of
    killing symid with its temporary file. Returns the handlers replaced."""
    previous: dict[int, _Handler] = {}
    wanted: dict[int, _Handler] = {signal.SIGTERM: _raise_terminated, signal.SIGHUP: _raise_terminated, signal.SIGXFSZ: signal.SIG_IGN,
              signal.SIGINT: _raise_terminated}
    for signum, handler in wanted.items():
        try:
            # SIGINT too: under `python -m`, a plain KeyboardInterrupt raised inside some
            # C call marks the interpreter to kill itself by SIGINT at exit, even when
            # caught (seen: exit -2 after "interrupted"); a subclass does not.
            if signal.getsignal(signum) in (signal.SIG_DFL, signal.default_int_handler):
                previous[signum] = signal.signal(signum, handler)
        except ValueError:  # not the main thread: leave signals alone
            break
    return previous


if __name__ == "__main__":
    raise SystemExit(main())
