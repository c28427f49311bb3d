"""The exact gradient of a bearing's L10 life (#29, point 6) against
independent truth: central differences of the life computed at 40 digits by
ISO 281's own formula (P_eq, then the life at the run's mean speed) from a
40-digit solver that shares none of the sensitivity code, on a crank pin
whose load and relative speed both move with each parameter; and a bearing
under a constant load, whose life (C / P)^p 1e6 / (60 n_rpm) and its
derivatives are written by hand."""

from __future__ import annotations

import math

import mpmath
import numpy as np
import pytest

from symid import api
from symid.io.reader import loads
from symid.model.mechanism import parameter_symbol
from symid.model.params import parameter_values
from symid.output.results import columns
from symid.study.figures import figure_names
from symid.study.gradients import figure_gradients, needed_columns
from symid.study.slow import figures_of, study_analysis
from symid.symbolic.assemble import assemble
from symid.tools.sensitive import solver


def _gradients(mech, names):
    """The run with its sensitivities (numpy), its figures and their exact gradients."""
    results = solver("numpy")(mech, names, needed_columns(mech, columns(assemble(mech), mech.analysis)))
    assert results.error is None
    return results, figures_of(mech, results), figure_gradients(mech, results, names)


def _life_40_digits(hp, mech, results, p, joint_name: str, C, exponent):
    """ISO 281's variable-load life of `joint_name` at base parameters p, every
    instant solved at 40 digits: P_eq = (int |F|^p |r| dt / int |r| dt)^(1/p),
    L10 = (C / P_eq)^p 1e6 revolutions at the mean relative speed int |r| dt / span."""
    joint = next(c for c in mech.constraints if c.name == joint_name)
    bodies = [b.name for b in mech.bodies]
    header = results.columns
    q_cols = [header.index(f"{b}.{c}") for b in bodies for c in ("x", "y", "phi")]
    t = [mpmath.mpf(float(x)) for x in results.t]
    load, rate = [], []
    at = hp._starts[joint_name]  # its reactions: Fx Fy T on i, then on j
    for k in range(len(t)):
        got = hp.solve(results.t[k], p, results.data[k, q_cols])  # Newton from the double solution
        load.append(mpmath.sqrt(got["reactions"][at + 3] ** 2 + got["reactions"][at + 4] ** 2))
        r = mpmath.mpf(0)
        for role, sign in (("j", 1), ("i", -1)):
            if joint.bodies[role] != "ground":
                r += sign * got["qd"][3 * bodies.index(joint.bodies[role]) + 2]
        rate.append(r)
    w = [mpmath.mpf(0)] * len(t)
    for k in range(len(t) - 1):
        w[k] += (t[k + 1] - t[k]) / 2
        w[k + 1] += (t[k + 1] - t[k]) / 2
    turned = sum(a * abs(r) for a, r in zip(w, rate))
    P = (sum(a * abs(r) * F ** exponent for a, r, F in zip(w, rate, load)) / turned) ** (1 / exponent)
    mean_speed = turned / (t[-1] - t[0])
    return (C / P) ** exponent * 10 ** 6 / (mean_speed / (2 * mpmath.pi)) / 3600


def test_life_gradient_matches_40_digit_central_differences():
    """The slider-crank's crank pin (needle rollers: p = 10/3): L_rod moves
    the rod's angular speed relative to the crank and the pin's load, n both
    through the crank speed. Central differences with a step of 1e-12 of a
    40-digit life are exact to ~1e-20 relative; the gradient is held to 1e-9
    (the double solve's rounding, summed over the run)."""
    from high_precision import DIGITS, Instant

    names = ["L_rod", "n"]
    mech = study_analysis(api.load_mechanism(api.example("slider_crank_sized"), steps=6))
    results, figures, grads = _gradients(mech, names)
    k = figure_names(mech).index("crank_pin.L10_h")
    hp = Instant(mech)
    values = parameter_values(mech.parameters)
    with mpmath.workdps(DIGITS):
        p0 = [mpmath.mpf(values[parameter_symbol(n)]) for n in hp.names]
        C, exponent = mpmath.mpf(9000), mpmath.mpf(10) / 3
        assert float(_life_40_digits(hp, mech, results, p0, "crank_pin", C, exponent)) == \
            pytest.approx(figures[k], rel=1e-12)  # the same life: what is differentiated is the figure
        for j, name in enumerate(names):
            at = hp.names.index(name)
            h = mpmath.mpf("1e-12") * abs(p0[at])
            up, down = list(p0), list(p0)
            up[at] += h
            down[at] -= h
            exact = (_life_40_digits(hp, mech, results, up, "crank_pin", C, exponent)
                     - _life_40_digits(hp, mech, results, down, "crank_pin", C, exponent)) / (2 * h)
            assert grads[k, j] == pytest.approx(float(exact), rel=1e-9), name
            assert abs(float(exact)) > 0.3 * figures[k] / float(p0[at])  # each parameter moves the life


def flywheel_at_constant_speed() -> str:
    """A wheel, its CM on the pin, spun at w0 against gravity: the pin carries m g."""
    return """
[mechanism]
name = "flywheel"
gravity = [0.0, -9.81]
[parameters]
m = 2.0
w0 = 5.0
C_b = 5000.0
p_b = 3.0
[analysis]
t1 = 1.0
steps = 11
[[body]]
name = "wheel"
mass = "m"
inertia = 0.05
q0 = [0.0, 0.0, 0.0]
[[constraint]]
name = "pin"
type = "revolute"
i = "ground"
j = "wheel"
si = [0.0, 0.0]
sj = [0.0, 0.0]
bearing = { C = "C_b", p = "p_b" }
[[constraint]]
name = "motor"
type = "relative_angle_driver"
i = "ground"
j = "wheel"
f = "w0*t"
"""


def test_constant_load_life_and_its_gradient_by_hand():
    """P = m g, n = 60 w0 / (2 pi) rpm: L10 = (C / (m g))^p 1e6 / (60 n) hours, so
    dL/dm = -p L / m, dL/dw0 = -L / w0 (the speed alone), dL/dC = p L / C,
    dL/dp = L ln(C / (m g)). The solve is exact to rounding (tol 1e-12): 1e-10."""
    names = ["m", "w0", "C_b", "p_b"]
    mech = study_analysis(loads(flywheel_at_constant_speed(), "flywheel.toml"))
    _, figures, grads = _gradients(mech, names)
    k = figure_names(mech).index("pin.L10_h")
    m, w0, C, p, g = 2.0, 5.0, 5000.0, 3.0, 9.81
    rpm = 60 * w0 / (2 * math.pi)
    life = (C / (m * g)) ** p * 1e6 / (60 * rpm)
    assert figures[k] == pytest.approx(life, rel=1e-12)
    by_hand = [-p * life / m, -life / w0, p * life / C, life * math.log(C / (m * g))]
    np.testing.assert_allclose(grads[k], by_hand, rtol=1e-10)
