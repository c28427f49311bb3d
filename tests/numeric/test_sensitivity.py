"""Sensitivities (`symid solve --sensitivity`) against independent truth:
Richardson-extrapolated central differences of whole runs (solved as
variants by the batch engine), closed forms on the slider-crank from power
balance, and CasADi's own automatic differentiation of the generated instant."""

from __future__ import annotations

import numpy as np
import pytest

from runshare import key_of, shared_value
from sensitivity_runs import solved
from symid import api
from symid.model.mechanism import parameter_symbol
from symid.model.params import base_names
from symid.output.results import columns
from symid.symbolic.assemble import assemble
from symid.symbolic.columns import GROUP_SUFFIXES

# friction: tests/numeric/test_friction_sensitivity.py. The scissor boom: its
# 16-bar lattice carries the runs' rounding into the differences at 8e-9 of a
# column's scale (above this file's 2e-9 floor); its forces are checked
# against Lagrange's equation in tests/numeric/test_scissor_boom.py
EXAMPLES = [e for e in api.examples() if "friction" not in e and e != "scissor_boom"]
# the quick tier checks the slider-crank's sensitivities; quick_return's (a slider in a moving slot: the same
# derivation, more parameters) are with the other examples in the slow tier
CHECKED = [pytest.param(e, marks=pytest.mark.slow) if e == "quick_return" else e for e in EXAMPLES]
BACKENDS = ("reference", "numpy", "casadi", "c")
STEPS = 4  # t0, t1 and two instants between (not only the slider-crank's dead centres)
REL = 2e-4  # the difference step, relative to the parameter's value
# Andrews' squeezer: lengths of ~1e-2 m and a driver torque that cancels ~20x
# (the spring's moment against 0.033 N m). At 2e-4 the differences' rounding
# reached 2e-9 of the scale (by sb: steps of 1e-6 m), at 2e-3 their truncation
# did (by xa: h^4 against 1e-2 m); at 5e-4 the worst are 2.6e-10 (coarse against
# fine) and 2.0e-10 (against the sensitivities)
REL_OF = {"andrews_squeezer": 5e-4}


def _stencil(study: api.Study, names: tuple[str, ...], h_scale: float) -> dict[str, np.ndarray]:
    """d(column)/d(name) for every column and name: the five-point central
    difference (error h^4), each variant solved from scratch."""
    base = np.array([study.values[parameter_symbol(n)] for n in names])
    steps = h_scale * np.maximum(np.abs(base), 1e-2)
    offsets = (1, -1, 2, -2)
    rows = []
    for k in range(len(names)):
        for o in offsets:
            row = base.copy()
            row[k] += o * steps[k]
            rows.append(row)
    runs = [r for chunk in study.solve_many(np.array(rows), names) for r in chunk]
    out = {}
    for k, name in enumerate(names):
        plus, minus, plus2, minus2 = (runs[4 * k + j] for j in range(4))
        assert all(r.error is None for r in (plus, minus, plus2, minus2)), name
        d = (8 * (plus.data - minus.data) - (plus2.data - minus2.data)) / (12 * steps[k])
        for c, col in enumerate(plus.columns):
            out[f"d({col})/d({name})"] = d[:, c]
    return out


def _kind(column: str) -> str:
    """A column's quantity: position, rate, acceleration, or force (multipliers, reactions)."""
    suffix = column.rsplit(".", 1)[-1]
    return next((g for g, names in GROUP_SUFFIXES.items() if suffix in names), "force")


_TRUTHS: dict[str, tuple[dict[str, dict[str, np.ndarray]], dict[str, float]]] = {}


def _truth(example: str, factory: pytest.TempPathFactory) -> tuple[dict[str, dict[str, np.ndarray]], dict[str, float]]:
    """_differences(example), computed once per run: its tests (every backend, the
    40-digit one's scales) fall on either xdist worker, and each computed it."""
    if example not in _TRUTHS:
        key = key_of("test_sensitivity._differences", example, api.example(example), STEPS, REL_OF.get(example, REL))
        _TRUTHS[example] = shared_value(factory, key, lambda: _differences(example))
    return _TRUTHS[example]


def _differences(example: str) -> tuple[dict[str, dict[str, np.ndarray]], dict[str, float]]:
    """The differences at two steps (h and h/2) and each sensitivity column's scale."""
    study = api.prepare(api.example(example), "numpy", steps=STEPS)
    names = base_names(study.mechanism.parameters)
    rel = REL_OF.get(example, REL)
    coarse, fine = _stencil(study, names, rel), _stencil(study, names, rel / 2)
    plain = study.solve()
    # floor for sensitivities that vanish (an angle's by a mass, or the
    # x of a body that stays on its axis): 1% of the peak of the columns
    # of the same kind (every body's vx, say) per unit relative change
    # of the parameter, above the differences' rounding (eps |column| / step).
    # The peaks per suffix and per kind are taken once (not once per column and parameter)
    top = {c: float(np.abs(plain[c]).max()) for c in plain.columns}
    by_suffix: dict[str, float] = {}
    for c in plain.columns:
        by_suffix[c.rsplit(".", 1)[-1]] = max(by_suffix.get(c.rsplit(".", 1)[-1], 0.0), top[c])
    by_kind: dict[str, float] = {}
    for c in plain.columns[1:]:  # a distance driver's T is 0
        by_kind[_kind(c)] = max(by_kind.get(_kind(c), 0.0), top[c])
    scale = {}
    for key in fine:
        if key.startswith("d(t)/"):
            continue
        column, name = key[2:].split(")/d(")
        peak = max(by_suffix[column.rsplit(".", 1)[1]], 1e-3 * by_kind[_kind(column)])
        value = abs(study.values[parameter_symbol(name[:-1])])
        scale[key] = max(np.abs(fine[key]).max(), peak / max(value, 1e-2) * 1e-2, 1e-9)
    return {"coarse": coarse, "fine": fine}, scale


@pytest.mark.parametrize("example", CHECKED)
def test_differences_reach_the_bound_they_are_used_for(example: str, tmp_path_factory) -> None:
    """Two step sizes of the extrapolated differences agree to 2e-9 of each
    column's scale: their truncation is gone and what is left is the runs'
    rounding over the step (worst: the excavator's bucket.alpha by L_bucket,
    1e-12 rad/s^2 absolute). The sensitivities meet 1e-9 against them; the
    CasADi test below is the tighter (1e-10) independent check."""
    fd, scale = _truth(example, tmp_path_factory)
    worst = max(np.abs(fd["coarse"][k] - fd["fine"][k]).max() / scale[k] for k in scale)
    assert worst < 2e-9


# The generated C of every parameter of Andrews' squeezer and the excavator is
# the costliest compile of the suite (a minute and a half under load): on the C
# backend these two are checked on three of their parameters (the code of each
# parameter's columns is the same derivation; tests/c/test_c_sensitivity.py
# checks chosen parameters of the others against the C solver's own differences).
FEW_ON_C = {"andrews_squeezer": 3, "excavator": 3}


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("example", CHECKED)
def test_sensitivities_match_central_differences_to_1e_9_of_peak(example: str, backend: str, tmp_path_factory) -> None:
    fd, scale = _truth(example, tmp_path_factory)
    names = base_names(api.load_mechanism(api.example(example)).parameters)
    if backend == "c" and example in FEW_ON_C:
        names = names[:FEW_ON_C[example]]
    results = solved(tmp_path_factory, example, backend, names, STEPS)  # the disc cam's: the expressions' test's too
    assert results.error is None
    sens = [c for c in results.columns if c.startswith("d(")]
    assert sens, "the default columns (efforts and reactions) are present"
    errors = {c: np.abs(results[c] - fd["fine"][c]).max() / scale[c] for c in sens}
    worst = max(errors, key=errors.get)  # type: ignore[arg-type]
    # the differences themselves hold to 2e-9 of the scale (test above): 1e-9, as the docstring there says
    assert errors[worst] < 1e-9, (worst, errors[worst])


def test_motor_torque_by_slider_mass_and_gas_load_is_the_power_balance_closed_form() -> None:
    """The slider moves along x, so its mass enters the motor's power only as
    m a v: T omega = m_slider ax vx + ..., so dT/dm_slider = ax vx / omega;
    the load -F_gas sin(omega t) on it gives dT/dF_gas = sin(omega t) vx / omega."""
    results = api.solve(api.example("slider_crank"), "reference", sensitivity="m_slider,F_gas",
                        sensitivity_of="motor.T_j", steps=7)
    omega = 2 * np.pi * 5
    ax, vx, t = results["slider.ax"], results["slider.vx"], results.t
    by_mass = ax * vx / omega
    by_load = np.sin(omega * t) * vx / omega
    # closed forms against a tol 1e-12 solve: rounding of the peak (both)
    np.testing.assert_allclose(results["d(motor.T_j)/d(m_slider)"], by_mass, rtol=0, atol=1e-12 * np.abs(by_mass).max())
    np.testing.assert_allclose(results["d(motor.T_j)/d(F_gas)"], by_load, rtol=0, atol=1e-12 * np.abs(by_load).max())


def test_crank_speed_moves_omega_through_its_definition() -> None:
    """`n` is a base parameter and `omega = 2*pi*n` derived: d(crank angle)/d(n)
    at time t is 2 pi t (crank angle omega t)."""
    results = api.solve(api.example("slider_crank"), "reference", sensitivity="n", sensitivity_of="crank.phi",
                        steps=5)
    # d(phi)/dn = 2 pi t exactly; rounding of values up to 1.3
    np.testing.assert_allclose(results["d(crank.phi)/d(n)"], 2 * np.pi * results.t, rtol=1e-13, atol=1e-15)


@pytest.mark.parametrize("example", ["slider_crank", "four_bar"])
def test_sensitivities_agree_with_casadi_automatic_differentiation(example: str, tmp_path) -> None:
    """CasADi differentiates its generated instant (Newton steps, solves) by AD."""
    casadi = pytest.importorskip("casadi")
    path = api.example(example)
    api.generate(path, "casadi", tmp_path)
    mech = api.load_mechanism(path)
    instant = casadi.Function.load(str(tmp_path / f"{mech.name}_instant.casadi"))
    names = base_names(mech.parameters)
    results = api.solve(path, "reference", sensitivity=names, steps=STEPS)
    study = api.prepare(path, "reference", steps=STEPS)
    p = np.array([study.values[parameter_symbol(n)] for n in names])
    ps = casadi.MX.sym("p", len(names))
    ng = study.layout.ng
    header = study.columns()
    q_cols = [header.index(f"{b.name}.{c}") for b in mech.bodies for c in ("x", "y", "phi")]
    r_cols = [c for c in header if c.endswith(("_i", "_j", "_k"))]
    for k, t in enumerate(results.t):
        guess = results.data[k, q_cols]  # converged: Newton from it is independent of p
        out = instant(guess, t, ps)
        jac = casadi.Function("j", [ps], [casadi.jacobian(out[4], ps)])(p).full()  # reactions
        for r, column in enumerate(r_cols):
            for j, name in enumerate(names):
                ours = results[f"d({column})/d({name})"][k]
                # the exact Jacobian against the solver's: the same quantity to rounding of the column's peak
                assert abs(ours - jac[r, j]) <= 1e-10 * max(1.0, np.abs(jac[:, j]).max()), (t, column, name)
    assert ng == len(q_cols)


@pytest.mark.parametrize("example", CHECKED)
def test_sensitivities_match_40_digit_central_differences(example: str, tmp_path_factory) -> None:
    """Central differences (step 1e-12) of a 40-digit instant solver
    (`high_precision`), exact to ~1e-20, at an interior instant."""
    from high_precision import DIGITS, Instant

    import mpmath

    path = api.example(example)
    mech = api.load_mechanism(path)
    hp = Instant(mech)
    every = columns(assemble(mech), mech.analysis)[1:]  # every column of the table, but t
    study = api.prepare(path, "reference", steps=STEPS, sensitivity=hp.names, sensitivity_of=every)
    results = study.solve()
    _, scale = _truth(example, tmp_path_factory)
    header = study.columns()
    groups = {"q": [c for c in header if _kind(c) == "q"][:study.layout.ng],
              "qd": [c for c in header if _kind(c) == "qdot"][:study.layout.ng],
              "qdd": [c for c in header if _kind(c) == "qddot"][:study.layout.ng],
              "lam": [c for c in header if ".lambda" in c and not c.startswith("d(")],
              "reactions": [c for c in header if c.endswith(("_i", "_j", "_k")) and not c.startswith("d(")]}
    p0 = [mpmath.mpf(study.values[parameter_symbol(n)]) for n in hp.names]
    worst = (0.0, "")
    with mpmath.workdps(DIGITS):
        for k in (2,):
            t = results.t[k]
            guess = results.data[k, [header.index(c) for c in groups["q"]]]
            for j, name in enumerate(hp.names):
                h = mpmath.mpf("1e-12") * max(abs(p0[j]), mpmath.mpf("1e-2"))
                plus, minus = list(p0), list(p0)
                plus[j] += h
                minus[j] -= h
                a, b = hp.solve(t, plus, guess), hp.solve(t, minus, guess)
                for what, columns_ in groups.items():
                    for r, column in enumerate(columns_):
                        exact = float((a[what][r] - b[what][r]) / (2 * h))
                        key = f"d({column})/d({name})"
                        err = abs(results[key][k] - exact) / scale[key]
                        worst = max(worst, (err, f"{key} at t = {t}"))
    # against the 40-digit instant: rounding of the double solve, relative to the column's scale
    assert worst[0] < 1e-9, worst


@pytest.mark.parametrize("example", ["slider_crank", "four_bar"])
def test_statics_sensitivities_match_central_differences(example: str) -> None:
    """Statics (qdot = 0, dampers exert nothing): the same check, its own run
    (a short one: statics predicts positions without rates)."""
    path = api.example(example)
    study = api.prepare(path, "numpy", steps=STEPS, kind="statics", t1=0.03)
    names = base_names(study.mechanism.parameters)
    fd = _stencil(study, names, REL)
    results = api.solve(path, "reference", sensitivity=names, steps=STEPS, kind="statics", t1=0.03)
    assert results.error is None
    sens = [c for c in results.columns if c.startswith("d(")]
    assert sens
    for c in sens:
        peak = max(np.abs(fd[c]).max(), 1e-6 * max(np.abs(results[k]).max() for k in results.columns[1:]
                                                   if not k.startswith("d(")))
        # central differences of whole runs (see the fd step above): 1e-9 of the peak
        assert np.abs(results[c] - fd[c]).max() <= 1e-9 * peak, c
