"""`symid size FILE`: the verdict's exit status (0 fits, 4 does not), `--json`
with the issue's keys, and bad sizing input as one line, exit 2, naming the
file and the key (#29, points 2 and 8)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from symid import api
from symid.cli import main

SLIDER_CRANK = api.example("slider_crank_sized")


def _variant(tmp_path: Path, old: str, new: str, name: str = "sc.toml") -> Path:
    text = SLIDER_CRANK.read_text()
    assert old in text, old
    path = tmp_path / name
    path.write_text(text.replace(old, new, 1))
    return path


def test_bundled_slider_crank_fits_and_json_has_the_contract_keys(capsys):
    assert main(["size", str(SLIDER_CRANK), "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert set(data) == {"drives", "bearings"}
    drive = data["drives"][0]
    assert {"driver", "ratio", "motor_rms", "motor_peak", "t_peak", "speed_peak", "fits", "why"} <= set(drive)
    assert drive["driver"] == "motor" and drive["ratio"] == 13.0 and drive["fits"] is True and drive["why"] == []
    assert [b["joint"] for b in data["bearings"]] == ["main_bearing", "crank_pin"]
    assert all(set(b) == {"joint", "P_eq", "L10_h"} and b["L10_h"] > 0 for b in data["bearings"])


def test_a_motor_too_small_exits_4_naming_what_and_when(tmp_path, capsys):
    path = _variant(tmp_path, "peak_torque = 1.91", "peak_torque = 1.0")
    assert main(["size", str(path)]) == 4
    out = capsys.readouterr().out
    line = next(l for l in out.splitlines() if l.startswith("motor:"))
    assert "does not fit: peak torque" in line and "at t = 0.056 s above peak 1" in line


def test_size_without_drives_or_bearings_is_an_input_error(capsys):
    assert main(["size", str(api.example("four_bar"))]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "four_bar.toml: nothing to size" in err[0]


BAD = [  # (old text, new text, the key the line names, a phrase of it)
    ('driver = "motor"', 'driver = "crank_pin"', "[[drive]] #1 key 'driver'", "not a driver of the file"),
    ('driver = "motor"', "", "[[drive]] #1", "missing key 'driver'"),
    ("ratio = 13.0", "ratio = 0.0", "drive 'motor' key 'ratio'", "must be in (0, inf)"),
    ("ratio = 13.0", "ratio = -13.0", "drive 'motor' key 'ratio'", "must be in (0, inf)"),
    ("ratio = 13.0", "ratio = [20.0, 5.0]", "drive 'motor' key 'ratio'", "0 < lo < hi"),
    ("efficiency = 0.9", "efficiency = 1.2", "drive 'motor' key 'efficiency'", "must be in (0, 1]"),
    ("efficiency = 0.9", "efficiency = 0.0", "drive 'motor' key 'efficiency'", "must be in (0, 1]"),
    ("efficiency = 0.9", "efficiency = 0.9\nback_efficiency = -0.5", "drive 'motor' key 'back_efficiency'",
     "must be in (0, 1]"),
    ("corner_speed = 314.0", "corner_speed = 700.0", "drive 'motor' key 'corner_speed'", "not monotone"),
    ("peak_torque = 1.91", "peak_torque = 0.5", "drive 'motor' key 'peak_torque'", "not monotone"),
    ("rotor_inertia = 1.4e-5", "rotor_inertia = -1.4e-5", "drive 'motor' key 'rotor_inertia'", "must be in [0"),
    ("max_speed = 628.0", "top_speed = 628.0", "[[drive]] #1 key 'top_speed'", "unknown key"),
    ("corner_speed = 314.0", "envelope = [[0.0, 1.91], [314.0, 1.95], [628.0, 0.0]]",
     "drive 'motor' key 'envelope'", "not monotone"),
    ("corner_speed = 314.0", "envelope = [[0.0, 1.91], [0.0, 1.5]]", "drive 'motor' key 'envelope'", "increase"),
    ("corner_speed = 314.0", "corner_speed = 314.0\nenvelope = [[0.0, 1.91], [628.0, 0.0]]",
     "drive 'motor' key 'envelope'", "not both"),
    ('name = "cylinder_guide"\ntype = "translational"', 'name = "cylinder_guide"\ntype = "translational"\n'
     'bearing = { C = 1000.0 }', "constraint 'cylinder_guide' key 'bearing'", "no rotation"),
    ("bearing = { C = 13500.0, p = 3 }", "bearing = { C = -1.0, p = 3 }", "constraint 'main_bearing' key 'bearing.C'",
     "must be positive"),
    ("bearing = { C = 13500.0, p = 3 }", "bearing = { C = 1.0, q = 3 }", "constraint 'main_bearing' key 'bearing.q'",
     "unknown bearing key"),
    ("bearing = { C = 13500.0, p = 3 }", "bearing = 5", "constraint 'main_bearing' key 'bearing'", "inline table"),
]


@pytest.mark.parametrize("old, new, key, phrase", BAD, ids=[f"{k}-{p}" for _, _, k, p in BAD])
def test_bad_sizing_input_is_one_line_exit_2_naming_file_and_key(tmp_path, capsys, old, new, key, phrase):
    path = _variant(tmp_path, old, new)
    assert main(["size", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"symid: {path}: {key}: ") and phrase in err[0], err


def test_bad_sizing_input_is_refused_by_solve_too(tmp_path, capsys):
    """The tables are part of the file: every command reads them, not only size."""
    path = _variant(tmp_path, "ratio = 13.0", "ratio = 0.0")
    assert main(["check", str(path)]) == 2
    assert "drive 'motor' key 'ratio'" in capsys.readouterr().err


def test_a_bearing_on_a_joint_that_does_not_turn(tmp_path, capsys):
    """The crank held still (f = 0): the main bearing never rotates, no rating life."""
    path = _variant(tmp_path, 'f = "omega*t"', 'f = "0"')
    assert main(["size", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{path}: constraint 'main_bearing' key 'bearing': the joint does not rotate" in err[0]


def test_a_run_that_fails_exits_3_naming_the_instant(tmp_path, capsys):
    """A rod shorter than the crank locks the mechanism part-way: nothing is sized from half a cycle."""
    path = _variant(tmp_path, "L_rod = 0.3 ", "L_rod = 0.05 ")
    assert main(["size", str(path)]) == 3
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"symid: {path}: t = ")
