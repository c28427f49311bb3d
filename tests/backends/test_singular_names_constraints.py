"""Found trying symid as a new user: a parallelogram four-bar driven through
its flattened (singular) position stopped with exit 3 on every backend, but on
`c` the message read 'dependent constraints: ;' (the LU's condition estimate
called Phi_q singular where the SVD's rank threshold still counted it full).
The message names the constraints of the near-null direction on every backend."""

from __future__ import annotations

from pathlib import Path

import pytest

from symid import cli

PARALLELOGRAM = """
[mechanism]
name = "pgram"

[parameters]
L = 0.4
D = 0.6
e = 0.3

[analysis]
t1 = 1.0
steps = 101

[[body]]
name = "crank"
mass = 1.0
inertia = 0.01
q0 = ["L/2*cos(e)", "L/2*sin(e)", "e"]

[[body]]
name = "coupler"
mass = 2.0
inertia = 0.06
q0 = ["L*cos(e) + D/2", "L*sin(e)", 0.0]

[[body]]
name = "rocker"
mass = 1.0
inertia = 0.01
q0 = ["D + L/2*cos(e)", "L/2*sin(e)", "e"]

[[constraint]]
name = "A"
type = "revolute"
i = "ground"
j = "crank"
si = [0.0, 0.0]
sj = ["-L/2", 0.0]

[[constraint]]
name = "B"
type = "revolute"
i = "crank"
j = "coupler"
si = ["L/2", 0.0]
sj = ["-D/2", 0.0]

[[constraint]]
name = "C"
type = "revolute"
i = "coupler"
j = "rocker"
si = ["D/2", 0.0]
sj = ["L/2", 0.0]

[[constraint]]
name = "O"
type = "revolute"
i = "ground"
j = "rocker"
si = ["D", 0.0]
sj = ["-L/2", 0.0]

[[constraint]]
name = "motor"
type = "relative_angle_driver"
i = "ground"
j = "crank"
f = "e - t"
"""


@pytest.mark.parametrize("backend", ["reference", "numpy", "c"])
def test_a_singular_position_names_its_dependent_constraints(tmp_path: Path, capsys, backend: str) -> None:
    path = tmp_path / "pgram.toml"
    path.write_text(PARALLELOGRAM)
    out = tmp_path / "out.csv"
    assert cli.main(["solve", str(path), "--backend", backend, "-o", str(out)]) == 3
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "t = 0.3" in err[0] and "singular" in err[0]
    named = err[0].split("dependent constraints: ")[1].split(";")[0]
    assert named.strip(), f"no constraint named: {err[0]}"
    assert set(named.split(", ")) <= {"A", "B", "C", "O", "motor"}
    assert len(out.read_text().splitlines()) == 31, "the 30 instants before are kept"
