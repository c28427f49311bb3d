"""A time function given as data: `f = { table = "motion.csv", column = "angle" }`.

The CSV is read and checked here and fitted once by a C2 cubic spline (so f'
and f'' are defined): interpolating with not-a-knot ends, or, with
`smoothing`, the penalized smoothing spline of scipy. The fit is registered
in `symid.model.motion` and returned as the expression `TableSpline(key, 0, t)`.
Rules and messages: docs/motion.md.
"""

from __future__ import annotations

import csv
import math
import re
from typing import Any, Callable, Mapping

import numpy as np
import sympy as sp

from symid.model import motion
from symid.errors import InputError
from symid.io.files import read_text
from symid.io.paths import table_path

KEYS = ("table", "column", "time", "smoothing")
MIN_ROWS = 5  # the smoothing spline's minimum; a not-a-knot cubic needs 4
MAX_ROWS = 100_000  # every row becomes a piece of the generated code
GAP_FACTOR = 10  # a step longer than this many median steps is a gap
_NUMBER = re.compile(r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?\Z")


def read(spec: Mapping[str, Any], source: str, where: str) -> sp.Expr:
    """The expression of t that a table specification stands for.

    Args:
        spec: the TOML table: table (path, relative to the mechanism file),
            column, optional time (default: the first column) and smoothing.
        source: the mechanism file (or "<string>": paths relative to the
            current folder), for the path and for messages.
        where: the element and key, for messages.
    """
    def fail(message: str) -> InputError:
        return InputError(f"{source}: {where}: {message}")

    extra = [k for k in spec if k not in KEYS]
    if extra:
        raise fail(f"unknown key '{extra[0]}' in a table function (allowed: {', '.join(KEYS)})")
    name = spec.get("table")
    if not isinstance(name, str) or not name:
        raise fail("a table function needs table = \"FILE.csv\"")
    column = spec.get("column")
    if not isinstance(column, str) or not column:
        raise fail(f"table {name!r}: needs column = \"NAME\" (the column of values)")
    time = spec.get("time")
    if time is not None and not isinstance(time, str):
        raise fail(f"table {name!r}: time must be a column name, not {time!r}")
    smoothing = _smoothing(spec.get("smoothing", 0), lambda m: fail(f"table {name!r}: key 'smoothing': {m}"))
    path = table_path(name, source)
    text = read_text(path, lambda m: fail(f"table {name!r}: {m}"))
    here = lambda m: fail(f"table {name!r}: {m}")  # noqa: E731
    t, y, lines = _columns(text, time, column, here)
    _check_times(t, lines, here)
    label = f"table {name!r} column {column!r}"
    return motion.register(motion.Spline(*_fit(t, y, smoothing, here), label))


def _smoothing(value: Any, fail: Callable[[str], InputError]) -> float:
    """0: interpolate; a number > 0: the weight lam of the curvature penalty.

    No automatic choice is offered: for a crank angle sampled 201 times with
    1e-4 rad noise, scipy's GCV choice (lam=None) smoothed f'' away entirely.
    """
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0:
        raise fail(f"must be a number >= 0, not {value!r}")
    return float(value)


def _columns(text: str, time: str | None, column: str, fail: Callable[[str], InputError],
             ) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """(times, values, line numbers) of the rows; blank and '#' lines are skipped."""
    rows = [(n, [c.strip() for c in cells]) for n, cells in enumerate(csv.reader(text.splitlines()), 1)
            if any(c.strip() for c in cells) and not cells[0].lstrip().startswith("#")]
    if not rows:
        raise fail("no header row")
    header_line, header = rows[0]
    if len(set(header)) != len(header) or "" in header:
        raise fail(f"line {header_line}: header names must be distinct and not empty")
    time = header[0] if time is None else time
    for key, name in (("time", time), ("column", column)):
        if name not in header:
            raise fail(f"key '{key}': no column {name!r} (columns: {', '.join(header)})")
    if time == column:
        raise fail(f"column {column!r} is the time column")
    data = rows[1:]
    if not MIN_ROWS <= len(data) <= MAX_ROWS:
        raise fail(f"has {len(data)} data rows; a table needs {MIN_ROWS} to {MAX_ROWS}")
    cols = (header.index(time), header.index(column))
    out = np.empty((2, len(data)))
    for r, (line, cells) in enumerate(data):
        if len(cells) != len(header):
            raise fail(f"line {line}: {len(cells)} cells, the header has {len(header)}")
        for k, c in enumerate(cols):
            cell = cells[c]
            if not _NUMBER.match(cell) or not math.isfinite(value := float(cell)):
                raise fail(f"line {line}, column {header[c]!r}: {cell!r} is not a finite number")
            out[k, r] = value
    return out[0], out[1], [line for line, _ in data]


def _check_times(t: np.ndarray, lines: list[int], fail: Callable[[str], InputError]) -> None:
    """Strictly increasing, and no step longer than GAP_FACTOR times the median step."""
    steps = np.diff(t)
    at = lambda k: repr(float(t[k]))  # noqa: E731 (shortest decimal, not numpy's repr)
    bad = np.flatnonzero(~(steps > 0))
    if bad.size:
        k = int(bad[0])
        raise fail(f"line {lines[k + 1]}: time {at(k + 1)} does not increase (after {at(k)} "
                   f"on line {lines[k]})")
    median = float(np.median(steps))
    gaps = np.flatnonzero(steps > GAP_FACTOR * median)
    if gaps.size:
        k = int(gaps[0])
        raise fail(f"lines {lines[k]}-{lines[k + 1]}: a gap in time from {at(k)} to {at(k + 1)} "
                   f"(step {steps[k]:.6g}, more than {GAP_FACTOR} times the median step {median:.6g})")


def _fit(t: np.ndarray, y: np.ndarray, smoothing: float, fail: Callable[[str], InputError],
         ) -> tuple[np.ndarray, np.ndarray]:
    """(knots, coef) of the C2 cubic: coef[k] = [c0, c1, c2, c3] about knots[k]."""
    # imported here: a run that tabulates nothing never loads scipy.interpolate
    from scipy.interpolate import CubicSpline, PPoly, make_smoothing_spline

    if smoothing == 0:
        pp = CubicSpline(t, y, bc_type="not-a-knot")
    else:
        pp = PPoly.from_spline(make_smoothing_spline(t, y, lam=smoothing))
    keep = np.flatnonzero(np.diff(pp.x) > 0)  # a B-spline's repeated end knots make empty pieces
    knots = np.append(pp.x[keep], pp.x[keep[-1] + 1])
    coef = np.ascontiguousarray(pp.c[::-1, keep].T)
    if not np.all(np.isfinite(coef)):
        raise fail("the fitted spline is not finite (values too large?)")
    return knots, coef
