"""Results: the contract's column names, arrays over time and the CSV table."""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Iterable, Iterator

import numpy as np

from symid.model.analysis import Analysis
from symid.backends import Array
from symid.numeric.solve import instant_row
from symid.symbolic.columns import GROUP_SUFFIXES, columns
from symid.errors import AnalysisError, InputError
from symid.io.limits import MAX_HELD_VALUES
from symid.text import number, plural

if TYPE_CHECKING:  # a cached run (symid.tools.plan) writes its table without sympy
    from symid.symbolic.assemble import Layout
    from symid.backends import Evaluator
    from symid.numeric.solve import Instant
    from symid.numeric.stability import Notes

# What a run may hold in memory as a table (the .npz, the plots, `Study.solve`,
# the summary's columns): 2^27 doubles, 1 GiB. The CSV itself is streamed.
MAX_TABLE_VALUES = MAX_HELD_VALUES

def check_table_size(instants: int, width: int, what: str) -> None:
    """Refuse, before the run, a table of instants x width values too large to hold.

    Raises:
        InputError: naming the count and the limit (exit 2).
    """
    if instants * width > MAX_TABLE_VALUES:
        raise InputError(f"{what}: {instants} instants x {width} columns = {instants * width} values to hold "
                         f"in memory, more than the {MAX_TABLE_VALUES} allowed (fewer steps or outputs, or a .csv)")


def table_rows(evaluator: Evaluator, analysis: Analysis, q0: Array, notes: Notes) -> Iterator[Array]:
    """The results table row by row; a compiled backend runs its own loop.

    Args:
        q0: the initial guess at t0, size ng.
        notes: collects the run's warnings (the Python loop's).
    """
    if evaluator.capabilities.own_loop:
        yield from evaluator.rows(analysis, q0, notes)  # type: ignore[attr-defined]
        return
    from symid.numeric.solve import run

    for instant in run(evaluator, analysis, q0, notes):
        yield instant_row(instant, len(q0), analysis)


def table_blocks(evaluator: Evaluator, analysis: Analysis, q0: Array, notes: Notes) -> Iterator[Array]:
    """As `table_rows`, but a compiled loop's rows come as its 2-D blocks (the
    writers take rows and blocks alike, and format blocks at once)."""
    if evaluator.capabilities.blocks:
        yield from evaluator.blocks(analysis, q0, notes)  # type: ignore[attr-defined]
        return
    yield from table_rows(evaluator, analysis, q0, notes)


def row(instant: Instant, layout: Layout, analysis: Analysis) -> Array:
    """One CSV row (same order as `columns`)."""
    return instant_row(instant, layout.ng, analysis)


@dataclass
class Results:
    """All instants of a run as arrays; a failed run keeps the solved ones.

    Attributes:
        columns: the contract's column names; data: (instants, columns).
        error: the failure that ended the run early, if any.
        warnings: one line each (ill-conditioning, redundant rows, allowed
            assembly-mode jumps), as `symid solve` prints them.
    """

    columns: list[str]
    data: Array
    error: AnalysisError | None = None
    warnings: list[str] = field(default_factory=list)
    index: dict[str, int] = field(init=False, repr=False)
    mechanism: Any = field(default=None, repr=False, compare=False)  # what was solved, for peaks and plots

    def __post_init__(self) -> None:
        self.index = {c: k for k, c in enumerate(self.columns)}

    def __getitem__(self, column: str) -> Array:
        """The values of one column over time, e.g. `results["motor.T_j"]`."""
        try:
            return self.data[:, self.index[column]]
        except KeyError:
            raise KeyError(f"no column {column!r}") from None

    @property
    def t(self) -> Array:
        return self.data[:, 0]

    def block(self, prefix_columns: list[str]) -> Array:
        """Several columns at once, shape (instants, len(prefix_columns))."""
        return self.data[:, [self.index[c] for c in prefix_columns]]

    def write_csv(self, path: str | Path) -> int:
        """Write the table this holds (no solving), atomically; returns the rows written.
        A path ending in .npz or .parquet writes that format instead; any other
        suffix than .csv is refused (InputError), as `symid solve -o` refuses it."""
        from symid.output.tables import write_table

        return write_table(path, self.columns, self.data)

    to_csv = write_csv

    def to_pandas(self) -> Any:
        """The table as a `pandas.DataFrame`, one column per CSV column (pandas is optional)."""
        try:
            import pandas
        except ImportError:
            raise ImportError("Results.to_pandas() needs pandas (python3 -m pip install pandas); "
                              "without it, Results.columns and Results.data hold the same table") from None
        return pandas.DataFrame(self.data, columns=list(self.columns))

    def plot(self, *columns: str) -> Any:
        """A matplotlib figure: the given columns against t, or, with none given,
        the drivers' efforts (as `symid solve --plot`) when the mechanism is known."""
        from symid.output import plot

        if not columns and self.mechanism is not None:
            return plot.efforts_figure(self, self.mechanism)
        if not columns:
            raise ValueError("Results.plot(): name the columns to plot, e.g. results.plot('motor.T_j') "
                             f"(columns: {', '.join(self.columns[1:])})")
        fig = plot._figure(6.4, 3.6)
        ax = fig.add_subplot()
        for name in columns:
            ax.plot(self.t, self[name], label=name)
        ax.set_xlabel("t")
        ax.legend()
        return fig

    def summary(self) -> list[str]:
        """What was solved, sizes, the drivers' peaks, warnings and the error: one line each."""
        name = getattr(self.mechanism, "name", None)
        span = f", t = {number(self.t[0])} .. {number(self.t[-1])}" if len(self.t) else ""
        head = f"{name + ': ' if name else ''}{plural(len(self.data), 'instant')}{span}, " \
               f"{plural(len(self.columns), 'column')}"
        peaks: list[str] = []
        if self.mechanism is not None and len(self.t):
            try:
                from symid.output import summary

                peaks = summary.lines(self.mechanism, self)
            except Exception:  # a display must never fail; the table itself is intact
                peaks = []
        stop = [f"stopped early: {self.error}"] if self.error is not None else []
        return [head, *peaks, *(f"warning: {w}" for w in self.warnings), *stop]

    def __repr__(self) -> str:
        return "Results(" + "; ".join(self.summary()) + ")"

    def _repr_html_(self) -> str:
        import html

        lines = self.summary()
        items = "".join(f"<li>{html.escape(line)}</li>" for line in lines[1:])
        return f"<b>Results</b> {html.escape(lines[0])}" + (f"<ul>{items}</ul>" if items else "")


def format_row(values: Iterable[float]) -> str:
    """17 significant digits: a CSV value reads back as the same double.
    (The writers format whole blocks to the same bytes: `symid.output.compiled_csv`.)"""
    items = values.tolist() if isinstance(values, np.ndarray) else list(values)
    return _row_format(len(items)) % tuple(items)  # one C-level format: 2x faster than a join


@functools.lru_cache(maxsize=8)
def _row_format(width: int) -> str:
    return ",".join(["%.17g"] * width)


def write_csv(path: str | Path, header: list[str], rows: Iterable[Array]) -> int:
    """Write rows (or 2-D blocks of rows) as they come, through
    `symid.io.files.atomic_write`, each value as `format_row` writes it.

    If the rows raise `AnalysisError`, the rows already produced are kept
    (the file is completed and renamed) and the error is re-raised; on any
    other error no file is left behind.

    Returns:
        the number of rows written.
    """
    from symid.output.tables import write_csv as write

    return write(path, header, rows)
