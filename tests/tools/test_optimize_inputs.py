"""Every bad input of `symid optimize` is one line on stderr and exit 2, before any solve."""

from __future__ import annotations

from pathlib import Path

import pytest

from symid import api
from symid.cli import main

CRANK = str(api.example("slider_crank"))


def run(tmp_path: Path, capsys, monkeypatch, *args: str) -> tuple[int, str]:
    import symid.tools.sensitive as sensitive

    def no_solve(backend: str):
        raise AssertionError("a bad input must be refused before any solve")

    monkeypatch.setattr(sensitive, "solver", no_solve)
    try:
        status = main(["optimize", CRANK, "--steps", "3", "-o", str(tmp_path / "out.toml"), *args])
    except SystemExit as exc:  # argparse's own usage errors (one line, exit 2)
        status = int(exc.code or 0)
    return status, capsys.readouterr().err


RMS = ["--minimize", "motor.effort_rms"]
BAD = {
    "unknown_figure": (["--minimize", "motor.effort_rmss", "--vary", "n=4:6"],
                       "--minimize: no figure 'motor.effort_rmss' (figures: motor.effort_peak"),
    "figure_of_no_driver": (["--minimize", "crank_pin.effort_rms", "--vary", "n=4:6"],
                            "no figure 'crank_pin.effort_rms'"),
    "unknown_figure_in_subject_to": (RMS + ["--vary", "n=4:6", "--subject-to", "crank_pin.peak<=800"],
                                     "--subject-to crank_pin.peak<=800: no figure 'crank_pin.peak'"),
    "time_of_peak_has_no_gradient": (["--minimize", "motor.effort_t_peak", "--vary", "n=4:6"],
                                     "'motor.effort_t_peak' is an instant of the time grid and has no gradient"),
    "unknown_parameter": (RMS + ["--vary", "L_bar=0.2:0.4"],
                          "--vary: no parameter 'L_bar' (base parameters: L_crank"),
    "derived_parameter": (RMS + ["--vary", "omega=20:40"],
                          "'omega' is a derived parameter (omega = 2*pi*n): vary the base parameters"),
    "varied_twice": (RMS + ["--vary", "n=4:6", "--vary", "n=3:7"], "parameter 'n' is varied twice"),
    "lo_above_hi": (RMS + ["--vary", "n=6:4"], "--vary n=6:4: LO 6 must be less than HI 4"),
    "lo_equals_hi": (RMS + ["--vary", "n=5:5"], "--vary n=5:5: LO 5 must be less than HI 5"),
    "vary_one_number": (RMS + ["--vary", "n=5"], "--vary n=5: expected NAME=LO:HI"),
    "vary_three_numbers": (RMS + ["--vary", "n=4:5:6"], "--vary n=4:5:6: expected NAME=LO:HI"),
    "vary_no_equals": (RMS + ["--vary", "n"], "--vary n: expected NAME=LO:HI"),
    "vary_not_a_number": (RMS + ["--vary", "n=a:6"], "--vary n=a:6: LO: 'a' is not a finite number"),
    "vary_infinite": (RMS + ["--vary", "n=4:inf"], "HI: 'inf' is not a finite number"),
    "vary_span_overflows": (RMS + ["--vary", "n=-1e308:1e308"],
                            "--vary n=-1e308:1e308: the span HI - LO is past the largest double"),
    "no_vary": (RMS, "--vary: name at least one parameter to vary"),
    "subject_to_strict": (RMS + ["--vary", "n=4:6", "--subject-to", "crank_pin.force_peak<800"],
                          "--subject-to crank_pin.force_peak<800: expected FIGURE<=VALUE or FIGURE>=VALUE"),
    "subject_to_not_a_number": (RMS + ["--vary", "n=4:6", "--subject-to", "crank_pin.force_peak<=lots"],
                                "VALUE: 'lots' is not a finite number"),
    "start_outside_bounds": (RMS + ["--vary", "n=6:8"],
                             "--vary n=6:8: the start n = 5 (the file's value) is outside [6, 8]"),
    "maxiter_zero": (RMS + ["--vary", "n=4:6", "--maxiter", "0"], "argument --maxiter: must be a whole number from 1 to"),
    "kinematics_has_no_figures": (RMS + ["--vary", "n=4:6", "--kind", "kinematics"], "invalid choice"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_option_is_one_line_exit_2(tmp_path, capsys, monkeypatch, case):
    args, message = BAD[case]
    status, err = run(tmp_path, capsys, monkeypatch, *args)
    assert status == 2, err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert message in err, err
    assert not (tmp_path / "out.toml").exists()


def test_a_start_set_inside_the_bounds_is_accepted_up_to_the_solve(tmp_path, capsys, monkeypatch):
    """--set moves the start: n = 7 inside [6, 8] passes every check (and reaches the solver)."""
    with pytest.raises(AssertionError, match="before any solve"):
        run(tmp_path, capsys, monkeypatch, *RMS, "--vary", "n=6:8", "--set", "n=7")
