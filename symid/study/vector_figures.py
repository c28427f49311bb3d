"""What the vectorized NumPy loop (`symid.study.batch_numpy`) needs beyond
the solve, for K variants at once: every parameter's value (derived ones by
their definitions), the initial guesses q0, and the figures of the solved
columns, as `variants.variant_values` and `variants.Measure` give them for
one variant.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np
import sympy as sp

from symid.backends import Array
from symid.model.mechanism import Mechanism, parameter_symbol
from symid.model.params import base_names
from symid.study.variants import Measure


class Values:
    """Every parameter's value of K variants (columns of `full`, base order);
    derived ones by their definitions, in dependency order, in doubles (as
    `to_float` evaluates them node by node).

    Attributes:
        symbols: every parameter's symbol, file order; arrays: symbol -> (K,);
        finite: (K,) whether every derived value is finite (else the variant
        goes to the normal path, which names the parameter).
    """

    def __init__(self, mechanism: Mechanism, full: Array) -> None:
        order = base_names(mechanism.parameters)
        self.symbols = [parameter_symbol(n) for n in mechanism.parameters]
        self.arrays: dict[sp.Symbol, Array] = {}
        k = len(full)
        self.finite = np.ones(k, dtype=bool)
        with np.errstate(all="ignore"):
            for name, expr in mechanism.parameters.items():
                sym = parameter_symbol(name)
                if name in order:
                    self.arrays[sym] = np.ascontiguousarray(full[:, order.index(name)], dtype=float)
                    continue
                known = list(self.arrays)
                value = sp.lambdify(known, sp.sympify(expr), [np])(*self.arrays.values())
                self.arrays[sym] = np.broadcast_to(np.asarray(value, dtype=float), (k,)).copy()
                self.finite &= np.isfinite(self.arrays[sym])

    def row(self, v: int) -> dict[sp.Symbol, float]:
        """One variant's values, as `variant_values` gives them."""
        return {s: float(self.arrays[s][v]) for s in self.symbols}

    def of(self, exprs: Sequence[sp.Expr]) -> Array:
        """Expressions of the parameters (e.g. q0), shape (len(exprs), K)."""
        k = len(self.finite)
        fn = sp.lambdify(self.symbols, [sp.sympify(e) for e in exprs], [np])
        with np.errstate(all="ignore"):
            out = fn(*[self.arrays[s] for s in self.symbols])
        return np.array([np.broadcast_to(np.asarray(x, dtype=float), (k,)) for x in out]).reshape(len(exprs), k)


class Figures:
    """`Measure` over K variants' solved columns at once.

    Args:
        measure: the study's Measure over the table's columns; the data given
            to `__call__` holds only `columns` (t first), in that order.
    """

    def __init__(self, measure: Measure) -> None:
        self.names = measure.names
        used = [0] + [c for _, c, _ in measure.drivers] + [i for pairs in measure.reactions for xy in pairs
                                                             for i in xy]
        self.columns = sorted(set(used))
        at = {c: j for j, c in enumerate(self.columns)}
        self.drivers = [(where, at[c], fns) for where, c, fns in measure.drivers]
        self.reactions = [[(at[x], at[y]) for x, y in pairs] for pairs in measure.reactions]
        self.symbols = measure.symbols

    def __call__(self, data: Array, values: Values, rows: Array) -> Array:
        """The figures (K', len(names)) of the variants `rows` (indices into
        `values`) from their columns `data` (K', instants, columns), every
        variant with the same instants."""
        out = np.full((len(rows), len(self.names)), np.nan)
        if not len(rows) or data.shape[1] == 0:
            return out
        t = data[0, :, 0]
        args = [values.arrays[s][rows][:, None] for s in self.symbols]
        span = float(t[-1] - t[0])
        k = 0
        for where, column, (f, fd) in self.drivers:
            shape = np.broadcast_to(np.asarray(f(t[None, :], *args), dtype=float), data.shape[:2])
            rate = np.broadcast_to(np.asarray(fd(t[None, :], *args), dtype=float), data.shape[:2])
            e = where.effort(t, data[:, :, column], shape, rate)  # elementwise: (K', instants)
            value, power = np.asarray(e.value), np.asarray(e.power)
            top = np.argmax(np.abs(value), axis=1)
            peak = np.abs(value[np.arange(len(rows)), top])
            scaled = (0 < peak) & (peak < np.inf)
            unit = np.where(scaled[:, None], value / np.where(scaled, peak, 1.0)[:, None], value)
            square = unit ** 2
            if span > 0:  # trapezoidal, in units of the peak (as `summarize`)
                rms = np.sqrt(np.sum((square[:, 1:] + square[:, :-1]) * np.diff(t), axis=1) / 2 / span)
            else:
                rms = np.sqrt(np.mean(square, axis=1))
            out[:, k] = peak
            out[:, k + 1] = t[top]
            out[:, k + 2] = np.where(scaled, rms * peak, rms)
            out[:, k + 3] = np.abs(power[np.arange(len(rows)), np.argmax(np.abs(power), axis=1)])
            k += 4
        for pairs in self.reactions:
            out[:, k] = np.max([np.max(np.hypot(data[:, :, x], data[:, :, y]), axis=1) for x, y in pairs], axis=0)
            k += 1
        return out


__all__ = ["Figures", "Values"]
