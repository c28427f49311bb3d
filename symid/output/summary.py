"""Driver efforts (motor torque, actuator force), their power and a summary line each.

An effort is what a driver's actuator applies, from the reference's reaction
formulas (`planar-inverse-dynamics.md`), with `lambda` the driver's multiplier
and `f(t)` its imposed function:

- relative_angle_driver: the torque on body j, `C.T_j` (= -lambda), positive
  counter-clockwise; rate fdot.
- coordinate_driver: `-lambda`, a force along x or y or a torque (`C.Fx_i`,
  `C.Fy_i`, `C.T_i`), positive along +x, +y or counter-clockwise; rate fdot.
- distance_driver: the axial force on j, `-2 |f| lambda`, positive pushing the
  points apart (the actuator in compression); rate d|f|/dt.
- translational_driver: the force on j along the slide `u_i`, `-lambda`,
  positive pushing j towards +u_i; rate fdot.

The power is effort x rate = `lambda Phi_t`, the power of the driver's
reaction forces: positive when the actuator delivers energy to the mechanism.
The rate is the derivative of `f`. Statics has no speeds (every one is zero),
so its summary lines give no power: a "peak power" there would be the
quasi-static power of a motion that statics does not have. Units: SI is
assumed (the file has none).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Callable, Iterable, Iterator, Mapping, Protocol, Sequence

import numpy as np

from symid.backends import Array
from symid.output.results import Results
from symid.output import friction_loss

if TYPE_CHECKING:  # sympy only where f(t) is evaluated: a cached run (symid.tools.plan) has it evaluated
    import sympy as sp

    from symid.model.mechanism import Element, Mechanism

DRIVERS = ("relative_angle_driver", "coordinate_driver", "distance_driver", "translational_driver")


class Table(Protocol):
    """What the efforts need of a results table: column names and columns by name."""

    columns: list[str]

    def __getitem__(self, column: str) -> Array: ...


@dataclass(frozen=True)
class Driven:
    """What a driver's effort is (the fields `Effort` and `Source` share).

    Attributes:
        name, type: the driver constraint's name and type.
        quantity: "torque" or "force"; unit and rate_unit: SI units of the
            effort and of the driven quantity's rate.
        meaning: what the effort is and its positive sense, in words.
    """

    name: str
    type: str
    quantity: str
    unit: str
    rate_unit: str
    meaning: str


@dataclass(frozen=True)
class Effort(Driven):
    """One driver's effort over the run.

    Attributes:
        name, type, quantity, unit, rate_unit, meaning: as in `Driven`.
        t, value, rate: shape (instants,); value in `unit`, rate in `rate_unit`.
    """

    t: Array
    value: Array
    rate: Array

    @property
    def power(self) -> Array:
        """Power delivered to the mechanism [W], shape (instants,): +-inf where the
        product passes the largest double (an effort near 1e307 N·m), said so
        by the value, not by a NumPy warning on stderr."""
        with np.errstate(over="ignore"):
            return self.value * self.rate


@dataclass(frozen=True)
class Summary:
    """Peak and RMS effort and peak power of one driver (SI units).

    `peak` is the largest |effort|; `peak_power` the power of largest
    magnitude, signed: negative when the actuator absorbs energy (brakes).
    """

    name: str
    quantity: str
    unit: str
    peak: float
    t_peak: float
    rms: float
    peak_power: float
    t_peak_power: float

    def line(self, power: bool = True) -> str:
        """The summary line; without `power` (statics), no peak power."""
        head = (f"{self.name}: peak {self.quantity} {self.peak:.4g} {self.unit} at t = {self.t_peak:.4g} s, "
                f"RMS {self.rms:.4g} {self.unit}")
        return head + (f", peak power {self.peak_power:.4g} W at t = {self.t_peak_power:.4g} s" if power else "")


def drivers(mechanism: Mechanism) -> list[Element]:
    """The driver constraints, in file order."""
    from symid.model.mechanism import is_driver  # loaded already: `mechanism` is one

    return [c for c in mechanism.constraints if is_driver(c)]


def _sources(c: Element) -> list[str]:
    """Columns an effort can be read from, preferred first (each alone is enough)."""
    if c.type == "relative_angle_driver":
        return [f"{c.name}.T_j", f"{c.name}.lambda"]
    if c.type == "coordinate_driver":
        column = {"x": "Fx_i", "y": "Fy_i", "phi": "T_i"}[c.options["coordinate"]]
        return [f"{c.name}.{column}", f"{c.name}.lambda"]
    return [f"{c.name}.lambda"]


def needed_columns(mechanism: Mechanism, header: Sequence[str]) -> list[str]:
    """`t` and the one column per driver that its effort is computed from."""
    present = set(header)
    out = ["t"]
    for c in drivers(mechanism):
        out += [col for col in _sources(c) if col in present][:1]
    return out + friction_loss.columns(header)  # the friction line's


def time_function(expr: sp.Expr, values: Mapping[sp.Symbol, float], t: Array, order: int = 0) -> Array:
    """An expression of t and the parameters (or its d^order/dt^order) at the instants t."""
    return time_functions((expr,), values, t, order)[:, 0]


def time_functions(exprs: Sequence[sp.Expr], values: Mapping[sp.Symbol, float], t: Array,
                   order: int = 0) -> Array:
    """Expressions of t and the parameters (or their d^order/dt^order) at the
    instants t, shape (len(t), len(exprs)): one function evaluates them all."""
    fn = _lambdified(tuple(exprs), order, tuple(values))
    columns = [np.broadcast_to(np.asarray(v, dtype=float), t.shape) for v in fn(t, *values.values())]
    return np.column_stack(columns).reshape(len(t), len(exprs)) if columns else np.zeros((len(t), 0))


@functools.lru_cache(maxsize=256)
def _lambdified(exprs: tuple[sp.Expr, ...], order: int, symbols: tuple[sp.Symbol, ...]) -> Callable[..., Any]:
    """d^order/dt^order of `exprs` as one NumPy function of (t, *symbols)
    returning a list: derived and lambdified once per expression, not once
    per set of values (an optimizer or a gradient sweep asks for the same
    drivers at every point; a lambdify costs 20 ms)."""
    import sympy as sp

    from symid.model.mechanism import T

    return sp.lambdify([T, *symbols], [sp.diff(sp.sympify(e), T, order) for e in exprs],  # type: ignore[no-any-return]
                       [np])


@dataclass(frozen=True)
class Source(Driven):
    """How one driver's effort is read from a results table, without its f(t).

    Attributes:
        name, type, quantity, unit, rate_unit, meaning: as in `Driven`.
        column: the table column the effort comes from (see `_sources`).
    """

    column: str

    def effort(self, t: Array, raw: Array, f: Array, fd: Array) -> Effort:
        """The effort from the column's values `raw` and the driver's f, f' at
        the instants t (all shape (instants,))."""
        if self.type == "distance_driver":
            value, rate = -2 * np.abs(f) * raw, np.sign(f) * fd
        else:
            value, rate = (-raw if self.column.endswith(".lambda") else raw), fd
        return Effort(self.name, self.type, self.quantity, self.unit, self.rate_unit, self.meaning, t, value, rate)


def source(c: Element, columns: Sequence[str]) -> Source | None:
    """Where driver `c`'s effort is read from, or None when `columns` lack it."""
    column = next((col for col in _sources(c) if col in columns), None)
    if column is None:
        return None
    if c.type == "distance_driver":
        return Source(c.name, c.type, "force", "N", "m/s",
                      f"axial force, positive pushing {c.bodies['i']} and {c.bodies['j']} apart", column)
    if c.type == "relative_angle_driver":
        return Source(c.name, c.type, "torque", "N·m", "rad/s",
                      f"motor torque on {c.bodies['j']}, positive counter-clockwise", column)
    if c.type == "translational_driver":
        return Source(c.name, c.type, "force", "N", "m/s",
                      f"force on {c.bodies['j']} along the slide, positive towards +vi", column)
    if c.type == "expression":
        return Source(c.name, c.type, "effort", "(J per unit of the row)", "(row units)/s",
                      "-lambda: the generalized force driving the row's g(q) = f(t), positive along +g", column)
    coordinate = c.options["coordinate"]
    if coordinate == "phi":
        return Source(c.name, c.type, "torque", "N·m", "rad/s",
                      f"torque on {c.bodies['i']}, positive counter-clockwise", column)
    return Source(c.name, c.type, "force", "N", "m/s", f"force on {c.bodies['i']} along +{coordinate}", column)


def effort(c: Element, table: Table, values: Mapping[sp.Symbol, float]) -> Effort | None:
    """The effort of driver `c`, or None when the table lacks its columns."""
    where = source(c, table.columns)
    if where is None:
        return None
    t = np.asarray(table["t"], dtype=float)
    raw = np.asarray(table[where.column], dtype=float)
    return where.effort(t, raw, time_function(c.values["f"], values, t), time_function(c.values["f"], values, t, 1))


def efforts(mechanism: Mechanism, table: Table) -> list[Effort]:
    """Every driver's effort that the table has the columns for, in file order."""
    from symid.model.params import parameter_values

    values = parameter_values(mechanism.parameters)
    found = (effort(c, table, values) for c in drivers(mechanism))
    return [e for e in found if e is not None]


def summarize(e: Effort) -> Summary:
    """Peak |effort|, RMS effort (time average, trapezoidal) and the signed peak power."""
    if len(e.t) == 0:
        nan = float("nan")
        return Summary(e.name, e.quantity, e.unit, nan, nan, nan, nan, nan)
    k = int(np.argmax(np.abs(e.value)))
    p = int(np.argmax(np.abs(e.power)))
    span = float(e.t[-1] - e.t[0])
    # in units of the peak: squares of efforts past 1e154 would overflow
    peak = float(abs(e.value[k]))
    unit = e.value / peak if 0 < peak < np.inf else e.value
    if span > 0:
        square = unit ** 2
        rms = float(np.sqrt(np.sum((square[1:] + square[:-1]) * np.diff(e.t)) / 2 / span))
    else:
        rms = float(np.sqrt(np.mean(unit ** 2)))
    rms = rms * peak if 0 < peak < np.inf else rms
    return Summary(e.name, e.quantity, e.unit, float(abs(e.value[k])), float(e.t[k]), rms,
                   float(e.power[p]), float(e.t[p]))


def lines(mechanism: Mechanism, table: Table) -> list[str]:
    """One summary line per driver; a driver without its columns says so
    (no line at all for a table without multipliers or reactions)."""
    return lines_of(inputs(mechanism, table), table, mechanism.analysis.kind == "statics")


@dataclass(frozen=True)
class Input:
    """What one driver's summary line needs beyond the table, without sympy.

    Attributes:
        source: where its effort is read (None: the table lacks it, say `missing`).
        missing: the line for a table without the effort.
        t, f, fd: the table's instants and f, f' there, shape (instants,)
            (empty when `source` is None).
    """

    source: Source | None
    missing: str
    t: Array
    f: Array
    fd: Array


def inputs(mechanism: Mechanism, table: Table) -> list[Input]:
    """The inputs of every driver's summary line for this table (none for a
    table without multipliers or reactions)."""
    from symid.model.params import parameter_values

    if not has_efforts(table.columns):
        return []  # a kinematics table: no driver has an effort, and none is missed
    values = parameter_values(mechanism.parameters)
    t = np.asarray(table["t"], dtype=float)
    empty = np.zeros(0)
    out = []
    for c in drivers(mechanism):
        where = source(c, table.columns)
        if where is None:
            out.append(Input(None, missing(c), empty, empty, empty))
        else:
            f = c.values["f"]
            out.append(Input(where, missing(c), t, time_function(f, values, t), time_function(f, values, t, 1)))
    return out


def lines_of(inputs: Sequence[Input], table: Table, statics: bool = False) -> list[str]:
    """One summary line per driver from `inputs(mechanism, table)` (statics:
    without power, there is no speed).

    Raises:
        ValueError: `table`'s instants are not those the inputs were made for.
    """
    out = []
    for item in inputs:
        if item.source is None:
            out.append(item.missing)
            continue
        t = np.asarray(table["t"], dtype=float)
        if not np.array_equal(t, item.t):
            raise ValueError("the table's instants differ from those of the summary inputs")
        raw = np.asarray(table[item.source.column], dtype=float)
        out.append(summarize(item.source.effort(t, raw, item.f, item.fd)).line(power=not statics))
    return out + friction_loss.line(table)


def has_efforts(columns: Sequence[str]) -> bool:
    """Whether a table with these columns has any effort to summarize (multipliers or reactions)."""
    return any(c.rpartition(".")[2].startswith(("lambda", "T_", "Fx_")) for c in columns)


def missing(c: Element) -> str:
    """The summary line of a driver whose effort the table lacks."""
    return f"{c.name}: no effort (the table has none of {', '.join(_sources(c))})"


class Recorder:
    """Pass a solve's rows (or 2-D blocks of rows) through unchanged, keeping
    a copy of some columns.

    Args:
        header: the rows' column names.
        keep: the columns to keep (None: all), in any order; kept in header order.
    """

    def __init__(self, header: Sequence[str], keep: Iterable[str] | None = None) -> None:
        wanted = set(header if keep is None else keep)
        self.index = [k for k, c in enumerate(header) if c in wanted]
        self.columns = [header[k] for k in self.index]
        # kept values go into blocks of BLOCK rows: a million instants of a few
        # columns cost a few tens of MB, not a Python object per row
        self.blocks: list[Array] = []
        self.current = np.empty((self.BLOCK, len(self.index)))
        self.filled = 0
        self.count = 0

    BLOCK = 4096

    def __call__(self, rows: Iterable[Array]) -> Iterator[Array]:
        for values in rows:
            data = np.asarray(values, dtype=float)
            if data.ndim == 2:
                self._close()
                self.blocks.append(data[:, self.index])  # fancy indexing: a copy
                self.count += data.shape[0]
            else:
                if self.filled == self.BLOCK:
                    self._close()
                self.current[self.filled] = data[self.index]
                self.filled += 1
                self.count += 1
            yield values

    def _close(self) -> None:
        """Keep the rows of the open block and start another."""
        if self.filled:
            self.blocks.append(self.current[:self.filled])
            self.current = np.empty((self.BLOCK, len(self.index)))
            self.filled = 0

    def results(self) -> Results:
        """What was kept, as a `Results` table."""
        self._close()
        width = len(self.columns)
        data = np.concatenate(self.blocks) if self.blocks else np.empty((0, width))
        return Results(list(self.columns), data.reshape(self.count, width))
