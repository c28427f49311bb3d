"""`symid solve`: read a mechanism, solve it over time, write the table.

A run with a plan (`symid.tools.plan`: the same command, file, tables and
symid as a run before) reuses the cached solver without sympy; any other run
takes the normal path and then keeps a plan. Either way the table is written
through one helper (progress bar, warnings), then the summary and the plots.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Callable, Iterator

from symid.cli.options import COND_WARN, STEPS, TIME, TOL, add_file, add_set, analysis_overrides, run_options, set_values
from symid.errors import AnalysisError, say_kept
from symid.text import number, plural

if TYPE_CHECKING:
    from symid.backends import Array, Evaluator
    from symid.model.mechanism import Mechanism
    from symid.output.results import Results
    from symid.tools import plan

SOLVE_EPILOG = """examples:
  symid solve "$(symid example slider_crank)" -o run.csv
  symid solve crank.toml --t1 2 --steps 401 --set omega=12.566 --backend c
  symid solve crank.toml --kind statics --cond --plot
  symid solve crank.toml --sensitivity L_crank,m_slider --sensitivity-of motor.T_j

The file's keys, defaults and the CSV columns: symid help format.
exit status: 0 ok, 2 bad input, 3 the analysis failed (solved instants kept)."""


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    solve = sub.add_parser("solve", help="solve a mechanism file and write the results table (CSV)",
                           description="Solve a mechanism over time and write one row per instant.",
                           epilog=SOLVE_EPILOG)
    add_file(solve)
    solve.add_argument("-o", "--output", metavar="OUT",
                       help="table to write, .csv, .npz or .parquet (default: <name>.csv in the current folder)")
    solve.add_argument("--kind", choices=("inverse_dynamics", "kinematics", "statics"),
                       help="what to compute (default: the file's [analysis] kind, else inverse_dynamics)")
    solve.add_argument("--t0", type=TIME, metavar="T", help="first instant (default: the file's, else 0)")
    solve.add_argument("--t1", type=TIME, metavar="T", help="last instant (default: the file's, else 1)")
    solve.add_argument("--steps", type=STEPS, metavar="N",
                       help="number of output instants, t0 and t1 included (default: the file's, else 1001)")
    solve.add_argument("--tol", type=TOL, metavar="X",
                       help="Newton tolerance on max |Phi| and the last correction (default: the file's, "
                            "else 1e-12)")
    solve.add_argument("--cond", action="store_true", help="add the cond column (condition estimate of Phi_q)")
    solve.add_argument("--cond-warn", type=COND_WARN, metavar="X", help="warn where cond exceeds X (default 1e6)")
    solve.add_argument("--redundant", choices=("error", "min_norm"),
                       help="redundant constraints: refuse (default) or solve with minimum-norm multipliers")
    solve.add_argument("--assembly-jump", choices=("error", "warn"),
                       help="a jump to another assembly mode: stop with exit 3 (default) or warn and continue")
    solve.add_argument("--backend", default="numpy", metavar="B",
                       help="how the derived expressions are evaluated: numpy (generated NumPy), c (generated "
                            "C, fastest), casadi, or reference (no code generation)")
    add_set(solve, "override a parameter (repeatable; VALUE may be an expression)")
    solve.add_argument("--sensitivity", metavar="NAME[,NAME...]",
                       help="add d(COLUMN)/d(NAME) columns: the exact derivative of each chosen column by these "
                            "base parameters, after all other columns")
    solve.add_argument("--sensitivity-of", metavar="COLUMN[,COLUMN...]",
                       help="the columns to differentiate (default: the drivers' effort columns and the "
                            "reaction columns)")
    solve.add_argument("--plot", action="store_true", help="also write PNG plots beside the output")
    solve.add_argument("--plot-dir", metavar="DIR", help="folder for the plots (implies --plot)")
    solve.set_defaults(run=cmd_solve)


def cmd_solve(args: argparse.Namespace) -> int:
    from symid.io.files import check_folder, check_target, output_format
    from symid.output.tables import SUFFIXES
    from symid.tools import plan

    if args.output:  # the format follows the suffix, and the folder takes it, else refused before any work
        output_format(args.output, SUFFIXES, "a results table")
        check_target(args.output)
    plots = args.plot or args.plot_dir is not None
    if args.plot_dir is not None:  # a file in the way is named before the run, not after its table
        check_folder(args.plot_dir)
    sensitive = args.sensitivity is not None or args.sensitivity_of is not None  # a plan has no sensitivities
    key = None if plots or sensitive else plan.key(args.file, run_options(args))
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
    from symid.io.files import beside
    from symid.tools import plan
    from symid.output import summary

    with progress.status(f"symid: setting up the {args.backend} backend"):  # on a terminal, past 1 s
        progress.stage("reading and deriving")
        study = api.prepare(args.file, args.backend, set_values(args.set, args.file),
                            sensitivity=args.sensitivity, sensitivity_of=args.sensitivity_of,
                            **analysis_overrides(args))
    out = Path(args.output) if args.output else Path(f"{study.mechanism.name}.csv")
    plots = args.plot or args.plot_dir is not None
    header = study.columns()
    keep = None if plots else summary.needed_columns(study.mechanism, header)
    results = _write_table(out, header, keep, study.blocks(), study.analysis.steps, study.mechanism.name,
                           args.file, lambda: study.warnings)
    inputs = summary.inputs(study.mechanism, results)
    _print_summary(summary.lines_of(inputs, results, study.analysis.kind == "statics"))
    if plots:
        folder, stem = beside(out, study.mechanism.name)  # not /dev/null_figures.png
        _write_plots(results, study.mechanism, Path(args.plot_dir) if args.plot_dir else folder, stem)
    elif key is not None and keep is not None:
        made = plan.of(study, args.backend, header, keep, inputs)
        if made is not None and plan.key(args.file, run_options(args)) == key:  # inputs unchanged meanwhile
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
        lines = summary.lines_of(run.summary, results, run.analysis.kind == "statics")
    except ValueError:  # other instants than the plan's f(t) was evaluated at: evaluate it again
        from symid import api

        mech = api.load_mechanism(args.file, set_values(args.set, args.file), **analysis_overrides(args))
        lines = summary.lines(mech, results)
    _print_summary(lines)
    return 0


def _write_table(out: Path, header: list[str], keep: list[str] | None, rows: Iterator[Array], steps: int,
                 name: str, file: str, warnings: Callable[[], list[str]]) -> Results:
    """Stream rows or blocks of rows to the CSV (.npz, .parquet) file with a
    progress bar; print the run's warnings and the file's line. Returns the
    kept columns (`keep`, None: all)."""
    from symid import progress
    from symid.output import summary
    from symid.io.files import check_target, output_format
    from symid.output.tables import SUFFIXES, write_table
    from symid.tools.plan import Stale
    from symid.output.results import check_table_size

    record = summary.Recorder(header, keep)
    suffix = output_format(out, SUFFIXES, "a results table")
    check_target(out)  # the default <name>.csv too: before the solve, not after it
    check_table_size(steps, len(header) if suffix == ".npz" else len(record.columns), file)
    if suffix == ".parquet":
        from symid.output.tables import arrow

        arrow()  # a missing pyarrow is said before the run, not after it
    stale = False
    try:
        count = write_table(out, header, record(progress.bar(rows, steps, name, size=_instants)), steps)
    except Stale:
        stale = True
        raise
    except KeyboardInterrupt as exc:  # the table goes to a temporary file, removed: say so
        if not out.exists() or out.is_file():  # a device or a FIFO got the rows written so far
            say_kept(exc, f"{out} not written")
        raise
    except AnalysisError as exc:
        where = f"t = {number(exc.time)}: " if exc.time is not None else ""
        solved = exc.solved or 0
        raise AnalysisError(f"{file}: {where}{exc}; the {plural(solved, 'instant')} "
                            f"before it {'is' if solved == 1 else 'are'} in {out}", exc.time,
                            exc.solved) from None
    finally:
        if not stale:
            _print_warnings(warnings())
    print(f"{out}: {count} instants, {len(header)} columns")
    return record.results()


def _instants(item: Array) -> int:
    """The instants in a row (1) or a block of rows (its length), for the progress bar."""
    return len(item) if item.ndim == 2 else 1


def _print_summary(lines: list[str]) -> None:
    """The summary lines: each driver's peak and RMS effort and peak power."""
    for line in lines:
        print(line)


def _print_warnings(warnings: list[str]) -> None:
    """The run's warnings on stderr, once per kind with its time span."""
    for warning in warnings:
        print(f"symid: warning: {warning}", file=sys.stderr)


def _write_plots(results: Results, mechanism: Mechanism, folder: Path, stem: str) -> None:
    """`--plot`: the PNG figures beside the table; what could not be drawn is said on stderr."""
    from symid.output import plot

    written = plot.write_all(results, mechanism, folder, stem)
    for path in written.paths:
        print(path)
    for note in written.skipped:
        print(f"symid: skipped the {note}", file=sys.stderr)
