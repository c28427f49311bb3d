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
