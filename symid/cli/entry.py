"""The command line: a thin layer over `symid.api`.

Exit status: 0 success, 2 input error or unusable resource (an output that
cannot be written: disk full, file-size limit, permissions), 3 analysis
failed, 128 + N ended by signal N (130 SIGINT, 143 SIGTERM, 129 SIGHUP, 141 a
closed stdout pipe). Errors are one line on stderr, never a traceback.
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Callable, Iterator, Sequence

from symid.errors import EXIT_INPUT, EXIT_SIGNAL_BASE, AnalysisError, InputError, SymidError, Terminated
from symid.text import number, plural

if TYPE_CHECKING:
    from symid.tools import plan
    from symid.backends import Array, Evaluator
    from symid.output.results import Results


class HelpFormatter(argparse.ArgumentDefaultsHelpFormatter, argparse.RawDescriptionHelpFormatter):
    """Defaults shown where one exists (not for "unset: the file's value"); epilogs kept as written."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        if action.default in (None, False, [], argparse.SUPPRESS) or "default" in (action.help or ""):
            return action.help
        return super()._get_help_string(action)


class _Parser(argparse.ArgumentParser):
    """argparse, but a usage error is one line and exit status 2."""

    def __init__(self, *args: object, **kwargs: object) -> None:
        kwargs.setdefault("formatter_class", HelpFormatter)
        super().__init__(*args, **kwargs)  # type: ignore[arg-type]

    def error(self, message: str) -> None:  # type: ignore[override]
        print(f"{self.prog}: {message} (see --help)", file=sys.stderr)
        raise SystemExit(EXIT_INPUT)


def _set_values(pairs: Sequence[str], file: str = "") -> dict[str, str]:
    out = {}
    for pair in pairs:
        name, sep, value = pair.partition("=")
        if not sep or not name.strip():
            raise InputError(f"{file + ': ' if file else ''}--set {pair}: expected NAME=VALUE")
        out[name.strip()] = value.strip()
    return out


def _analysis_overrides(args: argparse.Namespace) -> dict[str, object]:
    return {"kind": args.kind, "t0": args.t0, "t1": args.t1, "steps": args.steps, "tol": args.tol,
            "cond_warn": args.cond_warn, "redundant": args.redundant, "assembly_jump": args.assembly_jump,
            "cond_column": args.cond or None}


def _run_options(args: argparse.Namespace) -> dict[str, object]:
    """Every option of `solve` that changes the run (part of the run-plan key, `symid.tools.plan`)."""
    return {"backend": args.backend, "set": list(args.set), **_analysis_overrides(args)}


def cmd_solve(args: argparse.Namespace) -> int:
    from symid.tools import plan

    plots = args.plot or args.plot_dir is not None
    key = None if plots else plan.key(args.file, _run_options(args))
    found = plan.load(key) if key is not None else None
    if found is not None:
        try:
            return _solve_planned(args, *found)
        except plan.Stale:  # its solver failed where the planned run succeeded: trust nothing of it
            plan.discard(key)  # type: ignore[arg-type]
    return _solve(args, key)


def _solve(args: argparse.Namespace, key: str | None) -> int:
    """The normal path: read, lay out, find or build the solver, solve; then keep a plan."""
    from symid import api, progress
    from symid.tools import plan
    from symid.output import summary

    with progress.status(f"symid: setting up the {args.backend} backend"):  # on a terminal, past 1 s
        progress.stage("reading and deriving")
        study = api.prepare(args.file, args.backend, _set_values(args.set, args.file),
                            **_analysis_overrides(args))
    out = Path(args.output) if args.output else Path(f"{study.mechanism.name}.csv")
    plots = args.plot or args.plot_dir is not None
    header = study.columns()
    keep = None if plots else summary.needed_columns(study.mechanism, header)
    results = _write_table(out, header, keep, study.rows(), study.analysis.steps, study.mechanism.name,
                           args.file, lambda: study.warnings)
    inputs = summary.inputs(study.mechanism, results)
    for line in summary.lines_of(inputs, results):
        print(line)
    if plots:
        from symid.output import plot

        written = plot.write_all(results, study.mechanism, args.plot_dir or out.parent, out.stem)
        for path in written.paths:
            print(path)
        for note in written.skipped:
            print(f"symid: skipped the {note}", file=sys.stderr)
    elif key is not None and keep is not None:
        made = plan.of(study, args.backend, header, keep, inputs)
        if made is not None and plan.key(args.file, _run_options(args)) == key:  # inputs unchanged meanwhile
            plan.store(key, made)
    return 0


def _solve_planned(args: argparse.Namespace, run: plan.Plan, evaluator: Evaluator) -> int:
    """A run with a plan: the same table, warnings and summary lines, without sympy.

    Raises:
        symid.tools.plan.Stale: the solver failed; nothing was written or printed.
    """
    from symid.output import summary
    from symid.numeric.stability import Notes

    out = Path(args.output) if args.output else Path(f"{run.name}.csv")
    notes = Notes(run.analysis)
    results = _write_table(out, run.columns, run.keep, run.rows(evaluator, notes), run.analysis.steps, run.name,
                           args.file, notes.lines)
    try:
        lines = summary.lines_of(run.summary, results)
    except ValueError:  # other instants than the plan's f(t) was evaluated at: evaluate it again
        from symid import api

        mech = api.load_mechanism(args.file, _set_values(args.set, args.file), **_analysis_overrides(args))
        lines = summary.lines(mech, results)
    for line in lines:
        print(line)
    return 0


def _write_table(out: Path, header: list[str], keep: list[str] | None, rows: Iterator[Array], steps: int,
                 name: str, file: str, warnings: Callable[[], list[str]]) -> Results:
    """Stream rows to the CSV (or .npz) file with a progress bar; print the
    run's warnings and the file's line. Returns the kept columns (`keep`, None: all)."""
    from symid import progress
    from symid.output import summary
    from symid.output.npz import write_npz
    from symid.tools.plan import Stale
    from symid.output.results import check_table_size, write_csv

    record = summary.Recorder(header, keep)
    write = write_npz if out.suffix.lower() == ".npz" else write_csv
    check_table_size(steps, len(header) if write is write_npz else len(record.columns), file)
    stale = False
    try:
        count = write(out, header, record(progress.bar(rows, steps, name)))
    except Stale:
        stale = True
        raise
    except AnalysisError as exc:
        raise AnalysisError(f"{file}: t = {number(exc.time)}: {exc}; the {plural(exc.solved, 'instant')} "
                            f"before it {'is' if exc.solved == 1 else 'are'} in {out}", exc.time,
                            exc.solved) from None
    finally:
        if not stale:
            for warning in warnings():  # once per kind, with its time span
                print(f"symid: warning: {warning}", file=sys.stderr)
    print(f"{out}: {count} instants, {len(header)} columns")
    return record.results()


def cmd_check(args: argparse.Namespace) -> int:
    from symid import api
    from symid.tools.check import check

    study = api.prepare(args.file, "reference", _set_values(args.set, args.file))
    report = check(study)
    print(report.text())
    if report.singular:
        raise AnalysisError(f"{args.file}: t = {number(study.analysis.t0)}: Phi_q is rank-deficient (rank "
                            f"{report.rank} < {report.ng}); dependent constraints: {', '.join(report.dependent)}")
    return 0


def cmd_example(args: argparse.Namespace) -> int:
    from symid import api

    if args.name is None:
        print("\n".join(api.examples()))
        return 0
    try:
        print(api.example(args.name))
    except FileNotFoundError as exc:
        raise InputError(str(exc).strip('"')) from None
    return 0


def version() -> str:
    """The installed distribution's version (a checkout run without installing: unknown)."""
    from importlib.metadata import PackageNotFoundError
    from importlib.metadata import version as dist_version

    try:
        return dist_version("symid")
    except PackageNotFoundError:
        return "unknown (not installed)"


SOLVE_EPILOG = """examples:
  symid solve "$(symid example slider_crank)" -o run.csv
  symid solve crank.toml --t1 2 --steps 401 --set omega=12.566 --backend c
  symid solve crank.toml --kind statics --cond --plot

The file's keys, defaults and the CSV columns: symid help format.
exit status: 0 ok, 2 bad input, 3 the analysis failed (solved instants kept)."""


def build_parser() -> argparse.ArgumentParser:
    """The whole command line: `symid` and every subcommand."""
    parser = _Parser(prog="symid", description="Planar multibody inverse dynamics, derived by sympy.",
                     epilog="start with: symid example slider_crank; symid help format; "
                            "symid solve --help")
    parser.add_argument("--version", action="version", version=f"symid {version()}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser, metavar="COMMAND")

    solve = sub.add_parser("solve", help="solve a mechanism file and write the results table (CSV)",
                           description="Solve a mechanism over time and write one row per instant.",
                           epilog=SOLVE_EPILOG)
    solve.add_argument("file", metavar="FILE", help="the mechanism file (TOML; symid help format)")
    solve.add_argument("-o", "--output", metavar="OUT",
                       help="table to write, .csv or .npz (default: <name>.csv in the current folder)")
    solve.add_argument("--kind", choices=("inverse_dynamics", "kinematics", "statics"),
                       help="what to compute (default: the file's [analysis] kind, else inverse_dynamics)")
    solve.add_argument("--t0", type=float, metavar="T", help="first instant (default: the file's, else 0)")
    solve.add_argument("--t1", type=float, metavar="T", help="last instant (default: the file's, else 1)")
    solve.add_argument("--steps", type=int, metavar="N",
                       help="number of output instants, t0 and t1 included (default: the file's, else 1001)")
    solve.add_argument("--tol", type=float, metavar="X",
                       help="Newton tolerance on max |Phi| and the last correction (default: the file's, "
                            "else 1e-12)")
    solve.add_argument("--cond", action="store_true", help="add the cond column (condition estimate of Phi_q)")
    solve.add_argument("--cond-warn", type=float, metavar="X", help="warn where cond exceeds X (default 1e6)")
    solve.add_argument("--redundant", choices=("error", "min_norm"),
                       help="redundant constraints: refuse (default) or solve with minimum-norm multipliers")
    solve.add_argument("--assembly-jump", choices=("error", "warn"),
                       help="a jump to another assembly mode: stop with exit 3 (default) or warn and continue")
    solve.add_argument("--backend", default="numpy", metavar="B",
                       help="how the derived expressions are evaluated: numpy (generated NumPy), c (generated "
                            "C, fastest), casadi, or reference (no code generation)")
    solve.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                       help="override a parameter (repeatable; VALUE may be an expression)")
    solve.add_argument("--plot", action="store_true", help="also write PNG plots beside the output")
    solve.add_argument("--plot-dir", metavar="DIR", help="folder for the plots (implies --plot)")
    solve.set_defaults(run=cmd_solve)

    chk = sub.add_parser("check", help="validate a file; report ng, nc, rank and conditioning at q0",
                         description="Read and validate a mechanism file; report its sizes, the rank of "
                                     "Phi_q and its condition at t0.",
                         epilog='examples:\n  symid check "$(symid example four_bar)"\n'
                                "  symid check crank.toml --set L2=0.35")
    chk.add_argument("file", metavar="FILE", help="the mechanism file (TOML; symid help format)")
    chk.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                     help="override a parameter (repeatable)")
    chk.set_defaults(run=cmd_check)

    ex = sub.add_parser("example", help="print the path of a bundled example (no name: list them)",
                        description="Print the path of a bundled example mechanism file.",
                        epilog="examples:\n  symid example                  # list the examples\n"
                               "  cp \"$(symid example four_bar)\" my_linkage.toml   # start your own")
    ex.add_argument("name", nargs="?", metavar="NAME", help="an example's name; omit to list them")
    ex.set_defaults(run=cmd_example, file="example")

    from importlib import import_module

    from symid.cli.commands import MODULES

    for module in MODULES:
        import_module(module).register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    run: Callable[[argparse.Namespace], int] = args.run
    previous = _catch_signals()
    try:
        return _run(run, args)
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)


def _run(run: Callable[[argparse.Namespace], int], args: argparse.Namespace) -> int:
    """Run a subcommand; turn every fault into one line and its exit status."""
    try:
        status = run(args)
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
    except Terminated as exc:
        said = "interrupted" if exc.signum == signal.SIGINT else f"terminated by {signal.Signals(exc.signum).name}"
        print(f"symid: {said}", file=sys.stderr)
        return EXIT_SIGNAL_BASE + exc.signum
    except KeyboardInterrupt:
        print("symid: interrupted", file=sys.stderr)
        return EXIT_SIGNAL_BASE + signal.SIGINT
    except MemoryError:
        print("symid: out of memory", file=sys.stderr)
        return EXIT_INPUT
    except OSError as exc:  # a machine fault no layer below named: still one line
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"symid: {where}{exc.strerror or exc}", file=sys.stderr)
        return EXIT_INPUT


def _raise_terminated(signum: int, frame: object) -> None:
    raise Terminated(signum)


def _catch_signals() -> dict[int, signal.Handlers | Callable[[int, object], None] | int | None]:
    """SIGTERM, SIGHUP and SIGINT raise `Terminated` (unless ignored, as under nohup);
    SIGXFSZ is ignored, so a file-size limit fails the write (EFBIG) instead of
    killing symid with its temporary file. Returns the handlers replaced."""
    previous: dict[int, signal.Handlers | Callable[[int, object], None] | int | None] = {}
    wanted = {signal.SIGTERM: _raise_terminated, signal.SIGHUP: _raise_terminated, signal.SIGXFSZ: signal.SIG_IGN,
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
