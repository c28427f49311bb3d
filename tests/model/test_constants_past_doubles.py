"""A number written in a file that is a double but whose products are not
(a body's `mass = 1e308`: sympy folds m*g into one constant, 9.81e308) ends
as a value past the doubles does when given as a parameter: exit 3 at t0
naming the body, on every backend. The NumPy module printed that constant as
a 309-digit integer and raised OverflowError (issue 32); the printers now
print every constant as the double it rounds to (inf past the range).
"""

from __future__ import annotations

import math
from fractions import Fraction
from pathlib import Path

import pytest
import sympy as sp

from symid import api
from symid.cli import main
from symid.codegen.targets.numpy_target import mathcode, pycode

BACKENDS = ("numpy", "c", "casadi", "reference")


def _literal_mass_file(tmp_path: Path) -> Path:
    text = api.example("four_bar").read_text(encoding="utf-8")
    lines = text.splitlines()
    first = next(k for k, line in enumerate(lines) if line.startswith("mass = "))
    lines[first] = "mass = 1e308"  # the crank's mass as a literal, not a parameter
    path = tmp_path / "heavy.toml"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_literal_mass_past_the_doubles_times_g_stops_at_t0_naming_the_body(tmp_path: Path, capsys,
                                                                              backend: str) -> None:
    path = _literal_mass_file(tmp_path)
    out = tmp_path / "out.csv"
    status = main(["solve", str(path), "--steps", "5", "--backend", backend, "-o", str(out)])
    err = capsys.readouterr().err
    assert "Traceback" not in err and "OverflowError" not in err, err
    assert status == 3 and err.count("\n") == 1, err
    assert "heavy.toml: t = 0:" in err and "not finite" in err and "body crank" in err, err


@pytest.mark.parametrize("value", [
    sp.Integer(10) ** 400, -sp.Integer(10) ** 400, sp.Integer(2) ** 60 + 1, sp.Rational(981, 100) * sp.Integer(10) ** 306,
    sp.Rational(10 ** 400, 3 ** 700), sp.Rational(1, 2 ** 60 + 1), sp.Rational(-(10 ** 500), 7), sp.Float("1e400"),
])
def test_each_constant_prints_as_the_double_it_rounds_to(value: sp.Expr) -> None:
    """Truth: Python's exact Fraction rounded to a double (correctly rounded), +-inf past the range."""
    exact = Fraction(int(value.p), int(value.q)) if value.is_Rational else Fraction(str(value))
    try:
        want = float(exact)
    except OverflowError:
        want = math.inf if exact > 0 else -math.inf
    x = sp.Symbol("x")
    for code in (pycode(value + x), mathcode(value + x)):
        got = eval(code, {"x": 0.0, "numpy": None, "math": math})
        assert got == want, (code, want)
