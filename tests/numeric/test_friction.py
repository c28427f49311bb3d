"""Joint friction (contract v1.1, issue #16) against independent truth.

Closed forms (a block pushed along a rail; a motor swinging a bar on a pin),
power balance with the friction dissipation and Newton-Euler on every body
(tests/helpers/truth.py), the bundled slider-crank as mu -> 0, the Newton's
iteration count, the bad inputs of the friction table, and the backends
that refuse friction rather than ignore it.
"""

from __future__ import annotations

import subprocess

import numpy as np
import pytest

from bad_inputs import BASE, assert_one_line_input_error, solve_bad
from data_mechanisms import quick_return_with_friction
from symid import api
from symid.cli import main
from symid.io.reader import load, loads
from symid.numeric.solve import run
from tiers import first_quick
from truth import Truth, newton_euler_residual

BACKENDS = ["reference", "numpy", "casadi", "c"]
STRICT = ["-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", "-pedantic"]
G, M, MU, VISC, VS = 9.81, 2.0, 0.3, 0.7, 1e-2

RAIL = f"""
[mechanism]
name = "rail"
gravity = [0.0, -{G}]
[parameters]
A = 0.2
w = 3.0
P = 4.0
h = 0.05
[analysis]
t0 = 0.0
t1 = 2.0
steps = 41
[[body]]
name = "block"
mass = {M}
inertia = 0.01
q0 = [0.0, 0.0, 0.0]
[[constraint]]
name = "rail"
type = "translational"
i = "ground"
j = "block"
si = [0.0, 0.0]
vi = [2.0, 0.0]
sj = [0.0, 0.0]
friction = {{ mu = {MU}, viscous = {VISC}, arm = 0.1, v_smooth = {VS} }}
[[constraint]]
name = "push"
type = "coordinate_driver"
body = "block"
coordinate = "x"
f = "A*sin(w*t)"
[[force]]
name = "side"
type = "point_force"
body = "block"
s = [0.0, "h"]
F = ["P", "0"]
"""

BAR = f"""
[mechanism]
name = "bar"
gravity = [0.0, -{G}]
[parameters]
L = 0.4
r = 0.01
[analysis]
t0 = 0.0
t1 = 1.0
steps = 41
[[body]]
name = "bar"
mass = {M}
inertia = "{M}*L^2/12"
q0 = ["L/2", 0.0, 0.0]
[[constraint]]
name = "pin"
type = "revolute"
i = "ground"
j = "bar"
si = [0.0, 0.0]
sj = ["-L/2", 0.0]
friction = {{ mu = {MU}, radius = "r", viscous = {VISC}, v_smooth = {VS} }}
[[constraint]]
name = "motor"
type = "relative_angle_driver"
i = "ground"
j = "bar"
f = "2*t + 3*t^2 - 4*t^3"
"""


@pytest.mark.parametrize("backend", BACKENDS)
def test_block_on_rail_matches_coulomb_viscous_closed_form(backend):
    """Pushed along x: push = m a - P + mu (m g + h P / arm) tanh(v/vs) + c v."""
    res = api.solve(loads(RAIL, "rail.toml"), backend=backend)
    assert res.error is None
    t = res.t
    v, a = 0.2 * 3 * np.cos(3 * t), -0.2 * 9 * np.sin(3 * t)
    normal = M * G + 0.05 * 4.0 / 0.1
    friction = -(MU * normal * np.tanh(v / VS) + VISC * v)
    # closed forms against a tol 1e-12 solve; tanh(v / v_smooth) is steep near reversal and amplifies q's rounding (1e-10 with room)
    np.testing.assert_allclose(res["rail.friction"], friction, rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(res["rail.friction_power"], friction * v, rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(res["push.Fx_i"], M * a - 4.0 - friction, rtol=1e-10, atol=1e-9)
    # the reaction columns are the joint's whole action: normal force and friction
    np.testing.assert_allclose(res["rail.Fx_j"], friction, rtol=1e-10, atol=1e-10)
    # the normal load needs no friction: rounding of M g
    np.testing.assert_allclose(res["rail.Fy_j"], M * G, rtol=1e-12)


@pytest.mark.parametrize("backend", BACKENDS)
def test_bar_on_pin_motor_torque_matches_closed_form(backend):
    """The pin force is m |a_cm - g| (friction and motor are couples); the
    motor supplies J_O alpha minus gravity's moment minus the friction torque."""
    res = api.solve(loads(BAR, "bar.toml"), backend=backend)
    assert res.error is None
    t, half = res.t, 0.2
    phi = 2 * t + 3 * t ** 2 - 4 * t ** 3
    w, alpha = 2 + 6 * t - 12 * t ** 2, 6 - 24 * t
    acm = half * np.stack([-np.sin(phi) * alpha - np.cos(phi) * w ** 2,
                           np.cos(phi) * alpha - np.sin(phi) * w ** 2], 1)
    pin = M * np.linalg.norm(acm - np.array([0.0, -G]), axis=1)
    friction = -(MU * 0.01 * pin * np.tanh(w / VS) + VISC * w)
    # closed forms against a tol 1e-12 solve; tanh(w / v_smooth) is steep near reversal and amplifies the rounding (1e-10 with room)
    np.testing.assert_allclose(np.hypot(res["pin.Fx_j"], res["pin.Fy_j"]), pin, rtol=1e-10)
    np.testing.assert_allclose(res["pin.friction"], friction, rtol=1e-10, atol=1e-12)
    j_o = M * 0.4 ** 2 / 12 + M * half ** 2
    gravity_moment = -M * G * half * np.cos(phi)
    np.testing.assert_allclose(res["motor.T_j"], j_o * alpha - gravity_moment - friction, rtol=1e-10, atol=1e-10)


@pytest.fixture(scope="module", params=BACKENDS)
def crank(request):
    mech = load(api.example("slider_crank_friction"))
    res = api.solve(mech, backend=request.param, steps=41)
    assert res.error is None, res.error
    return mech, res


def _friction_power(mech, res) -> np.ndarray:
    return sum(res[f"{c.name}.friction_power"] for c in mech.constraints if c.friction)


def test_power_balance_counts_the_friction_dissipation(crank):
    """lambda^T Phi_t = d/dt(T + V) - P_nc - P_friction, with P_friction < 0."""
    mech, res = crank
    truth = Truth(mech, res)
    drive = res["motor.lambda"] * truth.driver_phi_t("motor")
    lost = _friction_power(mech, res)
    assert np.all(lost <= 0) and np.max(-lost) > 1.0  # it dissipates, and not negligibly
    expected = truth.kinetic_power() - truth.load_power(truth.applied_loads()) - lost
    # the power balance takes finite-precision rates and loads; smoothed friction near reversal costs digits (1e-8 of the peak)
    assert np.max(np.abs(drive - expected)) <= 1e-8 * np.max(np.abs(expected))


def test_newton_euler_holds_with_the_friction_loads(crank):
    mech, res = crank
    for body, (force, moment) in newton_euler_residual(Truth(mech, res)).items():
        # Newton-Euler with friction loads whose smoothed sign amplifies rounding near reversal: 1e-9 N
        assert force < 1e-9 and moment < 1e-9, (body, force, moment)


def test_friction_approaches_frictionless_as_mu_goes_to_zero():
    """The motor torque with friction tends to the frictionless one linearly in mu."""
    plain = api.solve(api.example("slider_crank"), backend="reference", steps=21)["motor.T_j"]
    gaps = []
    for scale in (1e-4, 2e-4):
        sets = {"mu_pin": f"{0.05 * scale}", "mu_guide": f"{0.1 * scale}", "c_main": f"{0.002 * scale}",
                "c_guide": f"{scale}"}
        mech = load(api.example("slider_crank_friction"), sets, {"steps": 21})
        gaps.append(api.solve(mech, backend="reference")["motor.T_j"] - plain)
    size = np.max(np.abs(plain))
    # linear in mu: at mu scaled by 1e-4 the gap is measurable (> 1e-7) and small (< 1e-3)
    assert 1e-7 * size < np.max(np.abs(gaps[0])) < 1e-3 * size
    # linear in mu: doubling mu doubles the gap, to its second-order term (1e-3)
    np.testing.assert_allclose(gaps[1], 2 * gaps[0], rtol=1e-3, atol=1e-9 * size)


@pytest.mark.slow  # the reference backend over the whole example; friction's truths stay in the quick tier
def test_friction_newton_converges_in_three_iterations_on_the_example():
    study = api.prepare(api.example("slider_crank_friction"), backend="reference")
    counts = [inst.friction.iterations for inst in run(study.evaluator, study.analysis, study.q0())]
    assert len(counts) == study.analysis.steps and max(counts) <= 3 and min(counts) >= 1


@pytest.mark.parametrize("backend", BACKENDS)
def test_exact_sign_at_rest_stops_with_the_time_and_joint(tmp_path, capsys, backend):
    text = RAIL.replace(f"v_smooth = {VS}", "v_smooth = 0").replace('"A*sin(w*t)"', '"(t - 1)^2 - 1"')
    path, out = tmp_path / "rest.toml", tmp_path / "rest.csv"
    path.write_text(text)
    status = main(["solve", str(path), "-o", str(out), "--backend", backend])
    err = capsys.readouterr().err
    assert status == 3 and err.count("\n") == 1
    assert "t = 1" in err and "rail" in err and "at rest" in err
    assert len(out.read_text().splitlines()) == 1 + 20  # the instants before t = 1 are kept


def test_exact_sign_away_from_rest_is_the_sign():
    text = RAIL.replace(f"v_smooth = {VS}", "v_smooth = 0").replace('"A*sin(w*t)"', '"t^2 + t"')
    res = api.solve(loads(text, "rail.toml"), backend="reference")
    normal = M * G + 0.05 * 4.0 / 0.1
    # with v_smooth = 0 the friction is a closed form of the solved state: rounding
    np.testing.assert_allclose(res["rail.friction"], -(MU * normal + VISC * (2 * res.t + 1)), rtol=1e-12)


@pytest.mark.parametrize("target", ["numpy", "casadi"])
def test_generate_refuses_friction_rather_than_ignore_it(tmp_path, capsys, target):
    status = main(["generate", str(api.example("slider_crank_friction")), "--target", target,
                   "-o", str(tmp_path / "gen")])
    err = capsys.readouterr().err
    assert status == 2 and err.count("\n") == 1
    assert "main_bearing" in err and "friction" in err and target in err


def test_generated_c_with_friction_compiles_with_strict_flags(tmp_path):
    api.generate(api.example("slider_crank_friction"), "c", tmp_path)
    source = tmp_path / "slider_crank_friction_solver.c"
    assert "friction_solve" in source.read_text()
    result = subprocess.run(["cc", *STRICT, "-c", str(source), "-o", str(tmp_path / "x.o")],
                            capture_output=True, text=True)
    assert result.returncode == 0, result.stderr


def test_c_solves_friction_in_its_own_loop(monkeypatch):
    """Every instant in the compiled loop (none handed to the Python loop),
    agreeing with the reference."""
    from symid.numeric import solve

    calls = []
    original = solve.Stepper.instant
    monkeypatch.setattr(solve.Stepper, "instant", lambda self, n, *a: calls.append(n) or original(self, n, *a))
    c = api.solve(api.example("slider_crank_friction"), backend="c", steps=41)
    assert calls == []
    monkeypatch.undo()
    ref = api.solve(api.example("slider_crank_friction"), backend="reference", steps=41)
    assert c.columns == ref.columns
    scale = np.abs(ref.data).max(axis=0) + 1e-300  # per column
    # the C and the reference solve the same equations to tol 1e-12; smoothed friction near reversal costs digits (1e-10 per column)
    assert np.max(np.abs(c.data - ref.data) / scale) <= 1e-10


def test_statics_and_kinematics_have_no_friction_columns():
    for kind in ("statics", "kinematics"):
        res = api.solve(api.example("slider_crank_friction"), backend="reference", kind=kind, steps=3)
        assert not any("friction" in c for c in res.columns)


def test_friction_columns_come_last_in_file_order():
    res = api.solve(api.example("slider_crank_friction"), backend="reference", steps=3)
    tail = res.columns[-8:]
    assert tail == [f"{n}.{w}" for n in ("main_bearing", "crank_pin", "wrist_pin", "cylinder_guide")
                    for w in ("friction", "friction_power")]


GUIDE = 'theta0 = 0.0\n'


def _table(keys: dict) -> str:
    return "friction = { " + ", ".join(f"{k} = {v}" for k, v in keys.items()) + " }\n"


BEARING = 'sj = ["-L_crank/2", 0.0]\n'
CASES = [
    ("friction-on-a-driver", BASE.replace('f = "omega*t"\n', 'f = "omega*t"\nfriction = { mu = 0.1 }\n'),
     r"bad\.toml: constraint 'motor' key 'friction': a relative_angle_driver has no friction"),
    ("friction-unknown-key", BASE.replace(GUIDE, GUIDE + "friction = { mu = 0.1, rho = 1 }\n"),
     r"bad\.toml: constraint 'cylinder_guide' key 'friction\.rho': unknown friction key"),
    ("friction-not-a-table", BASE.replace(GUIDE, GUIDE + "friction = 0.1\n"),
     r"bad\.toml: constraint 'cylinder_guide' key 'friction': must be an inline table"),
    ("friction-no-mu-nor-viscous", BASE.replace(GUIDE, GUIDE + "friction = { arm = 0.1 }\n"),
     r"bad\.toml: constraint 'cylinder_guide' key 'friction': needs 'mu'"),
    ("friction-revolute-mu-without-radius", BASE.replace(BEARING, BEARING + "friction = { mu = 0.1 }\n"),
     r"bad\.toml: constraint 'main_bearing' key 'friction\.radius': missing"),
    ("friction-zero-arm", BASE.replace(GUIDE, GUIDE + "friction = { mu = 0.1, arm = 0 }\n"),
     r"bad\.toml: constraint 'cylinder_guide' key 'friction\.arm': must be positive"),
    ("friction-bad-expression", BASE.replace(GUIDE, GUIDE + "friction = { mu = \"nope\" }\n"),
     r"bad\.toml: constraint 'cylinder_guide' key 'friction\.mu'"),
    ("friction-on-a-force", BASE.replace('F = ["-F_gas*sin(omega*t)", "0"]', 'F = ["0", "0"]\nfriction = { mu = 1 }'),
     r"bad\.toml: force 'gas_load' key 'friction': unknown key"),
] + [
    (f"friction-negative-{key}", BASE.replace(BEARING, BEARING + _table({"mu": 0.1, "radius": 0.01, key: -1})),
     rf"bad\.toml: constraint 'main_bearing' key 'friction\.{key}': must not be negative")
    for key in ("mu", "radius", "viscous", "arm", "v_smooth")
]


@pytest.mark.parametrize("content, pattern", [pytest.param(c, p, id=i) for i, c, p in CASES])
def test_bad_friction_input_is_one_line_exit_2(tmp_path, capsys, content, pattern):
    assert content != BASE  # the edit took
    status, err, path, out = solve_bad(tmp_path, capsys, content, [])
    assert_one_line_input_error(status, err, path, out, pattern)


def test_summary_line_gives_the_energy_friction_took_and_its_mean_power(crank):
    """The energy is what the drive supplied beyond d/dt(T + V) - P_nc, integrated:
    the power balance read backwards, independent of the friction columns."""
    mech, res = crank
    truth = Truth(mech, res)
    drive = res["motor.lambda"] * truth.driver_phi_t("motor")
    lost = drive - (truth.kinetic_power() - truth.load_power(truth.applied_loads()))
    energy = float(np.sum((lost[1:] + lost[:-1]) * np.diff(res.t)) / 2)
    (line,) = [s for s in res.summary() if s.startswith("friction:")]
    assert f"friction: {energy:.4g} J lost over the run, mean power {energy / 0.2:.4g} W" in line
    assert "cylinder_guide" in line and "main_bearing" in line


# slow: every figure of the friction crank on each backend; friction's power balance and Newton-Euler stay in
# the quick tier
@pytest.mark.slow
def test_plot_draws_each_joints_friction_power(crank, tmp_path):
    from symid.output import plot

    mech, res = crank
    written = plot.write_all(res, mech, tmp_path, "run")
    assert tmp_path / "run_friction.png" in written.paths
    fig = plot.friction_figure(res, mech)
    lines = {ln.get_gid(): ln for ax in fig.axes for ln in ax.get_lines()}
    for c in mech.constraints:
        if c.friction:
            np.testing.assert_array_equal(lines[f"friction:{c.name}"].get_ydata(), res[f"{c.name}.friction_power"])


@pytest.mark.slow  # a reference solve and every figure; the friction figure's test stays in the quick tier
def test_plot_of_a_frictionless_table_has_no_friction_figure(tmp_path):
    from symid.output import plot

    mech = load(api.example("slider_crank"))
    written = plot.write_all(api.solve(mech, backend="reference", steps=5), mech, tmp_path, "run")
    assert not (tmp_path / "run_friction.png").exists() and not written.skipped


# slow: friction of a slot between two moving bodies solved and checked body by body; the friction crank's power
# balance and Newton-Euler stay in the quick tier
@pytest.mark.slow
@pytest.mark.parametrize("backend", ["reference", "c"])
def test_slot_between_moving_bodies_balances_power_and_every_body(backend):
    mech = loads(quick_return_with_friction(), "quick_return.toml")
    res = api.solve(mech, backend=backend, steps=41)
    assert res.error is None, res.error
    truth = Truth(mech, res)
    drive = res["crank_motor.lambda"] * truth.driver_phi_t("crank_motor")
    lost = _friction_power(mech, res)
    assert np.all(lost <= 0) and np.min(res["crank_pin_in_lever_slot.friction_power"]) < -1.0
    expected = truth.kinetic_power() - truth.load_power(truth.applied_loads()) - lost
    # the power balance takes finite-precision rates and loads; smoothed friction near reversal costs digits (1e-8 of the peak)
    assert np.max(np.abs(drive - expected)) <= 1e-8 * np.max(np.abs(expected))
    for body, (force, moment) in newton_euler_residual(truth).items():
        # Newton-Euler with friction loads whose smoothed sign amplifies rounding near reversal: 1e-9 N
        assert force < 1e-9 and moment < 1e-9, (body, force, moment)


CARRIAGE = """
[mechanism]
name = "carriage"
gravity = [0.0, -9.81]
[analysis]
t1 = 1.0
steps = 41
[[body]]
name = "carriage"
mass = 3.0
inertia = 0.2
q0 = [0.0, 0.0, 0.0]
[[body]]
name = "block"
mass = 1.5
inertia = 0.01
q0 = [0.2, 0.1, 0.0]
[[constraint]]
name = "cx"
type = "coordinate_driver"
body = "carriage"
coordinate = "x"
f = "0.1*sin(2*t)"
[[constraint]]
name = "cy"
type = "coordinate_driver"
body = "carriage"
coordinate = "y"
f = "0.05*sin(3*t)"
[[constraint]]
name = "cphi"
type = "coordinate_driver"
body = "carriage"
coordinate = "phi"
f = "0.3*sin(2*t)"
[[constraint]]
name = "slide"
type = "translational"
i = "carriage"
j = "block"
si = [0.0, 0.1]
vi = [1.0, 0.0]
sj = [0.0, 0.0]
friction = { mu = 0.2, viscous = 3.0, arm = 0.04, v_smooth = 1e-3 }
[[constraint]]
name = "stroke"
type = "translational_driver"
i = "carriage"
j = "block"
si = [0.0, 0.1]
vi = [1.0, 0.0]
sj = [0.0, 0.0]
f = "0.2 + 0.1*sin(5*t)"
"""


@pytest.mark.parametrize("backend", first_quick(["c", "reference"]))
def test_slide_on_a_moving_offset_line_balances_power_and_every_body(backend):
    """The slide's line is off the carriage's centre and the carriage turns:
    the friction's moment on the slide body counts."""
    mech = loads(CARRIAGE, "carriage.toml")
    res = api.solve(mech, backend=backend)
    assert res.error is None, res.error
    truth = Truth(mech, res)
    drive = sum(res[f"{d}.lambda"] * truth.driver_phi_t(d) for d in ("cx", "cy", "cphi", "stroke"))
    lost = _friction_power(mech, res)
    assert np.all(lost <= 0) and np.min(lost) < -0.5
    expected = truth.kinetic_power() - truth.load_power(truth.applied_loads()) - lost
    # the power balance takes finite-precision rates and loads; smoothed friction near reversal costs digits (1e-8 of the peak)
    assert np.max(np.abs(drive - expected)) <= 1e-8 * np.max(np.abs(expected))
    for body, (force, moment) in newton_euler_residual(truth).items():
        # Newton-Euler with friction loads whose smoothed sign amplifies rounding near reversal: 1e-9 N
        assert force < 1e-9 and moment < 1e-9, (body, force, moment)



@pytest.mark.parametrize("name", [n for n in api.examples() if "friction" not in n])
def test_generated_code_of_a_frictionless_mechanism_carries_no_friction(name, tmp_path):
    """What a mechanism does not need is skipped: without a friction table no
    friction Newton, no tanh and no friction column reaches the generated C."""
    text = "".join(p.read_text() for p in api.generate(api.example(name), "c", tmp_path) if p.suffix in (".c", ".h"))
    assert "friction" not in text.lower()
    assert "tanh" not in text


def test_generated_code_with_friction_carries_its_newton(tmp_path):
    """The converse of the test above, so that it cannot pass by looking at nothing."""
    text = "".join(p.read_text() for p in api.generate(api.example("slider_crank_friction"), "c", tmp_path)
                   if p.suffix in (".c", ".h"))
    assert "friction" in text.lower() and "tanh" in text
