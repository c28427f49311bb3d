"""Numerical stability of the Python loop: the cond column and its warning,
singular and redundant Phi_q, damped Newton and divergence, branch tracking,
units (equilibration), long runs, and the near-singular stress cases against
a 40-digit reference (tests/helpers/stress.py). The long runs are in
`python -m benchmarks stability` (benchmarks/cases/stability.py)."""

from __future__ import annotations

import dataclasses
import math
import re
import tomllib
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

import stress
from symid import api
from symid.numeric import solve
from symid.numeric import stability
from symid.symbolic.assemble import assemble
from symid.cli import main
from symid.errors import AnalysisError
from symid.io.reader import load, loads
from truth import Truth, newton_euler_residual
from runshare import key_of, shared_value
from tiers import diagonal

EPS = np.finfo(float).eps
EXAMPLES = api.examples()
PYTHON_LOOP = ("reference", "numpy", "casadi")
SLIDER_CRANK = api.example("slider_crank")

# A parallelogram linkage with a third parallel crank: crank_c repeats what
# crank_a and crank_b already impose, so one of the 13 rows is redundant
# (ng = 12). The coupler translates on a circle: the motor torque is the
# gravity torque g cos(theta) L (3 m_c / 2 + m_k) exactly.
PARALLELOGRAM = """
[mechanism]
name = "parallelogram3"
gravity = [0.0, -9.81]

[parameters]
L = 0.2
b = 0.5
m_c = 0.4
m_k = 1.5
omega = 3.0

[analysis]
t1 = 1.0
steps = 21
{mode}

[[body]]
name = "crank_a"
mass = "m_c"
inertia = "m_c*L^2/12"
q0 = [0.0, "L/2", "pi/2"]

[[body]]
name = "crank_b"
mass = "m_c"
inertia = "m_c*L^2/12"
q0 = ["b", "L/2", "pi/2"]

[[body]]
name = "crank_c"
mass = "m_c"
inertia = "m_c*L^2/12"
q0 = ["2*b", "L/2", "pi/2"]

[[body]]
name = "coupler"
mass = "m_k"
inertia = "m_k*(2*b)^2/12"
q0 = ["b", "L", 0.0]
""" + "".join(f"""
[[constraint]]
name = "pivot_{n}"
type = "revolute"
i = "ground"
j = "crank_{n}"
si = ["{k}*b", 0.0]
sj = ["-L/2", 0.0]
""" for k, n in enumerate("abc")) + "".join(f"""
[[constraint]]
name = "pin_{n}"
type = "revolute"
i = "crank_{n}"
j = "coupler"
si = ["L/2", 0.0]
sj = ["{k - 1}*b", 0.0]
""" for k, n in enumerate("abc")) + """
[[constraint]]
name = "motor"
type = "relative_angle_driver"
i = "ground"
j = "crank_a"
f = "pi/2 + omega*t"
"""
LOOP_JOINTS = ("pivot_a", "pivot_b", "pivot_c", "pin_a", "pin_b", "pin_c")


def write(tmp_path: Path, text: str, name: str = "mech.toml") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def run_cli(capsys, *args: str) -> tuple[int, str, list[str]]:
    """(status, stdout, stderr lines) of `symid ARGS` run in process."""
    status = main(list(args))
    captured = capsys.readouterr()
    return status, captured.out, captured.err.splitlines()


def with_rod(length: str) -> str:
    """The bundled slider-crank with another connecting-rod length."""
    text = SLIDER_CRANK.read_text(encoding="utf-8")
    assert text.count("L_rod = 0.3 ") == 1
    return text.replace("L_rod = 0.3 ", f"L_rod = {length} ")


def read_csv(path: Path) -> tuple[list[str], np.ndarray]:
    lines = path.read_text().splitlines()
    return lines[0].split(","), np.array([[float(v) for v in ln.split(",")] for ln in lines[1:]]).reshape(
        len(lines) - 1, -1)


# -- 1. the cond column and its warning ------------------------------------------

def test_cond_is_the_last_column_and_the_estimate_of_each_instant():
    study = api.prepare(SLIDER_CRANK, "reference", steps=21, cond_column=True)
    columns = study.columns()
    assert columns[-1] == "cond" and columns.count("cond") == 1
    assert columns[:-1] == api.prepare(SLIDER_CRANK, "reference", steps=21).columns()
    results = study.solve()
    conds = [i.cond for i in study.instants()]
    assert np.array_equal(results["cond"], conds)
    assert np.all((results["cond"] > 1) & (results["cond"] < 100))


@pytest.mark.parametrize("backend", PYTHON_LOOP)
def test_cond_column_is_the_same_on_every_python_loop_backend(backend):
    base = api.prepare(SLIDER_CRANK, "reference", steps=11, outputs=["q", "cond"]).solve()
    other = api.prepare(SLIDER_CRANK, backend, steps=11, outputs=["q", "cond"]).solve()
    assert other.columns == ["t"] + [c for c in base.columns[1:]] and other.columns[-1] == "cond"
    # cond from the same matrices on another backend: the estimate's rounding, relative
    assert np.allclose(other["cond"], base["cond"], rtol=1e-9, atol=0)


def test_cli_cond_flag_appends_the_column(tmp_path, capsys):
    out = tmp_path / "out.csv"
    status, _, err = run_cli(capsys, "solve", str(SLIDER_CRANK), "-o", str(out), "--steps", "5", "--cond")
    assert status == 0 and err == []
    header, rows = read_csv(out)
    assert header[-1] == "cond" and rows.shape == (5, len(header))
    assert np.all(rows[:, -1] >= 1)


def test_cond_in_outputs_is_validated():
    with pytest.raises(Exception, match="unknown output 'condition'"):
        loads(SLIDER_CRANK.read_text().replace('steps = 201', 'steps = 5\noutputs = ["q", "condition"]'))
    mech = loads(SLIDER_CRANK.read_text().replace('steps = 201', 'steps = 5\noutputs = ["cond", "q"]'))
    assert mech.analysis.extra_outputs() == ("cond",) and mech.analysis.output_groups() == ("q",)


def test_ill_conditioning_warns_once_with_its_time_span(tmp_path, capsys):
    """Rod = crank (1 + 1e-6): near 90 degrees (t = 0.05 s) cond rises to ~1e3."""
    path = write(tmp_path, with_rod("0.1000001"))
    out = tmp_path / "out.csv"
    status, _, err = run_cli(capsys, "solve", str(path), "-o", str(out), "--cond", "--cond-warn", "300")
    assert status == 0, err
    header, rows = read_csv(out)
    t, cond = rows[:, 0], rows[:, -1]
    above = t[cond > 300]  # near 90 and 270 degrees: t = 0.05 and 0.15
    first, second = above[above < 0.1], above[above > 0.1]
    assert np.all(np.abs(first - 0.05) < 0.01) and np.all(np.abs(second - 0.15) < 0.01)
    assert len(err) == 1 and err[0].startswith("symid: warning: Phi_q is ill-conditioned"), err
    spans = [tuple(map(float, m)) for m in re.findall(r"\[([-0-9.e+]+), ([-0-9.e+]+)\]", err[0])]
    assert spans == [(first[0], first[-1]), (second[0], second[-1])]
    assert f"{above.size} instants" in err[0]
    results = api.solve(path, "reference", cond_warn=300)
    assert results.error is None and len(results.warnings) == 1 and "ill-conditioned" in results.warnings[0]


@pytest.mark.parametrize("name", EXAMPLES)  # one example per test: the big ones in the slow tier (tests/conftest.py)
def test_well_conditioned_examples_never_warn_nor_check_branches(monkeypatch, name):
    """The normal path: no warning, and the branch check never re-solves an instant."""
    calls = []
    monkeypatch.setattr(solve, "_continuation", lambda *a, **k: calls.append(a[3]))
    results = api.solve(api.example(name), "numpy")
    assert results.error is None and results.warnings == [], (name, results.warnings)
    assert calls == []


def test_singular_position_ends_the_run_with_exit_3_keeping_the_instants(tmp_path, capsys):
    """Rod = crank: at 90 degrees (t = 0.05 s) the rod is square to the guide."""
    path = write(tmp_path, with_rod("0.1"))
    out = tmp_path / "out.csv"
    status, _, err = run_cli(capsys, "solve", str(path), "-o", str(out), "--cond")
    assert status == 3
    assert re.search(r"t = 0\.05\d*: Phi_q is singular \(condition estimate [0-9.e+]+\); dependent constraints: "
                     r".*cylinder_guide", err[-1]), err
    header, rows = read_csv(out)
    assert rows.shape[0] == 50 and rows[-1, 0] < 0.05
    assert np.all(np.diff(rows[-10:, -1]) > 0), "cond rises towards the singular position"


@pytest.mark.parametrize("flag", [["--cond"], ["--cond-warn", "1e4"], ["--redundant", "min_norm"],
                                  ["--assembly-jump", "warn"]], ids=lambda f: f[0])
def test_c_backend_refuses_what_it_lacks_naming_the_backends_that_can(tmp_path, capsys, flag):
    out = tmp_path / "out.csv"
    status, _, err = run_cli(capsys, "solve", str(SLIDER_CRANK), "-o", str(out), "--backend", "c", *flag)
    assert status == 2 and len(err) == 1, err
    assert str(SLIDER_CRANK) in err[0] and "[analysis] key" in err[0] and "the c backend does not support" in err[0]
    assert all(b in err[0] for b in PYTHON_LOOP)
    assert not out.exists()


# -- 2. redundant constraints ---------------------------------------------------

@pytest.mark.parametrize("command", ["solve", "check"])
def test_redundant_rows_are_refused_naming_the_dependent_constraints(tmp_path, capsys, command):
    path = write(tmp_path, PARALLELOGRAM.format(mode=""))
    out = tmp_path / "out.csv"
    args = ["solve", str(path), "-o", str(out)] if command == "solve" else ["check", str(path)]
    status, _, err = run_cli(capsys, *args)
    assert status == 2 and len(err) == 1, err
    assert f"{path}: [[constraint]]: 13 constraint rows for 12 coordinates: 1 extra" in err[0]
    named = re.search(r"the rows of (.*) are dependent at t0 \(rank 12\)", err[0])
    assert named and tuple(named.group(1).split(", ")) == LOOP_JOINTS
    assert "motor" not in named.group(1) and 'redundant = "min_norm"' in err[0]
    assert not out.exists()


def _overdriven(extra_f: str) -> str:
    """The scotch yoke (one degree of freedom, its crank driven) with a second
    driver on the yoke's x: consistent with the crank at t0 or not."""
    import small_mechanisms as sm

    return sm.text("yoke", sm.CONSTRAINTS["scotch_yoke"] + sm._coordinate("yoke", "x", extra_f))


@pytest.mark.parametrize("command", ["solve", "check"])
@pytest.mark.parametrize("extra_f, holds", [("0.1 + 0.01*t", True), ("0.3", False)], ids=["holds", "contradicts"])
def test_a_driver_too_many_is_named_as_the_extra_one(tmp_path, capsys, command, extra_f, holds):
    """Two drivers on a one-degree-of-freedom linkage: the message names the
    driver whose removal leaves independent rows (drive_x: without the motor
    the yoke's x at dead centre does not fix the crank), not the largest
    residuals of a failed assembly nor only the dependent rows."""
    path = write(tmp_path, _overdriven(extra_f))
    args = ["solve", str(path), "-o", str(tmp_path / "o.csv")] if command == "solve" else ["check", str(path)]
    status, _, err = run_cli(capsys, *args)
    assert status == 2 and len(err) == 1, err
    assert "7 constraint rows for 6 coordinates: 1 extra: driver drive_x is one too many (without it" in err[0]
    assert ("the rows of crank_pin, slot, drive_x are dependent at t0" in err[0]) == holds
    assert ("the rows cannot all hold at t0" in err[0]) == (not holds)


def test_two_drivers_of_one_angle_name_the_later_and_the_other(tmp_path, capsys):
    import small_mechanisms as sm

    text = sm.text("two", sm.PENDULUM_PARTS + sm._constraint("drive2", "relative_angle_driver", i='"ground"',
                                                              j='"bar"', f='"2*t"'))
    status, _, err = run_cli(capsys, "solve", str(write(tmp_path, text)), "-o", str(tmp_path / "o.csv"))
    assert status == 2 and len(err) == 1, err
    assert "1 extra: driver drive2 is one too many (or drive: each alone drives" in err[0]


@pytest.mark.parametrize("target", ["c", "numpy", "casadi"])
@pytest.mark.parametrize("mode", ["", 'redundant = "min_norm"'], ids=["error", "min_norm"])
def test_generated_solvers_refuse_redundant_rows(tmp_path, capsys, target, mode):
    """Every generated solver factors a square Phi_q."""
    path = write(tmp_path, PARALLELOGRAM.format(mode=mode))
    status, _, err = run_cli(capsys, "generate", str(path), "--target", target, "-o", str(tmp_path / "gen"))
    assert status == 2 and len(err) == 1, err
    assert "1 extra: the rows of " + ", ".join(LOOP_JOINTS) + " are dependent" in err[0]
    assert "generated solvers need as many rows as coordinates" in err[0]


def test_check_reports_the_redundant_rows_under_min_norm(tmp_path, capsys):
    path = write(tmp_path, PARALLELOGRAM.format(mode='redundant = "min_norm"'))
    status, out, err = run_cli(capsys, "check", str(path))
    assert status == 0 and err == []
    assert "rank of Phi_q = 12 of 12" in out and "redundant constraints" in out
    assert all(j in out for j in LOOP_JOINTS) and "motor" not in out.splitlines()[-1]


@pytest.fixture(scope="module")
def parallelogram(tmp_path_factory):
    path = write(tmp_path_factory.mktemp("para"), PARALLELOGRAM.format(mode='redundant = "min_norm"'))
    return path, {b: api.prepare(path, b).solve() for b in PYTHON_LOOP}


def test_min_norm_gives_the_exact_motor_torque_and_kinematics(parallelogram):
    path, results = parallelogram
    res = results["reference"]
    assert res.error is None and res.data.shape[0] == 21
    L, b, m_c, m_k, w, g = 0.2, 0.5, 0.4, 1.5, 3.0, 9.81
    theta = math.pi / 2 + w * res.t
    # The run passes 0.07 rad from theta = pi (t = 0.5), where the three cranks
    # lie flat and have a first-order mobility: Phi_q's condition number kappa
    # rises from 26 to 336 there. The rates carry ~kappa eps and the
    # accelerations are solved from gamma(q, qd), so they and the torque carry
    # ~kappa^2 eps of their scale (measured at most 0.012 kappa^2 eps, 5e-13 of
    # ay at t = 0.5): a fixed 1e-12 failed by 1.3e-12 with another LAPACK.
    study = api.prepare(path, "reference")
    ng = study.layout.ng
    kappa = np.array([np.linalg.cond(study.evaluator.phi_q(row[1:1 + ng], row[0])) for row in res.data])
    bound = kappa**2 * np.finfo(float).eps
    torque = g * L * (1.5 * m_c + m_k)
    assert np.all(np.abs(res["motor.T_j"] - torque * np.cos(theta)) <= bound * torque)
    # the parallel cranks' closed form in coordinates of order 1: rounding
    assert np.allclose(res["coupler.x"], b + L * np.cos(theta), rtol=0, atol=1e-14)
    assert np.all(np.abs(res["coupler.ay"] + w**2 * L * np.sin(theta)) <= bound * w**2 * L)
    for crank in ("crank_a", "crank_b", "crank_c"):
        assert np.allclose(res[f"{crank}.phi"], theta, rtol=0, atol=1e-14)
    mech = load(path)
    for body, (force, moment) in newton_euler_residual(Truth(mech, res)).items():
        # Newton-Euler of a tol 1e-12 solve: rounding of loads of order 1 N
        assert force < 1e-12 and moment < 1e-12, body


def test_min_norm_multipliers_have_no_self_stress_component(parallelogram):
    """lambda is orthogonal to the left null space of Phi_q: no other solution is shorter."""
    path, results = parallelogram
    study = api.prepare(path, "reference")
    lam_cols = [c for c in results["reference"].columns if ".lambda" in c]
    for instant, lam in zip(study.instants(), results["reference"].block(lam_cols)):
        jac = study.evaluator.phi_q(instant.q, instant.t)
        u, sv, _ = np.linalg.svd(jac)
        null = u[:, -1]
        # the multipliers have no component along the redundant direction: zero to rounding of |lam|
        assert abs(null @ lam) <= 1e-12 * np.linalg.norm(lam)
        assert abs(null[study.layout.row_of["motor"][0]]) < 1e-12  # the motor's row is not in it


def test_min_norm_warns_that_the_loop_reactions_are_not_unique(parallelogram, tmp_path, capsys):
    path, results = parallelogram
    warning = results["reference"].warnings
    assert len(warning) == 1 and all(j in warning[0] for j in LOOP_JOINTS)
    assert "not unique" in warning[0] and "drive torques" in warning[0]
    status, _, err = run_cli(capsys, "solve", str(path), "-o", str(tmp_path / "o.csv"))
    assert status == 0 and len(err) == 1 and err[0].startswith("symid: warning: redundant constraints")


@pytest.mark.parametrize("backend", PYTHON_LOOP[1:])
def test_min_norm_agrees_on_every_python_loop_backend(parallelogram, backend):
    _, results = parallelogram
    base, other = results["reference"], results[backend]
    assert other.error is None
    scale = np.maximum(np.abs(base.data).max(axis=0), 1e-2 * np.abs(base.data).max())
    # the same run with equilibration: rounding of each column's scale
    assert np.max(np.abs(other.data - base.data) / scale) < 1e-10


def test_rank_deficient_square_check_reports_rank_and_exits_3(tmp_path, capsys):
    """The motor replaced by a copy of the guide's y row: nc = ng, rank ng - 1."""
    text = SLIDER_CRANK.read_text().replace(
        'type = "relative_angle_driver"\ni = "ground"\nj = "crank"\nf = "omega*t"',
        'type = "coordinate_driver"\nbody = "slider"\ncoordinate = "y"\nf = "0"')
    path = write(tmp_path, text)
    status, out, err = run_cli(capsys, "check", str(path))
    assert status == 3 and "rank of Phi_q = 8 of 9" in out
    assert len(err) == 1 and "rank-deficient" in err[0] and "cylinder_guide" in err[0] and "motor" in err[0]


# -- 3. robust position solve -----------------------------------------------------

class _Atan:
    """Phi = [atan(x - 2), y, phi]: undamped Newton from x = 3.5 diverges."""

    def __init__(self) -> None:
        self.layout = assemble(loads(SINGLE_BODY))

    def phi(self, q, t):
        return np.array([math.atan(q[0] - 2), q[1], q[2]])

    def phi_q(self, q, t):
        return np.diag([1 / (1 + (q[0] - 2) ** 2), 1.0, 1.0])


SINGLE_BODY = """
[mechanism]
name = "one"
[[body]]
name = "b"
mass = 1
inertia = 1
q0 = [0, 0, 0]
[[constraint]]
name = "cx"
type = "coordinate_driver"
body = "b"
coordinate = "x"
f = 0
[[constraint]]
name = "cy"
type = "coordinate_driver"
body = "b"
coordinate = "y"
f = 0
[[constraint]]
name = "cphi"
type = "coordinate_driver"
body = "b"
coordinate = "phi"
f = 0
"""


def test_damped_newton_converges_where_the_full_step_diverges():
    ev = _Atan()
    x = 3.5
    for _ in range(5):  # plain Newton runs away: |x - 2| grows every step
        x_new = x - math.atan(x - 2) * (1 + (x - 2) ** 2)
        assert abs(x_new - 2) > abs(x - 2)
        x = x_new
    q, iterations = solve.newton(ev, np.array([3.5, 0.0, 0.0]), 0.0, 1e-12)
    # damped Newton to tol 1e-12: q to the tolerance
    assert abs(q[0] - 2) < 1e-12 and iterations < 20


def test_iteration_limit_is_reported():
    with pytest.raises(AnalysisError, match=r"did not converge in 2 iterations .* largest residuals in: cx"):
        solve.newton(_Atan(), np.array([3.5, 0.0, 0.0]), 0.0, 1e-12, max_iterations=2)


def test_divergence_is_reported_with_time_and_constraints_keeping_the_instants(tmp_path, capsys):
    """Rod (0.05) shorter than the crank: past 30 degrees (t = 1/60 s) no position exists."""
    path = write(tmp_path, with_rod("0.05"))
    out = tmp_path / "out.csv"
    status, _, err = run_cli(capsys, "solve", str(path), "-o", str(out))
    assert status == 3 and len(err) == 1, err
    m = re.search(r"t = ([0-9.]+): Newton did not converge: diverging, .*largest residuals in: (.*); the (\d+) "
                  r"instants before it", err[0])
    assert m, err[0]
    assert float(m.group(1)) == pytest.approx(0.017) and set(m.group(2).split(", ")) <= {
        "crank_pin", "wrist_pin", "cylinder_guide"}
    assert read_csv(out)[1].shape[0] == int(m.group(3)) == 17


def test_a_step_too_long_for_the_predictor_is_recovered_by_sub_steps():
    """3 instants over the excavator's dig cycle: Newton from the Taylor guess
    diverges at the second; the continuation in sub-steps solves it."""
    coarse = api.solve(api.example("excavator"), "reference", steps=3, assembly_jump="warn")
    fine = api.solve(api.example("excavator"), "reference", steps=201)
    assert coarse.data.shape[0] == 3
    # the coarse step's instant is the fine run's: both to tol 1e-12, 1e-9 in q of order 1
    assert np.allclose(coarse.data[1, :40], fine.data[100, :40], rtol=0, atol=1e-9)


# -- branch tracking -------------------------------------------------------------

def test_assembly_mode_jump_stops_with_exit_3(tmp_path, capsys):
    """Three instants over a four-bar's crank revolution: at half a turn a
    step, Newton lands on the crossed assembly at the first step already; the
    motion is not what the rates at both ends explain, and the continuation
    in sub-steps ends elsewhere."""
    out = tmp_path / "out.csv"
    status, _, err = run_cli(capsys, "solve", str(api.example("four_bar")), "-o", str(out), "--steps", "3")
    assert status == 3 and len(err) == 1, err
    assert re.search(r"t = 0\.25: assembly mode jump: the step moved q by [0-9.]+ \(scaled\), not what the rates "
                     r"at both ends explain, continuing the previous instant in 16 sub-steps ends "
                     r"[0-9.]+ away; take more steps", err[0]), err[0]
    assert read_csv(out)[1].shape[0] == 1


def test_allowed_jump_continues_and_warns_once(tmp_path, capsys):
    out = tmp_path / "out.csv"
    status, _, err = run_cli(capsys, "solve", str(api.example("four_bar")), "-o", str(out), "--steps", "3",
                             "--assembly-jump", "warn")
    assert status == 0 and len(err) == 1
    assert err[0].startswith("symid: warning: assembly mode jump at 2 instants, t in [0.25, 0.5]")
    assert read_csv(out)[1].shape[0] == 3


def test_a_poor_prediction_on_the_same_branch_is_not_a_jump(monkeypatch):
    """Four instants over the slider-pendulum's period: a correction larger than
    the predicted motion, but the sub-step continuation agrees."""
    calls = []
    original = solve._continuation
    monkeypatch.setattr(solve, "_continuation", lambda *a, **k: calls.append(1) or original(*a, **k))
    results = api.solve(api.example("slider_pendulum"), "reference", steps=4)
    assert results.error is None and results.warnings == [] and calls


# -- 4. units ---------------------------------------------------------------------

# the dimension of each key: (length power, mass power); forces are M L, torques M L^2
_LEN, _FORCE, _TORQUE, _MASS = (1, 0), (1, 1), (2, 1), (0, 1)
KEY_DIMENSION = {"si": _LEN, "sj": _LEN, "s": _LEN, "length": _LEN, "L0": _LEN, "radius_i": _LEN,
                 "radius_j": _LEN, "F": _FORCE, "fa": _FORCE, "T": _TORQUE, "Ta": _TORQUE}
TYPE_DIMENSION = {("spring_damper", "k"): _MASS, ("spring_damper", "c"): _MASS,
                  ("rotational_spring_damper", "k"): _TORQUE, ("rotational_spring_damper", "c"): _TORQUE,
                  ("distance_driver", "f"): _LEN, ("translational_driver", "f"): _LEN,
                  ("rack_and_pinion", "r"): _LEN, ("rack_and_pinion", "C"): _LEN}


# lengths written into expression rows by name (disc_cam's pitch curve): scaled where the rows use them
ROW_LENGTHS = ("R0", "h")


def _rows_scaled(rows: list[str], u: float) -> list[str]:
    import re

    return [re.sub(r"\b(" + "|".join(ROW_LENGTHS) + r")\b", lambda m: f"({m.group(1)}*{u!r})", r) for r in rows]


def _scaled(value, dim: tuple[int, int], u: float, m: float):
    factor = u ** dim[0] * m ** dim[1]
    if dim == (0, 0):
        return value
    if isinstance(value, list):
        return [_scaled(v, dim, u, m) for v in value]
    return f"({value})*{factor!r}"


def in_units(text: str, u: float, m: float) -> str:
    """The mechanism with lengths times u and masses times m (seconds kept)."""
    data = tomllib.loads(text)
    data["mechanism"]["gravity"] = _scaled(data["mechanism"].get("gravity", [0, 0]), _LEN, u, m)
    for body in data["body"]:
        body["mass"] = _scaled(body["mass"], _MASS, u, m)
        body["inertia"] = _scaled(body["inertia"], (2, 1), u, m)
        body["q0"] = _scaled(body["q0"][:2], _LEN, u, m) + [body["q0"][2]]
    for element in data.get("constraint", []) + data.get("force", []):
        for key in element:
            dim = TYPE_DIMENSION.get((element["type"], key), KEY_DIMENSION.get(key, (0, 0)))
            if element["type"] == "coordinate_driver" and key == "f" and element["coordinate"] != "phi":
                dim = _LEN
            element[key] = (_rows_scaled(element[key], u) if (element["type"], key) == ("expression", "phi")
                            else _scaled(element[key], dim, u, m))
        if "friction" in element:  # contract v1.1: a pin's viscous is a torque per rad/s, a slide's a force per m/s
            pin = element["type"] == "revolute"
            dims = {"radius": _LEN, "arm": _LEN, "viscous": _TORQUE if pin else _MASS,
                    "v_smooth": (0, 0) if pin else _LEN}
            element["friction"] = {k: _scaled(v, dims.get(k, (0, 0)), u, m) for k, v in element["friction"].items()}
    return _toml(data)


def _toml(data: dict) -> str:
    def value(v) -> str:
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, list):
            return "[" + ", ".join(value(x) for x in v) + "]"
        if isinstance(v, dict):
            return "{ " + ", ".join(f"{k} = {value(x)}" for k, x in v.items()) + " }"
        return repr(v) if isinstance(v, float) else f'"{v}"' if isinstance(v, str) else str(v)

    out = []
    for section, content in data.items():
        tables = content if isinstance(content, list) else [content]
        for table in tables:
            out.append(f"[[{section}]]" if isinstance(content, list) else f"[{section}]")
            out += [f"{k} = {value(v)}" for k, v in table.items()]
    return "\n".join(out) + "\n"


def _unit_of(column: str) -> tuple[str, tuple[int, int]]:
    """(kind, dimension) of a results column; lambda columns are not compared."""
    suffix = column.split(".")[-1]
    if suffix in ("x", "y", "vx", "vy", "ax", "ay"):
        return "length", _LEN
    if suffix in ("phi", "omega", "alpha"):
        return "angle", (0, 0)
    if suffix[:2] in ("Fx", "Fy"):
        return "force", _FORCE
    if suffix[:2] == "T_":
        return "torque", _TORQUE
    return "other", (0, 0)


def _in_own_units(tmp_path_factory, text: str):
    """The file in its own units (in_units by 1, 1) solved: the same for the
    three unit cases of an example, so solved once per run (any worker)."""
    def solve_base():
        folder = tmp_path_factory.mktemp("own-units")
        return api.solve(write(folder, in_units(text, 1.0, 1.0), "a.toml"), "reference", steps=41, cond_column=True)

    return shared_value(tmp_path_factory, key_of("own-units", text, 41), solve_base)


@pytest.mark.parametrize("name, units", diagonal(EXAMPLES, ["mm", "mass1e6", "both"]))
def test_other_units_give_the_same_results_to_1e_12(tmp_path, tmp_path_factory, name, units):
    u, m = {"mm": (1000.0, 1.0), "mass1e6": (1.0, 1e6), "both": (1000.0, 1e6)}[units]
    text = api.example(name).read_text(encoding="utf-8")
    base = _in_own_units(tmp_path_factory, text)
    other = api.solve(write(tmp_path, in_units(text, u, m), "b.toml"), "reference", steps=41, cond_column=True)
    assert base.error is None and other.error is None
    kinds: dict[str, list[int]] = {}
    for k, column in enumerate(base.columns[1:], start=1):
        kinds.setdefault(_unit_of(column)[0], []).append(k)
    for kind, cols in kinds.items():
        if kind == "other":
            continue
        dim = _unit_of(base.columns[cols[0]])[1]
        converted = other.data[:, cols] / (u ** dim[0] * m ** dim[1])
        scale = np.max(np.abs(base.data[:, cols]))
        # units converted back: rounding of the conversion factors, relative to the peak
        assert np.max(np.abs(converted - base.data[:, cols])) <= 1e-12 * scale, (kind, name)
    # power-of-two scales: within a factor ~2; and LAPACK's gecon is a lower-bound
    # estimate that can land on another local maximum when the scales change (the
    # Andrews squeezer: 14 or 33 at neighbouring instants, its exact 1-norm cond 34)
    assert np.all(np.abs(np.log(other["cond"] / base["cond"])) <= np.log(3.0))


@pytest.mark.parametrize("tol", [1e-12, 1e-6])
def test_millimetre_newton_makes_the_same_decisions(tol):
    """Iteration counts are unit-free: the tol measure is equilibrated."""
    text = api.example("four_bar").read_text(encoding="utf-8")
    counts = []
    for u in (1.0, 1000.0, 1e-3):
        mech = loads(in_units(text, u, 1.0))
        study = api.prepare(mech, "reference", steps=21, tol=tol)
        counts.append([i.iterations for i in study.instants()])
    assert counts[0] == counts[1] == counts[2]


# -- 5. long runs ----------------------------------------------------------------

@pytest.fixture(scope="module")
def slider_crank_torque():
    """The bundled slider-crank's motor torque by the power method, sympy -> mpmath."""
    mech = load(SLIDER_CRANK)
    p = {k.name: v for k, v in api.prepare(mech, "reference").values.items()}
    t = sp.Symbol("t")
    r, l, w = (sp.Float(p[k], 30) for k in ("L_crank", "L_rod", "omega"))
    m1, m2, m3 = (sp.Float(p[k], 30) for k in ("m_crank", "m_rod", "m_slider"))
    th = w * t
    pin = sp.Matrix([r * sp.cos(th), r * sp.sin(th)])
    slider = sp.Matrix([r * sp.cos(th) + sp.sqrt(l**2 - r**2 * sp.sin(th) ** 2), 0])
    rod = sp.atan2(-r * sp.sin(th), slider[0] - pin[0])
    centres = [(m1, pin / 2), (m2, (pin + slider) / 2), (m3, slider)]
    kinetic = sum(m * (c.diff(t).T * c.diff(t))[0] for m, c in centres) / 2
    kinetic += (m1 * r**2 / 12 * w**2 + m2 * l**2 / 12 * rod.diff(t) ** 2) / 2
    power = sum(-m * 9.81 * c[1].diff(t) for m, c in centres) - p["F_gas"] * sp.sin(th) * slider[0].diff(t)
    return sp.lambdify(t, (kinetic.diff(t) - power) / w, "mpmath")


@pytest.mark.parametrize("backend", ("numpy", "c"))
def test_angles_past_1e4_rad_lose_only_what_the_angle_explains(slider_crank_torque, backend):
    """Two revolutions from 1592 turns (1.0003e4 rad): the motor torque
    against the 40-digit closed form at the same (double) times. On `c` the
    compiled trajectory rotates its sines and cosines from earlier angles,
    where the angle's own rounding (1.8e-12 rad) is what they must follow."""
    import mpmath

    from symid.output.results import Results, row, table_rows
    from symid.numeric.stability import Notes

    t0 = 1592 / 5  # 1592 turns at 5 rev/s
    study = api.prepare(SLIDER_CRANK, backend, t0=t0, t1=t0 + 0.4, steps=401)
    q0 = study.q0()
    q0[2] = 2 * math.pi * 1592  # the crank's angle; the rest of q0 is the same position
    if backend == "c":
        rows = list(table_rows(study.evaluator, study.analysis, q0, Notes(study.analysis)))
    else:
        rows = [row(i, study.layout, study.analysis) for i in solve.run(study.evaluator, study.analysis, q0)]
    results = Results(study.columns(), np.array(rows))
    assert results["crank.phi"][0] > 1e4
    with mpmath.workdps(40):
        expected = np.array([float(slider_crank_torque(mpmath.mpf(t))) for t in results.t])
    scale = np.max(np.abs(expected))
    # the angle itself carries 1e4 eps of rounding; the torque's slope is ~ omega scale
    assert np.max(np.abs(results["motor.T_j"] - expected)) <= 50 * 1e4 * EPS * scale


def test_streaming_memory_does_not_grow_with_the_instants(tmp_path):
    """Python's allocated blocks, sampled at every instant while a run streams
    to a CSV, peak at the same count for 10 times the instants."""
    import sys

    from symid.output.results import write_csv

    def sampled(rows, peak):
        for r in rows:
            peak[0] = max(peak[0], sys.getallocatedblocks())
            yield r

    # both prepared first: each prepare leaves a few hundred blocks in bounded
    # caches (sympy's, the model's facts), which is not what this measures
    studies = {steps: api.prepare(SLIDER_CRANK, "numpy", t1=0.2 * steps / 200, steps=steps) for steps in (2000, 200)}
    peaks = []
    for steps in (2000, 200, 2000):  # the first fills Python's free lists
        study = studies[steps]
        peak = [0]
        assert write_csv(tmp_path / "run.csv", study.columns(), sampled(study.rows(), peak)) == steps
        peaks.append(peak[0])
    assert peaks[2] < peaks[1] + 500, peaks  # a list of the times alone would hold 1800 more


# -- 6. stress: near-singular cases against 40 digits ------------------------------

@pytest.fixture(scope="module")
def stress_studies(tmp_path_factory):
    folder = tmp_path_factory.mktemp("stress")
    return {name: write(folder, fam.text, f"{name}.toml") for name, fam in stress.FAMILIES.items()}


@pytest.mark.parametrize("name, ks", [("slider_crank", range(1, 9)),
                                      pytest.param("four_bar_toggle", range(1, 11, 3), marks=pytest.mark.slow)])  # 34 s
def test_torque_error_near_singular_positions_stays_within_the_conditioning(stress_studies, name, ks):
    """err <= C cond^2 eps, and <= C kappa eps with kappa the torque's own
    relative condition number (40-digit derivative w.r.t. the angle and lengths)."""
    rows = []
    for k in ks:
        case = stress.solve_case(name, k, stress_studies[name], "reference")
        rows.append((k, case.cond, case.error, case.kappa))
        assert case.error <= 20 * case.kappa * EPS + 4 * EPS, (name, k, case)
        assert case.error <= 2 * case.cond**2 * EPS + 4 * EPS, (name, k, case)
    conds = [r[1] for r in rows]
    assert all(b > a for a, b in zip(conds, conds[1:])), "cond grows towards the singularity"


def balanced_crank(e: str):
    """stress.SLIDER_CRANK as a crank of 0.1 m, a rod of 0.3 m, its crank's
    centre of mass `e` from the bearing, turning from 0 at 10 rad/s for 0.2 s
    (the default outputs: the c backend has no cond column)."""
    values = {"r": "0.1", "eps": "2", "e": e, "th": "0", "omega": "10", "m1": "0.5", "m2": "1", "m3": "0.8"}
    mech = loads(stress.SLIDER_CRANK, "balanced.toml", values, {"t1": 0.2, "steps": 21})
    return dataclasses.replace(mech, analysis=dataclasses.replace(mech.analysis, outputs=None))


@pytest.mark.parametrize("backend", ["numpy", "c"])
def test_a_pin_at_a_centre_of_mass_is_no_length_scale(backend):
    """A crank balanced to within 1e-7 m of its bearing: that vanishing moment
    arm once became the reference length, scaled a well-conditioned Phi_q
    (cond 12) to 3e6 and reported the mechanism singular part-way. Its torques
    must approach those of the exactly balanced crank continuously."""
    exact = api.solve(balanced_crank("0"), backend=backend)
    near = api.solve(balanced_crank("1e-7"), backend=backend)
    assert exact.error is None and near.error is None, near.error
    assert not near.warnings, near.warnings
    peak = np.max(np.abs(exact["motor.T_j"]))
    # the crank 1e-7 m off balance: the torque moves by that arm times the loads, below 1e-5 of the peak
    assert np.max(np.abs(near["motor.T_j"] - exact["motor.T_j"])) <= 1e-5 * peak
    jac = np.array([[1, 0, 4e-18], [0, 1, -6.7e-8], [0, 1, 0.15]])
    assert stability.Scaling.of(jac, np.zeros(3)).lref == pytest.approx(0.15)
