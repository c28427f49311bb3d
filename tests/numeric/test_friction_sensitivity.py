"""Sensitivities with joint friction (issue 26 point 3; contract v1.1
"Sensitivities", "Joint friction") against independent truth: central
differences of a 40-digit instant solver that solves the friction with the
multipliers by its own fixed-point iteration (`high_precision`), on the
bundled slider-crank with friction, a small arm with friction on its pin and
on a prismatic joint between two moving bodies, and the quick-return with
friction in a pin-in-slot; every backend agreeing with the reference."""

from __future__ import annotations

import functools

import mpmath
import numpy as np
import pytest

from symid import api
from symid.io.reader import loads
from symid.model.mechanism import parameter_symbol
from data_mechanisms import quick_return_with_friction

pytestmark = pytest.mark.slow  # 40-digit central differences of every column (139 s under load)

BACKENDS = ("numpy", "casadi", "c")
STEPS = 4  # t0, t1 and two instants between, neither where a friction or a normal force crosses zero
# (the slider-crank at a quarter turn: |N| has a kink there, no derivative)

ARM = """
[mechanism]
name = "arm_slider"
gravity = [0.0, -9.81]
[parameters]
L = 0.5
m_arm = 2.0
m_slider = 0.7
mu_pin = 0.08
r_pin = 0.015
mu_slide = 0.12
c_slide = 1.5
a_slide = 0.04
vs = 0.2                       # wide: the slide speed is within a few v_smooth (tanh not saturated)
w = 2.0
A = 0.1
[analysis]
t0 = 0.0
t1 = 1.0
steps = 5
[[body]]
name = "arm"
mass = "m_arm"
inertia = "m_arm*L^2/12"
q0 = ["L/2", 0.0, 0.0]
[[body]]
name = "slider"
mass = "m_slider"
inertia = 0.002
q0 = ["L/2", 0.0, 0.0]
[[constraint]]
name = "pivot"
type = "revolute"
i = "ground"
j = "arm"
si = [0.0, 0.0]
sj = ["-L/2", 0.0]
friction = { mu = "mu_pin", radius = "r_pin", viscous = 0.01 }
[[constraint]]
name = "slide"
type = "translational"
i = "arm"
j = "slider"
si = [0.0, 0.0]
vi = [1.0, 0.0]
sj = [0.0, 0.0]
friction = { mu = "mu_slide", viscous = "c_slide", arm = "a_slide", v_smooth = "vs" }
[[constraint]]
name = "swing"
type = "relative_angle_driver"
i = "ground"
j = "arm"
f = "w*t + 0.3*sin(3*t)"
[[constraint]]
name = "stroke"
type = "translational_driver"
i = "arm"
j = "slider"
si = [0.0, 0.0]
vi = [1.0, 0.0]
sj = [0.0, 0.0]
f = "A*sin(4*t) + 0.05*t"
"""


def _mechanism(which: str):  # type: ignore[no-untyped-def]
    if which == "slider_crank_friction":
        return api.load_mechanism(api.example(which))
    if which == "arm_slider":
        return loads(ARM, "arm_slider.toml")
    if which == "arm_slider_exact_sign":  # v_smooth = 0 on the pin: the sign is a constant away from rest
        text = ARM.replace('viscous = 0.01 }', 'viscous = 0.01, v_smooth = 0 }')
        assert text != ARM
        return loads(text, "arm_slider.toml")
    return loads(quick_return_with_friction(), "quick_return.toml")


MECHANISMS = ("slider_crank_friction", "arm_slider", "arm_slider_exact_sign", "quick_return_friction")


def _names(mech) -> list[str]:  # type: ignore[no-untyped-def]
    from symid.model.params import base_names

    return list(base_names(mech.parameters))


@functools.cache
def _solved(which: str, backend: str) -> api.Results:
    mech = _mechanism(which)
    every = [c for c in api.prepare(mech, "reference", steps=2).columns()[1:]]
    study = api.prepare(mech, backend, sensitivity=_names(mech), sensitivity_of=every, steps=STEPS)
    results = study.solve()
    _VALUES[id(results)] = {n: study.values[parameter_symbol(n)] for n in _names(mech)}
    return results


@functools.cache
def _instant(which: str):  # type: ignore[no-untyped-def]
    """The 40-digit instant of a mechanism, derived once for both instants."""
    from high_precision import Instant

    return Instant(_mechanism(which))


@functools.cache
def _truth(which: str, k: int) -> dict[str, float]:
    """d(column)/d(name) at instant k by central differences (step 1e-15 of
    the parameter) of the 40-digit solver: truncation ~1e-30 times the third
    derivative (1e12 at most through tanh(v / v_smooth)), rounding 1e-40 / 1e-15."""
    from high_precision import DIGITS

    mech = _mechanism(which)
    hp = _instant(which)
    study = api.prepare(mech, "reference", steps=STEPS)
    plain = _solved(which, "reference")
    header = study.columns()
    ng = study.layout.ng
    groups = {"q": header[1:1 + ng], "qd": header[1 + ng:1 + 2 * ng], "qdd": header[1 + 2 * ng:1 + 3 * ng],
              "lam": [c for c in header if ".lambda" in c],
              "reactions": [c for c in header if c.endswith(("_i", "_j", "_k"))],
              "friction": [c for c in header if c.endswith((".friction", ".friction_power"))]}
    assert header == ["t", *(c for g in groups.values() for c in g)]  # every column is checked
    p0 = [mpmath.mpf(study.values[parameter_symbol(n)]) for n in hp.names]
    out = {}
    with mpmath.workdps(DIGITS):
        t = plain.t[k]
        guess = plain.data[k, 1:1 + ng]
        for j, name in enumerate(hp.names):
            h = mpmath.mpf("1e-15") * max(abs(p0[j]), mpmath.mpf("1e-2"))
            plus, minus = list(p0), list(p0)
            plus[j] += h
            minus[j] -= h
            a, b = hp.solve(t, plus, guess), hp.solve(t, minus, guess)
            for what, columns in groups.items():
                for r, column in enumerate(columns):
                    out[f"d({column})/d({name})"] = float((a[what][r] - b[what][r]) / (2 * h))
    return out


def _scale(results: api.Results, key: str) -> float:
    """A column's peak over the run, floored (a column zero by construction:
    a ground side's torque, a rate by a mass) at 1% of the peak of the
    plain columns of its kind (every body's alpha, every Fx_i, ...) per unit
    relative change of the parameter, as tests/numeric/test_sensitivity.py does."""
    column, name = key[2:-1].split(")/d(")
    peak = _peaks(results)[column.rsplit(".", 1)[-1]]
    value = abs(_VALUES[id(results)][name])
    return max(float(np.abs(results[key]).max()), 1e-2 * peak / max(value, 1e-2), 1e-12)


_VALUES: dict[int, dict[str, float]] = {}  # id of a solved run -> its base parameters' values
_PEAKS: dict[int, dict[str, float]] = {}  # id of a solved run -> the peak of its plain columns by suffix


def _peaks(results: api.Results) -> dict[str, float]:
    """The peak over the run of the plain columns (not d(...)) of each kind, by
    the column's last dotted part; worked out once per run (every key asks)."""
    if id(results) not in _PEAKS:
        peaks: dict[str, float] = {}
        for c in results.columns:
            if not c.startswith("d("):
                suffix = c.rsplit(".", 1)[-1]
                peaks[suffix] = max(peaks.get(suffix, 0.0), float(np.abs(results[c]).max()))
        _PEAKS[id(results)] = peaks
    return _PEAKS[id(results)]


@pytest.mark.parametrize("which", MECHANISMS)
def test_every_sensitivity_column_matches_40_digit_central_differences(which: str) -> None:
    """Every column (q to the friction columns) by every base parameter, at
    two interior instants, to 1e-11 of the column's peak: the double-precision
    solve's own rounding, amplified by the conditioning of Phi_q and of the
    friction Newton, measured at 1.4e-13 at most (the quick-return), and the
    friction converged to tol = 1e-12 of lambda moves a derivative by less."""
    results = _solved(which, "reference")
    worst = (0.0, "")
    for k in (1, 2):
        truth = _truth(which, k)
        assert set(truth) == {c for c in results.columns if c.startswith("d(")}
        for key, exact in truth.items():
            err = abs(results[key][k] - exact) / _scale(results, key)
            worst = max(worst, (err, f"{key} at t = {results.t[k]}"))
    # against the 40-digit instant: the double solve's rounding, amplified by the steep smoothed sign
    assert worst[0] < 1e-11, worst


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("which", MECHANISMS)
def test_backends_agree_with_the_reference_to_1e_12_of_each_columns_peak(which: str, backend: str) -> None:
    ref, other = _solved(which, "reference"), _solved(which, backend)
    assert other.columns == ref.columns
    worst = (0.0, "")
    for key in (c for c in ref.columns if c.startswith("d(")):
        err = float(np.abs(other[key] - ref[key]).max()) / _scale(ref, key)
        worst = max(worst, (err, key))
    # two backends evaluating the same sensitivity formulas at the same q: rounding of each column's scale
    assert worst[0] < 1e-12, worst


def test_sensitivity_columns_come_after_the_friction_columns() -> None:
    """The contract's order: every other column (friction columns included),
    then d(COLUMN)/d(NAME) for the default columns (the drivers' efforts and
    the reactions, here all reaction columns) in table order, columns outer
    and parameters inner."""
    path = api.example("slider_crank_friction")
    results = api.solve(path, "reference", sensitivity="mu_pin,L_crank", steps=3)
    plain = api.solve(path, "reference", steps=3).columns
    assert results.columns[:len(plain)] == plain and plain[-1] == "cylinder_guide.friction_power"
    reactions = [c for c in plain if c.endswith(("_i", "_j"))]
    assert results.columns[len(plain):] == [f"d({c})/d({n})" for c in reactions for n in ("mu_pin", "L_crank")]


@pytest.mark.parametrize("backend", ["c", "numpy"])
def test_sweep_gradients_with_friction_match_differences_of_the_figures(tmp_path, backend: str) -> None:
    """`symid sweep --gradients` reads the same sensitivities: at mu_pin =
    0.05, a_slider = 0.06, each figure's d/d(mu_pin) and d/d(a_slider)
    against the central difference of the figures of the variants 1e-5 on
    either side: truncation h^2 f''' / 6 (through 1/arm, 6 / a^4 ~ 5e5:
    ~1e-6 of a derivative at h = 1e-4, ~1e-8 here), rounding 1e-16 of the
    figure over the step (~1e-9 of its derivative): held to 1e-6."""

    import csv

    from symid.cli import main

    path = str(api.example("slider_crank_friction"))
    out = tmp_path / "sweep.csv"
    h = 1e-5
    assert main(["sweep", path, "--grid", f"mu_pin={0.05 - h}:{0.05 + h}:3", "--grid",
                 f"a_slider={0.06 - h}:{0.06 + h}:3", "--gradients", "--steps", "41", "--backend", backend,
                 "-o", str(out)]) == 0
    rows = list(csv.DictReader(out.open()))
    assert [r["status"] for r in rows] == ["ok"] * 9
    figures = [c for c in rows[0] if c.endswith(("_peak", "_rms")) and not c.startswith("d(")
               and not c.endswith("t_peak") and not c.startswith("motor.force")]
    worst = (0.0, "")
    for name, (plus, minus) in (("mu_pin", (7, 1)), ("a_slider", (5, 3))):  # a_slider varies fastest
        for figure in figures:
            fd = (float(rows[plus][figure]) - float(rows[minus][figure])) / (2 * h)
            exact = float(rows[4][f"d({figure})/d({name})"])
            err = abs(exact - fd) / max(abs(fd), 1e-3 * float(rows[4][figure]))
            worst = max(worst, (err, f"d({figure})/d({name})"))
    # central differences of whole runs: truncation and the runs' rounding over the step; 1e-6 relative
    assert worst[0] < 1e-6, worst


def test_compiled_instant_sensitivity_with_friction_equals_the_loops_row() -> None:
    """`<name>_instant_sensitivity`, which gives the row of an instant the
    Python loop solved for the compiled loop (a handed-over instant), solves
    the friction and its derivatives as the loop does: the reference's
    columns to 1e-12 of each column's peak."""
    mech = _mechanism("arm_slider")
    every = [c for c in api.prepare(mech, "reference", steps=2).columns()[1:]]
    study = api.prepare(mech, "c", sensitivity=_names(mech), sensitivity_of=every, steps=STEPS)
    ref = _solved("arm_slider", "reference")
    ev = study.evaluator
    header = ev.sensitivity_header
    assert header == [c for c in ref.columns if c.startswith("d(")]
    ng = study.layout.ng
    for k in (1, 2):
        row = ev.sensitivity_row(ref.data[k, 1:1 + ng], float(ref.t[k]), study.analysis.tol)
        err = max(abs(row[m] - ref[c][k]) / _scale(ref, c) for m, c in enumerate(header))
        # one instant re-evaluated at the table's own q: the same arithmetic, rounding
        assert err < 1e-12, (k, err)
