"""The user's own elements (issue 28.1, 28.2): constraints written as expressions.

Truth is independent of the new family: the built-in four-bar (whose families
are checked against the reference's hand blocks in test_derivations) written
again row by row as expressions must give the same table on every backend.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from symid import api
from symid.cli import main


from compare import assert_agree

BACKENDS = ("reference", "numpy", "casadi", "c")


def _point(role: str, s: tuple[str, str]) -> tuple[str, str]:
    """Global x, y of the body point s (body coordinates), written as the reference's r + A s."""
    x, y = s
    return (f"x_{role} + cos(phi_{role})*({x}) - sin(phi_{role})*({y})",
            f"y_{role} + sin(phi_{role})*({x}) + cos(phi_{role})*({y})")


def as_expressions(text: str) -> str:
    """A mechanism file with every revolute and relative angle driver written as
    `type = "expression"` rows: the reference's Phi, the same signs and order."""
    def revolute(m: re.Match) -> str:
        block = m.group(0)
        get = lambda k: re.search(rf"^{k} = (.*)$", block, re.M).group(1)  # noqa: E731
        pair = lambda k: tuple(str(v) for v in eval(get(k)))  # noqa: E731,S307 (the test's own file)
        xi, yi = _point("i", pair("si"))
        xj, yj = _point("j", pair("sj"))
        return (f'[[constraint]]\nname = {get("name")}\ntype = "expression"\ni = {get("i")}\nj = {get("j")}\n'
                f'phi = ["{xj} - ({xi})", "{yj} - ({yi})"]\nsi = {get("si")}\nsj = {get("sj")}\n')

    def driver(m: re.Match) -> str:
        name, i, j, f, c = m.groups()
        return (f'[[constraint]]\nname = {name}\ntype = "expression"\ni = {i}\nj = {j}\n'
                f'phi = ["phi_j - phi_i - ({c or 0}) - ({f})"]\n')

    out = re.sub(r'\[\[constraint\]\]\nname = "\w+"\ntype = "revolute"\n(?:.*\n)*?sj = .*\n', revolute, text)
    out = re.sub(r'\[\[constraint\]\]\nname = ("\w+")\ntype = "relative_angle_driver"\ni = (".*")\nj = (".*")\n'
                 r'f = "(.*)"\n(?:C = (.*)\n)?', driver, out)
    assert "revolute" not in out and "relative_angle_driver" not in out
    return out


@pytest.fixture(scope="module")
def four_bars(tmp_path_factory):
    folder = tmp_path_factory.mktemp("four_bar")
    builtin = api.example("four_bar")
    rewritten = folder / "four_bar.toml"
    rewritten.write_text(as_expressions(builtin.read_text()))
    return ({b: api.solve(builtin, backend=b) for b in BACKENDS},
            {b: api.solve(rewritten, backend=b) for b in BACKENDS})


# slow: the four-bar of expressions solved on every backend (seconds); the cart's closed forms keep expression
# rows on every backend in the quick tier
@pytest.mark.slow
@pytest.mark.parametrize("backend", BACKENDS)
def test_four_bar_of_expressions_equals_the_built_in_four_bar(four_bars, backend):
    builtin, rewritten = four_bars
    assert rewritten[backend].columns == builtin[backend].columns
    # every column to 1e-12 of its peak; a column that is zero by the built-in's
    # algebra (a revolute's torque) against the table's scale (compare.assert_agree):
    # the expression's (B s)^T Phi_r^T lambda - Phi_phi^T lambda cancels to rounding only
    assert_agree(rewritten[backend].data, builtin[backend].data, rel=1e-12)


# A slider on ground: y and phi held by one expression constraint of two rows,
# x driven by another. Each bad case changes one line of it.
SLIDER = """
[mechanism]
name = "slider"

[parameters]
h = 0.2

[signals]
stroke = "0.1*sin(2*t)"

[[body]]
name = "block"
mass = 1.0
inertia = 0.01
q0 = [0.0, 0.2, 0.0]

[[constraint]]
name = "guide"
type = "expression"
i = "block"
phi = ["y_i - h", "phi_i"]

[[constraint]]
name = "drive"
type = "expression"
i = "block"
phi = ["x_i - stroke"]
"""

BAD = [
    ("unknown symbol", ('"y_i - h"', '"y_i - hh"'), r"constraint 'guide' key 'phi' row 1: unknown name 'hh'"),
    ("coordinate of an absent j", ('"phi_i"]', '"phi_i - phi_j"]'), r"key 'phi' row 2: unknown name 'phi_j'"),
    ("unknown body", ('i = "block"\nphi = ["y_i', 'i = "blok"\nphi = ["y_i'),
     r"constraint 'guide' key 'i': unknown body 'blok'"),
    ("no coordinate", ('"phi_i"]', '"h - 0.2"]'), r"key 'phi' row 2: depends on no coordinate \(x_i, y_i, phi_i\)"),
    ("empty", ('["y_i - h", "phi_i"]', '[]'), r"constraint 'guide' key 'phi': must be a list of expressions, one per "
     r"constraint row, not an empty list"),
    ("dependent at q0", ('"phi_i"]', '"2*y_i - 2*h + phi_i^2"]'),
     r"constraint 'guide' key 'phi': row 2 depends on row 1 at q0"),
    ("state function in a row", ('"phi_i"]', '"phi_i - omega(block)"]'),
     r"key 'phi' row 2: omega\(\) at column 9 is a state function, allowed in forces only"),
    ("state function in a signal", ('"0.1*sin(2*t)"', '"0.1*sin(2*t) + vx(block)"'),
     r"\[signals\] key 'stroke': vx\(\) at column 16 is a state function, allowed in forces only"),
    ("abs in a row", ('"y_i - h"', '"abs(y_i) - h"'),
     r"key 'phi' row 1: abs\(\) at column 1 is not differentiable at 0"),
    ("sign in a row", ('"phi_i"]', '"phi_i*sign(x_i)"]'),
     r"key 'phi' row 2: sign\(\) at column 7 is not differentiable at 0"),
    ("a driver not g(q) - f(t)", ('"x_i - stroke"', '"x_i*(1 + t) - stroke"'),
     r"constraint 'drive' key 'phi' row 1: the term .* mixes t and the coordinates"),
    ("a driver among other rows", ('"phi_i"]', '"phi_i - 0.1*t"]'),
     r"constraint 'guide' key 'phi': a row with t is a driver: give each driver row a constraint of its own"),
]


@pytest.mark.parametrize("label,change,pattern", BAD, ids=[b[0] for b in BAD])
def test_bad_expression_input_is_one_line_exit_2_naming_file_and_key(tmp_path, capsys, label, change, pattern):
    old, new = change
    assert SLIDER.count(old) == 1, old
    path = tmp_path / "bad.toml"
    path.write_text(SLIDER.replace(old, new))
    status = main(["check", str(path)])
    err = capsys.readouterr().err
    assert status == 2, err
    assert len(err.strip().splitlines()) == 1, err
    assert err.startswith(f"symid: {path}: "), err
    assert re.search(pattern, err), err


def test_the_slider_itself_is_good(tmp_path, capsys):
    path = tmp_path / "slider.toml"
    path.write_text(SLIDER)
    assert main(["check", str(path)]) == 0, capsys.readouterr().err


# A cart on a rail (its own expression rows) pushed along x by a driver row,
# against a quadratic drag that reads its speed, F = -c vx |vx|, and a Coulomb
# friction -mu sign(vx) (vx stays above 0.2 m/s: sign = 1, its derivative 0).
CART = """
[mechanism]
name = "cart_drag"

[parameters]
m = 2.0
c = 0.7
mu = 1.5
a = 3.0
b = 0.5
w = 4.0

[[body]]
name = "cart"
mass = "m"
inertia = 0.1
q0 = [0, 0, 0]

[[constraint]]
name = "rail"
type = "expression"
i = "cart"
phi = ["y_i", "phi_i"]

[[constraint]]
name = "push"
type = "expression"
i = "cart"
phi = ["x_i - (a*t^2/2 + b*sin(w*t))"]

[[force]]
name = "drag"
type = "point_force"
body = "cart"
s = [0, 0]
F = ["-c*vx(cart)*abs(vx(cart)) - mu*sign(vx(cart))", "0"]

[analysis]
t1 = 2
steps = 41
"""
CART_VALUES = {"m": 2.0, "c": 0.7, "mu": 1.5, "a": 3.0, "b": 0.5, "w": 4.0}


def cart_closed_form(t: np.ndarray) -> dict[str, np.ndarray]:
    """x(t) = a t^2/2 + b sin(w t); the push = m xdd + c v |v| + mu sign(v) (Newton along the rail)."""
    m, c, mu, a, b, w = (CART_VALUES[k] for k in ("m", "c", "mu", "a", "b", "w"))
    v = a * t + b * w * np.cos(w * t)
    acc = a - b * w**2 * np.sin(w * t)
    assert np.all(v > 0.2)
    return {"v": v, "a": acc, "push": m * acc + c * v * np.abs(v) + mu * np.sign(v),
            # d(push)/d(a) = m + 2 c |v| t, d(push)/d(c) = v |v|
            "d_a": m + 2 * c * np.abs(v) * t, "d_c": v * np.abs(v), "d_mu": np.sign(v)}


@pytest.fixture(scope="module")
def cart_runs(tmp_path_factory):
    path = tmp_path_factory.mktemp("cart") / "cart.toml"
    path.write_text(CART)
    return path, {b: api.solve(path, backend=b, sensitivity=["a", "c", "mu"]) for b in BACKENDS}


@pytest.mark.parametrize("backend", BACKENDS)
def test_cart_with_quadratic_drag_needs_m_a_plus_c_v_abs_v(cart_runs, backend):
    _, runs = cart_runs
    res = runs[backend]
    cf = cart_closed_form(res.t)
    np.testing.assert_allclose(res["cart.vx"], cf["v"], rtol=0, atol=1e-12 * np.max(np.abs(cf["v"])))
    peak = np.max(np.abs(cf["push"]))
    # the driver's effort is -lambda (Phi = x - f(t): the force along +x)
    np.testing.assert_allclose(-res["push.lambda"], cf["push"], rtol=0, atol=1e-12 * peak)
    # the summary reads the driver row's effort and power like a built-in driver's
    from symid.output.summary import efforts

    (effort,) = efforts(api.load_mechanism(cart_runs[0]), res)
    np.testing.assert_allclose(effort.value, cf["push"], rtol=0, atol=1e-12 * peak)
    np.testing.assert_allclose(effort.power, cf["push"] * cf["v"], rtol=0, atol=1e-12 * peak * np.max(cf["v"]))
    # the state force's own sensitivities, by hand: d(lambda)/dp = -d(push)/dp
    for name in ("a", "c", "mu"):
        want = -cf[f"d_{name}"]
        np.testing.assert_allclose(res[f"d(push.lambda)/d({name})"], want, rtol=0,
                                   atol=1e-12 * np.max(np.abs(want)), err_msg=name)


def test_cart_power_balance_counts_the_drag(cart_runs):
    from symid.io.reader import loads
    from truth import Truth

    path, runs = cart_runs
    res = runs["reference"]
    truth = Truth(loads(path.read_text(), str(path)), res)
    drive = res["push.lambda"] * truth.driver_phi_t("push")  # lambda Phi_t: the driver's power
    drag = truth.load_power(truth.applied_loads())  # -c |v|^3 - mu |v| from the file's expression and the speeds
    assert np.max(np.abs(drag)) > 0.1 * np.max(np.abs(drive))  # the drag is a real share of the power
    np.testing.assert_allclose(drive + drag, truth.kinetic_power(), rtol=0, atol=1e-11 * np.max(np.abs(drive)))


@pytest.fixture(scope="module")
def cam_runs():
    path = api.example("disc_cam")
    return path, {b: api.solve(path, backend=b) for b in BACKENDS}


# slow: the disc cam solved on every backend (seconds); the cart and the torque reading other bodies keep
# expression elements' power balance and Newton-Euler in the quick tier
@pytest.mark.slow
def test_cam_power_balance_and_newton_euler_on_every_body(cam_runs):
    from symid.io.reader import loads
    from truth import Truth, newton_euler_residual

    path, runs = cam_runs
    res = runs["reference"]
    truth = Truth(loads(path.read_text(), str(path)), res)
    motor = res["motor.T_j"] * res["cam.omega"]  # the driver's torque on the cam times its speed
    applied = truth.load_power(truth.applied_loads())  # the spring and gravity, by the reference's formulas
    np.testing.assert_allclose(motor + applied, truth.kinetic_power(), rtol=0, atol=1e-11 * np.max(np.abs(motor)))
    # each body's F = m a and M = J alpha from the reactions of every constraint at their points
    # (the contact's at si = sj = the centres, by the file's default)
    for body, (force, moment) in newton_euler_residual(truth).items():
        assert force < 1e-12 and moment < 1e-12, (body, force, moment)
    # the follower rides the pitch curve: y = R0 + h/2 (1 - cos(pi/2 - phi)), by hand
    R0, h = 0.05, 0.02
    np.testing.assert_allclose(res["follower.y"], R0 + h / 2 * (1 - np.cos(np.pi / 2 - res["cam.phi"])), atol=1e-14)
    # the contact pushes (the spring keeps it closed), along the pitch curve's normal: tilted from the
    # line of centres by the pressure angle, tan = rho'(psi) / rho(psi) (the guide takes the side load)
    assert np.all(res["contact.Fy_j"] > 0)
    psi = np.pi / 2 - res["cam.phi"]
    tilt = (h / 2 * np.sin(psi)) / (R0 + h / 2 * (1 - np.cos(psi)))
    assert np.max(np.abs(tilt)) > 0.1  # a real pressure angle (up to 11 degrees)
    np.testing.assert_allclose(res["contact.Fx_j"], tilt * res["contact.Fy_j"], rtol=0,
                               atol=1e-12 * np.max(res["contact.Fy_j"]))


# slow: the disc cam solved on every backend (its fixture, seconds); the cart keeps expression rows on every
# backend in the quick tier
@pytest.mark.slow
@pytest.mark.parametrize("backend", BACKENDS[1:])
def test_cam_every_backend_agrees_with_the_reference(cam_runs, backend):
    _, runs = cam_runs
    assert runs[backend].columns == runs["reference"].columns
    assert_agree(runs[backend].data, runs["reference"].data, rel=1e-12)


# the quick tier keeps the cart (an expression constraint, an expression force with
# abs and sign: about a second); the disc cam's 8 parameters, derived for the reference and
# generated as C with every parameter's columns, are the slow tier's
@pytest.mark.parametrize("example,backend", [
    pytest.param("disc_cam", "reference", marks=pytest.mark.slow),
    pytest.param("disc_cam", "c", marks=pytest.mark.slow),
    ("cart", "reference")])
def test_expression_sensitivities_match_40_digit_central_differences(tmp_path, tmp_path_factory, example, backend):
    """Central differences (step 1e-12 of each parameter) of a 40-digit solve of
    the instant (tests/helpers/high_precision.py: the whole system lambdified with
    mpmath, no symbolic parameter derivative), exact to ~1e-20; held to 1e-9
    of each column's scale as the other sensitivity tests are."""
    import mpmath
    from high_precision import DIGITS, Instant
    from sensitivity_runs import solved

    from symid.model.params import parameter_values

    if example == "cart":
        path = tmp_path / "cart.toml"
        path.write_text(CART)
    else:
        path = api.example(example)
    mech = api.load_mechanism(path)
    hp = Instant(mech)
    if example == "cart":
        results = api.solve(path, backend, steps=5, sensitivity=hp.names)
    else:  # the run tests/numeric/test_sensitivity.py checks too (4 steps), solved once
        results = solved(tmp_path_factory, example, backend, hp.names, 4)
    header = results.columns
    chosen = sorted({c[2:c.index(")/d(")] for c in header if c.startswith("d(")}, key=header.index)
    assert chosen, header
    q_cols = [f"{b.name}.{c}" for b in mech.bodies for c in ("x", "y", "phi")]
    k = 2
    t = results.t[k]
    guess = results.data[k, [header.index(c) for c in q_cols]]
    values = parameter_values(mech.parameters)
    p0 = [mpmath.mpf(values[sp_symbol(n)]) for n in hp.names]
    worst = (0.0, "")
    with mpmath.workdps(DIGITS):
        for j, name in enumerate(hp.names):
            h = mpmath.mpf("1e-12") * max(abs(p0[j]), mpmath.mpf("1e-2"))
            plus, minus = list(p0), list(p0)
            plus[j] += h
            minus[j] -= h
            a, b = hp.solve(t, plus, guess), hp.solve(t, minus, guess)
            for column in chosen:
                what, r = _locate(mech, column)
                exact = float((a[what][r] - b[what][r]) / (2 * h))
                ours = results[f"d({column})/d({name})"][k]
                scale = max(1.0, float(np.max(np.abs(results[f"d({column})/d({name})"]))))
                worst = max(worst, (abs(ours - exact) / scale, f"d({column})/d({name})"))
    assert worst[0] < 1e-9, worst


def sp_symbol(name: str):  # noqa: ANN201
    from symid.model.mechanism import parameter_symbol

    return parameter_symbol(name)


def _locate(mech, column: str) -> tuple[str, int]:  # noqa: ANN001
    """Which of the 40-digit instant's vectors holds `column`, and where."""
    name, _, what = column.partition(".")
    rows = 0
    for c in mech.constraints:
        n = len(c.values["phi"]) if c.type == "expression" else None
        if c.name == name and what.startswith("lambda"):
            return "lam", rows + (int(what[6:]) - 1 if what[6:] else 0)
        rows += n if n is not None else _rows(c.type)
    start = 0
    for c in mech.constraints:
        if c.name == name:
            role_comp = what.split("_")
            comps = ["Fx", "Fy", "T"]
            roles = list(c.bodies)
            return "reactions", start + 3 * roles.index(role_comp[1]) + comps.index(role_comp[0])
        start += 3 * len(c.bodies)
    raise AssertionError(column)


def _rows(kind: str) -> int:
    from symid.symbolic.constraints import TYPES

    return TYPES[kind].rows


# The cam's contact row differentiated by hand: with d = r_f - r_c, nn = |d|,
# psi = atan2(d_y, d_x) - phi_c, sn = sin(psi), rho(psi) = R0 + h/2 (1 - cos psi):
#   dPhi/dr_f = d/nn - rho'(psi) grad(atan2) = d/nn - h/2 sn (-d_y, d_x)/nn^2,  dPhi/dphi_c = rho'(psi)
CAM_CLAIM = """
[claim]
mechanism = "disc_cam"
title = "the cam's contact row, by hand"

[define]
d = ["x_follower - x_cam", "y_follower - y_cam"]
nn = "sqrt(d_x^2 + d_y^2)"
sn = "sin(atan2(d_y, d_x) - phi_cam)"

[[entry]]
quantity = "Phi_q"
constraint = "contact"
body = "follower"
value = [["d_x/nn + h/2*sn*d_y/nn^2", "d_y/nn - h/2*sn*d_x/nn^2", 0]]

[[entry]]
quantity = "Phi_q"
constraint = "contact"
body = "cam"
value = [["-d_x/nn - h/2*sn*d_y/nn^2", "-d_y/nn + h/2*sn*d_x/nn^2", "h/2*sn"]]
"""


def test_verify_checks_a_hand_derivation_of_an_expression_constraint(tmp_path, capsys):
    claims = tmp_path / "cam_claims.toml"
    claims.write_text(CAM_CLAIM)
    assert main(["verify", str(claims)]) == 0, capsys.readouterr().out
    # a sign slip in the hand result is caught
    claims.write_text(CAM_CLAIM.replace('"h/2*sn"]]', '"-h/2*sn"]]'))
    assert main(["verify", str(claims)]) == 1
    assert "NOT EQUAL" in capsys.readouterr().out


# slow: derives the disc cam in LaTeX; tests/symbolic/test_show.py keeps derive's printing in the quick tier
@pytest.mark.slow
def test_derive_shows_an_expression_constraint_of_a_file_and_refuses_the_bare_type(capsys):
    assert main(["derive", str(api.example("disc_cam")), "--latex"]) == 0
    out = capsys.readouterr().out
    assert "contact" in out and r"atan}_{2}" in out, out[:2000]  # the row as LaTeX
    assert main(["derive", "expression"]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "derive the file" in err, err


@pytest.mark.slow  # two solvers compiled and run under callgrind
@pytest.mark.skipif(not __import__("shutil").which("valgrind") or not __import__("shutil").which("gcc"),
                    reason="valgrind and gcc are needed to count instructions")
def test_four_bar_of_expressions_costs_within_1_2x_the_built_in_instant_in_c(tmp_path):
    """Instructions per instant (callgrind: independent of the machine's load) of the
    compiled trajectory, the four-bar as expressions against the built-in (#28, Speed)."""
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
    from benchmarks import callgrind as instructions

    rewritten = tmp_path / "four_bar.toml"
    rewritten.write_text(as_expressions(api.example("four_bar").read_text()))
    counts = {}
    for label, path in (("built-in", api.example("four_bar")), ("expressions", rewritten)):
        study = api.prepare(path, backend="c")
        counts[label] = instructions.counted(Path(study.evaluator.artifact), study.mechanism.name, study.analysis,
                                             study.q0(), 100, 600)
    assert counts["expressions"] <= 1.2 * counts["built-in"], counts


def test_help_elements_shows_the_page_with_every_symbol_and_state_function(capsys):
    from symid.io.state import FUNCTIONS
    from symid.symbolic import symbols as s
    from symid.tools import manual

    assert main(["help", "elements"]) == 0
    out = capsys.readouterr().out
    assert out.strip() == manual.page("elements").strip()
    for role in ("i", "j"):
        assert " ".join(f"{c}_{role}" for c in s.COORDS) in out
    for name in FUNCTIONS:
        assert f"{name}(B)" in out, name


@pytest.mark.parametrize("backend", ["c", "numpy"])
def test_sweep_of_the_cart_gives_each_variants_closed_form_effort(tmp_path, backend):
    """A grid over the drag coefficient: each variant's peak effort of the driver row
    is the closed form's largest m a + c v|v| + mu sign(v) at the output instants."""
    from symid.study.design import grid

    path = tmp_path / "cart.toml"
    path.write_text(CART)
    table = api.sweep(path, grid(["c=0.2:1.2:3"]), backend=backend, workers=1)
    t = np.linspace(0, 2, 41)
    for c, peak, status in zip(table["c"], table["push.effort_peak"], table["status"]):
        values = dict(CART_VALUES, c=c)
        v = values["a"] * t + values["b"] * values["w"] * np.cos(values["w"] * t)
        acc = values["a"] - values["b"] * values["w"] ** 2 * np.sin(values["w"] * t)
        want = np.max(np.abs(values["m"] * acc + c * v * np.abs(v) + values["mu"] * np.sign(v)))
        assert status == "ok" and abs(peak - want) <= 1e-12 * want, (c, peak, want)


@pytest.fixture(scope="module")
def braked_four_bar(tmp_path_factory):
    """The four-bar with a torque on the rocker that reads two other bodies' state:
    a viscous brake between rocker and coupler, scaled by the crank's speed."""
    text = api.example("four_bar").read_text() + (
        '\n[[force]]\nname = "brake"\ntype = "torque"\nbody = "rocker"\n'
        'T = "-0.2*(omega(rocker) - omega(coupler))*abs(omega(crank)) + 2*sin(omega*t)"\n')
    path = tmp_path_factory.mktemp("braked") / "four_bar.toml"
    path.write_text(text)
    return path, {b: api.solve(path, backend=b) for b in BACKENDS}


def test_a_torque_reading_other_bodies_keeps_the_power_balance_and_newton_euler(braked_four_bar):
    from symid.io.reader import loads
    from truth import Truth, newton_euler_residual

    path, runs = braked_four_bar
    res = runs["reference"]
    mech = loads(path.read_text(), str(path))
    brake = next(f for f in mech.forces if f.name == "brake")
    assert set(brake.bodies.values()) == {"rocker", "coupler", "crank"}  # its own body and the two it reads
    truth = Truth(mech, res)
    motor = res["crank_motor.T_j"] * res["crank.omega"]
    loads_ = truth.applied_loads()
    brake_power = truth.load_power([ld for ld in loads_[-1:]])  # the brake's, from the file's expression
    assert np.max(np.abs(brake_power)) > 0.05 * np.max(np.abs(motor))
    np.testing.assert_allclose(motor + truth.load_power(loads_), truth.kinetic_power(), rtol=0,
                               atol=1e-11 * np.max(np.abs(motor)))
    for body, (force, moment) in newton_euler_residual(truth).items():
        assert force < 1e-12 and moment < 1e-12, (body, force, moment)


@pytest.mark.parametrize("backend", BACKENDS[1:])
def test_a_torque_reading_other_bodies_agrees_on_every_backend(braked_four_bar, backend):
    _, runs = braked_four_bar
    assert_agree(runs[backend].data, runs["reference"].data, rel=1e-12)


@pytest.mark.slow  # a 159-coordinate solver compiled
def test_ladder_of_expressions_gives_the_closed_form_torque_through_the_looped_c_kernels(tmp_path):
    """Past c_loops.LOOP_MIN coordinates the C target loops over each family's members
    (an expression row shape is one family variant): the ladder of 26 parallelograms
    written as expressions (ng = 159) against its closed-form motor torque
    (benchmarks/ladder.py: I_eff thetaddot + G_eff cos theta)."""
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
    from benchmarks import ladder
    from symid.codegen.c import loops as c_loops

    lad = ladder.Ladder(26)
    assert lad.ng >= c_loops.LOOP_MIN
    path = tmp_path / "ladder.toml"
    path.write_text(as_expressions(ladder.toml(lad, steps=21)))
    res = api.solve(path, backend="c")
    assert res.error is None, res.error
    want = lad.torque(res.t)
    # 1e-10 of the peak: Newton's 1e-12 on 159 coordinates, rounded through a chain of 79 pins
    np.testing.assert_allclose(res["motor.T_j"], want, rtol=0, atol=1e-10 * np.max(np.abs(want)))


@pytest.mark.parametrize("backend", ["reference", "c"])
def test_statics_reads_the_state_at_rest(braked_four_bar, tmp_path, backend):
    """Statics evaluates forces at qdot = 0: the brake's terms of the speeds vanish, its
    term of t stays: the same table as the four-bar with that term alone."""
    path, _ = braked_four_bar
    plain = tmp_path / "plain.toml"
    plain.write_text(path.read_text().replace(
        '"-0.2*(omega(rocker) - omega(coupler))*abs(omega(crank)) + 2*sin(omega*t)"', '"2*sin(omega*t)"'))
    got, want = (api.solve(p, backend=backend, kind="statics", steps=21) for p in (path, plain))
    assert got.columns == want.columns
    assert_agree(got.data, want.data, rel=1e-12)


def test_help_expression_says_its_rows_come_from_phi(capsys):
    assert main(["help", "expression"]) == 0
    out = capsys.readouterr().out
    assert "rows: one per entry of phi" in out and "rows: 1;" not in out, out
    assert re.search(r"^  j +body, default ground$", out, re.M), out


BAD_FORCES = [
    ("unknown body in a state function", ("vx(cart)*abs", "vx(kart)*abs"),
     r"force 'drag' key 'F': unknown name 'kart'"),
    ("a body name outside a state function", ('"0"]', '"cart"]'),
     r"force 'drag' key 'F': the body name 'cart' is only an argument of a state function"),
    ("a term of t and the state", ('"0"]', '"t*vy(cart)"]'),
     r"force 'drag' key 'F': the term .* mixes t and the state: write the expression as g\(state\) \+ f\(t\)"),
    ("a state function in another force type", ('[analysis]', '[[force]]\nname = "s"\ntype = "spring_damper"\n'
     'i = "ground"\nj = "cart"\nsi = [0, 0]\nsj = [0, 0]\nk = 1\nc = 0\nL0 = 1\nfa = "x(cart)"\n\n[analysis]'),
     r"force 's' key 'fa': x\(\) at column 1 is a state function, allowed in forces only"),
]


@pytest.mark.parametrize("label,change,pattern", BAD_FORCES, ids=[b[0] for b in BAD_FORCES])
def test_bad_state_functions_are_one_line_exit_2(tmp_path, capsys, label, change, pattern):
    old, new = change
    assert CART.count(old) == 1, old
    path = tmp_path / "bad.toml"
    path.write_text(CART.replace(old, new))
    status = main(["check", str(path)])
    err = capsys.readouterr().err
    assert status == 2 and len(err.strip().splitlines()) == 1 and err.startswith(f"symid: {path}: "), err
    assert re.search(pattern, err), err
