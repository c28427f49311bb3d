"""Sizing (#29) against closed forms: a flywheel driven through a gear
(motor torque per instant, motoring and back-driven; RMS, peak and the best
ratio sqrt(J_load / J_motor)), bearings under a constant and a varying load,
and the bundled slider-crank's motor from power balance (independent of the
solver's multipliers)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from symid import api
from symid.output import sizing
from symid.io.reader import loads
from symid.output.sizing import motor as motors
from truth import Truth

# A flywheel (CM on its pin: the pin carries m g and whatever acts at the
# centre) turned by a relative-angle driver f(t) from ground.
M, J_LOAD, G = 2.0, 0.05, 9.81


def flywheel(f: str, drive: str = "", t1: float = 1.0, steps: int = 2001, bearing: str = "C = 5000.0, p = 3",
             force: str = "") -> str:
    text = f"""
[mechanism]
name = "flywheel"
gravity = [0.0, -{G}]
[parameters]
A = 0.8
w = "2*pi"
[analysis]
t0 = 0.0
t1 = {t1}
steps = {steps}
[[body]]
name = "wheel"
mass = {M}
inertia = {J_LOAD}
q0 = [0.0, 0.0, 0.0]
[[constraint]]
name = "pin"
type = "revolute"
i = "ground"
j = "wheel"
si = [0.0, 0.0]
sj = [0.0, 0.0]
bearing = {{ {bearing} }}
[[constraint]]
name = "motor"
type = "relative_angle_driver"
i = "ground"
j = "wheel"
f = "{f}"
"""
    if force:
        text += f'[[force]]\nname = "push"\ntype = "point_force"\nbody = "wheel"\ns = [0.0, 0.0]\nF = {force}\n'
    if drive:
        text += f'[[drive]]\ndriver = "motor"\n{drive}\n'
    return text


MOTOR = "rotor_inertia = 2e-4\ncontinuous_torque = 100.0\npeak_torque = 200.0\nmax_speed = 1e4\n"


def sized(text: str) -> tuple[sizing.Report, object, object]:
    mech = sizing.for_sizing(loads(text, "flywheel.toml", analysis=sizing.ANALYSIS))
    results = api.solve(mech)
    return sizing.size(mech, results), mech, results


def test_motor_torque_per_instant_motoring_and_back_driven():
    """Spin-down and reverse, theta = w0 t - a t^2 / 2 over [0, 2 w0 / a]: the
    first half the load drives the motor (T qd < 0: T eta_b / n), the second
    the motor drives (T / (n eta)); the rotor adds J_m n qdd throughout."""
    w0, a, n, eta, back = 3.0, 6.0, 7.0, 0.8, 0.6
    report, _, _ = sized(flywheel(f"{w0}*t - {a / 2}*t^2", f"ratio = {n}\nefficiency = {eta}\n"
                                  f"back_efficiency = {back}\n" + MOTOR, t1=2 * w0 / a, steps=1000))
    v = report.drives[0]
    t = v.t
    load = -J_LOAD * a  # the torque on the wheel, constant
    speed = w0 - a * t
    through = np.where(load * speed >= 0, load / eta, load * back)
    expected = 2e-4 * n * (-a) + through / n
    assert np.all(speed[:500] > 0) and np.all(speed[500:] < 0)  # no instant at rest: both sides tested
    np.testing.assert_allclose(v.torque, expected, rtol=1e-10)  # solver exact to rounding (tol 1e-12)
    np.testing.assert_allclose(v.speed, n * speed, rtol=1e-12, atol=1e-12 * n * w0)
    # RMS (trapezoidal time mean of the square), peak and its instant, peak speed
    half = np.abs(expected[:500]).max(), np.abs(expected[500:]).max()
    assert v.motor_peak == pytest.approx(max(half), rel=1e-10)
    assert v.t_peak >= t[500]  # the motoring side needs more: 1/eta > eta_b
    rms = math.sqrt(np.trapezoid(expected ** 2, t) / t[-1])
    assert v.motor_rms == pytest.approx(rms, rel=1e-10)
    assert v.speed_peak == pytest.approx(n * w0, rel=1e-12)
    assert v.thermal_margin == pytest.approx(1 - (rms / 100.0) ** 2, rel=1e-12)


def test_sinusoidal_flywheel_rms_peak_and_best_ratio_sqrt_of_inertias():
    """theta = A sin(w t) over one period, eta = 1: the motor torque is
    -(J_m n + J_L / n) A w^2 sin(w t), RMS (J_m n + J_L / n) A w^2 / sqrt(2),
    least at n = sqrt(J_L / J_m) = 15.81 inside [1, 100]."""
    A, w, J_m = 0.8, 2 * math.pi, 2e-4
    report, _, _ = sized(flywheel("A*sin(w*t)", "ratio = [1.0, 100.0]\n" + MOTOR))
    v = report.drives[0]
    best = math.sqrt(J_LOAD / J_m)
    assert v.ratio == pytest.approx(best, rel=1e-9)  # 2001 instants: the trapezoid is exact for sin^2
    assert v.motor_rms == pytest.approx(2 * math.sqrt(J_LOAD * J_m) * A * w * w / math.sqrt(2), rel=1e-9)
    assert v.motor_peak == pytest.approx(2 * math.sqrt(J_LOAD * J_m) * A * w * w, rel=1e-9)
    assert min(abs(v.t_peak - 0.25), abs(v.t_peak - 0.75)) < 1e-12
    assert v.speed_peak == pytest.approx(best * A * w, rel=1e-9)


def test_rms_derivative_is_exact_and_the_range_clips_the_best_ratio():
    """d RMS / d n against a central difference (step 1e-4 n: error ~1e-8
    relative), zero at the best ratio; a range below it chooses its top."""
    _, mech, results = sized(flywheel("A*sin(w*t)", "ratio = [1.0, 100.0]\n" + MOTOR, steps=401))
    from symid.model.params import parameter_values

    values = parameter_values(mech.parameters)
    load, _, _ = sizing.load_of(mech, results, "motor", values)
    motor = motors.motor_of(mech.sizing.drives[0], values)
    for n in (2.0, 15.0, 40.0):
        h = 1e-4 * n
        fd = (motors.rms(load, motor, n + h) - motors.rms(load, motor, n - h)) / (2 * h)
        assert motors.rms_derivative(load, motor, n) == pytest.approx(fd, rel=1e-6, abs=1e-12)
    best = motors.best_ratio(load, motor)
    assert abs(motors.rms_derivative(load, motor, best)) < 1e-12
    low = motors.Motor(**{**motor.__dict__, "ratio": (1.0, 5.0)})
    assert motors.best_ratio(load, low) == 5.0


def test_envelope_corner_speed_and_the_first_instant_outside():
    """Peak 2 N m to corner 5 rad/s, falling to 0 at 10: available 2 (10 - w) / 5.
    A constant 1 N m at speeds 0..10 leaves it past w = 7.5: named with its instant."""
    m = motors.Motor("d", (1.0, 1.0), 1.0, 1.0, 0.0, 1.5, 2.0, 10.0, 5.0)
    np.testing.assert_allclose(m.available(np.array([0.0, 5.0, -7.5, 10.0, 12.0])), [2.0, 2.0, 1.0, 0.0, 0.0])
    t = np.linspace(0.0, 1.0, 101)
    load = motors.Load(t, np.ones_like(t), 10 * t * 0.999, np.zeros_like(t))
    v = motors.verdict(load, m)
    assert not v.fits and len(v.why) == 1 and "outside the envelope" in v.why[0]
    first = t[np.argmax(10 * t * 0.999 > 7.5)]
    assert f"first at t = {first:.12g} s" in v.why[0]
    fine = motors.verdict(motors.Load(t, np.ones_like(t), 7.4 * t, np.zeros_like(t)), m)
    assert fine.fits and fine.thermal_margin == pytest.approx(1 - (1 / 1.5) ** 2)


@pytest.mark.parametrize("limit, said", [("continuous_torque", "RMS torque"), ("peak_torque", "peak torque"),
                                         ("max_speed", "speed")])
def test_each_limit_just_exceeded_is_named(limit, said):
    """The sinusoid at n = 10: RMS, peak and speed from the closed form; each
    limit set 0.1 % below its figure fails on that figure alone."""
    A, w, J_m, n = 0.8, 2 * math.pi, 2e-4, 10.0
    figures = {"continuous_torque": (J_m * n + J_LOAD / n) * A * w * w / math.sqrt(2),
               "peak_torque": (J_m * n + J_LOAD / n) * A * w * w, "max_speed": n * A * w}
    keys = {"continuous_torque": 100.0, "peak_torque": 200.0, "max_speed": 1e4, limit: 0.999 * figures[limit]}
    if limit == "peak_torque":  # the peak stays above the continuous rating (a monotone envelope)
        keys["continuous_torque"] = 1.001 * figures["continuous_torque"]
    text = "\n".join(f"{k} = {v!r}" for k, v in keys.items())
    report, _, _ = sized(flywheel("A*sin(w*t)", f"ratio = {n}\nrotor_inertia = {J_m}\n{text}\n"))
    v = report.drives[0]
    assert not report.fits and len(v.why) == 1 and v.why[0].startswith(said), v.why


def test_bearing_under_constant_load_l10_closed_form():
    """Constant speed w0, the pin carrying m g: P_eq = m g, L10 = (C / m g)^3 1e6
    revolutions, at w0 / 2 pi rev/s."""
    w0, C = 5.0, 5000.0
    report, _, _ = sized(flywheel(f"{w0}*t"))
    life = report.bearings[0]
    assert life.P_eq == pytest.approx(M * G, rel=1e-12)
    assert life.L10_h == pytest.approx((C / (M * G)) ** 3 * 1e6 / (w0 / (2 * math.pi)) / 3600, rel=1e-12)


def test_oscillating_bearing_weights_its_load_by_its_own_rotation():
    """theta = A sin(w t), a push F0 sin(w t) along x at the centre, p = 2:
    the rotation-weighted mean of sin^2 by |cos| is 1/3 (the time mean, 1/2),
    so P_eq^2 = (m g)^2 + F0^2 / 3; the mean relative speed is 2 A w / pi."""
    A, w, F0, C = 0.8, 2 * math.pi, 30.0, 5000.0
    report, _, _ = sized(flywheel("A*sin(w*t)", bearing=f"C = {C}, p = 2", steps=4001,
                                  force=f'["{F0}*sin(w*t)", "0"]'))
    life = report.bearings[0]
    # the kink of |cos| at the turning points costs the trapezoid O(h^2): 1e-6 here
    assert life.P_eq == pytest.approx(math.sqrt((M * G) ** 2 + F0 ** 2 / 3), rel=1e-5)
    speed = 2 * A * w / math.pi
    assert life.L10_h == pytest.approx((C / life.P_eq) ** 2 * 1e6 * 2 * math.pi / speed / 3600, rel=1e-5)


def test_bundled_slider_crank_motor_from_power_balance():
    """The crank torque tau from power balance (dT/dt minus the applied
    loads' power, divided by the crank speed: no multiplier used); at constant
    speed the rotor adds nothing, so the motor gives tau / (n eta) where it
    drives and tau eta / n where the load drives, at n omega."""
    mech = sizing.for_sizing(api.load_mechanism(api.example("slider_crank_sized"), **sizing.ANALYSIS))
    results = api.solve(mech)
    report = sizing.size(mech, results)
    truth = Truth(mech, results)
    omega = 2 * math.pi * 5
    tau = (truth.kinetic_power() - truth.load_power(truth.applied_loads())) / omega
    n, eta = 13.0, 0.9
    motor = np.where(tau >= 0, tau / (n * eta), tau * eta / n)
    v = report.drives[0]
    np.testing.assert_allclose(v.torque, motor, rtol=0, atol=1e-8 * np.abs(motor).max())
    assert v.motor_rms == pytest.approx(math.sqrt(np.trapezoid(motor ** 2, truth.t) / truth.t[-1]), rel=1e-8)
    assert v.speed_peak == pytest.approx(n * omega, rel=1e-12)
    assert report.fits and v.why == ()


@pytest.mark.parametrize("ratio", ["ratio = 10.0", "ratio = [1.0, 100.0]"])
def test_motor_figure_gradients_match_central_differences(ratio):
    """d motor_rms / dA, d motor_peak / dA and d L10_h / dA of the sinusoidal
    flywheel (A moves the acceleration the rotor sees, the load torque and the
    pin's speed), at a fixed ratio and
    at the best of a range (which moves with A: first order nothing), against
    central differences of the figures (h = 1e-5 A: truncation ~1e-10)."""
    from symid.model.mechanism import parameter_symbol
    from symid.model.params import parameter_values
    from symid.output.results import columns
    from symid.study.figures import figure_names
    from symid.study.gradients import figure_gradients, needed_columns
    from symid.study.slow import figures_of, solve_variant, study_analysis, with_values
    from symid.symbolic.assemble import assemble
    from symid.tools.sensitive import solver

    # a back-driving efficiency: the side each instant is on enters the gradient
    mech = study_analysis(loads(flywheel("A*sin(w*t)", f"{ratio}\nefficiency = 0.8\nback_efficiency = 0.7\n" + MOTOR,
                                         steps=201), "flywheel.toml"))
    results = solver("numpy")(mech, ["A"], needed_columns(mech, columns(assemble(mech), mech.analysis)))
    grads = figure_gradients(mech, results, ["A"])
    names = figure_names(mech)
    p = parameter_values(mech.parameters)[parameter_symbol("A")]
    h = 1e-5 * p
    up, down = with_values(mech, ["A"], [p + h]), with_values(mech, ["A"], [p - h])
    central = (figures_of(up, solve_variant(up, "numpy")) - figures_of(down, solve_variant(down, "numpy"))) / (2 * h)
    for figure in ("motor.motor_rms", "motor.motor_peak", "pin.L10_h"):  # the pin's life: through its speed
        k = names.index(figure)
        assert grads[k, 0] == pytest.approx(central[k], rel=1e-6), figure
    assert math.isnan(grads[names.index("motor.fits"), 0])  # a verdict: its margins have gradients instead


@pytest.mark.parametrize("backend", ["numpy", "c"])
def test_sweep_figures_of_drives_and_bearings_are_each_variants_closed_form(backend):
    """A sweep over A of the sinusoidal flywheel (eta = 1, n = 10): per variant
    motor_rms (J_m n + J_L / n) A w^2 / sqrt(2), fits while it stays under the
    continuous 0.2 N m (0.078, 0.156, 0.313), and L10_h of the pin at m g over the mean speed 2 A w / pi."""
    from symid.study.engine import solve_figures

    J_m, n, w, C = 2e-4, 10.0, 2 * math.pi, 5000.0
    motor = "rotor_inertia = 2e-4\ncontinuous_torque = 0.2\npeak_torque = 200.0\nmax_speed = 1e4\n"
    mech = loads(flywheel("A*sin(w*t)", f"ratio = {n}\n" + motor, steps=4001), "flywheel.toml")
    amplitudes = np.array([[0.4], [0.8], [1.6]])
    got = solve_figures(mech, ["A"], amplitudes, backend=backend)
    column = {name: got.values[:, k] for k, name in enumerate(got.names)}
    rms = (J_m * n + J_LOAD / n) * amplitudes[:, 0] * w * w / math.sqrt(2)
    np.testing.assert_allclose(column["motor.motor_rms"], rms, rtol=1e-9)
    np.testing.assert_array_equal(column["motor.fits"], (rms <= 0.2).astype(float))
    assert list(column["motor.fits"]) == [1.0, 1.0, 0.0]
    hours = (C / (M * G)) ** 3 * 1e6 * 2 * math.pi / (2 * amplitudes[:, 0] * w / math.pi) / 3600
    np.testing.assert_allclose(column["pin.L10_h"], hours, rtol=1e-5)  # the kink of |cos|: see above


def test_envelope_from_points_is_their_interpolation_capped_by_the_peak():
    """Points (0, 3), (4, 2), (8, 1) under a peak of 2.5 and max_speed 9: 2.5
    (capped) at 0, 2.25 at 3, 2 at 4, 1.5 at 6, 1 at 8, 0 past the last point."""
    m = motors.Motor("d", (1.0, 1.0), 1.0, 1.0, 0.0, 1.0, 2.5, 9.0, None, ((0.0, 3.0), (4.0, 2.0), (8.0, 1.0)))
    np.testing.assert_allclose(m.available(np.array([0.0, 3.0, -4.0, 6.0, 8.0, 8.5, 10.0])),
                               [2.5, 2.25, 2.0, 1.5, 1.0, 0.0, 0.0])


def test_envelope_points_are_read_from_the_file():
    text = flywheel("A*sin(w*t)", MOTOR + "envelope = [[0.0, 200.0], [5000.0, \"100 + 50\"], [1e4, 0.0]]\n")
    drive = loads(text, "flywheel.toml").sizing.drives[0]
    assert [(float(w), float(T)) for w, T in drive.envelope] == [(0.0, 200.0), (5000.0, 150.0), (1e4, 0.0)]
