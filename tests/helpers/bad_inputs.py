"""Bad inputs to `symid solve`: the slider-crank text they edit, the run of
one, and the input-error contract's check (exit 2, one line, no file)."""

from __future__ import annotations

import re
from pathlib import Path

from symid.cli import main

# The bundled slider-crank, without comments.
BASE = """\
[mechanism]
name = "slider_crank"
gravity = [0.0, -9.81]

[parameters]
L_crank = 0.1
L_rod = 0.3
m_crank = 0.5
m_rod = 1.0
m_slider = 0.8
a_slider = 0.06
b_slider = 0.04
n = 5
omega = "2*pi*n"
F_gas = 100.0

[analysis]
kind = "inverse_dynamics"
t0 = 0.0
t1 = 0.2
steps = 201

[[body]]
name = "crank"
mass = "m_crank"
inertia = "m_crank*L_crank^2/12"
q0 = ["L_crank/2", 0.0, 0.0]

[[body]]
name = "connecting_rod"
mass = "m_rod"
inertia = "m_rod*L_rod^2/12"
q0 = ["L_crank + L_rod/2", 0.0, 0.0]

[[body]]
name = "slider"
mass = "m_slider"
inertia = "m_slider*(a_slider^2 + b_slider^2)/12"
q0 = ["L_crank + L_rod", 0.0, 0.0]

[[constraint]]
name = "main_bearing"
type = "revolute"
i = "ground"
j = "crank"
si = [0.0, 0.0]
sj = ["-L_crank/2", 0.0]

[[constraint]]
name = "crank_pin"
type = "revolute"
i = "crank"
j = "connecting_rod"
si = ["L_crank/2", 0.0]
sj = ["-L_rod/2", 0.0]

[[constraint]]
name = "wrist_pin"
type = "revolute"
i = "connecting_rod"
j = "slider"
si = ["L_rod/2", 0.0]
sj = [0.0, 0.0]

[[constraint]]
name = "cylinder_guide"
type = "translational"
i = "ground"
j = "slider"
si = [0.0, 0.0]
vi = [1.0, 0.0]
sj = [0.0, 0.0]
theta0 = 0.0

[[constraint]]
name = "motor"
type = "relative_angle_driver"
i = "ground"
j = "crank"
f = "omega*t"

[[force]]
name = "gas_load"
type = "point_force"
body = "slider"
s = [0.0, 0.0]
F = ["-F_gas*sin(omega*t)", "0"]
"""

# Sentinels for cases that are not a text.
MISSING = object()  # the file does not exist
DIRECTORY = object()  # the path is a folder

def write_case(path: Path, content: object) -> None:
    if content is MISSING:
        return
    if content is DIRECTORY:
        path.mkdir()
    elif isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content, encoding="utf-8")


def solve_bad(tmp_path: Path, capsys, content: object, extra: list[str]):
    """Run `symid solve` on `content` written to tmp_path/bad.toml.

    Returns (status, the stderr text, the input path, the output path)."""
    path = tmp_path / "bad.toml"
    write_case(path, content)
    out = tmp_path / "out.csv"
    status = main(["solve", str(path), "-o", str(out), *extra])
    err = capsys.readouterr().err
    return status, err, path, out


def assert_one_line_input_error(status: int, err: str, path: Path, out: Path, pattern: str) -> None:
    assert status == 2, f"exit status {status}, stderr {err!r}"
    assert "Traceback" not in err
    assert err.endswith("\n") and err.count("\n") == 1, f"stderr is not one line: {err!r}"
    assert re.search(pattern, err), f"{err!r} does not match {pattern!r}"
    assert not out.exists(), "an input error must not write a results file"
    assert not list(out.parent.glob(".*.tmp")), "temporary file left behind"
