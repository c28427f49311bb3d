"""What the subcommands share: the argparse classes (one-line usage errors,
defaults in the help), the mechanism FILE and `--set` options and their
pairs, the options that change a run, and `Number`, the type of every
numeric option (finite, in range, checked as argparse reads it).
"""

from __future__ import annotations

import argparse
import math
import sys
from typing import Sequence

from symid.errors import EXIT_INPUT, InputError
from symid.io.limits import MAX_STEPS


class HelpFormatter(argparse.ArgumentDefaultsHelpFormatter, argparse.RawDescriptionHelpFormatter):
    """Defaults shown where one exists (not for "unset: the file's value"); epilogs kept as written."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        if action.default in (None, False, [], argparse.SUPPRESS) or "default" in (action.help or ""):
            return action.help
        return super()._get_help_string(action)


class UsageError(SystemExit):
    """A command line argparse refused (its line already printed): `main` returns its exit status 2."""


class Parser(argparse.ArgumentParser):
    """argparse, but a usage error is one line and exit status 2."""

    def __init__(self, *args: object, **kwargs: object) -> None:
        kwargs.setdefault("formatter_class", HelpFormatter)
        super().__init__(*args, **kwargs)  # type: ignore[arg-type]

    def error(self, message: str) -> None:  # type: ignore[override]
        print(f"{self.prog}: {message} (see --help)", file=sys.stderr)
        raise UsageError(EXIT_INPUT)


MECHANISM_HELP = "the mechanism file (TOML; symid help format)"


def add_file(p: argparse.ArgumentParser, help: str = MECHANISM_HELP) -> None:
    """The positional FILE: the mechanism file a command reads (`args.file`)."""
    p.add_argument("file", metavar="FILE", help=help)


def add_set(p: argparse.ArgumentParser, help: str = "override a parameter (repeatable)") -> None:
    """`--set NAME=VALUE` (repeatable, `args.set`, read by `set_values`); `help`
    says what the override means to this command."""
    p.add_argument("--set", action="append", default=[], metavar="NAME=VALUE", help=help)


def set_values(pairs: Sequence[str], file: str = "") -> dict[str, str]:
    """`--set NAME=VALUE` pairs as name -> expression text (an input error names a malformed one)."""
    out = {}
    for pair in pairs:
        name, sep, value = pair.partition("=")
        if not sep or not name.strip():
            raise InputError(f"{file + ': ' if file else ''}--set {pair}: expected NAME=VALUE")
        out[name.strip()] = value.strip()
    return out


def analysis_overrides(args: argparse.Namespace) -> dict[str, object]:
    """The `[analysis]` keys a `solve` command line overrides (None: the file's)."""
    return {"kind": args.kind, "t0": args.t0, "t1": args.t1, "steps": args.steps, "tol": args.tol,
            "cond_warn": args.cond_warn, "redundant": args.redundant, "assembly_jump": args.assembly_jump,
            "cond_column": args.cond or None}


def run_options(args: argparse.Namespace) -> dict[str, object]:
    """Every option of `solve` that changes the run (part of the run-plan key, `symid.tools.plan`)."""
    return {"backend": args.backend, "set": list(args.set), **analysis_overrides(args)}


def add_time_grid(p: argparse.ArgumentParser, kinds: Sequence[str], per: str) -> None:
    """`--kind`, `--t0`, `--t1`, `--steps` and `--tol` of a study command (sweep,
    optimize): each overrides the file's `[analysis]` key for every `per`."""
    p.add_argument("--kind", choices=tuple(kinds), help="what to compute (default: the file's)")
    p.add_argument("--t0", type=TIME, metavar="T", help="first instant (default: the file's)")
    p.add_argument("--t1", type=TIME, metavar="T", help="last instant (default: the file's)")
    p.add_argument("--steps", type=STEPS, metavar="N", help=f"instants per {per} (default: the file's)")
    p.add_argument("--tol", type=TOL, metavar="X", help="Newton tolerance (default: the file's)")


class Number:
    """The type of a numeric option: its text read as an int or a finite float
    within [lo, hi] (None: unbounded), else argparse's one-line usage error
    naming the option (exit 2). Every numeric option of every subcommand is
    one of these (a test walks the parsers), so nan, inf, -1 or 1e400 never
    reach a run.

    Args:
        whole: an int (a decimal integer) rather than a float.
        lo, hi: the range, both included; lo_open: lo itself excluded (a tolerance > 0).
    """

    def __init__(self, whole: bool, lo: float | None = None, hi: float | None = None, lo_open: bool = False) -> None:
        self.whole, self.lo, self.hi, self.lo_open = whole, lo, hi, lo_open
        self.__name__ = "whole number" if whole else "number"  # argparse's name of the type

    def __call__(self, text: str) -> int | float:
        value: int | float
        try:
            value = int(text.strip(), 10) if self.whole else float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be a {self.range()}, not {text!r}") from None
        if (not self.whole and not math.isfinite(value)) or not self.inside(value):
            raise argparse.ArgumentTypeError(f"must be a {self.range()}, not {text!r}")
        return value

    def inside(self, value: float) -> bool:
        if self.lo is not None and not (value > self.lo if self.lo_open else value >= self.lo):
            return False
        return self.hi is None or value <= self.hi

    def range(self) -> str:
        """What the option takes, e.g. "whole number from 1 to 10000000" or "finite number > 0 and <= 1"."""
        show = (lambda x: str(int(x))) if self.whole else (lambda x: f"{x:g}")
        bounds = ([f"{'>' if self.lo_open else '>='} {show(self.lo)}"] if self.lo is not None else []) + \
                 ([f"<= {show(self.hi)}"] if self.hi is not None else [])
        if self.lo is not None and self.hi is not None and not self.lo_open:
            bounds = [f"from {show(self.lo)} to {show(self.hi)}"]
        return " ".join(["whole number" if self.whole else "finite number", " and ".join(bounds)]).strip()


# the options that override an [analysis] key take what the key takes (symid.io.reader;
# whether t1 > t0 and the grid's instants are distinct doubles is checked there, with both)
TIME = Number(False)
STEPS = Number(True, 1, MAX_STEPS)
TOL = Number(False, 0.0, lo_open=True)
COND_WARN = Number(False, 1.0)  # a condition number is >= 1
