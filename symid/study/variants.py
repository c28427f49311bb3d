"""The variants of a design study: base parameter vectors, their values, and
their figures measured from a solved table (the normal solve path).

A variant is one row of base parameter values; derived parameters are
recomputed from it by their definitions, as `--set` does.
"""

from __future__ import annotations

import dataclasses
from typing import Any, Mapping, Sequence

import numpy as np
import sympy as sp

from symid.backends import Array
from symid.errors import InputError
from symid.model.mechanism import Mechanism, parameter_symbol
from symid.model.params import base_names, parameter_values, to_float
from symid.output.summary import drivers, source, summarize
from symid.study.design import check_names
from symid.study.figures import figure_names
from symid.symbolic.constraints import TYPES as CONSTRAINTS


def study_mechanism(mechanism: Mechanism) -> Mechanism:
    """The mechanism with every output group of its kind, so that the figures
    can be read (effort needs the multipliers, force_peak the reactions);
    the chosen reactions stay those of `[analysis] reactions`."""
    reactions = mechanism.analysis.reactions
    if reactions is not None and mechanism.sizing.bearings:  # a bearing's life reads its joint's reactions
        reactions = reactions + tuple(b.joint for b in mechanism.sizing.bearings if b.joint not in reactions)
    return dataclasses.replace(mechanism, analysis=dataclasses.replace(mechanism.analysis, outputs=None,
                                                                       reactions=reactions))


def base_matrix(mechanism: Mechanism, names: Sequence[str], base: Any) -> Array:
    """The full base parameter vectors, shape (K, NP) in `base_names` order:
    the mechanism's values, with `names` taken from `base` (K, len(names)).

    Raises:
        InputError: an unknown or derived name (naming its definition), or a
            `base` of the wrong shape.
    """
    params = mechanism.parameters
    order = base_names(params)
    check_names(names, params, mechanism.source, "variants")
    data = np.asarray(base, dtype=float)
    if data.ndim != 2 or data.shape[1] != len(names):
        raise InputError(f"{mechanism.source}: the variants must have shape (K, {len(names)}), not {data.shape}")
    values = parameter_values(params)
    full = np.tile(np.array([values[parameter_symbol(n)] for n in order], dtype=float), (len(data), 1))
    for k, name in enumerate(names):
        full[:, order.index(name)] = data[:, k]
    return full


def variant_values(mechanism: Mechanism, row: Array) -> dict[sp.Symbol, float]:
    """Every parameter's value (derived ones by their definitions) for one
    full base vector `row` (`base_names` order).

    Raises:
        ValueError: (name, message) when a derived value is not finite.
    """
    given = dict(zip(base_names(mechanism.parameters), row.tolist()))
    values: dict[sp.Symbol, float] = {}
    for name, expr in mechanism.parameters.items():  # dependency order
        sym = parameter_symbol(name)
        values[sym] = float(given[name]) if name in given else to_float(expr, values, name)
    return values


class Measure:
    """The figures of one solved table of a mechanism (the study's columns).

    Args:
        mechanism: the study's mechanism (`study_mechanism`); columns: the table's.
    """

    def __init__(self, mechanism: Mechanism, columns: Sequence[str]) -> None:
        from symid.model.mechanism import T

        self.names = figure_names(mechanism)
        self.columns = list(columns)
        index = {c: k for k, c in enumerate(columns)}
        symbols = [parameter_symbol(n) for n in mechanism.parameters]
        self.drivers = []
        for c in drivers(mechanism):
            where = source(c, columns)
            if where is None or mechanism.analysis.kind == "kinematics":
                continue
            f = sp.sympify(c.values["f"])
            fns = [sp.lambdify([T, *symbols], e, [np]) for e in (f, sp.diff(f, T))]
            self.drivers.append((where, index[where.column], fns))
        chosen = [n.rpartition(".")[0] for n in self.names if n.endswith(".force_peak")]
        by_name = {c.name: c for c in mechanism.constraints}
        self.reactions = [[(index[f"{n}.Fx_{r}"], index[f"{n}.Fy_{r}"]) for r in CONSTRAINTS[by_name[n].type].roles]
                          for n in chosen]
        self.symbols = symbols
        self.sizing = mechanism if mechanism.sizing and mechanism.analysis.kind == "inverse_dynamics" else None

    def __call__(self, data: Array, values: Mapping[sp.Symbol, float]) -> Array:
        """The figures (contract order) of a table `data` (instants, columns);
        NaN when it has no instant."""
        out = np.full(len(self.names), np.nan)
        if len(data) == 0:
            return out
        t = data[:, 0]
        args = [values[s] for s in self.symbols]
        k = 0
        for where, column, (f, fd) in self.drivers:
            shape = np.broadcast_to(np.asarray(f(t, *args), dtype=float), t.shape)
            rate = np.broadcast_to(np.asarray(fd(t, *args), dtype=float), t.shape)
            s = summarize(where.effort(t, data[:, column], shape, rate))
            out[k:k + 4] = [s.peak, s.t_peak, s.rms, abs(s.peak_power)]
            k += 4
        for pairs in self.reactions:
            out[k] = max(float(np.max(np.hypot(data[:, x], data[:, y]))) for x, y in pairs)
            k += 1
        if self.sizing is not None:  # drives and bearings: post-processing of the whole table
            from symid.output import sizing
            from symid.output.results import Results

            got = sizing.figures(self.sizing, Results(self.columns, data), values)
            out[k:k + len(got)] = got
        return out
