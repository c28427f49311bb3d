"""The derivatives of a study's figures with respect to base parameters.

From one solved trajectory with the exact per-instant sensitivities of its
columns (`d(COLUMN)/d(NAME)`, the contract's "Sensitivities"), each figure of
`symid.study.figures.figure_names` is differentiated exactly as it is
computed (`symid.study.slow.figures_of`, `symid.output.summary.summarize`):

- `effort_rms`, the trapezoidal time average `rms^2 = sum w_k e_k^2 / span`:
  `d rms = sum w_k e_k de_k / (span rms)` (the time grid does not move).
- `effort_peak = |e(t*)|`: `sign(e(t*)) de(t*)` at the peak's own instant
  (the derivative of the discrete maximum while that instant stays the peak).
- `power_peak = |e(t*) v(t*)|`: `sign(p) (de v + e dv)`; the rate `v` is
  `f'(t)` of the driver's motion, which depends on parameters too (`n` moves
  `omega`), differentiated by sympy through the derived parameters' definitions.
- `force_peak = |F(t*)|` on the body and instant of the peak: `F . dF / |F|`
  (a force that is zero throughout, a driver's pure torque: max |dF|, its
  derivative from above, 0 when it stays zero).
- `effort_t_peak` is an instant of a discrete grid: it has no derivative
  (NaN in every gradient column); nor has a drive's `fits` (1 or 0), whose
  checks' margins do (`drive_margins`).
- a drive's `motor_rms`, `motor_peak` and a bearing's `L10_h`:
  `symid.study.sizing_gradients`.
"""

from __future__ import annotations

import functools
from typing import TYPE_CHECKING, Mapping, Sequence

import numpy as np
import sympy as sp

from symid.backends import Array
from symid.model.mechanism import Element, Mechanism, T, parameter_symbol
from symid.model.params import is_derived, parameter_values
from symid.output.results import Results
from symid.output.summary import Source, drivers, source, time_function, time_functions
from symid.study.figures import figure_names

if TYPE_CHECKING:
    from symid.study.sizing_gradients import MotorSide

# figures with no derivative: an instant of the grid and a verdict (1 or 0; its
# checks' margins have one: `drive_margins`)
NO_GRADIENT = ("effort_t_peak", "fits")


def sensitivity_column(column: str, name: str) -> str:
    """The results column of `d(column)/d(name)` (the contract's name)."""
    return f"d({column})/d({name})"


def gradient_names(figures: Sequence[str], names: Sequence[str]) -> list[str]:
    """`d(FIGURE)/d(P)` for every figure (outer) and every parameter (inner)."""
    return [sensitivity_column(f, p) for f in figures for p in names]


def has_gradient(figure: str) -> bool:
    """Whether a figure has a derivative (`effort_t_peak` has none)."""
    return figure.rsplit(".", 1)[-1] not in NO_GRADIENT


def needed_columns(mechanism: Mechanism, header: Sequence[str]) -> list[str]:
    """The results columns whose sensitivities the figures need: each driver's
    effort column and the reaction forces of each `force_peak` constraint."""
    out = []
    for c in drivers(mechanism):
        where = source(c, header)
        if where is not None:
            out.append(where.column)
    for figure in figure_names(mechanism):
        if figure.endswith(".force_peak"):
            joint = figure[: -len(".force_peak")]
            out += [col for col in header if col.startswith((f"{joint}.Fx_", f"{joint}.Fy_"))]
    if mechanism.sizing:  # a bearing's life: its joint's force and relative rotation
        from symid.study.sizing_gradients import needed_columns as sizing_columns

        out += sizing_columns(mechanism, header)
    return list(dict.fromkeys(out))


def in_base(expr: sp.Expr, parameters: Mapping[str, sp.Expr]) -> sp.Expr:
    """`expr` with every derived parameter replaced by its definition, down to base parameters."""
    e = sp.sympify(expr)
    for name in reversed(list(parameters)):  # a definition only uses parameters given before it
        if is_derived(parameters[name]):
            e = e.xreplace({parameter_symbol(name): sp.sympify(parameters[name])})
    return e


@functools.lru_cache(maxsize=64)
def _by_parameters(f: sp.Expr, definitions: tuple[tuple[str, sp.Expr], ...],
                   names: tuple[str, ...]) -> tuple[sp.Expr, ...]:
    """A driver's df/dP and d(f')/dP for P in `names` (in that order), through
    the derived parameters' `definitions` (in order): derived once per run,
    not per point."""
    e = in_base(f, dict(definitions))
    by = [sp.diff(e, parameter_symbol(p)) for p in names]
    return tuple(by + [sp.diff(d, T) for d in by])


class _Driver:
    """One driver's effort e, rate v and their derivatives over the run's instants."""

    def __init__(self, c: Element, where: Source, mechanism: Mechanism, results: Results,
                 names: Sequence[str], values: Mapping[sp.Symbol, float]) -> None:
        t = results.t
        raw = results[where.column]
        draw = np.column_stack([results[sensitivity_column(where.column, p)] for p in names]).reshape(len(t), -1)
        f, fd = time_function(c.values["f"], values, t), time_function(c.values["f"], values, t, 1)  # as `efforts`
        definitions = tuple((n, e) for n, e in mechanism.parameters.items() if is_derived(e))
        both = time_functions(_by_parameters(c.values["f"], definitions, tuple(names)), values, t)
        df_, dfd_ = both[:, :len(names)], both[:, len(names):]
        if where.type == "distance_driver":  # e = -2 |f| lambda, v = d|f|/dt = sign(f) f'
            s = np.sign(f)[:, None]
            self.e, self.v = -2 * np.abs(f) * raw, np.sign(f) * fd
            self.de = -2 * s * df_ * raw[:, None] - 2 * np.abs(f)[:, None] * draw
            self.dv = s * dfd_
        else:
            sign = -1.0 if where.column.endswith(".lambda") else 1.0
            self.e, self.v, self.de, self.dv = sign * raw, fd, sign * draw, dfd_
        self.t = t


def _rms_gradient(t: Array, e: Array, de: Array) -> Array:
    """d/dp of the trapezoidal RMS of `summarize`; de shape (instants, params)."""
    span = float(t[-1] - t[0]) if len(t) else 0.0
    if span > 0:
        w = np.zeros(len(t))
        h = np.diff(t)
        w[:-1] += h / 2
        w[1:] += h / 2
    else:
        w, span = np.ones(len(t)), float(len(t))
    rms = np.sqrt(np.sum(w * e ** 2) / span)
    if rms == 0:
        return np.full(de.shape[1], np.nan)  # |e| has no derivative where every e is 0
    return (w * e) @ de / (span * rms)


def figure_gradients(mechanism: Mechanism, results: Results, names: Sequence[str]) -> Array:
    """d(FIGURE)/d(P) of the solved run, shape (len(figure_names), len(names)).

    Args:
        mechanism: the mechanism that was solved (its parameter values: the point).
        results: its run, with the columns `d(C)/d(P)` for C in `needed_columns`
            and P in `names`; a failed run differentiates the figures of the
            instants solved before it.
        names: base parameters.

    NaN where a figure has no derivative: `effort_t_peak`, a run with no
    instant, an RMS of exactly zero.
    """
    figures = figure_names(mechanism)
    at = {f: k for k, f in enumerate(figures)}
    out = np.full((len(figures), len(names)), np.nan)
    if not len(results.t) or not figures:
        return out
    values = parameter_values(mechanism.parameters)
    for c in drivers(mechanism):
        where = source(c, results.columns)
        if where is None:
            continue
        d = _Driver(c, where, mechanism, results, names, values)
        k = int(np.argmax(np.abs(d.e)))
        out[at[f"{c.name}.effort_peak"]] = np.sign(d.e[k]) * d.de[k]
        out[at[f"{c.name}.effort_rms"]] = _rms_gradient(d.t, d.e, d.de)
        power = d.e * d.v
        k = int(np.argmax(np.abs(power)))
        out[at[f"{c.name}.power_peak"]] = np.sign(power[k]) * (d.de[k] * d.v[k] + d.e[k] * d.dv[k])
        if f"{c.name}.motor_rms" in at:
            side = _motor_side(c, d, mechanism, names, values)
            out[at[f"{c.name}.motor_rms"]] = side.rms_gradient()
            out[at[f"{c.name}.motor_peak"]] = side.peak_gradient()
    for figure in figures:
        if figure.endswith(".force_peak"):
            out[at[figure]] = _force_peak_gradient(results, figure[: -len(".force_peak")], names)
    bearings = [b for b in mechanism.sizing.bearings if f"{b.joint}.L10_h" in at]
    if bearings:
        from symid.study.sizing_gradients import life_gradient

        joints = {c.name: c for c in mechanism.constraints}
        for b in bearings:
            out[at[f"{b.joint}.L10_h"]] = life_gradient(b, joints[b.joint], mechanism, results, names, values)
    return out


def _motor_side(c: Element, d: _Driver, mechanism: Mechanism, names: Sequence[str],
                values: Mapping[sp.Symbol, float]) -> MotorSide:
    from symid.study.sizing_gradients import MotorSide

    drive = next(x for x in mechanism.sizing.drives if x.driver == c.name)
    return MotorSide(drive, c, d, mechanism, names, values)


def drive_margins(mechanism: Mechanism, results: Results, names: Sequence[str],
                  only: Sequence[str]) -> dict[str, tuple[Array, Array | None]]:
    """Per driver of `only` (each with a drive), `Verdict.margins` of its
    drive and their gradients (4 x len(names); None without `names`).

    Args:
        results: the run, with the sensitivity columns of `needed_columns` by `names`.
    """
    from symid.output.sizing import load_of
    from symid.output.sizing.motor import motor_of, verdict
    from symid.study.sizing_gradients import margin_gradients

    values = parameter_values(mechanism.parameters)
    out: dict[str, tuple[Array, Array | None]] = {}
    for c in drivers(mechanism):
        if c.name not in only:
            continue
        drive = next(x for x in mechanism.sizing.drives if x.driver == c.name)
        load, _, _ = load_of(mechanism, results, c.name, values)
        margins = verdict(load, motor_of(drive, values)).margins()
        grads = None
        if names:
            where = source(c, results.columns)
            assert where is not None  # a drive's driver has an effort (`load_of` read it)
            side = _motor_side(c, _Driver(c, where, mechanism, results, names, values), mechanism, names, values)
            grads = margin_gradients(drive, side, mechanism, names, values)
        out[c.name] = (margins, grads)
    return out


def _force_peak_gradient(results: Results, joint: str, names: Sequence[str]) -> Array:
    """F . dF / |F| at the body and instant of the largest |(Fx, Fy)|."""
    roles = [c[len(joint) + 4:] for c in results.columns if c.startswith(f"{joint}.Fx_")]
    best, at_role, at_k = -1.0, "", 0
    for r in roles:
        size = np.hypot(results[f"{joint}.Fx_{r}"], results[f"{joint}.Fy_{r}"])
        k = int(np.argmax(size))
        if size[k] > best:  # the first role wins a tie, as max() over roles does
            best, at_role, at_k = float(size[k]), r, k
    if best <= 0:  # no force at any instant (a driver's pure torque): the derivative from above,
        # max |dF|, which is 0 for a force that is zero whatever the parameters
        return np.array([max(float(np.max(np.hypot(results[sensitivity_column(f"{joint}.Fx_{r}", p)],
                                                    results[sensitivity_column(f"{joint}.Fy_{r}", p)])))
                             for r in roles) for p in names])
    fx, fy = results[f"{joint}.Fx_{at_role}"][at_k], results[f"{joint}.Fy_{at_role}"][at_k]
    return np.array([(fx * results[sensitivity_column(f"{joint}.Fx_{at_role}", p)][at_k]
                      + fy * results[sensitivity_column(f"{joint}.Fy_{at_role}", p)][at_k]) / best
                     for p in names])
