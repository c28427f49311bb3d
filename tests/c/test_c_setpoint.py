"""The generated C solver's set-point entry (`<name>_setpoint`, issue #30 point 1).

Truth: (1) fed the values the compiled law gives at t (f, f', f'' of each
driver, evaluated here by sympy from the mechanism file, not by the C code),
setpoint reproduces `_instant` at t on every bundled example, in double to
1e-12 of each output group's peak and in single to the README's 1e-5 of
peak (single precision's stated bound); (2) a computed-torque check against
the closed form of a pendulum with set-points from no law; (3) statics and
kinematics solvers; (4) bad set-points are refused.
"""

from __future__ import annotations

import ctypes
import math
from pathlib import Path

import numpy as np
import pytest

from symid import api
from symid.model.mechanism import DRIVER_TYPES
from small_mechanisms import _body, _constraint, _coordinate, text
from setpoints import BAD_ARGUMENT, G, J, L, M, OK, PENDULUM, Laws, Solver, expression_drivers, laws, needs_cc
from runshare import key_of, shared_value
from tiers import diagonal, first_quick





def _instants(solver: Solver, count: int) -> list[tuple[float, np.ndarray]]:
    """count instants of the file's grid with the solution there (by the
    C trajectory in double), as (t, q)."""
    a = solver.mech.analysis
    fn = getattr(solver.lib, f"{solver.name}_trajectory")
    fn.restype = ctypes.c_int
    n = a.steps
    state, rows = np.zeros(solver.ctx.state, solver.real), np.zeros((n, solver.ctx.row_width), solver.real)
    state[:solver.ng] = solver.q0
    work, iwork, solved = np.zeros(solver.ctx.work, solver.real), np.zeros(solver.ng, np.intc), ctypes.c_long()
    h = (a.t1 - a.t0) / (n - 1)
    status = fn(solver.ct(a.t0), solver.ct(h), ctypes.c_long(n), solver._ptr(solver.p), solver.ct(a.tol),
                solver._ptr(state), solver._ptr(rows), ctypes.byref(solved), solver._ptr(work), solver._ptr(iwork))
    assert status == OK and solved.value == n
    picks = np.linspace(0, n - 1, count).round().astype(int)
    return [(float(rows[k, 0]), rows[k, 1:1 + solver.ng].astype(float)) for k in picks]


@pytest.fixture(scope="module")
def doubles(tmp_path_factory) -> dict[str, Solver]:
    return {}


def _solver(cache: dict[str, Solver], tmp_path_factory, example: str, precision: str) -> Solver:
    key = f"{example}-{precision}"
    if key not in cache:
        # the file, not its text: the export's text and header, so the run's shared object
        cache[key] = Solver(api.example(example), tmp_path_factory.mktemp(key), precision,
                            share=tmp_path_factory)
    return cache[key]


# the guess's offset from the solution: Newton has work to do (a few
# iterations), as in a controller's call from the last sample's q
OFFSET = 1e-3
# double: the law's value computed by sympy and by the C code differ by a
# rounding or two of f, which the solve carries to ~1e-15 of the outputs;
# 1e-12 leaves room for the conditioning of the bigger mechanisms
DOUBLE_BOUND = 1e-12
# single: the README's bound for single precision (every column within 1e-5
# of its peak against double) applies to the set-points rounded to float too
SINGLE_BOUND = 1e-5


@needs_cc
@pytest.mark.parametrize("example, precision", diagonal(api.examples(), ("double", "single")))
def test_setpoints_of_the_compiled_law_reproduce_instant(doubles, tmp_path_factory, example: str,
                                                         precision: str) -> None:
    solver = _solver(doubles, tmp_path_factory, example, precision)
    # the double build's 7 instants, once per run for both precisions (any worker):
    # a single case elsewhere needs no double build of its own
    instants = shared_value(tmp_path_factory, key_of("setpoint-instants", api.example(example).read_text(), 7),
                            lambda: _instants(_solver(doubles, tmp_path_factory, example, "double"), 7))
    _reproduces_instant(instants, solver, example, precision)


def _reproduces_instant(instants: list[tuple[float, np.ndarray]], solver: Solver, example: str,
                        precision: str) -> None:
    """setpoint fed the compiled laws (by sympy) against instant at the
    instants (t, q) of the file's grid (a double build's trajectory), each
    output group to the precision's bound of its peak."""
    bound = DOUBLE_BOUND if precision == "double" else SINGLE_BOUND
    results: dict[str, list[np.ndarray]] = {"instant": [], "setpoint": []}
    law = Laws(solver.mech)
    for t, q in instants:
        guess = q + OFFSET
        status, inst = solver.call("instant", t, guess)
        assert status == OK, (example, t)
        status, sp_out = solver.call("setpoint", t, guess, law(t))
        assert status == OK, (example, t)
        results["instant"].append(inst)
        results["setpoint"].append(sp_out)
    for key in ("q", "qd", "qdd", "lam", "reactions"):
        a = np.array([r[key] for r in results["instant"]], dtype=float)
        b = np.array([r[key] for r in results["setpoint"]], dtype=float)
        if key == "q":  # angles reduced by whole turns in single: compare modulo 2 pi
            a[:, 2::3] = np.angle(np.exp(1j * (a[:, 2::3] - b[:, 2::3]))) + b[:, 2::3]
        peak = max(np.max(np.abs(a)), 1e-300)
        assert np.max(np.abs(a - b)) <= bound * peak, (example, precision, key, np.max(np.abs(a - b)) / peak)



# the four-bar (one driver), the disc cam (its contact an expression row too)
# and the slider pendulum (an expression driver with an offset, between the
# carriage's translational driver's row and the rest)
EXPRESSION_DRIVEN = ("four_bar", "disc_cam", "slider_pendulum")


@needs_cc
@pytest.mark.parametrize("example, precision", [pytest.param(e, p, id=f"{e}-{p}", marks=() if (e, p) == ("four_bar", "double") else pytest.mark.slow)
                                                for e in EXPRESSION_DRIVEN for p in ("double", "single")])
def test_setpoints_of_an_expression_driver_reproduce_instant(tmp_path: Path, tmp_path_factory, example: str,
                                                             precision: str) -> None:
    """An expression driver row g(q) - f(t) is a driver of setpoint (its f
    the set-point), listed in the order of its row among the others."""
    source = expression_drivers(api.example(example).read_text())
    reference = Solver(source, tmp_path / "double", share=tmp_path_factory)  # built once for both precisions' cases
    solver = reference if precision == "double" else Solver(source, tmp_path / precision, precision)
    drivers = [c.name for c in reference.mech.constraints if c.type in DRIVER_TYPES or "f" in c.values]
    assert any(c.type == "expression" and c.name in drivers for c in reference.mech.constraints)
    assert [d.name for d in reference.ctx.setpoint.drivers] == drivers
    assert reference.rows == sorted(reference.rows) and len(reference.rows) == len(drivers)
    _reproduces_instant(_instants(reference, 7), solver, example, precision)


# A pendulum: a bar of mass m and inertia J about its centre of mass, pinned
# the row g(q) - f(t), here phi (sign 1) or, the row written f - phi, -phi
EXPRESSION_DRIVES = {"phi_i - sin(t)": 1, "sin(t) - phi_i": -1}
PENDULUMS = {"coordinate_driver": (PENDULUM, "drive_phi", 1)}
PENDULUMS.update({row: (PENDULUM.replace(_coordinate("bar", "phi", "sin(t)"),
                                         _constraint("drive", "expression", i='"bar"', phi=f'["{row}"]')),
                        "drive", sign) for row, sign in EXPRESSION_DRIVES.items()})


@needs_cc
@pytest.mark.parametrize("drive, precision", diagonal(list(PENDULUMS), ("double", "single")))
def test_computed_torque_of_a_pendulum_is_the_closed_form(tmp_path: Path, tmp_path_factory, drive: str,
                                                          precision: str) -> None:
    source, driver, sign = PENDULUMS[drive]
    solver = Solver(source, tmp_path, precision, share=tmp_path_factory)
    assert solver.nd == 1
    rng = np.random.default_rng(30)
    bound = 1e-12 if precision == "double" else 1e-5  # of the torque's scale (single: README's bound)
    q = solver.q0.astype(float)
    for phi, rate, accel in zip(rng.uniform(-3, 3, 12), rng.uniform(-5, 5, 12), rng.uniform(-40, 40, 12)):
        t = float(rng.uniform(0, 10))  # read by nothing: no other function of time
        status, out = solver.call("setpoint", t, q, tuple(sign * np.array([v]) for v in (phi, rate, accel)))
        assert status == OK
        tau = (J + M * L * L) * accel + M * G * L * math.cos(phi)
        scale = (J + M * L * L) * 40 + M * G * L
        # the driver's reaction on the bar: [Fx, Fy, T] at its centre of mass, T = -Phi_phi lambda = -sign lambda
        reaction = out["reactions"][solver.reaction(f"{driver}.T_i")]
        lam = out["lam"][solver.rows[0]]
        assert abs(reaction - tau) <= bound * scale, (reaction, tau)
        assert abs(-sign * lam - tau) <= bound * scale
        # single reads the driver's row modulo 2 pi (the header says so): the angle to whole turns
        assert abs(math.remainder(float(out["q"][2]) - phi, 2 * math.pi)) <= (1e-12 if precision == "double" else 1e-6)
        assert abs(float(out["qd"][2]) - rate) <= bound * 5
        assert abs(float(out["qdd"][2]) - accel) <= bound * 40
        # the pin carries the rest: m a_cm = F_pin + F_drive + m g (the drive is a pure torque)
        x, y = L * math.cos(phi), L * math.sin(phi)
        ax = -L * math.sin(phi) * accel - x * rate ** 2
        assert abs(float(out["qdd"][0]) - ax) <= bound * 100
        assert abs(float(out["q"][1]) - y) <= 1e-6
        q = out["q"]



# the pendulum driven by a row nonlinear in q, sin(phi_i) - f(t): its
# set-point is s = sin(phi) (the pendulum's height over l), so phi = asin s,
# phi' = s' / cos phi, phi'' = (s'' + sin(phi) phi'^2) / cos phi; the row's
# Phi_phi = cos phi makes the torque on the bar T = -cos(phi) lambda
SINE_PENDULUM = PENDULUM.replace(_coordinate("bar", "phi", "sin(t)"),
                                 _constraint("drive", "expression", i='"bar"', phi='["sin(phi_i) - 0.5*sin(t)"]'))


@needs_cc
@pytest.mark.parametrize("precision", ["double", "single"])
def test_computed_torque_through_a_nonlinear_expression_driver_is_the_closed_form(tmp_path: Path,
                                                                                    precision: str) -> None:
    """The set-points enter Phi, nu and gamma of a row whose g is not a
    coordinate: gamma's sin(phi) phi'^2 and the effort's cos(phi) are the
    row's, not the set-point's."""
    solver = Solver(SINE_PENDULUM, tmp_path, precision)
    assert solver.nd == 1
    rng = np.random.default_rng(31)
    bound = 1e-12 if precision == "double" else 1e-5  # as above
    for height, rate, accel in zip(rng.uniform(-0.9, 0.9, 12), rng.uniform(-3, 3, 12), rng.uniform(-30, 30, 12)):
        status, out = solver.call("setpoint", 0.0, solver.q0.astype(float),
                                  (np.array([height]), np.array([rate]), np.array([accel])))
        assert status == OK
        phi = math.asin(height)  # Newton from phi = 0 stays on the principal branch
        phid = rate / math.cos(phi)
        phidd = (accel + math.sin(phi) * phid ** 2) / math.cos(phi)
        tau = (J + M * L * L) * phidd + M * G * L * math.cos(phi)
        scale = (J + M * L * L) * abs(phidd) + M * G * L  # the torque's terms' size at this sample
        # phi' and phi'' to the bound of their own size (1/cos phi <= 2.3 amplifies the set-points' rounding)
        assert abs(float(out["qd"][2]) - phid) <= bound * max(abs(phid), 1.0)
        assert abs(float(out["qdd"][2]) - phidd) <= bound * max(abs(phidd), 1.0)
        assert abs(out["reactions"][solver.reaction("drive.T_i")] - tau) <= bound * scale
        assert abs(-math.cos(phi) * out["lam"][solver.rows[0]] - tau) <= bound * scale

@needs_cc
@pytest.mark.parametrize("kind", ["statics", "kinematics"])
def test_statics_and_kinematics_setpoints_reproduce_instant(tmp_path: Path, kind: str) -> None:
    """The analyses with no rates (statics: q_des only, qd_des and qdd_des
    may be NULL) or no multipliers (kinematics)."""
    solver = Solver(PENDULUM.replace("[analysis]\n", f'[analysis]\nkind = "{kind}"\n'), tmp_path)
    law = Laws(solver.mech)
    for t in (0.3, 1.7):
        f, fd, fdd = law(t)
        status, inst = solver.call("instant", t, solver.q0 + OFFSET)
        assert status == OK
        status, got = solver.call("setpoint", t, solver.q0 + OFFSET, (f, None, None) if kind == "statics"
                                  else (f, fd, fdd))
        assert status == OK
        for key in ("q", "qd", "qdd", "lam", "reactions"):
            peak = max(np.max(np.abs(inst[key])), 1.0)
            assert np.max(np.abs(got[key] - inst[key])) <= DOUBLE_BOUND * peak, (kind, key)


@needs_cc
def test_bad_setpoints_are_refused_and_leave_q(tmp_path: Path, tmp_path_factory) -> None:
    solver = Solver(PENDULUM, tmp_path, share=tmp_path_factory)
    f, fd, fdd = laws(solver.mech, 0.5)
    for des in ((f * np.nan, fd, fdd), (f, fd * np.inf, fdd), (f, fd, fdd * np.nan), (None, fd, fdd),
                (f, None, fdd), (f, fd, None)):
        status, out = solver.call("setpoint", 0.5, solver.q0 + OFFSET, des)
        assert status == BAD_ARGUMENT
        assert np.array_equal(out["q"], solver.q0 + OFFSET)


# a pendulum whose angle driver has an offset C = phi_off (read by the
# driver's row: its position stage) and a law amplitude (read by the law only)
OFFSET_PENDULUM = text("offset_pendulum",
                       '\n[parameters]\nphi_off = 0.3\namp = 0.8\nm_bar = 1.5\n'
                       + _body("bar", "0.5, 0.0, 0.0", mass='"m_bar"')
                       + _constraint("pin", "revolute", i='"ground"', j='"bar"', si="[0.0, 0.0]", sj="[-0.5, 0.0]")
                       + _constraint("drive", "relative_angle_driver", i='"ground"', j='"bar"', f='"amp*sin(t)"',
                                     C='"phi_off"'))
SENSITIVITY_CASES = {
    # the carriage: a translational driver along a guide inclined by alpha
    # (read by its rows' rates), its stroke s_amp read by its law only
    "slider_pendulum": (api.example("slider_pendulum").read_text(), ("alpha", "s_amp", "h_hinge"), "s_amp"),
    "offset_pendulum": (OFFSET_PENDULUM, ("phi_off", "amp", "m_bar"), "amp"),
    # the same drive as an expression row: phi_off in g(q) (its constant c_0), amp in f(t)
    "expression_offset_pendulum": (OFFSET_PENDULUM.replace(
        _constraint("drive", "relative_angle_driver", i='"ground"', j='"bar"', f='"amp*sin(t)"', C='"phi_off"'),
        _constraint("drive", "expression", i='"bar"', phi='["phi_i - phi_off - amp*sin(t)"]')),
        ("phi_off", "amp", "m_bar"), "amp"),
}
assert 'type = "expression"' in SENSITIVITY_CASES["expression_offset_pendulum"][0]


@needs_cc
@pytest.mark.slow  # central differences of set-points on three mechanisms
@pytest.mark.parametrize("case", list(SENSITIVITY_CASES))
def test_setpoint_sensitivities_are_central_differences_with_the_setpoints_held(tmp_path: Path, case: str) -> None:
    """setpoint_sensitivity against central differences of setpoint itself,
    the set-points held: a parameter read by the driver's row moves the
    results, one read by its law only has no effect."""
    source, names, law_only = SENSITIVITY_CASES[case]
    solver = Solver(source, tmp_path, sensitivity=",".join(names))
    sens_ctx = solver.ctx.sens
    ns, of = sens_ctx.ns, sens_ctx.of
    columns = list(solver.columns)
    fn = getattr(solver.lib, f"{solver.name}_setpoint_sensitivity")
    fn.restype = ctypes.c_int
    law = Laws(solver.mech)
    for t, q in _instants(solver, 3)[1:]:
        des = law(t)
        sens = np.zeros(len(of) * ns)
        work, iwork = np.zeros(solver.ctx.work), np.zeros(solver.ng, np.intc)
        guess = q + OFFSET
        status = fn(ctypes.c_double(t), solver._ptr(solver.p), ctypes.c_double(1e-13),
                    *(solver._ptr(d) for d in des), solver._ptr(guess), solver._ptr(sens), None,
                    solver._ptr(work), solver._ptr(iwork))
        assert status == OK
        got = sens.reshape(len(of), ns)

        def row(p: np.ndarray) -> np.ndarray:
            saved, solver.p = solver.p, p
            status, out = solver.call("setpoint", t, q, des, tol=1e-14)
            solver.p = saved
            assert status == OK
            values = np.concatenate([[t], out["q"], out["qd"], out["qdd"], out["lam"], out["reactions"]])
            return np.array([values[columns.index(c)] for c in of])

        base = row(solver.p)
        for k, name in enumerate(names):
            j = solver.mech_params.index(name)
            h = 1e-5 * max(1.0, abs(solver.p[j]))
            up, down = solver.p.copy(), solver.p.copy()
            up[j] += h
            down[j] -= h
            fd = (row(up) - row(down)) / (2 * h)
            # central differences: truncation h^2 ~ 1e-10, rounding ~1e-16 / h of each column's scale
            scale = np.max(np.abs(base)) / max(abs(solver.p[j]), 1e-2) + np.max(np.abs(fd))
            assert np.max(np.abs(got[:, k] - fd)) <= 1e-6 * scale, (name, np.max(np.abs(got[:, k] - fd)) / scale)
        assert np.max(np.abs(got[:, names.index(law_only)])) == 0.0  # read by the driver's law only


@needs_cc
@pytest.mark.parametrize("precision", ["double", "single"])
def test_position_only_sensitivities_compile_strictly_and_hold_the_crank(tmp_path: Path, precision: str) -> None:
    """Sensitivities of q columns only (no rate or multiplier stage): the
    solver builds with -Werror (no set-point kernel, and no transposed
    solve, left unused), and the crank's angle, a set-point, does not move
    with the slider's mass."""
    solver = Solver(api.example("slider_crank").read_text(), tmp_path, precision, sensitivity="m_slider,L_rod",
                    of="crank.phi,slider.x")
    fn = getattr(solver.lib, f"{solver.name}_setpoint_sensitivity")
    fn.restype = ctypes.c_int
    t = 0.013
    sens = np.full(4, np.nan, solver.real)
    work, iwork = np.zeros(solver.ctx.work, solver.real), np.zeros(solver.ng, np.intc)
    status = fn(solver.ct(t), solver._ptr(solver.p), solver.ct(1e-12 if precision == "double" else 1e-6),
                *(solver._ptr(np.asarray(d, solver.real)) for d in laws(solver.mech, t)), solver._ptr(solver.q0.copy()),
                solver._ptr(sens), None, solver._ptr(work), solver._ptr(iwork))
    assert status == OK
    assert sens[0] == 0.0 and sens[1] == 0.0  # d(crank.phi)/d(m_slider), d(crank.phi)/d(L_rod): the set-point's
    assert sens[2] == 0.0 and abs(sens[3]) > 0.5  # the slider's position: not by mass, by the rod's length


# --- split time: setpoint_at(whole, frac) ---

# The four-bar's coupler load F_tool (1 + 0.5 sin(omega t)) reads t through a
# phase while its driver reads the set-points: at t = 1e6 s a float t is a
# multiple of 1/16 s. n = 2.375 rev/s, exact in float (a rounded n would move
# the phase by n's rounding times 1e6 s), makes whole seconds no whole turns.
SPLIT_N, SPLIT_WHOLE, SPLIT_FRAC = 2.375, 1_000_001, 0.3


@needs_cc
def test_setpoint_at_a_million_seconds_in_single_is_double_within_the_header_bound(tmp_path: Path,
                                                                                    tmp_path_factory) -> None:
    from cbuild import single_bound

    source = api.example("four_bar")  # the file: the export's text and object
    double = Solver(source, tmp_path / "double", share=tmp_path_factory)
    single = Solver(source, tmp_path / "single", "single", share=tmp_path_factory)
    at = double.mech_params.index("n")
    double.p[at], single.p[at] = SPLIT_N, SPLIT_N
    frac = float(np.float32(SPLIT_FRAC))  # the time single is given: whole + its float fraction, exactly
    t = SPLIT_WHOLE + frac
    omega = 2 * math.pi * SPLIT_N
    angle = math.remainder(omega * SPLIT_WHOLE, 2 * math.pi) + omega * frac  # the crank's law, reduced
    des = (np.array([angle]), np.array([omega]), np.array([0.0]))
    # the guess: the file's run (at this n) at the crank angle nearest (positions depend on the angle only)
    runs = _instants(double, 201)
    guess = min(runs, key=lambda r: abs(math.remainder(omega * r[0] - angle, 2 * math.pi)))[1]
    status, truth = double.call("setpoint", t, guess, des)
    assert status == OK
    status, same = double.call("setpoint_at", (SPLIT_WHOLE, frac), guess, des)
    assert status == OK and all(np.array_equal(same[k], truth[k]) for k in truth)  # double: whole + frac, rounded once
    status, split = single.call("setpoint_at", (SPLIT_WHOLE, frac), guess, des)
    assert status == OK
    status, naive = single.call("setpoint", t, guess, des)  # t rounded to a float: 1000001.3125
    assert status == OK
    bound = single_bound(tmp_path / "single", "four_bar")  # what the single header states
    worst = {}
    for name, got in (("split", split), ("naive", naive)):
        for key in ("q", "qd", "qdd", "lam", "reactions"):
            a, b = truth[key].astype(float), got[key].astype(float)
            if key == "q":  # angles modulo 2 pi
                a[2::3] = np.angle(np.exp(1j * (a[2::3] - b[2::3]))) + b[2::3]
            worst[name, key] = np.max(np.abs(a - b)) / np.max(np.abs(a))
    assert max(v for (name, _), v in worst.items() if name == "split") <= bound, worst
    assert max(v for (name, _), v in worst.items() if name == "naive") > 100 * bound, worst  # the split is what holds
