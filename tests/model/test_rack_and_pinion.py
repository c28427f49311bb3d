"""The rack and pinion (issue 28.4) against closed forms, and named signals (28.3).

Truth is written out here by hand: the rack's travel is r times the pinion's
turn, the tooth force is the rack's mass times its acceleration along the rack
plus the loads along it, the motor carries the pinion's inertia plus r times
the tooth force. Newton-Euler on each body and the power balance use
tests/helpers/truth.py (the pitch point restated there from the geometry).
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

from symid import api
from symid.cli import main
from symid.io.reader import loads
from symid.model.mechanism import T

from compare import assert_agree
from truth import Truth, newton_euler_residual

BACKENDS = ("reference", "numpy", "casadi", "c")

# Ground pinion (axis at the origin), a rack inclined at BETA on a translational
# guide, tangent below-right of the pitch circle; the load F pushes the rack
# back along -u, gravity has a component along the rack. The pinion's angle is
# a signal built on another signal (a motion law written once).
BETA = 0.4
GROUND_PINION = f"""
[mechanism]
name = "rack_ground"
gravity = [0, -9.81]

[parameters]
R = 0.05
m_rack = 2.5
I_p = 0.004
F = 30.0
a = 6.0
b = 0.8
w = 5.0
beta = {BETA}

[signals]
law = "a*t^2/2 + b*sin(w*t)"
theta = "law - b*w*t"

[[body]]
name = "pinion"
mass = 1.2
inertia = "I_p"
q0 = [0, 0, 0]

[[body]]
name = "rack"
mass = "m_rack"
inertia = 0.2
q0 = ["R*sin(beta)", "-R*cos(beta)", "beta"]

[[constraint]]
name = "axle"
type = "revolute"
i = "ground"
j = "pinion"
si = [0, 0]
sj = [0, 0]

[[constraint]]
name = "guide"
type = "translational"
i = "ground"
j = "rack"
si = ["R*sin(beta)", "-R*cos(beta)"]
vi = ["cos(beta)", "sin(beta)"]
sj = [0, 0]
theta0 = "beta"

[[constraint]]
name = "mesh"
type = "rack_and_pinion"
i = "pinion"
j = "rack"
r = "R"
vj = [2, 0]

[[constraint]]
name = "motor"
type = "relative_angle_driver"
i = "ground"
j = "pinion"
f = "theta"

[[force]]
name = "load"
type = "point_force"
body = "rack"
s = [0.1, 0.02]
F = ["-F*cos(beta)", "-F*sin(beta)"]

[analysis]
t0 = 0
t1 = 1.5
steps = 61
"""


def closed_form_ground(t: np.ndarray) -> dict[str, np.ndarray]:
    """theta(t) and what it fixes, by hand (the parameters of GROUND_PINION)."""
    R, m, I, F, a, b, w, g = 0.05, 2.5, 0.004, 30.0, 6.0, 0.8, 5.0, -9.81
    theta = a * t**2 / 2 + b * np.sin(w * t) - b * w * t
    omega = a * t + b * w * np.cos(w * t) - b * w
    alpha = a - b * w**2 * np.sin(w * t)
    g_u = g * np.sin(BETA)  # gravity's component along the rack
    tooth = m * R * alpha + F - m * g_u  # on the rack, along +u
    return {"theta": theta, "omega": omega, "alpha": alpha, "tooth": tooth,
            "torque": I * alpha + R * tooth, "travel": R * (theta - BETA)}  # the turn relative to the rack


@pytest.fixture(scope="module")
def ground_runs(tmp_path_factory):
    path = tmp_path_factory.mktemp("rack") / "rack_ground.toml"
    path.write_text(GROUND_PINION)
    return path, {b: api.solve(path, backend=b) for b in BACKENDS}


def test_driven_pinion_gives_the_closed_form_motion_torque_and_tooth_force(ground_runs):
    path, runs = ground_runs
    res = runs["reference"]
    cf = closed_form_ground(res.t)
    u = np.array([np.cos(BETA), np.sin(BETA)])
    # the drivers' derivatives of the signal come out right (omega, alpha by hand)
    for col, want in (("pinion.phi", cf["theta"]), ("pinion.omega", cf["omega"]),
                      ("pinion.alpha", cf["alpha"])):
        # the closed forms against a tol 1e-12 solve: rounding relative to each peak (this block)
        np.testing.assert_allclose(res[col], want, rtol=0, atol=1e-12 * np.max(np.abs(want)), err_msg=col)
    # positive turn drives the rack along +vj by r (phi_i - phi_j), from the foot of the axis
    start = 0.05 * np.array([np.sin(BETA), -np.cos(BETA)])
    travel = (np.stack([res["rack.x"], res["rack.y"]], 1) - start) @ u
    np.testing.assert_allclose(travel, cf["travel"], atol=1e-13)
    np.testing.assert_allclose((np.stack([res["rack.ax"], res["rack.ay"]], 1) @ u), 0.05 * cf["alpha"],
                               atol=1e-12 * np.max(np.abs(cf["alpha"])))
    # the motor: m r^2 alpha + F r (+ gravity along the rack) + I_p alpha
    peak = np.max(np.abs(cf["torque"]))
    np.testing.assert_allclose(res["motor.T_j"], cf["torque"], rtol=0, atol=1e-12 * peak)
    # the tooth force at the pitch point: along the rack, +tooth on the rack, - on the pinion, no couple
    peak = np.max(np.abs(cf["tooth"]))
    for role, sign in (("j", 1), ("i", -1)):
        np.testing.assert_allclose(res[f"mesh.Fx_{role}"], sign * cf["tooth"] * u[0], atol=1e-12 * peak)
        np.testing.assert_allclose(res[f"mesh.Fy_{role}"], sign * cf["tooth"] * u[1], atol=1e-12 * peak)
        np.testing.assert_allclose(res[f"mesh.T_{role}"], 0, atol=1e-12 * peak * 0.05)


def test_ground_pinion_power_balance_and_newton_euler(ground_runs):
    path, runs = ground_runs
    res = runs["reference"]
    truth = Truth(loads(path.read_text(), str(path)), res)
    motor = res["motor.T_j"] * res["pinion.omega"]
    applied = truth.load_power(truth.applied_loads())
    kinetic = truth.kinetic_power()
    scale = np.max(np.abs(motor))
    # the drive's power goes into kinetic energy and the work against the load and gravity
    np.testing.assert_allclose(motor + applied, kinetic, atol=1e-11 * scale)
    for body, (force, moment) in newton_euler_residual(truth).items():
        # Newton-Euler of a tol 1e-12 solve: rounding of loads of order 1 N
        assert force < 1e-12 and moment < 1e-12, (body, force, moment)


@pytest.mark.parametrize("backend", BACKENDS[1:])
def test_every_backend_agrees_with_the_reference(ground_runs, backend):
    _, runs = ground_runs
    assert runs[backend].columns == runs["reference"].columns
    assert_agree(runs[backend].data, runs["reference"].data, rel=1e-12)


# The pinion on a moving body: an arm turning about the ground pivot carries
# the pinion at (L, 0) and a rack sliding along it on the line y = -R of its
# frame. phi_i - phi_j is the pinion's turn on the arm: the relative form.
ARM = """
[mechanism]
name = "rack_arm"
gravity = [0, 0]

[parameters]
R = 0.04
L = 0.3
C = 0.05
m_rack = 1.5
I_p = 0.002

[signals]
psi = "0.6*sin(2*t)"
theta = "1.5*t^2 - 0.5*t^3"

[[body]]
name = "arm"
mass = 3
inertia = 0.09
q0 = [0.2, 0, 0]

[[body]]
name = "pinion"
mass = 0.5
inertia = "I_p"
q0 = ["L", 0, 0]

[[body]]
name = "rack"
mass = "m_rack"
inertia = 0.05
q0 = ["L + C", "-R", 0]

[[constraint]]
name = "pivot"
type = "revolute"
i = "ground"
j = "arm"
si = [0, 0]
sj = [-0.2, 0]

[[constraint]]
name = "axle"
type = "revolute"
i = "arm"
j = "pinion"
si = ["L - 0.2", 0]
sj = [0, 0]

[[constraint]]
name = "guide"
type = "translational"
i = "arm"
j = "rack"
si = [0, "-R"]
vi = [1, 0]
sj = [0, 0]

[[constraint]]
name = "mesh"
type = "rack_and_pinion"
i = "pinion"
j = "rack"
r = "R"
vj = [1, 0]
C = "C"

[[constraint]]
name = "swing"
type = "relative_angle_driver"
i = "ground"
j = "arm"
f = "psi"

[[constraint]]
name = "motor"
type = "relative_angle_driver"
i = "arm"
j = "pinion"
f = "theta"

[analysis]
t0 = 0
t1 = 1.2
steps = 49
"""


# slow: every backend on a second rack mechanism; the driven pinion's closed form stays in the quick tier
@pytest.mark.slow
def test_pinion_on_a_moving_arm_couples_the_relative_turn(tmp_path):
    path = tmp_path / "rack_arm.toml"
    path.write_text(ARM)
    runs = {b: api.solve(path, backend=b) for b in BACKENDS}
    res = runs["reference"]
    t = res.t
    R, L, C, m, I = 0.04, 0.3, 0.05, 1.5, 0.002
    psi, dpsi, ddpsi = 0.6 * np.sin(2 * t), 1.2 * np.cos(2 * t), -2.4 * np.sin(2 * t)
    th, dth, ddth = 1.5 * t**2 - 0.5 * t**3, 3 * t - 1.5 * t**2, 3 - 3 * t
    s, ds, dds = L + C + R * th, R * dth, R * ddth  # the rack's centre along the arm
    c, sn = np.cos(psi), np.sin(psi)
    e1, e2 = np.stack([c, sn], 1), np.stack([-sn, c], 1)  # the arm's axes
    # acceleration of the point (s, -R) of the turning frame, by hand
    acc = ((dds - s * dpsi**2 + R * ddpsi)[:, None] * e1
           + (2 * ds * dpsi + s * ddpsi + R * dpsi**2)[:, None] * e2)
    # the closed forms against a tol 1e-12 solve: rounding relative to each peak (this block)
    np.testing.assert_allclose(np.stack([res["rack.ax"], res["rack.ay"]], 1), acc,
                               atol=1e-12 * np.max(np.abs(acc)))
    pos = s[:, None] * e1 - R * e2
    np.testing.assert_allclose(np.stack([res["rack.x"], res["rack.y"]], 1), pos, atol=1e-13)
    tooth = m * np.sum(acc * e1, 1)  # the guide pushes only across the arm
    torque = I * (ddpsi + ddth) + R * tooth
    np.testing.assert_allclose(res["motor.T_j"], torque, atol=1e-12 * np.max(np.abs(torque)))
    np.testing.assert_allclose(np.stack([res["mesh.Fx_j"], res["mesh.Fy_j"]], 1), tooth[:, None] * e1,
                               atol=1e-12 * np.max(np.abs(tooth)))
    truth = Truth(loads(ARM, str(path)), res)
    for body, (force, moment) in newton_euler_residual(truth).items():
        # Newton-Euler of a tol 1e-12 solve: rounding of loads of order 1 N
        assert force < 1e-12 and moment < 1e-12, (body, force, moment)
    drive = res["swing.T_j"] * res["arm.omega"] + res["motor.T_j"] * (res["pinion.omega"] - res["arm.omega"])
    # the power balance sums products of rates and loads: one digit more of rounding than each
    np.testing.assert_allclose(drive, truth.kinetic_power(), atol=1e-11 * np.max(np.abs(drive)))
    for b in BACKENDS[1:]:
        assert_agree(runs[b].data, res.data, rel=1e-12)


# -- signals -------------------------------------------------------------------

def test_a_signal_is_substituted_before_derivation():
    """A driver's f written through two signals is the same expression written out."""
    mech = loads(GROUND_PINION, "rack.toml")
    assert mech.name == "rack_ground"  # not the last signal's name
    f = next(c for c in mech.constraints if c.name == "motor").values["f"]
    a, b, w = (sp.Symbol(n, real=True) for n in "abw")
    assert sp.simplify(f - (a * T**2 / 2 + b * sp.sin(w * T) - b * w * T)) == 0


def _with(old: str, new: str, text: str = GROUND_PINION) -> str:
    assert old in text
    return text.replace(old, new)


BAD_SIGNALS = [
    ("cycle", _with('law = "a*t^2/2 + b*sin(w*t)"', 'law = "theta + t"'),
     r"\[signals\]: signals defined in a cycle: (law -> theta -> law|theta -> law -> theta)"),
    ("self", _with('law = "a*t^2/2 + b*sin(w*t)"', 'law = "2*law"'), r"\[signals\]: .*cycle: law -> law"),
    ("shadows a parameter", _with('law = "a*t^2', 'w = "t"\nlaw = "a*t^2'),
     r"\[signals\] key 'w': shadows the parameter 'w'"),
    ("shadows a body", _with('law = "a*t^2', 'rack = "t"\nlaw = "a*t^2'),
     r"\[signals\] key 'rack': shadows the body 'rack'"),
    ("shadows a function", _with('law = "a*t^2', 'sin = "t"\nlaw = "a*t^2'),
     r"\[signals\] key 'sin': shadows the built-in 'sin'"),
    ("shadows a motion law", _with('law = "a*t^2', 'cycloidal = "t"\nlaw = "a*t^2'),
     r"\[signals\] key 'cycloidal': shadows the built-in 'cycloidal'"),
    ("shadows t", _with('law = "a*t^2', 't = "1"\nlaw = "a*t^2'), r"\[signals\] key 't': shadows the built-in 't'"),
    ("in a constant", _with('mass = 1.2', 'mass = "1 + law"'),
     r"body 'pinion' key 'mass': uses the signal 'law', a function of t"),
    ("in a parameter", _with('F = 30.0', 'F = "theta"'),
     r"\[parameters\] key 'F': uses the signal 'theta', a function of t"),
    ("unknown name", _with('theta = "law - b*w*t"', 'theta = "law - q*t"'),
     r"\[signals\] key 'theta': unknown name 'q'"),
    ("not a table", "signals = 3\n" + _with('[signals]\nlaw = "a*t^2/2 + b*sin(w*t)"\ntheta = "law - b*w*t"\n', '')
     .replace('"theta"', '"t"'),
     r"\[signals\]: must be a table"),
]


@pytest.mark.parametrize("label,text,pattern", BAD_SIGNALS, ids=[b[0] for b in BAD_SIGNALS])
def test_bad_signals_are_one_line_input_errors(tmp_path, capsys, label, text, pattern):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    status = main(["solve", str(path), "-o", str(tmp_path / "out.csv")])
    err = capsys.readouterr().err
    assert status == 2, err
    assert len(err.strip().splitlines()) == 1, err
    assert err.startswith(f"symid: {path}: "), err
    import re
    assert re.search(pattern, err), err


BAD_RACK = [
    ("zero radius", _with('r = "R"', 'r = "R - 0.05"'), r"constraint 'mesh' key 'r': must be positive, not 0"),
    ("negative radius", _with('r = "R"', 'r = -0.01'), r"constraint 'mesh' key 'r': must be positive, not -0.01"),
    ("zero direction", _with('vj = [2, 0]', 'vj = ["R - 0.05", 0]'),
     r"constraint 'mesh' key 'vj': is the zero vector"),
    ("no radius", _with('r = "R"\n', ''), r"constraint 'mesh': missing key 'r'"),
]


@pytest.mark.parametrize("label,text,pattern", BAD_RACK, ids=[b[0] for b in BAD_RACK])
def test_bad_rack_and_pinion_keys_are_one_line_input_errors(tmp_path, capsys, label, text, pattern):
    test_bad_signals_are_one_line_input_errors(tmp_path, capsys, label, text, pattern)
