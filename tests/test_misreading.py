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


@pytest.mark.parametrize("name", api.examples())
def test_bundled_examples_have_no_angle_warning(name: str) -> None:
    assert angle_warnings(load(api.example(name))) == []


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


def test_plot_accepts_the_table_with_the_parameters_it_was_solved_with(longer_rod_table: Path,
                                                                       tmp_path: Path) -> None:
    assert main(["plot", str(longer_rod_table), "--mechanism", str(SLIDER_CRANK), "--set", "L_rod=0.35",
                 "-o", str(tmp_path)]) == 0
    assert (tmp_path / "run_mechanism.png").is_file()
