"""The figures of a study by solving each variant through the normal path.

The obviously-correct definition that the fast batch engine must match: each
variant is the mechanism with its varied parameters set (derived ones follow
by their definitions), laid out, evaluated on the backend and solved instant
by instant as `symid solve` does; its figures come from that run's table
(efforts as in `symid.output.summary`, reaction forces from the reaction
columns). A variant that fails keeps the figures of the instants before.
"""

from __future__ import annotations

import dataclasses
from typing import Sequence

import numpy as np
import sympy as sp

from symid.backends import Array
from symid.backends.prepare import prepare
from symid.errors import AnalysisError
from symid.model.mechanism import Mechanism
from symid.output.results import Results, columns, table_rows
from symid.output.summary import efforts, summarize
from symid.numeric.stability import Notes
from symid.study.figures import STATUS, Figures, cond_of, figure_names, status_of


def with_values(mechanism: Mechanism, names: Sequence[str], values: Sequence[float]) -> Mechanism:
    """The mechanism with base parameters `names` set to `values` (exact doubles)."""
    params = dict(mechanism.parameters)
    for name, value in zip(names, values):
        params[name] = sp.Float(float(value))  # 53 bits: float() gives the same double back
    return dataclasses.replace(mechanism, parameters=params)


def study_analysis(mechanism: Mechanism) -> Mechanism:
    """The mechanism with the outputs the figures are read from (multipliers and reactions)."""
    a = mechanism.analysis
    if a.kind == "kinematics":
        return mechanism
    if mechanism.sizing and a.kind == "inverse_dynamics":  # a bearing's life reads the bodies' speeds
        from symid.study.variants import study_mechanism

        return study_mechanism(mechanism)
    return dataclasses.replace(mechanism, analysis=dataclasses.replace(a, outputs=("lambda", "reactions")))


def solve_variant(mechanism: Mechanism, backend: str) -> Results:
    """One variant solved as `api.prepare(...).solve()` does (a failure kept in `Results.error`)."""
    solver = prepare(mechanism, backend)
    a = mechanism.analysis
    header = columns(solver.layout, a)
    rows: list[Array] = []
    error = None
    notes = Notes(a)
    try:
        for row in table_rows(solver.evaluator, a, solver.q0(), notes):
            rows.append(np.asarray(row, dtype=float))
    except AnalysisError as exc:
        error = exc
    data = np.array(rows).reshape(len(rows), len(header))
    return Results(header, data, error, notes.lines(), mechanism=mechanism)


def figures_of(mechanism: Mechanism, results: Results) -> Array:
    """The figure row of one solved variant, in `figure_names` order (NaN: no instant solved)."""
    names = figure_names(mechanism)
    out = np.full(len(names), np.nan)
    if not len(results.t) or not names:
        return out
    at = {n: k for k, n in enumerate(names)}
    for e in efforts(mechanism, results):
        s = summarize(e)
        out[at[f"{e.name}.effort_peak"]] = s.peak
        out[at[f"{e.name}.effort_t_peak"]] = s.t_peak
        out[at[f"{e.name}.effort_rms"]] = s.rms
        out[at[f"{e.name}.power_peak"]] = float(np.max(np.abs(e.power)))  # the contract's: largest |power|
    for name in names:
        if not name.endswith(".force_peak"):
            continue
        joint = name[: -len(".force_peak")]
        roles = [c[len(joint) + 4:] for c in results.columns if c.startswith(f"{joint}.Fx_")]
        peaks = [np.max(np.hypot(results[f"{joint}.Fx_{r}"], results[f"{joint}.Fy_{r}"])) for r in roles]
        if peaks:
            out[at[name]] = float(max(peaks))
    if mechanism.sizing and mechanism.analysis.kind == "inverse_dynamics":  # drives and bearings: last
        from symid.output import sizing

        got = sizing.figures(mechanism, results)
        out[len(names) - len(got):] = got
    return out


def figures_by_solving(mechanism: Mechanism, names: Sequence[str], base: Array, backend: str) -> Figures:
    """The figures of K variants, each solved alone.

    Args:
        mechanism: the study's mechanism (its parameters: every variant's defaults).
        names: the varied base parameters.
        base: shape (K, len(names)), each row one variant's values of `names`.
        backend: one of `symid.backends.names()`.
    """
    base = np.asarray(base, dtype=float).reshape(-1, len(names))
    fig_names = figure_names(mechanism)
    k = len(base)
    values = np.full((k, len(fig_names)), np.nan)
    status = np.zeros(k, dtype=np.int8)
    t_end = np.full(k, np.nan)
    cond = np.zeros(k)
    for row in range(k):
        variant = study_analysis(with_values(mechanism, names, base[row]))
        try:
            results = solve_variant(variant, backend)
        except ValueError:  # a derived parameter is not finite for these values: nothing solved
            status[row] = STATUS.index("nonfinite")
            continue
        values[row] = figures_of(variant, results)
        if len(results.t):
            t_end[row] = results.t[-1]
        if results.error is not None:
            status[row] = status_of(results.error)
        cond[row] = cond_of(results.warnings)
    return Figures(fig_names, values, status, t_end, cond)
