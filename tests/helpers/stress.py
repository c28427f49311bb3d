"""Near-singular mechanisms and their motor torque to 40 digits (mpmath).

Two families, each one mechanism file whose nearness to the singularity is a
parameter (so one generated solver serves every case):

- `slider_crank`: crank r = 1, rod l = r (1 + eps). At a crank angle of 90
  degrees the rod is nearly square to the guide: cond grows like eps^-1/2,
  the motor torque like eps^-3/2. Its crank's centre of mass is e from the
  bearing (its middle, r/2, here; tests/numeric/test_stability.py moves it onto the
  bearing), and its q0 is the closed-form position at t = 0.
- `four_bar_toggle`: crank 1, coupler 1.5, rocker 1, ground 2. The crank
  angle th is `toggle - delta`: at delta = 0 the coupler and the rocker are
  collinear (extended), the crank's limit position.

Each is solved at one instant, t = 0, with the crank angle th + omega t, so
the reference sees exactly the double the solver sees. The reference is the
closed-form position written here again (not symid's constraints), its time
derivatives by sympy, and the torque by the power method

    tau omega = dT/dt - sum m g . v

evaluated with mpmath at 40 significant digits from the exact binary values
of the parameters the solver used.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cache
from typing import Callable, Mapping

import mpmath
import numpy as np
import sympy as sp

DIGITS = 40
G = 9.81

SLIDER_CRANK = """
[mechanism]
name = "stress_slider_crank"
gravity = [0.0, -9.81]

[parameters]
r = 1.0
eps = 0.1
l = "r*(1 + eps)"
e = 0.5
th = 1.5707963267948966
omega = 10.0
m1 = 1.0
m2 = 2.0
m3 = 0.5

[analysis]
steps = 1
outputs = ["q", "qdot", "qddot", "lambda", "reactions", "cond"]

[[body]]
name = "crank"
mass = "m1"
inertia = "m1*r^2/12"
q0 = ["e*cos(th)", "e*sin(th)", "th"]

[[body]]
name = "rod"
mass = "m2"
inertia = "m2*l^2/12"
q0 = ["r*cos(th) + sqrt(l^2 - (r*sin(th))^2)/2", "r*sin(th)/2", "-asin(r*sin(th)/l)"]

[[body]]
name = "slider"
mass = "m3"
inertia = "m3/12"
q0 = ["r*cos(th) + sqrt(l^2 - (r*sin(th))^2)", 0.0, 0.0]

[[constraint]]
name = "bearing"
type = "revolute"
i = "ground"
j = "crank"
si = [0.0, 0.0]
sj = ["-e", 0.0]

[[constraint]]
name = "crank_pin"
type = "revolute"
i = "crank"
j = "rod"
si = ["r - e", 0.0]
sj = ["-l/2", 0.0]

[[constraint]]
name = "wrist_pin"
type = "revolute"
i = "rod"
j = "slider"
si = ["l/2", 0.0]
sj = [0.0, 0.0]

[[constraint]]
name = "guide"
type = "translational"
i = "ground"
j = "slider"
si = [0.0, 0.0]
vi = [1.0, 0.0]
sj = [0.0, 0.0]

[[constraint]]
name = "motor"
type = "relative_angle_driver"
i = "ground"
j = "crank"
f = "th + omega*t"
"""

FOUR_BAR = """
[mechanism]
name = "stress_four_bar"
gravity = [0.0, -9.81]

[parameters]
a = 1.0
b = 1.5
c = 1.0
d = 2.0
th = 1.0
omega = 10.0
m1 = 1.0
m2 = 1.5
m3 = 1.0

[analysis]
steps = 1
outputs = ["q", "qdot", "qddot", "lambda", "reactions", "cond"]

[[body]]
name = "crank"
mass = "m1"
inertia = "m1*a^2/12"
q0 = [0.0, 0.5, 1.0]

[[body]]
name = "coupler"
mass = "m2"
inertia = "m2*b^2/12"
q0 = [1.0, 1.0, 0.0]

[[body]]
name = "rocker"
mass = "m3"
inertia = "m3*c^2/12"
q0 = [2.0, 0.5, 1.5]

[[constraint]]
name = "crank_pivot"
type = "revolute"
i = "ground"
j = "crank"
si = [0.0, 0.0]
sj = ["-a/2", 0.0]

[[constraint]]
name = "crank_pin"
type = "revolute"
i = "crank"
j = "coupler"
si = ["a/2", 0.0]
sj = ["-b/2", 0.0]

[[constraint]]
name = "rocker_pin"
type = "revolute"
i = "coupler"
j = "rocker"
si = ["b/2", 0.0]
sj = ["c/2", 0.0]

[[constraint]]
name = "rocker_pivot"
type = "revolute"
i = "ground"
j = "rocker"
si = ["d", 0.0]
sj = ["-c/2", 0.0]

[[constraint]]
name = "motor"
type = "relative_angle_driver"
i = "ground"
j = "crank"
f = "th + omega*t"
"""

TOGGLE = math.acos((1.0 + 4.0 - 2.5**2) / (2 * 1.0 * 2.0))  # crank angle where coupler and rocker align


@dataclass(frozen=True)
class Family:
    """One stress family: its file, what varies, and its closed form.

    Attributes:
        text: the mechanism file.
        values: k -> the parameter overrides (--set) of case k.
        positions: symbolic closed form, (theta, parameters) -> [(mass, centre, angle, J)].
    """

    name: str
    text: str
    values: Callable[[int], dict[str, float]]
    distance: Callable[[int], float]
    positions: Callable[[sp.Expr, Mapping[str, sp.Symbol]], list[tuple[sp.Expr, sp.Matrix, sp.Expr, sp.Expr]]]


def _slider_crank(theta: sp.Expr, p: Mapping[str, sp.Symbol]) -> list:
    r, l = p["r"], p["l"]  # the double the solver computed from r (1 + eps)
    pin = sp.Matrix([r * sp.cos(theta), r * sp.sin(theta)])
    slider = sp.Matrix([r * sp.cos(theta) + sp.sqrt(l**2 - (r * sp.sin(theta)) ** 2), 0])
    psi = sp.atan2(slider[1] - pin[1], slider[0] - pin[0])
    return [(p["m1"], pin * p["e"] / r, theta, p["m1"] * r**2 / 12),
            (p["m2"], (pin + slider) / 2, psi, p["m2"] * l**2 / 12),
            (p["m3"], slider, sp.Integer(0), p["m3"] / 12)]


def _four_bar(theta: sp.Expr, p: Mapping[str, sp.Symbol]) -> list:
    a, b, c, d = p["a"], p["b"], p["c"], p["d"]
    pin = sp.Matrix([a * sp.cos(theta), a * sp.sin(theta)])
    dx, dy = d - pin[0], -pin[1]
    e2 = dx**2 + dy**2
    alpha = sp.acos((b**2 + e2 - c**2) / (2 * b * sp.sqrt(e2)))
    phi3 = sp.atan2(dy, dx) + alpha  # open assembly: coupler above the diagonal
    tip = pin + b * sp.Matrix([sp.cos(phi3), sp.sin(phi3)])
    phi4 = sp.atan2(tip[1], tip[0] - d)
    return [(p["m1"], pin / 2, theta, p["m1"] * a**2 / 12),
            (p["m2"], (pin + tip) / 2, phi3, p["m2"] * b**2 / 12),
            (p["m3"], (tip + sp.Matrix([d, 0])) / 2, phi4, p["m3"] * c**2 / 12)]


SLIDER = Family("slider_crank", SLIDER_CRANK,
                lambda k: {"eps": 10.0**-k, "th": math.pi / 2},
                lambda k: 10.0**-k, _slider_crank)
TOGGLE_FAMILY = Family("four_bar_toggle", FOUR_BAR,
                       lambda k: {"th": TOGGLE - 10.0**-k},
                       lambda k: 10.0**-k, _four_bar)
FAMILIES = {f.name: f for f in (SLIDER, TOGGLE_FAMILY)}
NAMES = {"slider_crank": ("r", "l", "e", "th", "omega", "m1", "m2", "m3"),
         "four_bar_toggle": ("a", "b", "c", "d", "th", "omega", "m1", "m2", "m3")}


@cache
def _closed_form(name: str) -> tuple[tuple[sp.Symbol, ...], Callable, Callable]:
    """(parameter symbols, torque(params) in mpmath, q(params) in floats)."""
    family = FAMILIES[name]
    t = sp.Symbol("t", real=True)
    syms = {n: sp.Symbol(n, real=True) for n in NAMES[name]}
    theta = syms["th"] + syms["omega"] * t
    parts = family.positions(theta, syms)
    kinetic = sum(m * (c.diff(t).T * c.diff(t))[0] / 2 + j * ang.diff(t) ** 2 / 2 for m, c, ang, j in parts)
    gravity_power = sum(-m * G * c[1].diff(t) for m, c, _, _ in parts)
    tau = ((kinetic.diff(t) - gravity_power) / syms["omega"]).subs(t, 0)
    args = tuple(syms.values())
    # cse: the four-bar's torque has ~9600 operations, mostly repeats of a few
    # subtrees; evaluated once per subtree it is ~100x faster at 60 digits
    # (the same arithmetic otherwise: the values agree to 1e-60)
    torque = sp.lambdify(args, tau, "mpmath", cse=True)
    coords = [e.subs(t, 0) for _, c, ang, _ in parts for e in (c[0], c[1], ang)]
    q = sp.lambdify(args, coords, "math", cse=True)
    return args, torque, q


def reference(name: str, values: Mapping[str, float]) -> float:
    """The motor torque (the driver's T_j) to DIGITS digits, rounded to a double.

    Args:
        values: every parameter of NAMES[name], as the doubles the solver used.
    """
    args, torque, _ = _closed_form(name)
    with mpmath.workdps(DIGITS):
        return float(torque(*[mpmath.mpf(values[s.name]) for s in args]))


def assembled(name: str, values: Mapping[str, float]) -> np.ndarray:
    """q at t = 0 from the closed form in doubles: the solver's initial guess."""
    args, _, q = _closed_form(name)
    return np.array(q(*[values[s.name] for s in args]), dtype=float)


def kappa(name: str, values: Mapping[str, float]) -> float:
    """The torque's relative condition number: sum over the angle and the
    lengths p of |p dtau/dp| / |tau| (what one rounding of each input costs,
    in units of eps), by 60-digit central differences."""
    args, torque, _ = _closed_form(name)
    inputs = [s.name for s in args if s.name in ("th", "r", "l", "a", "b", "c", "d")]
    with mpmath.workdps(60):
        point = {s.name: mpmath.mpf(values[s.name]) for s in args}
        tau = torque(*point.values())
        total = mpmath.mpf(0)
        for name_p in inputs:
            def f(x: mpmath.mpf, name_p: str = name_p) -> mpmath.mpf:
                return torque(*[x if n == name_p else v for n, v in point.items()])
            x = point[name_p]
            total += abs(x * mpmath.diff(f, x, h=mpmath.mpf(10) ** -24 * max(1, abs(x)))) / abs(tau)
        return float(total)


@dataclass(frozen=True)
class Case:
    """One stress instant: the solver's motor torque against the reference.

    Attributes:
        cond: the instant's cond (NaN on a backend without it).
        error: |tau - reference| / |reference|.
        kappa: the torque's relative condition number (see `kappa`).
    """

    name: str
    k: int
    distance: float
    backend: str
    cond: float
    torque: float
    reference: float
    error: float
    kappa: float


def solve_case(name: str, k: int, path: object, backend: str) -> Case:
    """Solve case k of a family at t = 0 from the closed-form guess."""
    from symid import api, backends
    from symid.numeric.solve import run
    from symid.numeric.stability import requested

    family = FAMILIES[name]
    overrides = {n: repr(v) for n, v in family.values(k).items()}
    if "cond" in backends.capabilities(backend).lacks:  # the compiled loop
        study = api.prepare(path, backend, overrides, outputs=["q", "lambda", "reactions"])
    else:
        study = api.prepare(path, backend, overrides)
    values = {s.name: float(v) for s, v in study.values.items()}
    q0 = assembled(name, values)
    columns = study.columns()
    own = getattr(study.evaluator, "rows", None)
    row = next(iter(own(study.analysis, q0))) if own is not None else None
    if row is None:
        from symid.output.results import row as make_row

        row = make_row(next(run(study.evaluator, study.analysis, q0)), study.layout, study.analysis)
    assert not requested(study.analysis) or "cond" in columns
    cond = float(row[columns.index("cond")]) if "cond" in columns else float("nan")
    tau = float(row[columns.index("motor.T_j")])
    ref = reference(name, values)
    return Case(name, k, family.distance(k), backend, cond, tau, ref, abs(tau - ref) / abs(ref),
                kappa(name, values))
