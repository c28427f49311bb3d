"""Motion from data and standard motion laws (symid.model.motion, symid.io.table).

A table sampled from a known formula must give back the formula's motor
torque within a bound derived from the sampling step; a bad table or a run
outside its span is an input error; the motion laws have the values and
exact derivatives of their textbook formulas and run on every backend.
"""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

from symid import api
from symid.cli import main
from symid.codegen.cache import key
from symid.codegen.model import options_for
from symid.errors import InputError
from symid.model.expr import parse_expression
from symid.io.reader import load, loads
from symid.model.mechanism import T
from symid.model.motion import LAWS
from tiers import diagonal

needs_cc = pytest.mark.skipif(shutil.which("cc") is None and shutil.which("gcc") is None, reason="no C compiler")
SLIDER_CRANK = api.example("slider_crank").read_text()
OMEGA = 2 * math.pi * 5  # the example's crank speed, rad/s; its run is t = [0, 0.2]
A = 0.2  # speed ripple: f(t) = omega t + A sin(omega t), so f' = omega (1 + A cos(omega t)) > 0
FORMULA = f"omega*t + {A}*sin(omega*t)"
TABLED = 'f = { table = "motion.csv", column = "angle"%s }'


def motor(f_line: str) -> str:
    """The slider-crank example with its motor's `f = ...` line replaced."""
    assert 'f = "omega*t"' in SLIDER_CRANK
    return SLIDER_CRANK.replace('f = "omega*t"', f_line)


def write_table(folder: Path, t: np.ndarray, y: np.ndarray, name: str = "motion.csv",
                header: str = "time,angle") -> Path:
    path = folder / name
    path.write_text(header + "\n" + "".join(f"{float(a)!r},{float(b)!r}\n" for a, b in zip(t, y)))
    return path


def formula(t: np.ndarray) -> np.ndarray:
    return OMEGA * t + A * np.sin(OMEGA * t)


def tabled_mechanism(folder: Path, h: float, smoothing: str = "", noise: float = 0.0) -> Path:
    n = round(0.2 / h)
    t = np.linspace(0.0, 0.2, n + 1)
    y = formula(t) + np.random.default_rng(7).normal(0.0, noise, t.size) if noise else formula(t)
    write_table(folder, t, y)
    path = folder / "tabled.toml"
    path.write_text(motor(TABLED % smoothing))
    return path


@pytest.fixture(scope="module")
def formula_run(tmp_path_factory: pytest.TempPathFactory) -> dict:
    """The formula-driven solve: the torque to recover, and the largest inertia the motor sees."""
    path = tmp_path_factory.mktemp("formula") / "formula.toml"
    path.write_text(motor(f'f = "{FORMULA}"'))
    study = api.prepare(path, "reference")
    res = study.solve()
    assert res.error is None
    qd = res.block([c for c in res.columns if c.endswith((".vx", ".vy", ".omega"))])
    theta_dot = OMEGA * (1 + A * np.cos(OMEGA * res.t))
    # generalized inertia at the crank: 2 * kinetic energy / theta'^2 (M is diagonal)
    j_eff = (qd**2 @ study.evaluator.mass()) / theta_dot**2
    return {"torque": res["motor.T_j"], "j_max": float(np.max(j_eff)), "path": path}


def torque_bound(h: float, j_max: float) -> float:
    """What sampling at step h may cost in motor torque.

    The torque is J(theta) f'' + (terms in f', f). The interpolating cubic
    spline's errors are |f'' - s''| <= 3/8 h^2 max|f''''|, |f' - s'| <=
    1/24 h^3 max|f''''|, |f - s| <= 5/384 h^4 max|f''''| (Hall & Meyer 1976,
    for the complete spline; not-a-knot ends have the same order). Here
    max|f''''| = A omega^4, so f'' dominates: the f' term is below 1% of it
    (h/9 times J'/J * 2 theta' ~ 0.01 at h = 2e-3). A factor of 2 covers it,
    the f term and the not-a-knot ends. Observed: about h^2/12 (a ninth of this).
    """
    return 2.0 * j_max * 3.0 / 8.0 * h**2 * A * OMEGA**4


# -- motion from a table -------------------------------------------------------


@pytest.mark.parametrize("backend, h", [pytest.param(*p.values, id=p.id, marks=[*p.marks, needs_cc] if p.values[0] == "c" else p.marks)
                                        for p in diagonal(["reference", "numpy", "c"], [2e-3, 1e-3])])
def test_table_sampled_from_a_formula_recovers_its_motor_torque(tmp_path, formula_run, backend, h) -> None:
    res = api.solve(tabled_mechanism(tmp_path, h), backend=backend)
    assert res.error is None
    err = np.max(np.abs(res["motor.T_j"] - formula_run["torque"]))
    bound = torque_bound(h, formula_run["j_max"])
    assert err <= bound, (err, bound)
    assert err >= bound / 100, "suspiciously exact: is the table really what was solved?"


@pytest.mark.slow  # solves the tabled run at several step sizes
def test_torque_error_falls_as_h_squared(tmp_path, formula_run) -> None:
    errors = []
    for h in (4e-3, 2e-3, 1e-3):
        folder = tmp_path / f"h{h}"
        folder.mkdir()
        res = api.solve(tabled_mechanism(folder, h), backend="reference")
        errors.append(np.max(np.abs(res["motor.T_j"] - formula_run["torque"])))
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(orders > 1.8), orders


def test_smoothing_tames_noisy_samples(tmp_path, formula_run) -> None:
    """1e-4 rad of noise at h = 1e-3 ruins f'' by interpolation (noise / h^2);
    the smoothing spline (lam = 1e-7: cut-off near (lam h)^(-1/4) = 316 rad/s,
    ten times the crank speed) recovers the torque away from the table's ends,
    where a smoothing spline is natural (f'' = 0)."""
    interior = slice(20, 181)  # t in [0.02, 0.18]
    errors = {}
    for smoothing in ("", ", smoothing = 1e-7"):
        folder = tmp_path / str(len(smoothing))
        folder.mkdir()
        res = api.solve(tabled_mechanism(folder, 1e-3, smoothing, noise=1e-4), backend="numpy")
        errors[smoothing] = np.max(np.abs(res["motor.T_j"] - formula_run["torque"])[interior])
    peak = np.max(np.abs(formula_run["torque"]))
    assert errors[", smoothing = 1e-7"] < errors[""] / 100  # observed: 1.2 and 0.002 times the peak
    assert errors[", smoothing = 1e-7"] < 0.01 * peak


def test_time_column_by_name_and_extra_columns(tmp_path) -> None:
    t = np.linspace(0.0, 0.2, 101)
    path = tmp_path / "motion.csv"
    path.write_text("angle,other,time\n" + "".join(f"{float(b)!r},1,{float(a)!r}\n"
                                                   for a, b in zip(t, formula(t))))
    mech = tmp_path / "m.toml"
    mech.write_text(motor(TABLED % ', time = "time"'))
    res = api.solve(mech, backend="reference", steps=11)
    assert res.error is None
    # the instants fall on the table's samples: the sampled formula to rounding and the Newton tol, 1e-8 rad with room
    assert np.allclose(res["crank.phi"], formula(res.t), rtol=0, atol=1e-8)


def test_last_instant_an_ulp_past_the_span_still_solves(tmp_path) -> None:
    """t0 + k (t1 - t0) / (steps - 1) can round past t1; the table must still answer there."""
    t1, steps = next((t1, n) for t1 in (0.2, 0.17, 0.19, 0.13) for n in range(2, 400)
                     if (n - 1) * (t1 / (n - 1)) > t1)
    t = np.linspace(0.0, t1, 101)
    write_table(tmp_path, t, formula(t))
    mech = tmp_path / "m.toml"
    mech.write_text(motor(TABLED % ""))
    for backend in ("reference", "numpy"):
        res = api.solve(mech, backend=backend, t1=t1, steps=steps)
        assert res.error is None and np.all(np.isfinite(res.data))
        assert res.t[-1] > t1


def test_a_table_is_printed_in_c_only_where_used(tmp_path) -> None:
    """A static C function never called is an error under -Werror: a table only a
    force uses is left out of kinematics (which prints no forces), kept otherwise."""
    t = np.linspace(0.0, 0.2, 41)
    write_table(tmp_path, t, np.cos(t), name="load.csv", header="t,torque")
    text = SLIDER_CRANK + '\n[[force]]\nname = "brake"\ntype = "torque"\nbody = "crank"\n' \
                          'T = { table = "load.csv", column = "torque" }\n'
    mech = tmp_path / "m.toml"
    for kind, printed in (("kinematics", False), ("inverse_dynamics", True)):
        mech.write_text(text.replace('kind = "inverse_dynamics"', f'kind = "{kind}"'))
        api.generate(mech, "c", tmp_path / kind)
        source = (tmp_path / kind / "slider_crank_solver.c").read_text()
        assert ("slider_crank_spline" in source) is printed
    if shutil.which("cc") or shutil.which("gcc"):
        # (kinematics on the C backend does not compile yet for a reason of its own:
        # solve_t is emitted unused)
        assert api.solve(mech, backend="c", steps=5).error is None


def test_cache_key_follows_the_table_contents(tmp_path) -> None:
    t = np.linspace(0.0, 0.2, 21)
    keys = []
    for k, scale in enumerate((1.0, 1.0, 1.001)):
        folder = tmp_path / str(k)
        folder.mkdir()
        write_table(folder, t, scale * formula(t), name=f"data{k}.csv")
        path = folder / "m.toml"
        path.write_text(motor(f'f = {{ table = "data{k}.csv", column = "angle" }}'))
        mech = load(path)
        keys.append(key(mech, options_for(mech), "c"))
    assert keys[0] == keys[1], "same data under another name: same code"
    assert keys[0] != keys[2], "changed data: new code"


# -- bad tables and runs outside them: exit 2, one line ------------------------


def run_cli(tmp_path: Path, capsys, csv_text: str, *extra: str, f_line: str = TABLED % "") -> tuple[int, str]:
    (tmp_path / "motion.csv").write_text(csv_text)
    path = tmp_path / "m.toml"
    path.write_text(motor(f_line))
    status = main(["solve", str(path), "-o", str(tmp_path / "out.csv"), *extra])
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert err.count("\n") == 1, err
    return status, err


def good_csv(t: np.ndarray | None = None) -> str:
    t = np.linspace(0.0, 0.2, 101) if t is None else t
    return "time,angle\n" + "".join(f"{float(a)!r},{float(b)!r}\n" for a, b in zip(t, formula(t)))


def test_a_table_with_a_gap_is_rejected(tmp_path, capsys) -> None:
    t = np.linspace(0.0, 0.2, 101)
    t = np.concatenate([t[:40], t[60:]])  # 21 steps missing: the step is 21x the median
    status, err = run_cli(tmp_path, capsys, good_csv(t))
    assert status == 2
    assert "motion.csv" in err and "motor" in err and "gap" in err and "lines 41-42" in err


def test_a_table_with_time_not_increasing_is_rejected(tmp_path, capsys) -> None:
    lines = good_csv().splitlines()
    lines[11], lines[12] = lines[12], lines[11]
    status, err = run_cli(tmp_path, capsys, "\n".join(lines) + "\n")
    assert status == 2
    assert "line 13" in err and "does not increase" in err


def test_a_missing_column_is_rejected(tmp_path, capsys) -> None:
    status, err = run_cli(tmp_path, capsys, good_csv(), f_line=TABLED.replace("angle", "angel") % "")
    assert status == 2
    assert "no column 'angel'" in err and "columns: time, angle" in err


def test_a_non_numeric_cell_is_rejected(tmp_path, capsys) -> None:
    lines = good_csv().splitlines()
    lines[5] = lines[5].split(",")[0] + ",n/a"
    status, err = run_cli(tmp_path, capsys, "\n".join(lines) + "\n")
    assert status == 2
    assert "line 6, column 'angle': 'n/a' is not a finite number" in err


@pytest.mark.parametrize("cell", ["nan", "inf", "1_0", "0x10", ""])
def test_cells_that_float_would_accept_are_not_numbers_here(tmp_path, capsys, cell) -> None:
    lines = good_csv().splitlines()
    lines[3] = lines[3].split(",")[0] + "," + cell
    status, err = run_cli(tmp_path, capsys, "\n".join(lines) + "\n")
    assert status == 2 and "line 4" in err


@pytest.mark.parametrize("extra, span", [((), "[0.0, 0.15]"), (("--t1", "0.25"), "[0.0, 0.2]"),
                                         (("--t0", "-0.01"), "[0.0, 0.2]")])
def test_a_run_outside_the_table_span_is_rejected(tmp_path, capsys, extra, span) -> None:
    t = np.linspace(0.0, 0.15 if not extra else 0.2, 101)
    status, err = run_cli(tmp_path, capsys, good_csv(t), *extra)
    assert status == 2
    assert "m.toml" in err and "constraint 'motor' key 'f'" in err and span in err and "motion.csv" in err


def test_a_run_outside_the_span_is_rejected_from_the_api_too(tmp_path) -> None:
    write_table(tmp_path, np.linspace(0.0, 0.2, 101), formula(np.linspace(0.0, 0.2, 101)))
    path = tmp_path / "m.toml"
    path.write_text(motor(TABLED % ""))
    mech = load(path)
    with pytest.raises(InputError, match=r"outside the span \[0.0, 0.2\]"):
        api.prepare(mech, "reference", t1=0.3)


@pytest.mark.parametrize("spec, message", [
    ('{ column = "angle" }', 'needs table = "FILE.csv"'),
    ('{ table = "motion.csv" }', 'needs column = "NAME"'),
    ('{ table = "motion.csv", column = "angle", smoothing = -1 }', "must be a number >= 0"),
    ('{ table = "motion.csv", column = "angle", order = 3 }', "unknown key 'order'"),
    ('{ table = "nowhere.csv", column = "angle" }', "cannot read"),
    ('{ table = "motion.csv", column = "time" }', "is the time column"),
])
def test_bad_table_keys_are_input_errors(tmp_path, spec, message) -> None:
    (tmp_path / "motion.csv").write_text(good_csv())
    with pytest.raises(InputError, match=message):
        loads(motor(f"f = {spec}"), str(tmp_path / "m.toml"))


def test_too_few_rows_are_rejected(tmp_path) -> None:
    (tmp_path / "motion.csv").write_text(good_csv(np.linspace(0.0, 0.2, 4)))
    with pytest.raises(InputError, match="has 4 data rows; a table needs 5"):
        loads(motor(TABLED % ""), str(tmp_path / "m.toml"))


# -- motion laws ---------------------------------------------------------------


def law(text: str) -> sp.Expr:
    return parse_expression(text, {"t": T}, "test", functions=LAWS)


def values(expr: sp.Expr, t: np.ndarray, order: int = 0) -> np.ndarray:
    fn = sp.lambdify(T, sp.diff(expr, T, order), "numpy")
    return np.array([float(fn(x)) for x in t])


X0, DUR, H = 0.3, 0.5, 2.0  # rise by H over [X0, X0 + DUR]
POINTS = np.array([0.0, 0.29, 0.3, 0.35, 0.45, 0.55, 0.62, 0.79, 0.8, 1.2])


def hand(name: str, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Textbook cam laws (e.g. Norton, Cam Design), written independently of symid."""
    u = np.clip((t - X0) / DUR, 0.0, 1.0)
    inside = (t >= X0) & (t < X0 + DUR)
    if name == "cycloidal":
        s = H * (u - np.sin(2 * np.pi * u) / (2 * np.pi))
        v = H / DUR * (1 - np.cos(2 * np.pi * u))
        a = 2 * np.pi * H / DUR**2 * np.sin(2 * np.pi * u)
    elif name == "harmonic":
        s = H / 2 * (1 - np.cos(np.pi * u))
        v = np.pi * H / (2 * DUR) * np.sin(np.pi * u)
        a = np.pi**2 * H / (2 * DUR**2) * np.cos(np.pi * u)
    else:
        s = H * (10 * u**3 - 15 * u**4 + 6 * u**5)
        v = H / DUR * (30 * u**2 - 60 * u**3 + 30 * u**4)
        a = H / DUR**2 * (60 * u - 180 * u**2 + 120 * u**3)
    return s, np.where(inside, v, 0.0), np.where(inside, a, 0.0)


@pytest.mark.parametrize("name", ["cycloidal", "harmonic", "poly345"])
def test_motion_law_values_and_derivatives_match_the_textbook(name) -> None:
    expr = law(f"{name}(t, {X0}, {DUR}, {H})")
    for order, expected in enumerate(hand(name, POINTS)):
        # the law's closed form evaluated two ways in double: rounding, relative to values of order 1
        assert np.allclose(values(expr, POINTS, order), expected, rtol=1e-13, atol=1e-12), order


@pytest.mark.parametrize("name", ["cycloidal", "poly345"])
def test_second_derivative_is_continuous_for_c2_laws(name) -> None:
    """The rise piece's s' and s'' are exactly zero at both ends, as the dwells' are."""
    expr = law(f"{name}(t, 3/10, 1/2, 2)")
    for order in (1, 2):
        rise = sp.diff(expr, T, order).args[1][0]  # the piece on [x0, x0 + T)
        assert sp.simplify(rise.subs(T, sp.Rational(3, 10))) == 0
        assert sp.simplify(rise.subs(T, sp.Rational(4, 5))) == 0


def test_harmonic_is_only_c1() -> None:
    expr = law("harmonic(t, 0, 1, 1)")
    rise = sp.diff(expr, T, 2).args[1][0]
    assert sp.simplify(rise.subs(T, 0) - sp.pi**2 / 2) == 0  # jumps from the dwell's 0


def test_rise_dwell_return() -> None:
    expr = law("rise_dwell_return(t, 0.1, 0.2, 0.3, 0.4, 1.5)")
    t = np.array([0.0, 0.1, 0.2, 0.3, 0.45, 0.6, 0.8, 1.0, 1.5])
    u_rise, u_ret = np.clip((t - 0.1) / 0.2, 0, 1), np.clip((t - 0.6) / 0.4, 0, 1)
    p = lambda u: 10 * u**3 - 15 * u**4 + 6 * u**5  # noqa: E731
    # the same polynomial in double: rounding of values of order 1
    assert np.allclose(values(expr, t), 1.5 * (p(u_rise) - p(u_ret)), rtol=0, atol=1e-14)


@pytest.mark.parametrize("text, message", [
    ("cycloidal(t, 0, -1, 1)", "duration T must be positive"),
    ("poly345(t, 0, 0, 1)", "duration T must be positive"),
    ("rise_dwell_return(t, 0, 1, -1, 1, 1)", "T_dwell must not be negative"),
    ("harmonic(t, 0, 1)", "takes 4 arguments"),
])
def test_bad_motion_law_arguments_are_input_errors(text, message) -> None:
    with pytest.raises(InputError, match=message):
        law(text)


def test_parameter_named_like_a_law_still_works() -> None:
    """The laws are not reserved names: files with such parameters stay valid (contract v1)."""
    text = SLIDER_CRANK.replace("[parameters]\n", "[parameters]\nharmonic = 0.0\n")
    text = text.replace('f = "omega*t"', 'f = "omega*t + harmonic"')
    assert loads(text).parameters["harmonic"] == 0


@pytest.fixture(scope="module")
def cycloidal_mechanism(tmp_path_factory: pytest.TempPathFactory) -> Path:
    text = motor('f = "omega*t + cycloidal(t, t_a, T_a, h_a)"')
    text = text.replace("[parameters]\n", "[parameters]\nt_a = 0.05\nT_a = 0.1\nh_a = 0.5\n")
    path = tmp_path_factory.mktemp("cycloidal") / "cycloidal.toml"
    path.write_text(text)
    return path


# slow: one law on every backend; the other motion laws' tests keep c in the quick tier
@pytest.mark.slow
@pytest.mark.parametrize("backend", [pytest.param("c", marks=needs_cc), "numpy", "casadi"])
def test_cycloidal_driver_agrees_on_every_backend(cycloidal_mechanism, backend) -> None:
    reference = api.solve(cycloidal_mechanism, backend="reference").data
    got = api.solve(cycloidal_mechanism, backend=backend).data
    col = np.max(np.abs(reference), axis=0)
    scale = np.maximum(col, 1e-3 * np.max(col))
    # every backend solves the same equations to tol 1e-12: rounding of each column's scale
    assert np.max(np.abs(got - reference) / scale) <= 1e-12


def test_cycloidal_driver_is_the_law(cycloidal_mechanism) -> None:
    res = api.solve(cycloidal_mechanism, backend="reference")
    s, v, a = hand_at(res.t, 0.05, 0.1, 0.5)
    # Newton to tol 1e-12, then rates and accelerations from linear solves: each derivative loses about one digit (1e-10, 1e-9, 1e-7 with room)
    assert np.allclose(res["crank.phi"], OMEGA * res.t + s, rtol=0, atol=1e-10)
    assert np.allclose(res["crank.omega"], OMEGA + v, rtol=0, atol=1e-9)
    assert np.allclose(res["crank.alpha"], a, rtol=0, atol=1e-7)


def hand_at(t: np.ndarray, x0: float, dur: float, h: float) -> tuple[np.ndarray, ...]:
    u = np.clip((t - x0) / dur, 0.0, 1.0)
    inside = (t >= x0) & (t < x0 + dur)
    return (h * (u - np.sin(2 * np.pi * u) / (2 * np.pi)),
            np.where(inside, h / dur * (1 - np.cos(2 * np.pi * u)), 0.0),
            np.where(inside, 2 * np.pi * h / dur**2 * np.sin(2 * np.pi * u), 0.0))


@pytest.mark.parametrize("backend", [pytest.param("c", marks=needs_cc)] + [pytest.param(b, marks=pytest.mark.slow)
                                                                    for b in ("reference", "numpy", "casadi")])  # c: quick
def test_tabled_driver_agrees_on_every_backend(tmp_path, backend) -> None:
    path = tabled_mechanism(tmp_path, 2e-3)
    reference = api.solve(path, backend="reference").data
    got = api.solve(path, backend=backend).data
    col = np.max(np.abs(reference), axis=0)
    scale = np.maximum(col, 1e-3 * np.max(col))
    # every backend solves the same equations to tol 1e-12: rounding of each column's scale
    assert np.max(np.abs(got - reference) / scale) <= 1e-12
