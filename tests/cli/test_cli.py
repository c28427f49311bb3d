"""The command-line contract: `symid solve` and `symid check`, exit statuses,
the results table (CSV) and its atomic write.

See /work/shared/reference/mechanism-file.md ("contract v1").
"""

from __future__ import annotations

import math
import os
import re
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from cli_files import EXAMPLES, SLIDER_CRANK, base_text, read_csv, set_line, with_analysis
from symid import api
from symid.cli import main

REPO = Path(__file__).resolve().parents[2]
# Rows of each constraint type (planar-inverse-dynamics.md); every other type has 1.
ROWS = {"revolute": 2, "translational": 2}

BODIES = ("crank", "connecting_rod", "slider")
CONSTRAINTS = (("main_bearing", 2), ("crank_pin", 2), ("wrist_pin", 2), ("cylinder_guide", 2), ("motor", 1))
REACTION_SUFFIXES = ("Fx_i", "Fy_i", "T_i", "Fx_j", "Fy_j", "T_j")


def q_columns(bodies=BODIES):
    return [f"{b}.{c}" for b in bodies for c in ("x", "y", "phi")]


def qdot_columns(bodies=BODIES):
    return [f"{b}.{c}" for b in bodies for c in ("vx", "vy", "omega")]


def qddot_columns(bodies=BODIES):
    return [f"{b}.{c}" for b in bodies for c in ("ax", "ay", "alpha")]


def lambda_columns(constraints=CONSTRAINTS):
    out = []
    for name, rows in constraints:
        out += [f"{name}.lambda"] if rows == 1 else [f"{name}.lambda{k + 1}" for k in range(rows)]
    return out


def reaction_columns(names=tuple(c for c, _ in CONSTRAINTS)):
    return [f"{c}.{s}" for c in names for s in REACTION_SUFFIXES]


ALL_COLUMNS = (["t"] + q_columns() + qdot_columns() + qddot_columns() + lambda_columns()
               + reaction_columns())


def edited(*pairs: str) -> str:
    """The bundled slider-crank with each `old` (occurring once) replaced by `new`."""
    text = base_text()
    for old, new in zip(pairs[::2], pairs[1::2]):
        assert text.count(old) == 1, f"{old!r} occurs {text.count(old)} times in {SLIDER_CRANK}"
        text = text.replace(old, new)
    return text


def column(header: list[str], rows: list[list[str]], name: str) -> list[float]:
    k = header.index(name)
    return [float(r[k]) for r in rows]


def solve(tmp_path: Path, capsys, text_or_path, *extra: str, out: Path | None = None):
    """Run `symid solve` in process; returns (status, stdout, stderr, output path)."""
    if isinstance(text_or_path, Path):
        path = text_or_path
    else:
        path = tmp_path / "mech.toml"
        path.write_text(text_or_path, encoding="utf-8")
    out = out or tmp_path / "out.csv"
    status = main(["solve", str(path), "-o", str(out), *extra])
    captured = capsys.readouterr()
    return status, captured.out, captured.err, out


def assert_one_line(err: str) -> str:
    assert "Traceback" not in err
    assert err.endswith("\n") and err.count("\n") == 1, f"stderr is not one line: {err!r}"
    return err.strip()


def no_temporaries(folder: Path) -> None:
    assert not list(folder.glob(".*.tmp")), f"temporary files left in {folder}"
    assert not list(folder.glob("*.tmp"))


# -- solve: the results table ---------------------------------------------------

@pytest.fixture(scope="module")
def bundled_run(tmp_path_factory):
    folder = tmp_path_factory.mktemp("bundled")
    out = folder / "slider_crank_out.csv"
    status = main(["solve", str(SLIDER_CRANK), "-o", str(out)])
    return status, out


def test_bundled_slider_crank_solves_with_exit_0(bundled_run):
    status, out = bundled_run
    assert status == 0
    assert out.is_file()
    no_temporaries(out.parent)


def test_header_is_t_then_every_group_in_contract_order(bundled_run):
    header, _ = read_csv(bundled_run[1])
    assert header == ALL_COLUMNS


def test_one_row_per_step_at_the_contract_instants(bundled_run):
    analysis = tomllib.loads(base_text())["analysis"]
    t0, t1, steps = analysis.get("t0", 0.0), analysis.get("t1", 1.0), analysis.get("steps", 1001)
    header, rows = read_csv(bundled_run[1])
    assert len(rows) == steps
    assert all(len(r) == len(header) for r in rows)
    t = column(header, rows, "t")
    for k, tk in enumerate(t):
        assert tk == pytest.approx(t0 + k * (t1 - t0) / (steps - 1), rel=0, abs=1e-15)
    assert t[0] == t0
    assert t[-1] == pytest.approx(t1, rel=1e-15)


def test_numbers_have_17_significant_digits_and_round_trip(bundled_run):
    _, rows = read_csv(bundled_run[1])
    seen_long = False
    for r in rows:
        for field in r:
            value = float(field)
            assert math.isfinite(value)
            assert "%.17g" % value == field, field
            assert float("%.17g" % value) == value
            digits = re.sub(r"e.*|[^0-9]", "", field.lower()).lstrip("0")
            seen_long |= len(digits) == 17
    assert seen_long, "no value was written with 17 significant digits"


def test_results_follow_the_driver(bundled_run):
    """Sanity of the numbers: the crank turns at omega = 2 pi n, the motor works."""
    params = tomllib.loads(base_text())["parameters"]
    omega = 2 * math.pi * params["n"]
    header, rows = read_csv(bundled_run[1])
    t, phi = column(header, rows, "t"), column(header, rows, "crank.phi")
    for tk, pk in zip(t, phi):
        assert pk == pytest.approx(omega * tk, abs=1e-9)
    assert all(w == pytest.approx(omega) for w in column(header, rows, "crank.omega"))
    assert max(abs(v) for v in column(header, rows, "motor.T_j")) > 0


def test_default_output_is_name_csv_in_current_folder(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["solve", str(SLIDER_CRANK), "--steps", "3"]) == 0
    capsys.readouterr()
    name = tomllib.loads(base_text())["mechanism"]["name"]
    out = tmp_path / f"{name}.csv"
    assert out.is_file()
    header, rows = read_csv(out)
    assert header == ALL_COLUMNS
    assert len(rows) == 3
    assert sorted(p.name for p in tmp_path.iterdir()) == [f"{name}.csv"]


def test_steps_and_t1_on_the_command_line(tmp_path, capsys):
    status, _, err, out = solve(tmp_path, capsys, SLIDER_CRANK, "--steps", "5", "--t1", "0.1")
    assert status == 0, err
    header, rows = read_csv(out)
    assert column(header, rows, "t") == pytest.approx([0.0, 0.025, 0.05, 0.075, 0.1], abs=1e-15)


def test_single_step_is_the_instant_t0(tmp_path, capsys):
    status, _, err, out = solve(tmp_path, capsys, SLIDER_CRANK, "--steps", "1")
    assert status == 0, err
    header, rows = read_csv(out)
    assert len(rows) == 1 and float(rows[0][0]) == 0.0


def test_kind_statics_has_no_rate_columns_by_default(tmp_path, capsys):
    status, _, err, out = solve(tmp_path, capsys, SLIDER_CRANK, "--kind", "statics", "--steps", "5")
    assert status == 0, err
    header, rows = read_csv(out)
    assert header == ["t"] + q_columns() + lambda_columns() + reaction_columns()
    assert len(rows) == 5


def test_kind_statics_rate_columns_asked_for_are_zero(tmp_path, capsys):
    text = with_analysis(base_text(), 'outputs = ["q", "qdot", "qddot", "lambda", "reactions"]')
    status, _, err, out = solve(tmp_path, capsys, text, "--kind", "statics", "--steps", "5")
    assert status == 0, err
    header, rows = read_csv(out)
    assert header == ALL_COLUMNS
    for name in qdot_columns() + qddot_columns():
        assert column(header, rows, name) == [0.0] * 5
    # statics still positions the mechanism and loads the motor (gravity, gas load)
    assert column(header, rows, "crank.phi")[-1] != 0.0




def backend_params(**xfail: str) -> list:
    """Every backend (numpy, c, casadi, reference): output shapes and failures
    must not depend on the backend. `xfail`: backend -> the known bug that
    makes it fail (a strict xfail, so that the fix is noticed)."""
    return [pytest.param(b, marks=pytest.mark.xfail(strict=True, reason=xfail[b])) if b in xfail else b
            for b in ("numpy", "c", "casadi", "reference")]


def skip_unknown_backend(backend: str) -> None:
    from symid import backends
    if backend not in backends.names():
        pytest.skip(f"no backend {backend}")
    if backend == "c" and shutil.which(os.environ.get("CC") or "cc") is None:
        pytest.skip("no C compiler")


@pytest.mark.parametrize("backend", backend_params())
def test_kind_kinematics_has_no_lambda_or_reaction_columns(tmp_path, capsys, backend):
    skip_unknown_backend(backend)
    status, _, err, out = solve(tmp_path, capsys, SLIDER_CRANK, "--kind", "kinematics", "--steps", "11",
                                "--backend", backend)
    assert status == 0, err
    header, rows = read_csv(out)
    assert header == ["t"] + q_columns() + qdot_columns() + qddot_columns()
    assert not any("lambda" in c or ".F" in c or ".T_" in c for c in header)
    # same motion as inverse dynamics
    status, _, err, out2 = solve(tmp_path, capsys, SLIDER_CRANK, "--steps", "11", out=tmp_path / "id.csv")
    assert status == 0, err
    header2, rows2 = read_csv(out2)
    for name in q_columns() + qdot_columns() + qddot_columns():
        assert column(header, rows, name) == pytest.approx(column(header2, rows2, name), rel=1e-12, abs=1e-12)


def test_kind_in_file_is_overridden_by_command_line(tmp_path, capsys):
    text = set_line(base_text(), "kind", '"kinematics"')
    status, _, err, out = solve(tmp_path, capsys, text, "--kind", "inverse_dynamics", "--steps", "3")
    assert status == 0, err
    assert read_csv(out)[0] == ALL_COLUMNS


def test_angles_are_not_wrapped(tmp_path, capsys):
    """Two crank revolutions: phi keeps growing past 2 pi."""
    status, _, err, out = solve(tmp_path, capsys, SLIDER_CRANK, "--t1", "0.4", "--steps", "41")
    assert status == 0, err
    header, rows = read_csv(out)
    phi = column(header, rows, "crank.phi")
    assert phi[-1] == pytest.approx(4 * math.pi, rel=1e-9)
    assert all(b > a for a, b in zip(phi, phi[1:]))


def test_unknown_backend_is_an_input_error(tmp_path, capsys):
    status, _, err, out = solve(tmp_path, capsys, SLIDER_CRANK, "--backend", "fortran")
    assert status == 2
    assert "fortran" in assert_one_line(err)
    assert not out.exists()


def test_set_n_changes_omega_and_the_motor_torque(tmp_path, capsys):
    status, _, err, default = solve(tmp_path, capsys, SLIDER_CRANK, "--steps", "21", out=tmp_path / "a.csv")
    assert status == 0, err
    # omega = "2*pi*n" is derived: the base parameter n is set, omega follows
    status, _, err, faster = solve(tmp_path, capsys, SLIDER_CRANK, "--steps", "21", "--set", "n=10/pi",
                                   out=tmp_path / "b.csv")
    assert status == 0, err
    h1, r1 = read_csv(default)
    h2, r2 = read_csv(faster)
    assert h1 == h2
    t = column(h2, r2, "t")
    assert column(h2, r2, "crank.phi") == pytest.approx([20 * tk for tk in t], abs=1e-9)
    assert column(h2, r2, "crank.omega") == pytest.approx([20.0] * len(t))
    torque_default, torque_faster = column(h1, r1, "motor.T_j"), column(h2, r2, "motor.T_j")
    assert max(abs(a - b) for a, b in zip(torque_default, torque_faster)) > 1e-3


def test_set_is_repeatable_and_takes_expressions(tmp_path, capsys):
    status, _, err, out = solve(tmp_path, capsys, SLIDER_CRANK, "--steps", "5",
                                "--set", "n=2*L_rod/L_rod", "--set", "F_gas=150")
    assert status == 0, err
    header, rows = read_csv(out)
    w = 2 * math.pi * 2
    assert column(header, rows, "crank.omega") == pytest.approx([w] * 5)


@pytest.mark.parametrize("backend", backend_params())
def test_outputs_q_gives_exactly_the_q_columns(tmp_path, capsys, backend):
    skip_unknown_backend(backend)
    text = with_analysis(base_text(), 'outputs = ["q"]')
    status, _, err, out = solve(tmp_path, capsys, text, "--steps", "5", "--backend", backend)
    assert status == 0, err
    header, rows = read_csv(out)
    assert header == ["t"] + q_columns()
    assert len(rows) == 5 and all(len(r) == 10 for r in rows)


def test_reactions_motor_gives_only_the_motor_reaction_columns(tmp_path, capsys):
    text = with_analysis(base_text(), 'reactions = ["motor"]')
    status, _, err, out = solve(tmp_path, capsys, text, "--steps", "5")
    assert status == 0, err
    header, _ = read_csv(out)
    assert header == (["t"] + q_columns() + qdot_columns() + qddot_columns() + lambda_columns()
                      + reaction_columns(["motor"]))


def test_outputs_and_reactions_subset_keep_file_order(tmp_path, capsys):
    text = with_analysis(base_text(), 'outputs = ["reactions", "q"]\nreactions = ["motor", "main_bearing"]')
    status, _, err, out = solve(tmp_path, capsys, text, "--steps", "5")
    assert status == 0, err
    header, rows = read_csv(out)
    assert header == ["t"] + q_columns() + reaction_columns(["main_bearing", "motor"])
    # the subset holds the same numbers as the full table
    status, _, err, full = solve(tmp_path, capsys, SLIDER_CRANK, "--steps", "5", out=tmp_path / "full.csv")
    assert status == 0, err
    fh, fr = read_csv(full)
    for name in header:
        assert column(header, rows, name) == column(fh, fr, name)


def test_motor_torque_is_minus_lambda(tmp_path, capsys):
    """relative_angle_driver: T_on_j = -lambda (reference), and C.T_j is the motor torque."""
    status, _, err, out = solve(tmp_path, capsys, SLIDER_CRANK, "--steps", "11")
    assert status == 0, err
    header, rows = read_csv(out)
    assert column(header, rows, "motor.T_j") == pytest.approx(
        [-v for v in column(header, rows, "motor.lambda")], rel=1e-12, abs=1e-12)


def test_coordinate_driver_has_reaction_columns_i_only(tmp_path, capsys):
    motor = ('[[constraint]]\nname = "motor"\ntype = "relative_angle_driver"\ni = "ground"\n'
             'j = "crank"\nf = "omega*t"\n')
    driver = ('[[constraint]]\nname = "motor"\ntype = "coordinate_driver"\nbody = "crank"\n'
              'coordinate = "phi"\nf = "omega*t"\n')
    status, _, err, out = solve(tmp_path, capsys, edited(motor, driver), "--steps", "5")
    assert status == 0, err
    header, _ = read_csv(out)
    motor_columns = [c for c in header if c.startswith("motor.")]
    assert motor_columns == ["motor.lambda", "motor.Fx_i", "motor.Fy_i", "motor.T_i"]


def _expected_header(data: dict) -> list[str]:
    """The contract's header for a mechanism file's default outputs (inverse dynamics)."""
    bodies = [b["name"] for b in data["body"]]
    constraints = data["constraint"]
    head = ["t"] + q_columns(bodies) + qdot_columns(bodies) + qddot_columns(bodies)
    head += lambda_columns([(c["name"], ROWS.get(c["type"], 1)) for c in constraints])
    for c in constraints:
        if c["type"] == "coordinate_driver":
            roles = ("i",)
        elif c["type"] == "gear_on_link":
            roles = ("i", "j", "k")
        else:
            roles = ("i", "j")
        head += [f"{c['name']}.{q}_{r}" for r in roles for q in ("Fx", "Fy", "T")]
    # contract v1.1: joint friction after all other columns
    return head + [f"{c['name']}.{w}" for c in constraints if "friction" in c for w in ("friction", "friction_power")]


EXAMPLE_FILES = sorted(EXAMPLES.glob("*.toml"))


@pytest.mark.parametrize("example", [p.stem for p in EXAMPLE_FILES])  # by name: the quick tier's examples (conftest)
def test_every_bundled_example_has_the_contract_header(tmp_path, capsys, example):
    path = EXAMPLES / f"{example}.toml"
    data = tomllib.loads(path.read_text(encoding="utf-8"))
    if data.get("analysis", {}).get("kind", "inverse_dynamics") != "inverse_dynamics" or \
            "outputs" in data.get("analysis", {}) or "reactions" in data.get("analysis", {}):
        pytest.skip("example selects its own outputs")
    t0 = data.get("analysis", {}).get("t0", 0.0)
    t1 = data.get("analysis", {}).get("t1", 1.0)
    # two close instants: a header check, not a long run (nor a leap of the warm start)
    status, _, err, out = solve(tmp_path, capsys, path, "--steps", "2", "--t1", repr(t0 + (t1 - t0) / 1000))
    assert status == 0, err
    assert read_csv(out)[0] == _expected_header(data)


# -- analysis failures: exit 3 ---------------------------------------------------

def _failure(err: str, path: Path) -> tuple[str, float]:
    line = assert_one_line(err)
    assert str(path) in line, f"the message must name the file: {line}"
    m = re.search(r"t = ([-+0-9.eE]+)", line)
    assert m, f"the message must give the time: {line}"
    return line, float(m.group(1))


@pytest.mark.parametrize("backend", backend_params())
def test_newton_failure_part_way_exits_3_and_keeps_solved_instants(tmp_path, capsys, backend):
    """A rod (0.05) shorter than the crank (0.1): the slider cannot follow once
    the crank pin rises above 0.05, i.e. past 30 degrees (t = 1/60 s)."""
    skip_unknown_backend(backend)
    text = set_line(base_text(), "L_rod", "0.05")
    status, _, err, out = solve(tmp_path, capsys, text, "--backend", backend)
    assert status == 3, err
    line, t_fail = _failure(err, tmp_path / "mech.toml")
    assert 0 < t_fail and t_fail == pytest.approx(1 / 60, abs=2e-3)
    assert re.search(r"crank_pin|wrist_pin|cylinder_guide", line), "the constraints involved"
    header, rows = read_csv(out)
    assert header == ALL_COLUMNS
    t = column(header, rows, "t")
    assert len(t) >= 1 and t[-1] < t_fail
    # exactly the instants before the failure: the grid up to it, with none missing
    h = 0.2 / 200
    assert t == pytest.approx([k * h for k in range(len(t))], abs=1e-15)
    assert t_fail == pytest.approx(len(t) * h, abs=1e-15)
    m = re.search(r"(\d+) instants", line)
    if m:
        assert int(m.group(1)) == len(rows)
    no_temporaries(tmp_path)


@pytest.mark.parametrize("backend", backend_params())
def test_singular_configuration_part_way_exits_3(tmp_path, capsys, backend):
    """Rod as long as the crank: at 90 degrees (t = 0.05 s) the slider reaches
    the main bearing, the rod is square to the guide and Phi_q is singular."""
    skip_unknown_backend(backend)
    text = set_line(base_text(), "L_rod", "0.1")
    status, _, err, out = solve(tmp_path, capsys, text, "--backend", backend)
    assert status == 3, err
    line, t_fail = _failure(err, tmp_path / "mech.toml")
    assert t_fail == pytest.approx(0.05, abs=2e-3)
    assert re.search(r"singular|ill-conditioned|converge", line)
    assert re.search(r"main_bearing|crank_pin|wrist_pin|cylinder_guide", line)
    header, rows = read_csv(out)
    t = column(header, rows, "t")
    assert len(rows) >= 1 and t[-1] < t_fail
    no_temporaries(tmp_path)


REDUNDANT_DRIVER = ('[[constraint]]\nname = "motor"\ntype = "coordinate_driver"\nbody = "slider"\n'
                    'coordinate = "y"\nf = "0"\n')
MOTOR = ('[[constraint]]\nname = "motor"\ntype = "relative_angle_driver"\ni = "ground"\n'
         'j = "crank"\nf = "omega*t"\n')


def redundant_text() -> str:
    """The motor replaced by a second copy of the guide's y row: nc = ng, rank ng - 1,
    and the crank is free. Phi_q is singular everywhere."""
    return edited(MOTOR, REDUNDANT_DRIVER)




@pytest.mark.parametrize("backend", backend_params())
def test_redundant_constraints_exit_3_at_t0_with_header_only(tmp_path, capsys, backend):
    skip_unknown_backend(backend)
    out = tmp_path / "out.csv"
    path = tmp_path / "mech.toml"
    path.write_text(redundant_text(), encoding="utf-8")
    status = main(["solve", str(path), "-o", str(out), "--backend", backend])
    err = capsys.readouterr().err
    assert status == 3, err
    line, t_fail = _failure(err, path)
    assert t_fail == 0.0
    assert "singular" in line
    assert "cylinder_guide" in line and "motor" in line
    header = [c for c in ALL_COLUMNS if c not in ("motor.Fx_j", "motor.Fy_j", "motor.T_j")]
    assert out.read_text().splitlines() == [",".join(header)]
    no_temporaries(tmp_path)


def test_check_reports_rank_deficiency_and_dependent_constraints(tmp_path, capsys):
    path = tmp_path / "mech.toml"
    path.write_text(redundant_text(), encoding="utf-8")
    status = main(["check", str(path)])
    captured = capsys.readouterr()
    text = captured.out + captured.err
    assert "Traceback" not in text
    assert status in (0, 3)
    assert re.search(r"rank\D{0,20}8\b", text), text
    assert "cylinder_guide" in text and "motor" in text


def test_check_function_reports_rank_deficiency(tmp_path):
    from symid.tools.check import check
    from symid import backends
    backend = "reference" if "reference" in backends.names() else "numpy"
    path = tmp_path / "mech.toml"
    path.write_text(redundant_text(), encoding="utf-8")
    report = check(api.prepare(path, backend))
    assert report.ng == 9 and report.nc == 9 and report.rank == 8
    assert {"cylinder_guide", "motor"} <= set(report.dependent)


@pytest.mark.parametrize("backend", backend_params())
def test_failure_at_t0_writes_header_only(tmp_path, capsys, backend):
    """The crank starts at 90 degrees with a rod too short to reach the guide:
    nothing can be assembled at t0."""
    skip_unknown_backend(backend)
    text = set_line(base_text(), "L_rod", "0.05").replace('f = "omega*t"', 'f = "omega*t + pi/2"')
    status, _, err, out = solve(tmp_path, capsys, text, "--backend", backend)
    assert status == 3, err
    line, t_fail = _failure(err, tmp_path / "mech.toml")
    assert t_fail == 0.0
    assert out.read_text().splitlines() == [",".join(ALL_COLUMNS)]
    no_temporaries(tmp_path)


@pytest.mark.parametrize("backend", backend_params())
def test_failure_replaces_an_existing_output(tmp_path, capsys, backend):
    out = tmp_path / "out.csv"
    skip_unknown_backend(backend)
    out.write_text("old,table\n1,2\n")
    text = set_line(base_text(), "L_rod", "0.05")
    status, _, err, _ = solve(tmp_path, capsys, text, "--backend", backend, out=out)
    assert status == 3
    assert out.read_text().splitlines()[0] == ",".join(ALL_COLUMNS)
    no_temporaries(tmp_path)


# -- atomic write ------------------------------------------------------------------

def test_success_leaves_no_temporary_files(tmp_path, capsys):
    status, _, err, out = solve(tmp_path, capsys, SLIDER_CRANK, "--steps", "3")
    assert status == 0, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.csv"]


def test_output_in_a_missing_folder_is_an_input_error(tmp_path, capsys):
    status, _, err, out = solve(tmp_path, capsys, SLIDER_CRANK, "--steps", "3",
                                out=tmp_path / "no_such_folder" / "out.csv")
    assert status == 2
    line = assert_one_line(err)
    assert "out.csv" in line
    no_temporaries(tmp_path)


def test_output_that_is_a_folder_is_an_input_error(tmp_path, capsys):
    folder = tmp_path / "results"
    folder.mkdir()
    try:
        status = main(["solve", str(SLIDER_CRANK), "-o", str(folder), "--steps", "3"])
    finally:
        no_temporaries(tmp_path)
    err = capsys.readouterr().err
    assert status == 2
    assert "results" in assert_one_line(err)


# -- check -----------------------------------------------------------------------

@pytest.mark.parametrize("example", [p.stem for p in EXAMPLE_FILES])  # by name: the quick tier's examples (conftest)
def test_check_reports_counts_rank_and_condition_of_every_example(capsys, example):
    path = EXAMPLES / f"{example}.toml"
    data = tomllib.loads(path.read_text(encoding="utf-8"))
    ng = 3 * len(data["body"])
    nc = sum(ROWS.get(c["type"], 1) for c in data["constraint"])
    status = main(["check", str(path)])
    captured = capsys.readouterr()
    assert status == 0, captured.err
    assert captured.err == ""
    text = captured.out
    assert re.search(rf"\bng = {ng}\b", text), text
    assert re.search(rf"\bnc = {nc}\b", text), text
    rank = re.search(r"rank\D{0,20}(\d+)", text)
    assert rank and int(rank.group(1)) == ng, text
    cond = re.search(r"condition number\D{0,5}([0-9.]+(?:e[-+]?\d+)?)", text)
    assert cond and 1.0 <= float(cond.group(1)) < 1e12, text


def test_examples_listed_by_the_api_are_the_bundled_files():
    assert sorted(api.examples()) == sorted(p.stem for p in EXAMPLE_FILES)


# -- the module entry point in a child process -------------------------------------

def run_module(args: list[str], cwd: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")]))}
    return subprocess.run([sys.executable, "-m", "symid", *args], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=300)


def test_python_m_symid_solve_exit_0(tmp_path):
    proc = run_module(["solve", str(SLIDER_CRANK), "--steps", "4"], tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == ""
    header, rows = read_csv(tmp_path / "slider_crank.csv")
    assert header == ALL_COLUMNS and len(rows) == 4
    no_temporaries(tmp_path)


def test_python_m_symid_input_error_exit_2(tmp_path):
    (tmp_path / "bad.toml").write_text(set_line(base_text(), "steps", "0"), encoding="utf-8")
    proc = run_module(["solve", "bad.toml", "-o", "out.csv"], tmp_path)
    assert proc.returncode == 2
    line = assert_one_line(proc.stderr)
    assert re.search(r"bad\.toml: \[analysis\] key 'steps'", line)
    assert not (tmp_path / "out.csv").exists()


def test_python_m_symid_analysis_failure_exit_3(tmp_path):
    (tmp_path / "short.toml").write_text(set_line(base_text(), "L_rod", "0.05"), encoding="utf-8")
    proc = run_module(["solve", "short.toml", "-o", "out.csv"], tmp_path)
    assert proc.returncode == 3
    line = assert_one_line(proc.stderr)
    assert "short.toml" in line and "t = " in line
    assert (tmp_path / "out.csv").exists()
    no_temporaries(tmp_path)


def test_python_m_symid_usage_error_exit_2(tmp_path):
    proc = run_module(["solve"], tmp_path)
    assert proc.returncode == 2
    assert_one_line(proc.stderr)
    proc = run_module(["solve", str(SLIDER_CRANK), "--kind", "dynamics"], tmp_path)
    assert proc.returncode == 2
    assert_one_line(proc.stderr)
    assert list(tmp_path.iterdir()) == []


def test_python_m_symid_check_exit_0(tmp_path):
    proc = run_module(["check", str(SLIDER_CRANK)], tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert "ng = 9" in proc.stdout and "nc = 9" in proc.stdout
