"""The summary line of joint friction (contract v1.1): the energy the joints'
friction took over the run and its mean power, from the table's
`C.friction_power` columns alone (so a replayed run needs no mechanism)."""

from __future__ import annotations

from typing import Protocol, Sequence

import numpy as np

from symid.numeric.evaluator import Array

SUFFIX = ".friction_power"


class Table(Protocol):
    columns: list[str]

    def __getitem__(self, column: str) -> Array: ...


def columns(header: Sequence[str]) -> list[str]:
    """The friction power columns of a header, in its order."""
    return [c for c in header if c.endswith(SUFFIX)]


def energy(t: Array, power: Array) -> float:
    """The energy dissipated, -integral of the (<= 0) power, trapezoidal."""
    if len(t) < 2:
        return 0.0
    return float(-np.sum((power[1:] + power[:-1]) * np.diff(t)) / 2)


def line(table: Table) -> list[str]:
    """One line "friction: ... J lost, mean ... W (joint share, ...)", or none
    for a table without friction columns."""
    names = columns(table.columns)
    if not names:
        return []
    t = np.asarray(table["t"], dtype=float)
    each = [energy(t, np.asarray(table[c], dtype=float)) for c in names]
    total = sum(each)
    span = float(t[-1] - t[0]) if len(t) else 0.0
    mean = f", mean power {total / span:.4g} W" if span > 0 else ""
    shares = ", ".join(f"{c[:-len(SUFFIX)]} {e:.4g} J" for c, e in zip(names, each))
    return [f"friction: {total:.4g} J lost over the run{mean} ({shares})"]
