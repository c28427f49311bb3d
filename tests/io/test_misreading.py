"""No silent misreading: angles that look like degrees and bodies assembled far
from their q0 are warned about; `symid plot` refuses a table that the
mechanism it is given could not have produced."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from symid import api
from symid.cli import main
from symid.io.reader import load, loads
from symid.io.misreading import angle_warnings

SLIDER_CRANK = api.example("slider_crank")
TEXT = SLIDER_CRANK.read_text()


def _edited(old: str, new: str) -> str:
    assert old in TEXT
    return TEXT.replace(old, new, 1)


@pytest.mark.parametrize(("old", "new", "key"), [
    ("theta0 = 0.0", "theta0 = 90", "constraint 'cylinder_guide' key 'theta0' = 90"),
    ('q0 = ["L_crank/2", 0.0, 0.0]', 'q0 = ["L_crank/2", 0.0, 30]', "body 'crank' key 'q0' (phi) = 30"),
    ('f = "omega*t"', 'f = "omega*t + 45"', "constraint 'motor' key 'f' at t0 = 0 = 45")])
def test_an_angle_above_two_pi_is_warned_about_naming_its_key(old: str, new: str, key: str) -> None:
    lines = angle_warnings(loads(_edited(old, new), "m.toml"))
    assert len(lines) == 1 and key in lines[0]
    assert "radians expected; did you mean" in lines[0] and "degrees" in lines[0]


@pytest.mark.parametrize(("f", "rate"), [("270*t", "270"), ("90*sin(t)", "90"), ("pi/2 + 360*t", "360")])
def test_a_driver_rate_in_degrees_per_second_is_warned_about(f: str, rate: str) -> None:
    """The theta0 rule on the driver's rate at t0: above 2 pi and a whole
    multiple of 15 (a rate in rad/s above a turn a second is 2 pi n, measured
    or a round 10, 20, 50, 100)."""
    lines = angle_warnings(loads(_edited('f = "omega*t"', f'f = "{f}"'), "m.toml"))
    assert len(lines) == 1 and f"constraint 'motor' key 'f': its rate at t0 = 0 = {rate} rad/s" in lines[0]
    assert "did you mean" in lines[0] and f"{math.radians(float(rate)):.6f}"[:6] in lines[0]


@pytest.mark.parametrize("f", ["omega*t", "31.4*t", "6*t", "10*t", "20*t", "100*t", "2*pi*50*t",
                               "0.5*t^2 + 400*t^3"])
def test_a_driver_rate_in_radians_per_second_passes(f: str) -> None:
    assert angle_warnings(loads(_edited('f = "omega*t"', f'f = "{f}"'), "m.toml")) == []


@pytest.mark.parametrize("name", api.examples())
def test_bundled_examples_have_no_angle_warning(name: str) -> None:
    assert angle_warnings(load(api.example(name))) == []


def test_a_driver_in_degrees_reaches_the_command_line_as_a_warning(tmp_path: Path, capsys) -> None:
    path = tmp_path / "deg.toml"
    path.write_text(_edited('f = "omega*t"', 'f = "270*t"'))
    assert main(["solve", str(path), "--t1", "0.01", "--steps", "3", "--backend", "reference", "-o",
                 str(tmp_path / "x.csv")]) == 0
    err = capsys.readouterr().err
    assert "symid: warning:" in err and "270 rad/s, a multiple of 15 above 2 pi" in err


def test_degrees_reach_the_command_line_as_a_warning(tmp_path: Path, capsys) -> None:
    path = tmp_path / "deg.toml"
    path.write_text(_edited("theta0 = 0.0", "theta0 = 90"))
    assert main(["solve", str(path), "--steps", "3", "--backend", "reference", "-o", str(tmp_path / "x.csv")]) == 0
    err = capsys.readouterr().err
    assert "symid: warning:" in err and "theta0' = 90 is more than 2 pi" in err
    assert f"{math.radians(90):.6f}"[:6] in err  # the radians it probably meant


def test_a_body_assembled_far_from_its_q0_is_warned_about() -> None:
    text = _edited('q0 = ["L_crank + L_rod/2", 0.0, 0.0]', 'q0 = ["L_crank + L_rod/2", 0.0, 3.0]')
    results = api.prepare(loads(text, "far.toml"), "reference", steps=2).solve()
    far = [w for w in results.warnings if "far from its q0" in w]
    assert any("body 'connecting_rod'" in w for w in far)


def test_an_exact_q0_gives_no_assembly_warning() -> None:
    assert not api.prepare(SLIDER_CRANK, "reference", steps=2).solve().warnings


@pytest.fixture(scope="module")
def longer_rod_table(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("plot") / "run.csv"
    assert main(["solve", str(SLIDER_CRANK), "--set", "L_rod=0.35", "--steps", "21", "--backend", "reference",
                 "-o", str(out)]) == 0
    return out


def test_plot_refuses_a_table_solved_with_other_parameters(longer_rod_table: Path, tmp_path: Path, capsys) -> None:
    status = main(["plot", str(longer_rod_table), "--mechanism", str(SLIDER_CRANK), "-o", str(tmp_path)])
    assert status == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "do not satisfy the constraints" in err and "--set" in err
    assert not list(tmp_path.glob("*.png"))


# slow: a solve and a plot of its table with --set; the misreading checks of a plot's table stay in the quick
# tier
@pytest.mark.slow
def test_plot_accepts_the_table_with_the_parameters_it_was_solved_with(longer_rod_table: Path,
                                                                       tmp_path: Path) -> None:
    assert main(["plot", str(longer_rod_table), "--mechanism", str(SLIDER_CRANK), "--set", "L_rod=0.35",
                 "-o", str(tmp_path)]) == 0
    assert (tmp_path / "run_mechanism.png").is_file()
