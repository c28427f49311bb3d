"""Found trying symid as a new user: a parameter whose value is complex
(`log(-1)`, `sqrt(-2)`) was refused with sympy's internal class name in the
message; the line now shows the value."""

from __future__ import annotations

from pathlib import Path

import pytest

from symid import cli

FILE = """
[mechanism]
name = "pend"

[parameters]
phi0 = "{value}"

[[body]]
name = "rod"
mass = 1.0
inertia = 0.1
q0 = [0.0, 0.0, 0.0]

[[constraint]]
name = "motor"
type = "coordinate_driver"
body = "rod"
coordinate = "phi"
f = "phi0"
"""


@pytest.mark.parametrize("value, shown", [("log(-1)", "I*pi"), ("sqrt(-2)", "sqrt(2)*I")])
def test_a_complex_parameter_is_one_line_showing_its_value(tmp_path: Path, capsys, value, shown) -> None:
    path = tmp_path / "m.toml"
    path.write_text(FILE.format(value=value))
    assert cli.main(["check", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert "[parameters] key 'phi0'" in err[0] and "is not a real number" in err[0]
    assert "class" not in err[0] and shown in err[0]


PENDULUM = FILE.format(value="0.5") + """
[[constraint]]
name = "dx"
type = "coordinate_driver"
body = "rod"
coordinate = "x"
f = "sin(t)"

[[constraint]]
name = "dy"
type = "coordinate_driver"
body = "rod"
coordinate = "y"
f = "cos(t)"
"""


@pytest.mark.parametrize("grid", [["--t0", "1e15", "--t1", "1000000000000000.5", "--steps", "11"],
                                  ["--t0", "1", "--t1", "1.0000000000000002", "--steps", "3"]])
def test_a_time_grid_finer_than_the_doubles_is_refused(tmp_path: Path, capsys, grid) -> None:
    """t0 + k h rounded to the same double twice gave repeated rows of t, exit 0."""
    path = tmp_path / "m.toml"
    path.write_text(PENDULUM)
    out = tmp_path / "out.csv"
    assert cli.main(["solve", str(path), *grid, "--backend", "numpy", "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--t1" in err[0] and "not distinct" in err[0]
    assert not out.exists()


def test_a_fine_grid_that_the_doubles_hold_still_solves(tmp_path: Path, capsys) -> None:
    path = tmp_path / "m.toml"
    path.write_text(PENDULUM)
    out = tmp_path / "out.csv"
    assert cli.main(["solve", str(path), "--t0", "1e15", "--t1", "1000000000000002", "--steps", "9",
                     "--backend", "numpy", "-o", str(out)]) == 0
    times = [line.split(",")[0] for line in out.read_text().splitlines()[1:]]
    assert len(set(times)) == len(times) == 9
