"""Every bad input of `symid solve --sensitivity / --sensitivity-of` is one line
on stderr and exit 2, before any solving, and nothing is written."""

from __future__ import annotations

from pathlib import Path

import pytest

from symid import api
from symid.cli import main
from symid.errors import InputError

CRANK = str(api.example("slider_crank"))
FRICTION = str(api.example("slider_crank_friction"))


def run(tmp_path: Path, capsys, *args: str, file: str = CRANK) -> tuple[int, str]:
    status = main(["solve", file, "--steps", "3", "--backend", "reference", "-o", str(tmp_path / "out.csv"), *args])
    return status, capsys.readouterr().err


BAD = {
    "unknown_parameter": (["--sensitivity", "L_bar"], "--sensitivity L_bar: no such parameter (base parameters: L_crank"),
    "derived_parameter": (["--sensitivity", "omega"],
                          "'omega' is a derived parameter (omega = \"2*pi*n\" in [parameters]); take the "
                          "sensitivity to the base parameters it is computed from (n)"),
    "empty_list": (["--sensitivity", ""], "--sensitivity: an empty name in the list"),
    "empty_item": (["--sensitivity", "L_rod,,n"], "--sensitivity: an empty name in the list"),
    "named_twice": (["--sensitivity", "L_rod,n,L_rod"], "--sensitivity: 'L_rod' is named twice"),
    "unknown_column": (["--sensitivity", "n", "--sensitivity-of", "motor.T_k"],
                       "--sensitivity-of motor.T_k: no such column in this table"),
    "column_not_output": (["--sensitivity", "n", "--sensitivity-of", "slider.ax", "--kind", "statics"],
                          "--sensitivity-of slider.ax: no such column"),
    "time_column": (["--sensitivity", "n", "--sensitivity-of", "t"], "--sensitivity-of t: no such column"),
    "column_twice": (["--sensitivity", "n", "--sensitivity-of", "motor.T_j,motor.T_j"],
                     "--sensitivity-of: 'motor.T_j' is named twice"),
    "empty_columns": (["--sensitivity", "n", "--sensitivity-of", ","], "--sensitivity-of: an empty name"),
    "columns_without_parameters": (["--sensitivity-of", "motor.T_j"], "--sensitivity-of: needs --sensitivity"),
    "kinematics_has_no_default": (["--sensitivity", "n", "--kind", "kinematics"],
                                  "a kinematics table without lambda or reactions has no effort or reaction columns"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_option_is_one_line_exit_2(tmp_path, capsys, case):
    args, message = BAD[case]
    status, err = run(tmp_path, capsys, *args)
    assert status == 2, err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert message in err, err
    assert CRANK in err  # names the file
    assert not (tmp_path / "out.csv").exists()


def test_joint_friction_has_sensitivities_after_its_columns(tmp_path, capsys):
    """Sensitivities with joint friction (issue 26 point 3): the friction
    columns can be differentiated too, and come before every d(...) column."""
    status, err = run(tmp_path, capsys, "--sensitivity", "mu_pin",
                      "--sensitivity-of", "motor.T_j,cylinder_guide.friction", file=FRICTION)
    assert status == 0, err
    header = (tmp_path / "out.csv").read_text().splitlines()[0].split(",")
    assert header[-3:] == ["cylinder_guide.friction_power", "d(motor.T_j)/d(mu_pin)",
                           "d(cylinder_guide.friction)/d(mu_pin)"]


def test_kinematics_with_named_columns_has_sensitivities(tmp_path, capsys):
    """A kind without efforts still differentiates the columns it has."""
    status, err = run(tmp_path, capsys, "--sensitivity", "n", "--sensitivity-of", "crank.phi", "--kind", "kinematics")
    assert status == 0, err
    header = (tmp_path / "out.csv").read_text().splitlines()[0].split(",")
    assert header[-1] == "d(crank.phi)/d(n)"


def test_api_refuses_the_same_as_the_command_line():
    with pytest.raises(InputError, match="derived parameter"):
        api.prepare(api.example("slider_crank"), "reference", sensitivity=["omega"])
    with pytest.raises(InputError, match="no such column"):
        api.prepare(api.example("slider_crank"), "reference", sensitivity=["n"], sensitivity_of=["nope"])


def test_columns_are_outer_and_parameters_inner_after_every_other_column():
    study = api.prepare(api.example("slider_crank"), "reference", sensitivity="L_rod,n",
                        sensitivity_of=["motor.T_j", "crank_pin.Fx_i"], steps=2)
    header = study.columns()
    assert header[-4:] == ["d(motor.T_j)/d(L_rod)", "d(motor.T_j)/d(n)",
                           "d(crank_pin.Fx_i)/d(L_rod)", "d(crank_pin.Fx_i)/d(n)"]
    assert not any(c.startswith("d(") for c in header[:-4])
