"""The refinement of the multipliers is decided by the residual
(symid.numeric.stability.refine_wanted): made where the first transposed
solve is past REFINE_BERR roundings of a body's own terms, skipped where it
is at rounding. A scissor lift near flat (cond 1e8 at t1) carrying a 20 mg
lamp on a pin: the lamp pin's multipliers from the first solve carry the
lift's rounding (1e-10 of the lamp's weight); the refined ones are those of
a 40-digit solve of the same system (mpmath, as tests/helpers/high_precision.py).
On a well-conditioned run of uniform scales the correction's solve is not
made: one solve per multiplier solve, where it was always two."""

from __future__ import annotations

import mpmath
import numpy as np
import pytest

from symid import api
from symid.io.reader import loads
from symid.numeric import stability
from symid.numeric.stability import Factor, Scaling, jacobian
from scissor import scissor_lift

# a 20 mg lamp held on the platform by a pin and a fixed angle
LAMP_BODY = """
[[body]]
name = "lamp"
mass = "m_lamp"
inertia = "m_lamp"
q0 = ["L/2", "L*sin(a0 + e) + 0.1", 0.0]
"""
LAMP_CONSTRAINTS = """
[[constraint]]
name = "lamp_pin"
type = "revolute"
i = "platform"
j = "lamp"
si = [0.0, 0.0]
sj = [0.0, -0.1]

[[constraint]]
name = "lamp_hold"
type = "relative_angle_driver"
i = "platform"
j = "lamp"
f = "0"
"""
SCISSOR_LAMP = scissor_lift("scissor_lamp", """
L = 1.0
a0 = 0.6
e = 1e-7
m_lamp = 2e-5
""", 41, "a0 + e", "pi - a0 - e", "L*cos(a0*(1 - t) + e)", more_bodies=LAMP_BODY, more_constraints=LAMP_CONSTRAINTS)


def test_near_a_singular_position_refinement_takes_a_light_bodys_multipliers_to_40_digits() -> None:
    mech = loads(SCISSOR_LAMP, "scissor_lamp.toml")
    study = api.prepare(mech, "reference")
    res = study.solve()
    assert res.error is None and any("ill-conditioned" in w for w in res.warnings)  # cond 1e8 at t1
    ev, q0 = study.evaluator, study.q0()
    coords = [f"{b.name}.{x}" for b in mech.bodies for x in ("x", "y", "phi")]
    rows = [res.columns.index(c) for c in ("lamp_pin.lambda1", "lamp_pin.lambda2")]
    rows = [r - res.columns.index("A.lambda1") for r in rows]  # the multipliers' indices
    weight = 2e-5 * 9.81
    mpmath.mp.dps = 40
    for k in (len(res.t) - 1, len(res.t) - 3):
        q, t = np.array([res[c][k] for c in coords]), float(res.t[k])
        jac = jacobian(ev, q, t)
        factor = Factor(jac, Scaling.of(jacobian(ev, q0, 0.0), q0))
        b = np.asarray(ev.applied(q, None, t), dtype=float)
        exact = mpmath.lu_solve(mpmath.matrix(jac.T.tolist()), mpmath.matrix(b.tolist()))
        truth = np.array([float(exact[r]) for r in rows])
        first = factor._solve_t(b)[rows]
        refined = factor.solve_t(b)[rows]
        # the first solve: the lift's rounding (measured 1.6e-10 of the lamp's weight);
        # refined: the 40-digit solution to a rounding of the lamp's own loads
        assert np.max(np.abs(first - truth)) > 1e-12 * weight, (k, first - truth)
        assert np.max(np.abs(refined - truth)) <= 1e-14 * weight, (k, refined - truth)


@pytest.mark.parametrize("which", ["slider_crank", "scissor_far_from_flat"])
def test_a_well_conditioned_run_makes_one_solve_per_multiplier_solve(monkeypatch, which: str) -> None:
    """The scissor 0.05 rad from flat with a 5 kg lamp: its platform has no
    horizontal load, a row whose terms are all rounding noise (a body's x and
    y rows share their scale: no correction for that noise)."""
    calls = {"solve_t": 0, "solves": 0}
    solve_t, inner = Factor.solve_t, Factor._solve_t

    def counted_solve_t(self, b):  # type: ignore[no-untyped-def]
        calls["solve_t"] += 1
        return solve_t(self, b)

    def counted(self, b):  # type: ignore[no-untyped-def]
        calls["solves"] += 1
        return inner(self, b)

    monkeypatch.setattr(stability.Factor, "solve_t", counted_solve_t)
    monkeypatch.setattr(stability.Factor, "_solve_t", counted)
    mech = (api.example("slider_crank") if which == "slider_crank" else
            loads(SCISSOR_LAMP.replace("e = 1e-7", "e = 0.05").replace("m_lamp = 2e-5", "m_lamp = 5.0"), "s.toml"))
    res = api.solve(mech, "reference")
    assert res.error is None and calls["solve_t"] >= len(res.t)
    # every instant's first solve at rounding (measured <= 15 eps of a body's own terms): no correction's solve
    assert calls["solves"] == calls["solve_t"], calls
