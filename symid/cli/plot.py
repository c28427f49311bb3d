"""`symid plot RESULTS [--mechanism FILE] [-o DIR] [--gif]`: PNGs (and a GIF) of a results table."""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from symid.cli.options import add_set, set_values
from symid.errors import InputError
from symid.output.results import Results

if TYPE_CHECKING:  # registering the subcommand must not import sympy (see symid.tools.plan)
    from symid.model.mechanism import Mechanism


def read_csv(path: Path) -> Results:
    """A results table written by `symid solve` (CSV) as a `Results`."""
    try:
        with path.open(encoding="utf-8-sig") as f, warnings.catch_warnings():  # a spreadsheet's BOM dropped
            warnings.simplefilter("ignore", UserWarning)  # no rows: a run that failed at t0
            header = f.readline().strip().split(",")
            data = np.loadtxt(f, delimiter=",", ndmin=2)
    except OSError as exc:
        raise InputError(f"{path}: cannot read: {exc.strerror or exc}") from None
    except (ValueError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: not a symid results table: {exc}") from None
    if header[0] != "t" or (data.size and data.shape[1] != len(header)):
        raise InputError(f"{path}: not a symid results table (first column 't', one value per column)")
    return Results(header, data.reshape(len(data), len(header)))


def read_results(path: str | Path) -> Results:
    """A results table from a `.csv`, `.npz` or `.parquet` file written by `symid solve`."""
    path = Path(path)
    if path.suffix.lower() == ".npz":
        from symid.output.npz import read_npz

        return read_npz(path)
    if path.suffix.lower() == ".parquet":
        from symid.output.results import Results
        from symid.output.tables import read_parquet

        names, data = read_parquet(path)
        if not names or names[0] != "t":
            raise InputError(f"{path}: not a symid results table (first column 't')")
        return Results(names, data)
    return read_csv(path)


def check_match(table: Results, mechanism: Mechanism, results: str, file: str) -> None:
    """Every column must belong to a body or constraint of the mechanism."""
    names = {b.name for b in mechanism.bodies} | {c.name for c in mechanism.constraints}
    for column in table.columns[1:]:
        if column.rpartition(".")[0] not in names:
            raise InputError(f"{results}: column '{column}' names nothing in {file}: "
                             "were these results solved from it?")


SAMPLES = 25  # rows checked against the mechanism: enough to catch other parameters, fast on any table


def check_configurations(table: Results, mechanism: Mechanism, results: str, file: str) -> None:
    """The tabled configurations must satisfy the mechanism's constraints, else
    the drawing would show joints that do not meet (other `--set` values, or
    another version of the file). Without q columns there is nothing to check."""
    from symid import backends
    from symid.symbolic.assemble import assemble
    from symid.model.params import parameter_values
    from symid.text import number

    names = [f"{b.name}.{c}" for b in mechanism.bodies for c in ("x", "y", "phi")]
    if not all(n in table.index for n in names) or not len(table.t):
        return
    layout = assemble(mechanism)
    ev = backends.get("reference").evaluator(layout, parameter_values(mechanism.parameters),
                                             backends.Needs(velocity=False, reactions=()))
    q_all = table.block(names)
    worst = (0.0, 0, 0, 0.0)
    for k in np.unique(np.linspace(0, len(table.t) - 1, SAMPLES).astype(int)):
        phi = np.abs(np.asarray(ev.phi(q_all[k], float(table.t[k]))))
        scale = 1e-6 * (1 + float(np.max(np.abs(q_all[k])))) ** 2  # 17-digit tables hold Phi to ~1e-12
        if phi.size and np.max(phi) / scale > worst[0]:
            worst = (float(np.max(phi) / scale), int(k), int(np.argmax(phi)), float(np.max(phi)))
    if worst[0] > 1:
        _, k, row, residual = worst
        constraint = layout.constraint_names_of_rows([row])[0]
        raise InputError(f"{results}: its configurations do not satisfy the constraints of {file} "
                         f"(constraint '{constraint}' has |Phi| = {residual:.3g} at "
                         f"t = {number(table.t[k])}): were the results solved with other parameters "
                         f"(give the same --set NAME=VALUE) or from another version of the file?")


def _is_sweep(path: Path) -> bool:
    """A sweep table (`symid sweep`): a CSV or Parquet table whose columns have `variant` first and a `status`."""
    from symid.study.table import is_sweep

    if path.suffix.lower() == ".parquet":  # `symid solve` writes Parquet too: its columns decide
        try:
            import pyarrow.parquet as pq

            return is_sweep(list(pq.read_schema(path).names))
        except Exception:  # noqa: BLE001 (no pyarrow, not Parquet: read_results names the fault)
            return False
    if path.suffix.lower() == ".npz":
        return False
    try:
        with path.open(encoding="utf-8-sig") as f:
            return is_sweep(f.readline().strip().split(","))
    except (OSError, UnicodeDecodeError):
        return False  # read_results names the fault


def _plot_sweep(args: argparse.Namespace) -> int:
    """The figures of a design study: contours, lines or histograms (`symid.output.sweep_plot`)."""
    from symid.output.sweep_plot import write_all
    from symid.study.table import read

    if args.mechanism or args.gif:
        raise InputError(f"{args.file}: a sweep table is plotted alone (no --mechanism, no --gif)")
    table = read(args.file)
    directory = Path(args.output) if args.output else Path(args.file).parent
    notes: list[str] = []
    for path in write_all(table.params, table.values, table.figures.names, table.figures.values,
                          table["status"], directory, Path(args.file).stem, table.kind, notes):
        print(path)
    for note in notes:
        print(f"symid plot: {note}", file=sys.stderr)
    return 0


def run(args: argparse.Namespace) -> int:
    from symid.output import plot

    if _is_sweep(Path(args.file)):
        return _plot_sweep(args)
    table = read_results(args.file)
    mechanism = None
    if args.mechanism:  # the reader imports sympy: a table plotted alone never needs it
        from symid.io.reader import load

        mechanism = load(args.mechanism, set_values(args.set))
        check_match(table, mechanism, args.file, args.mechanism)
        check_configurations(table, mechanism, args.file, args.mechanism)
    directory = Path(args.output) if args.output else Path(args.file).parent
    written = plot.write_all(table, mechanism, directory, Path(args.file).stem, gif=args.gif)
    for path in written.paths:
        print(path)
    for note in written.skipped:
        print(f"symid plot: skipped the {note}", file=sys.stderr)
    return 0


def register(sub: Any) -> None:
    p = sub.add_parser("plot", help="plot a results table (efforts, reactions, the mechanism) or a sweep table",
                       description="Plot a results table written by symid solve.",
                       epilog="examples:\n  symid plot run.csv --mechanism crank.toml\n"
                              "  symid plot run.csv --mechanism crank.toml --set omega=12 --gif -o figures/")
    p.add_argument("file", metavar="RESULTS",
                   help="a .csv (or .npz, .parquet) written by symid solve, or a .csv (.parquet) written by symid sweep")
    p.add_argument("--mechanism", metavar="FILE",
                   help="the mechanism file it was solved from: needed for efforts and the drawing")
    add_set(p, "the parameter overrides the results were solved with (repeatable)")
    p.add_argument("-o", "--output", metavar="DIR", help="folder for the images (default: beside RESULTS)")
    p.add_argument("--gif", action="store_true", help="also write an animated GIF of the motion")
    p.set_defaults(run=run)
