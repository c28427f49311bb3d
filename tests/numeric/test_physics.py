"""The solver's results against physics it does not use: a closed form,
power balance and Newton-Euler on every body, finite differences."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

from symid import api
from symid.io.reader import load
from truth import Truth, newton_euler_residual

EXAMPLES = api.examples()


@pytest.fixture(scope="module", params=EXAMPLES)
def solved(request):
    mech = load(api.example(request.param))
    results = api.solve(mech)
    assert results.error is None, results.error
    return mech, results


def test_every_example_solves_every_instant(solved):
    mech, results = solved
    assert results.data.shape[0] == mech.analysis.steps
    assert np.all(np.isfinite(results.data))


def test_newton_euler_holds_on_every_body(solved):
    mech, results = solved
    for body, (force, moment) in newton_euler_residual(Truth(mech, results)).items():
        # Newton-Euler of a tol 1e-12 solve: loads of order 10-1000 N keep 1e-9 N with room
        assert force < 1e-9 and moment < 1e-9, (body, force, moment)


def _friction_power(mech, results) -> np.ndarray:
    """The power joint friction dissipates (<= 0; zero without friction), from the table."""
    return sum((results[f"{c.name}.friction_power"] for c in mech.constraints if c.friction),
               np.zeros(len(results.t)))


def test_power_balance_lambda_phi_t(solved):
    """lambda^T Phi_t = d/dt(T + V) - P_nc - P_friction, i.e. dT/dt - P_applied -
    P_friction, with Phi_t of the drivers written by hand and lambda straight
    from the table."""
    mech, results = solved
    truth = Truth(mech, results)
    drive = np.zeros(truth.n)
    for c in mech.constraints:
        if c.type.endswith("driver"):
            drive += results[f"{c.name}.lambda"] * truth.driver_phi_t(c.name)
    expected = truth.kinetic_power() - truth.load_power(truth.applied_loads()) - _friction_power(mech, results)
    scale = np.max(np.abs(expected)) + np.max(np.abs(drive))
    # the power balance sums products of rates and loads: 1e-8 of the largest power
    assert np.max(np.abs(drive - expected)) <= 1e-8 * scale


def test_reactions_do_no_work_except_drivers(solved):
    """The power of all reactions equals the drive power: joints are workless
    but for their friction (the reaction columns include it)."""
    mech, results = solved
    truth = Truth(mech, results)
    drive = np.zeros(truth.n)
    for c in mech.constraints:
        if c.type.endswith("driver"):
            drive += results[f"{c.name}.lambda"] * truth.driver_phi_t(c.name)
    reactions = truth.load_power(truth.reaction_loads()) - _friction_power(mech, results)
    # the power balance sums products of rates and loads: 1e-8 of the largest power (1e-12: no zero division)
    assert np.max(np.abs(reactions - drive)) <= 1e-8 * (np.max(np.abs(drive)) + 1e-12)


def _central(values: np.ndarray, h: float) -> np.ndarray:
    """6th-order central difference of equally spaced samples (interior points)."""
    v = values
    return (-v[:-6] + 9 * v[1:-5] - 45 * v[2:-4] + 45 * v[4:-2] - 9 * v[5:-1] + v[6:]) / (60 * h)


def test_velocities_and_accelerations_match_finite_differences(solved):
    mech, results = solved
    h = results.t[1] - results.t[0]
    for b in mech.bodies:
        for pos, vel in (("x", "vx"), ("y", "vy"), ("phi", "omega")):
            fd = _central(results[f"{b.name}.{pos}"], h)
            exact = results[f"{b.name}.{vel}"][3:-3]
            # 6th-order central differences of the table: truncation O(h^6) and rounding / h, within 1e-5 of the peak
            assert np.max(np.abs(fd - exact)) <= 1e-5 * (np.max(np.abs(exact)) + 1e-3), (b.name, pos)
        for vel, acc in (("vx", "ax"), ("vy", "ay"), ("omega", "alpha")):
            fd = _central(results[f"{b.name}.{vel}"], h)
            exact = results[f"{b.name}.{acc}"][3:-3]
            # 6th-order central differences of the table: truncation O(h^6) and rounding / h, within 1e-5 of the peak
            assert np.max(np.abs(fd - exact)) <= 1e-5 * (np.max(np.abs(exact)) + 1e-3), (b.name, vel)


def test_slider_crank_motor_torque_equals_closed_form():
    """Power method by hand: tau*omega = dT/dt - sum(m g . v) - F_gas . v_slider."""
    mech = load(api.example("slider_crank"))
    truth = Truth(mech, api.solve(mech, steps=200))
    p = {k.name: v for k, v in truth.values.items()}
    r, l, w = p["L_crank"], p["L_rod"], p["omega"]
    m1, m2, m3 = p["m_crank"], p["m_rod"], p["m_slider"]
    j1, j2 = m1 * r**2 / 12, m2 * l**2 / 12
    g = -9.81
    t = sp.Symbol("t")
    th = w * t
    pin = sp.Matrix([r * sp.cos(th), r * sp.sin(th)])
    slider = sp.Matrix([r * sp.cos(th) + sp.sqrt(l**2 - r**2 * sp.sin(th) ** 2), 0])
    rod_angle = sp.atan2(-r * sp.sin(th), slider[0] - pin[0])
    centres = [(m1, pin / 2), (m2, (pin + slider) / 2), (m3, slider)]
    kinetic = sum(m * (c.diff(t).T * c.diff(t))[0] for m, c in centres) / 2
    kinetic += (j1 * w**2 + j2 * rod_angle.diff(t) ** 2) / 2
    gravity_power = sum(m * g * c[1].diff(t) for m, c in centres)
    gas_power = -p["F_gas"] * sp.sin(th) * slider[0].diff(t)
    tau = (kinetic.diff(t) - gravity_power - gas_power) / w
    expected = sp.lambdify(t, tau, "numpy")(truth.t)
    got = truth.res["motor.T_j"]
    # the closed form of the torque against a tol 1e-12 solve: rounding of the peak, with room
    assert np.max(np.abs(got - expected)) <= 1e-10 * np.max(np.abs(expected))
    # and the motor's reaction on ground is the opposite torque
    assert np.allclose(truth.res["motor.T_i"], -got, rtol=0, atol=1e-12 * np.max(np.abs(got)))


def test_statics_lambda_balances_gravity_only():
    """In statics the slider-crank motor holds the weights: torque from virtual work by hand."""
    mech = load(api.example("slider_crank"))
    res = api.solve(mech, kind="statics", steps=50)
    truth = Truth(mech, res)
    p = {k.name: v for k, v in truth.values.items()}
    r, l, w = p["L_crank"], p["L_rod"], p["omega"]
    th = w * res.t
    # virtual work with dtheta: crank centre and crank pin heights move with r cos(th)
    # (slider stays on y = 0, so the rod centre height is half the pin's).
    dy_crank, dy_rod = r / 2 * np.cos(th), r / 2 * np.cos(th)
    x_slider_d = -r * np.sin(th) - r**2 * np.sin(th) * np.cos(th) / np.sqrt(l**2 - (r * np.sin(th)) ** 2)
    gas = -p["F_gas"] * np.sin(th) * x_slider_d
    tau = 9.81 * (p["m_crank"] * dy_crank + p["m_rod"] * dy_rod) - gas
    # the static torque by virtual work against a tol 1e-12 solve: rounding of the peak, with room
    assert np.allclose(res["motor.T_j"], tau, rtol=0, atol=1e-10 * np.max(np.abs(tau)))
