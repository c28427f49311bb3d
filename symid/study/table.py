"""The results table of a design study: one row per variant, in variant order.

Columns (the contract's `symid sweep`): `variant`, one per varied parameter,
`status`, `t_end`, then the figures (`symid.study.figures.figure_names`), then
`cond_worst` (`symid.study.figures.COND_COLUMN`: the variant's worst condition
estimate past cond_warn, 0 without a warning).
Written as CSV (17 significant digits, as the solve table) or Parquet, atomically.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from symid.errors import InputError
from symid.io.files import atomic_write, output_format, read_text
from symid.output.compiled_csv import csv_block, formatter
from symid.output.tables import arrow, read_arrow
from symid.study.figures import COND_COLUMN, STATUS, Figures
from symid.text import plural

FORMATS = (".csv", ".parquet")


@dataclass(frozen=True)
class SweepTable:
    """The results of a sweep.

    Attributes:
        kind: how the variants were made ("grid", "table", "sample"; "" unknown).
        params: the varied parameters; values: shape (K, len(params)).
        figures: the figures, status and t_end of each variant.
        variant: shape (K,), each row's variant number (0, 1, ...; a partial
            table of an interrupted cluster sweep may skip some).
    """

    kind: str
    params: tuple[str, ...]
    values: np.ndarray
    figures: Figures
    variant: np.ndarray

    @property
    def columns(self) -> list[str]:
        """Column names in table order."""
        return ["variant", *self.params, "status", "t_end", *self.figures.names, COND_COLUMN]

    @property
    def data(self) -> np.ndarray:
        """shape (K, len(columns)) floats; the `status` column holds the index into `STATUS`."""
        f = self.figures
        return np.column_stack([self.variant.astype(float), self.values, f.status.astype(float), f.t_end,
                                f.values, f.cond]).reshape(len(f), len(self.columns))

    def __len__(self) -> int:
        return len(self.variant)

    def __getitem__(self, column: str) -> np.ndarray:
        """One column; `status` as strings."""
        if column == "status":
            return np.array([STATUS[s] for s in self.figures.status], dtype=object)
        try:
            return self.data[:, self.columns.index(column)]
        except ValueError:
            raise KeyError(f"no column {column!r} (columns: {', '.join(self.columns)})") from None

    @property
    def failed(self) -> int:
        """How many variants did not run to t1."""
        return int(np.count_nonzero(self.figures.status))

    def to_pandas(self) -> Any:
        """The table as a `pandas.DataFrame` (pandas is optional)."""
        try:
            import pandas
        except ImportError:
            raise ImportError("SweepTable.to_pandas() needs pandas (python3 -m pip install pandas); "
                              "without it, columns and data (or table[column]) hold the same table") from None
        frame = pandas.DataFrame(self.data, columns=self.columns)
        frame["variant"] = self.variant.astype(np.int64)
        frame["status"] = self["status"]
        return frame

    def write(self, path: str | Path) -> Path:
        """Write as CSV or Parquet (by suffix; any other refused), atomically: complete or untouched."""
        path = Path(path)
        suffix = output_format(path, FORMATS, "a sweep table")
        if suffix == ".parquet":
            _write_parquet(self, path)
        else:
            _write_csv(self, path)
        return path


def _write_csv(t: SweepTable, path: Path) -> None:
    """17 significant digits, the solve table's format and formatter; `variant` as a whole number."""
    data = t.data
    at = 1 + len(t.params)
    fn = formatter(data.size)
    params = csv_block(data[:, 1:at], fn).splitlines() if at > 1 else None
    rest = csv_block(data[:, at + 1:], fn).splitlines()
    with atomic_write(path, binary=True) as out:
        out.write((",".join(t.columns) + "\n").encode())
        for k, row in enumerate(data):
            cells = [b"%d" % int(row[0])]
            if params is not None:
                cells.append(params[k])
            cells.append(STATUS[int(row[at])].encode())
            cells.append(rest[k])
            out.write(b",".join(cells) + b"\n")


def _write_parquet(t: SweepTable, path: Path) -> None:
    pa, pq = arrow()  # without pyarrow: the solve table's one line, exit 2

    arrays: dict[str, Any] = {"variant": pa.array(t.variant.astype(np.int64))}
    for k, name in enumerate(t.params):
        arrays[name] = pa.array(t.values[:, k], type=pa.float64())
    arrays["status"] = pa.array([STATUS[s] for s in t.figures.status], type=pa.string())
    arrays["t_end"] = pa.array(t.figures.t_end, type=pa.float64())
    for k, name in enumerate(t.figures.names):
        arrays[name] = pa.array(t.figures.values[:, k], type=pa.float64())
    arrays[COND_COLUMN] = pa.array(t.figures.cond, type=pa.float64())
    table = pa.table(arrays, metadata={"symid.kind": t.kind})
    with atomic_write(path, binary=True) as out:  # a device or FIFO written into, never replaced
        pq.write_table(table, out)


def conditioning_note(table: SweepTable, threshold: float, shown: int = 10) -> str:
    """One line naming the variants whose run passed cond_warn (as `symid
    solve --set` would warn for each), or "" when none did."""
    warned = table.figures.warned
    if not warned.size:
        return ""
    names = ", ".join(str(int(v)) for v in table.variant[warned[:shown]])
    more = f" and {warned.size - shown} more" if warned.size > shown else ""
    worst = warned[int(np.argmax(table.figures.cond[warned]))]
    return (f"Phi_q is ill-conditioned (cond above cond_warn = {threshold:g}) in {warned.size} of "
            f"{plural(len(table), 'variant')}: {names}{more} (worst {table.figures.cond[worst]:.3g} in variant "
            f"{int(table.variant[worst])}); their figures may have lost digits: the table's {COND_COLUMN} "
            f"column, `symid solve --set` for the times")


def is_sweep(columns: list[str]) -> bool:
    """Whether a table's columns are those of a sweep (a `variant` first, a `status`)."""
    return bool(columns) and columns[0] == "variant" and "status" in columns


def _assemble(columns: list[str], variant: np.ndarray, numbers: dict[str, np.ndarray], status: list[str],
              where: str, kind: str = "") -> SweepTable:
    at = columns.index("status")
    params = tuple(columns[1:at])
    figures = tuple(c for c in columns[at + 2:] if c != COND_COLUMN)  # a table of before it has none
    if columns[at + 1: at + 2] != ["t_end"]:
        raise InputError(f"{where}: not a symid sweep table (no t_end after status)")
    bad = [s for s in status if s not in STATUS]
    if bad:
        raise InputError(f"{where}: status {bad[0]!r} is none of {', '.join(STATUS)}")
    k = len(variant)
    values = np.column_stack([numbers[p] for p in params]).reshape(k, len(params))
    fig = Figures(figures, np.column_stack([numbers[f] for f in figures]).reshape(k, len(figures)),
                  np.array([STATUS.index(s) for s in status], dtype=np.int8), numbers["t_end"],
                  numbers.get(COND_COLUMN))
    return SweepTable(kind, params, values, fig, variant.astype(np.int64))


def read(path: str | Path) -> SweepTable:
    """A sweep table written by `symid sweep` (.csv or .parquet)."""
    path = Path(path)
    if path.suffix.lower() == ".parquet":
        table = read_arrow(path)
        columns = list(table.column_names)
        if not is_sweep(columns):
            raise InputError(f"{path}: not a symid sweep table (first column 'variant', a 'status' column)")
        meta = table.schema.metadata or {}
        numbers = {c: np.asarray(table.column(c).to_numpy(), dtype=float) for c in columns if c != "status"}
        status = [str(s) for s in table.column("status").to_pylist()]
        return _assemble(columns, numbers["variant"], numbers, status, str(path),
                         meta.get(b"symid.kind", b"").decode())
    rows = list(csv.reader(read_text(path).splitlines()))
    if not rows or not is_sweep(rows[0]):
        raise InputError(f"{path}: not a symid sweep table (first column 'variant', a 'status' column)")
    columns = rows[0]
    at = columns.index("status")
    cells_of: dict[str, list[float]] = {c: [] for c in columns if c != "status"}
    status = []
    for line, cells in enumerate(rows[1:], 2):
        if len(cells) != len(columns):
            raise InputError(f"{path}: line {line}: {len(cells)} cells, the header has {len(columns)}")
        for k, cell in enumerate(cells):
            if k == at:
                status.append(cell)
                continue
            try:
                cells_of[columns[k]].append(float(cell))
            except ValueError:
                raise InputError(f"{path}: line {line}, column {columns[k]!r}: {cell!r} is not a number") from None
    arrays = {c: np.array(v, dtype=float) for c, v in cells_of.items()}
    return _assemble(columns, arrays["variant"], arrays, status, str(path))
