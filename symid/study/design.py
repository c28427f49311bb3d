"""The design of a study: its variants as a grid, a table of rows, or a random sample.

Each kind gives `Variants`: the varied base parameters and one row of their
values per variant. Every malformed input is an `InputError` (one line, exit 2)
naming the option, file, line or parameter.
"""

from __future__ import annotations

import csv
import itertools
import math
import re
import sys
from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np
import sympy as sp

from symid.errors import InputError
from symid.io.files import read_text
from symid.io.limits import MAX_VARIANTS
from symid.model.params import base_names

KINDS = ("grid", "table", "sample")
_NUMBER = re.compile(r"\s*[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?\s*\Z")


@dataclass(frozen=True)
class Variants:
    """K variants of the base parameters `names`.

    Attributes:
        kind: "grid", "table" or "sample" (how they were made: the plots differ).
        names: the varied base parameters, in the order given.
        values: shape (K, len(names)), one row per variant.
    """

    kind: str
    names: tuple[str, ...]
    values: np.ndarray

    def __len__(self) -> int:
        return len(self.values)


def check_names(names: Sequence[str], parameters: Mapping[str, sp.Expr], source: str, option: str) -> None:
    """Each name must be a base parameter of the mechanism (`symid.model.params.is_derived`),
    and varied once: the one check of every study input (sweep, optimize, the variants' matrix).

    Raises:
        InputError: naming an unknown parameter (and the known base ones), a
            derived one and its definition, or one varied twice.
    """
    base = base_names(parameters)
    for name in names:
        if name not in parameters:
            raise InputError(f"{source}: {option}: no parameter {name!r} (base parameters: "
                             f"{', '.join(base) or 'none'})")
        if name not in base:
            uses = ", ".join(sorted(str(x) for x in sp.sympify(parameters[name]).free_symbols))
            raise InputError(f"{source}: {option}: {name!r} is a derived parameter ({name} = "
                             f"{parameters[name]}): vary the base parameters it is defined from ({uses})")
    seen = set()
    for name in names:
        if name in seen:
            raise InputError(f"{source}: {option}: parameter {name!r} is varied twice")
        seen.add(name)


def check_count(count: int, what: str) -> None:
    """Refuse more variants than `MAX_VARIANTS` before any work."""
    if count > MAX_VARIANTS:
        raise InputError(f"{what}: {count} variants, more than the {MAX_VARIANTS} a sweep allows "
                         "(split the study into several sweeps)")


def finite_number(text: str, what: str) -> float:
    """A finite decimal number written in an option (`what` names it in the error)."""
    if not _NUMBER.match(text) or not math.isfinite(value := float(text)):
        raise InputError(f"{what}: {text.strip()!r} is not a finite number")
    return value


def check_span(lo: float, hi: float, what: str) -> None:
    """Refuse a range whose width HI - LO is past the doubles (1e308 each side):
    spacing, drawing or scaling in it gives inf and NaN (a grid's values, numpy's
    uniform raises OverflowError)."""
    if not math.isfinite(hi - lo):
        raise InputError(f"{what}: the span HI - LO is past the largest double ({sys.float_info.max:.4g}); "
                         "narrow the range")


def _pair(spec: str, option: str, form: str) -> tuple[str, str]:
    name, sep, rest = spec.partition("=")
    if not sep or not name.strip():
        raise InputError(f"{option} {spec}: expected {form}")
    return name.strip(), rest


def _two(spec: str, option: str, first: str, second: str) -> tuple[str, float, float, list[str]]:
    """`NAME=FIRST,SECOND` of a distribution option: the name, both numbers and their texts."""
    form = f"NAME={first},{second}"
    name, rest = _pair(spec, option, form)
    parts = rest.split(",")
    if len(parts) != 2:
        raise InputError(f"{option} {spec}: expected {form}")
    return (name, finite_number(parts[0], f"{option} {spec}: {first}"),
            finite_number(parts[1], f"{option} {spec}: {second}"), parts)


def grid(specs: Sequence[str]) -> Variants:
    """`--grid NAME=LO:HI:N ...`: N equally spaced values from LO to HI (both
    included) per name; several grids form their product, the last varying fastest."""
    names, ranges = [], []
    for spec in specs:
        name, rest = _pair(spec, "--grid", "NAME=LO:HI:N")
        parts = rest.split(":")
        if len(parts) != 3:
            raise InputError(f"--grid {spec}: expected NAME=LO:HI:N")
        lo = finite_number(parts[0], f"--grid {spec}: LO")
        hi = finite_number(parts[1], f"--grid {spec}: HI")
        if not re.fullmatch(r"\s*[0-9]+\s*", parts[2]) or int(parts[2]) < 1:
            raise InputError(f"--grid {spec}: N must be a whole number >= 1, not {parts[2].strip()!r}")
        n = int(parts[2])
        if lo > hi:
            raise InputError(f"--grid {spec}: LO {parts[0].strip()} is greater than HI {parts[1].strip()}")
        check_span(lo, hi, f"--grid {spec}")
        if n == 1 and lo != hi:
            raise InputError(f"--grid {spec}: N = 1 needs LO = HI (one value)")
        names.append(name)
        ranges.append((lo, hi, n))
    check_count(math.prod(n for _, _, n in ranges), "--grid")  # before any value is made: N may be 10^20
    axes = [np.linspace(lo, hi, n) for lo, hi, n in ranges]
    rows = np.array(list(itertools.product(*axes)), dtype=float).reshape(-1, len(names))
    return Variants("grid", tuple(names), rows)


def table(path: str) -> Variants:
    """`--table VARIANTS.csv`: a header row of base parameter names, one variant per row."""
    text = read_text(path, lambda reason: InputError(f"--table {path}: {reason}"))
    rows = [(n, cells) for n, cells in enumerate(csv.reader(text.splitlines()), 1)
            if any(c.strip() for c in cells) and not cells[0].lstrip().startswith("#")]
    if not rows:
        raise InputError(f"--table {path}: no header row (the names of the varied parameters)")
    line, header = rows[0]
    names = [c.strip() for c in header]
    if "" in names or len(set(names)) != len(names):
        raise InputError(f"{path}: line {line}: header names must be distinct and not empty")
    check_count(len(rows) - 1, f"--table {path}")
    out = np.empty((len(rows) - 1, len(names)))
    for r, (line, cells) in enumerate(rows[1:]):
        if len(cells) != len(names):
            raise InputError(f"{path}: line {line}: {len(cells)} cells, the header has {len(names)}")
        for k, cell in enumerate(cells):
            if not cell.strip():
                raise InputError(f"{path}: line {line}, column {names[k]!r}: missing value")
            out[r, k] = finite_number(cell, f"{path}: line {line}, column {names[k]!r}")
    if not len(out):
        raise InputError(f"--table {path}: no variants (only a header row)")
    return Variants("table", tuple(names), out)


def sample(count: int, normal: Sequence[str], uniform: Sequence[str], seed: int) -> Variants:
    """`--sample N`: N variants, each named parameter drawn from its distribution
    (`--normal NAME=MEAN,SD`, `--uniform NAME=LO,HI`), reproducibly from `seed`.

    Draws come from `numpy.random.default_rng(seed)`, one parameter after the
    other (normal ones first, each in the order given), N values each.
    """
    if count < 1:
        raise InputError(f"--sample {count}: N must be >= 1")
    check_count(count, f"--sample {count}")
    if not normal and not uniform:
        raise InputError("--sample: name the parameters to draw with --normal NAME=MEAN,SD or "
                         "--uniform NAME=LO,HI")
    rng = np.random.default_rng(seed)
    names, columns = [], []
    for spec in normal:
        name, mean, sd, parts = _two(spec, "--normal", "MEAN", "SD")
        if sd <= 0:
            raise InputError(f"--normal {spec}: SD must be > 0, not {parts[1].strip()}")
        drawn = rng.normal(mean, sd, count)
        if not np.isfinite(drawn).all():  # MEAN and SD near the largest double: draws past it
            raise InputError(f"--normal {spec}: draws past the largest double ({sys.float_info.max:.4g}); "
                             "a smaller MEAN or SD")
        names.append(name)
        columns.append(drawn)
    for spec in uniform:
        name, lo, hi, parts = _two(spec, "--uniform", "LO", "HI")
        if hi < lo:
            raise InputError(f"--uniform {spec}: HI {parts[1].strip()} is less than LO {parts[0].strip()}")
        check_span(lo, hi, f"--uniform {spec}")
        names.append(name)
        columns.append(rng.uniform(lo, hi, count))
    return Variants("sample", tuple(names), np.column_stack(columns))


def of_options(grids: Sequence[str], table_path: str | None, count: int | None, normal: Sequence[str],
               uniform: Sequence[str], seed: int) -> Variants:
    """The variants of a command line: exactly one of the grid, the table or the sample."""
    given = [k for k, on in zip(KINDS, (bool(grids), table_path is not None, count is not None)) if on]
    if (normal or uniform) and count is None:
        raise InputError(f"{'--normal' if normal else '--uniform'} needs --sample N (the number of variants)")
    if len(given) != 1:
        raise InputError("give the variants as one of --grid NAME=LO:HI:N, --table VARIANTS.csv or --sample N"
                         + (f" (not {' and '.join('--' + g for g in given)} together)" if given else ""))
    if grids:
        return grid(grids)
    if table_path is not None:
        return table(table_path)
    return sample(int(count or 0), normal, uniform, seed)
