"""Every number of every option of every subcommand is checked at parsing
(`symid.cli.options.Number`): nan, inf, a negative count, a value past its
range or not a number at all is one line naming the option, exit 2, before
any file is read. The cases are generated from the argparse parsers, so an
option added later is covered (or fails the first test if it skips `Number`).
"""

from __future__ import annotations

import argparse
import subprocess
import sys

import pytest

from symid import api
from symid.cli import main
from symid.cli.entry import build_parser
from symid.cli.options import Number


def _subcommands() -> dict[str, argparse.ArgumentParser]:
    parser = build_parser()
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(action.choices)


SUBCOMMANDS = _subcommands()


def _required(parser: argparse.ArgumentParser) -> list[str]:
    """Placeholder arguments that satisfy the parser's required ones (never read: parsing fails first)."""
    out: list[str] = []
    for action in parser._actions:
        if not action.option_strings and action.nargs not in ("?", "*", argparse.REMAINDER):
            out.append("placeholder.toml")
        elif action.option_strings and action.required:
            out += [action.option_strings[-1], "placeholder"]
    return out


def _numeric() -> list[tuple[str, str, Number]]:
    """(subcommand, option, its Number) for every option that takes a number."""
    found = []
    for name, parser in SUBCOMMANDS.items():
        for action in parser._actions:
            if isinstance(action.type, Number):
                found.append((name, action.option_strings[-1], action.type))
    return found


def _bad_values(kind: Number) -> list[str]:
    """What each numeric option must refuse: not finite, not a number, and just past each end."""
    bad = ["nan", "inf", "-inf", "1e400", "-1e400", "twelve", ""]
    if kind.whole:
        bad += ["2.5", "1e3"]
    if kind.lo is not None:
        bad.append(str(kind.lo) if kind.lo_open else (str(int(kind.lo) - 1) if kind.whole else repr(kind.lo - 1)))
    if kind.hi is not None:
        bad.append(str(int(kind.hi) + 1) if kind.whole else repr(kind.hi * 2 if kind.hi > 0 else kind.hi + 1))
    return bad


def _good_values(kind: Number) -> list[str]:
    """An ordinary value inside the range and each end of it, which must be taken."""
    lo = kind.lo if kind.lo is not None else -3.0
    hi = kind.hi if kind.hi is not None else lo + 6.0
    middle = (lo + hi) / 2 if hi - lo < 1e6 else lo + 2
    good = [str(int(middle)) if kind.whole else repr(middle + 0.25)]
    if kind.lo is not None:
        good.append(repr(kind.lo * (1 + 1e-12) + (1e-300 if kind.lo == 0 else 0)) if kind.lo_open and not kind.whole
                    else str(int(kind.lo)) if kind.whole else repr(kind.lo))
    if kind.hi is not None:
        good.append(str(int(kind.hi)) if kind.whole else repr(kind.hi))
    return good


NUMERIC = _numeric()
BAD = [(c, o, v) for c, o, k in NUMERIC for v in _bad_values(k)]
GOOD = [(c, o, v) for c, o, k in NUMERIC for v in _good_values(k)]


@pytest.mark.parametrize("name", sorted(SUBCOMMANDS))
def test_every_numeric_option_is_a_checked_number(name: str) -> None:
    for action in SUBCOMMANDS[name]._actions:
        if action.type is not None:
            assert isinstance(action.type, Number), f"symid {name} {action.option_strings}: type {action.type!r} " \
                                                    "is not checked (use symid.cli.options.Number)"


def test_the_walk_finds_the_numeric_options() -> None:
    found = {(c, o) for c, o, _ in NUMERIC}
    for expected in [("solve", "--t0"), ("solve", "--steps"), ("solve", "--tol"), ("solve", "--cond-warn"),
                     ("sweep", "--seed"), ("sweep", "--sample"), ("sweep", "--workers"), ("sweep", "--t1"),
                     ("optimize", "--maxiter"), ("bench", "--budget"), ("bench", "--instants"), ("bench", "--tol")]:
        assert expected in found


@pytest.mark.parametrize(("command", "option", "value"), BAD, ids=[f"{c}{o}={v}" for c, o, v in BAD])
def test_a_bad_number_is_one_line_naming_the_option_exit_2(command: str, option: str, value: str, capsys) -> None:
    status = main([command, *_required(SUBCOMMANDS[command]), f"{option}={value}"])
    err = capsys.readouterr().err
    assert status == 2, err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert f"argument {option}: must be a " in err and f"not {value!r}" in err, err


@pytest.mark.parametrize(("command", "option", "value"), GOOD, ids=[f"{c}{o}={v}" for c, o, v in GOOD])
def test_each_end_of_a_range_is_taken(command: str, option: str, value: str) -> None:
    args = SUBCOMMANDS[command].parse_args([*_required(SUBCOMMANDS[command]), f"{option}={value}"])
    assert getattr(args, option.lstrip("-").replace("-", "_")) == (int(value) if "." not in value and "e" not in value
                                                                     else float(value))


@pytest.mark.parametrize("args", [["sweep", "--seed", "-1", "--sample", "3", "--uniform", "L_rod=0.3,0.4"],
                                  ["bench", "--budget", "nan"]])
def test_the_reported_cases_end_in_one_line_as_a_process(args: list[str], tmp_path) -> None:
    """As the issue ran them: a real process, no traceback, exit 2, nothing written."""
    crank = str(api.example("slider_crank"))
    run = subprocess.run([sys.executable, "-m", "symid", args[0], crank, *args[1:]], cwd=tmp_path,
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 2, run.stderr
    assert run.stderr.count("\n") == 1 and "Traceback" not in run.stderr, run.stderr
    assert f"argument {args[1]}" in run.stderr
    assert not list(tmp_path.iterdir())
