"""The bundled scissor boom (8 stages, 16 bars, ng 48) on every backend,
against truth that uses none of symid's derivations: Lagrange's equation for
its one coordinate (every bar's centre at height L/2 sin(theta), stage k's at
x = (2k + 1) L/2 cos(theta)), the power balance and Newton-Euler on every bar
from the reactions (`tests/helpers/truth.py`)."""

from __future__ import annotations

import numpy as np
import pytest

from symid import api
from symid.io.reader import loads

BACKENDS = ("reference", "numpy", "casadi", "c")
STAGES, L, M_BAR, M_TIP, G = 8, 0.6, 1.2, 5.0, 9.81


@pytest.fixture(scope="module")
def runs():
    path = api.example("scissor_boom")
    return path, {b: api.solve(path, backend=b) for b in BACKENDS}


def lagrange_torque(theta: np.ndarray, rate: np.ndarray, accel: np.ndarray) -> np.ndarray:
    """The motor torque on a0 by hand: tau = I(theta) theta'' + I'(theta) theta'^2 / 2 + dV/dtheta."""
    k = np.arange(STAGES)[:, None]
    s, c = np.sin(theta), np.cos(theta)
    j = M_BAR * L ** 2 / 12
    # two bars per stage: the centre moves by ((2k + 1) L/2 (-sin), L/2 cos) per unit of theta
    inertia = (2 * (M_BAR * (L / 2) ** 2 * ((2 * k + 1) ** 2 * s ** 2 + c ** 2) + j)).sum(axis=0)
    slope = (2 * M_BAR * (L / 2) ** 2 * ((2 * k + 1) ** 2 - 1) * 2 * s * c).sum(axis=0)
    # weight of the bars (centres at L/2 sin) and of the payload (at the tip, L sin)
    dv = (2 * STAGES * M_BAR * G * L / 2 + M_TIP * G * L) * c
    return inertia * accel + slope * rate ** 2 / 2 + dv


@pytest.mark.slow  # the 16-bar boom solved on every backend (its fixture), a big example
@pytest.mark.parametrize("backend", ["c", "reference", "numpy", "casadi"])
def test_the_motor_torque_is_lagranges(runs, backend: str) -> None:
    _, results = runs
    res = results[backend]
    assert res.error is None, res.error
    theta, rate, accel = res["a0.phi"], res["a0.omega"], res["a0.alpha"]
    exact = lagrange_torque(theta, rate, accel)
    # the hand formula's own rounding and the solve's (Newton tol 1e-12 scaled, cond ~ 300): 1e-10 of the peak
    np.testing.assert_allclose(res["motor.T_j"], exact, rtol=0, atol=1e-10 * np.max(np.abs(exact)))
    # the deploy: theta from theta_0 to theta_1 (the boom from 2.4 to 4.3 m), at rest at both ends
    assert theta[0] == pytest.approx(1.05, abs=1e-13) and theta[-1] == pytest.approx(0.45, abs=1e-13)
    assert abs(rate[0]) < 1e-12 and abs(rate[-1]) < 1e-12


# slow: the 16-bar boom solved on every backend (its fixture), a big example; power balance and Newton-Euler of
# the bundled quick examples stay in the quick tier
@pytest.mark.slow
def test_power_balance_and_newton_euler_on_every_bar(runs) -> None:
    from truth import Truth, newton_euler_residual

    path, results = runs
    for backend, res in results.items():
        truth = Truth(loads(path.read_text(), str(path)), res)
        motor = res["motor.T_j"] * res["a0.omega"]  # the motor's torque on a0 times its speed
        applied = truth.load_power(truth.applied_loads())  # gravity and the payload, by hand
        np.testing.assert_allclose(motor + applied, truth.kinetic_power(), rtol=0,
                                   atol=1e-10 * np.max(np.abs(applied)), err_msg=backend)
        # each bar's F = m a and M = J alpha from the reactions of every pin at its points
        for body, (force, moment) in newton_euler_residual(truth).items():
            assert force < 1e-11 and moment < 1e-11, (backend, body, force, moment)
