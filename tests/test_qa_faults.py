"""Faults a new user meets on the study and export paths, tried after issue 32
was built (its "Done when"): a limit the optimizer cannot meet is named, not
hidden behind SLSQP's line-search message."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from symid import api
from symid.cli import main

CRANK = str(api.example("slider_crank"))
STEPS = "11"


def test_a_limit_that_cannot_be_met_is_named_with_its_value(tmp_path, capsys, monkeypatch):
    """crank_pin.force_peak <= 1 N cannot hold for any rod: at t = 0 (outer dead
    centre) crank and rod lie on the x axis with no vertical acceleration and no
    angular acceleration of the rod, so the rod's weight m_rod*g = 9.81 N is
    shared equally by its two pins: the crank pin carries at least 4.905 N.
    The line names the limit, the figure where the optimizer stopped and the
    bounds, and nothing is written (exit 3)."""
    monkeypatch.chdir(tmp_path)
    status = main(["optimize", CRANK, "--minimize", "motor.effort_rms", "--vary", "L_rod=0.25:0.5",
                   "--subject-to", "crank_pin.force_peak<=1", "--steps", STEPS, "--backend", "numpy",
                   "-o", "best.toml"])
    err = capsys.readouterr().err
    assert status == 3, err
    assert err.count("\n") == 1 and "Traceback" not in err
    found = re.search(r"with a limit not met: crank_pin\.force_peak = (\S+) \(<= 1\)", err)
    assert found, err
    assert float(found.group(1)) >= 9.81 * 1.0 / 2
    assert "--vary bounds" in err and "nothing written" in err
    assert not Path("best.toml").exists()


def test_a_limit_that_can_be_met_still_converges(tmp_path, capsys, monkeypatch):
    """The unmet-limit line is not said of a feasible limit: with 1000 N on the
    crank pin (far above the ~250 N the slider-crank reaches) it converges."""
    monkeypatch.chdir(tmp_path)
    status = main(["optimize", CRANK, "--minimize", "motor.effort_rms", "--vary", "L_rod=0.25:0.5",
                   "--subject-to", "crank_pin.force_peak<=1000", "--steps", STEPS, "--backend", "numpy",
                   "-o", "best.toml"])
    captured = capsys.readouterr()
    assert status == 0, captured.err
    assert "not met" not in captured.err and Path("best.toml").is_file()
