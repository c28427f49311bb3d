"""The user's own elements (issue 28.1, 28.2): constraints written as expressions.

Truth is independent of the new family: the built-in four-bar (whose families
are checked against the reference's hand blocks in test_derivations) written
again row by row as expressions must give the same table on every backend.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from symid import api
from symid.cli import main


from compare import assert_agree

BACKENDS = ("reference", "numpy", "casadi", "c")


def _point(role: str, s: tuple[str, str]) -> tuple[str, str]:
    """Global x, y of the body point s (body coordinates), written as the reference's r + A s."""
    x, y = s
    return (f"x_{role} + cos(phi_{role})*({x}) - sin(phi_{role})*({y})",
            f"y_{role} + sin(phi_{role})*({x}) + cos(phi_{role})*({y})")


def as_expressions(text: str) -> str:
    """A mechanism file with every revolute and relative angle driver written as
    `type = "expression"` rows: the reference's Phi, the same signs and order."""
    def revolute(m: re.Match) -> str:
        block = m.group(0)
        get = lambda k: re.search(rf"^{k} = (.*)$", block, re.M).group(1)  # noqa: E731
        pair = lambda k: tuple(str(v) for v in eval(get(k)))  # noqa: E731,S307 (the test's own file)
        xi, yi = _point("i", pair("si"))
        xj, yj = _point("j", pair("sj"))
        return (f'[[constraint]]\nname = {get("name")}\ntype = "expression"\ni = {get("i")}\nj = {get("j")}\n'
                f'phi = ["{xj} - ({xi})", "{yj} - ({yi})"]\nsi = {get("si")}\nsj = {get("sj")}\n')

    def driver(m: re.Match) -> str:
        name, i, j, f = m.groups()
        return f'[[constraint]]\nname = {name}\ntype = "expression"\ni = {i}\nj = {j}\nphi = ["phi_j - phi_i - ({f})"]\n'

    out = re.sub(r'\[\[constraint\]\]\nname = "\w+"\ntype = "revolute"\n(?:.*\n)*?sj = .*\n', revolute, text)
    out = re.sub(r'\[\[constraint\]\]\nname = ("\w+")\ntype = "relative_angle_driver"\ni = (".*")\nj = (".*")\n'
                 r'f = "(.*)"\n', driver, out)
    assert "revolute" not in out and "relative_angle_driver" not in out
    return out


@pytest.fixture(scope="module")
def four_bars(tmp_path_factory):
    folder = tmp_path_factory.mktemp("four_bar")
    builtin = api.example("four_bar")
    rewritten = folder / "four_bar.toml"
    rewritten.write_text(as_expressions(builtin.read_text()))
    return ({b: api.solve(builtin, backend=b) for b in BACKENDS},
            {b: api.solve(rewritten, backend=b) for b in BACKENDS})


@pytest.mark.parametrize("backend", BACKENDS)
def test_four_bar_of_expressions_equals_the_built_in_four_bar(four_bars, backend):
    builtin, rewritten = four_bars
    assert rewritten[backend].columns == builtin[backend].columns
    # every column to 1e-12 of its peak; a column that is zero by the built-in's
    # algebra (a revolute's torque) against the table's scale (compare.assert_agree):
    # the expression's (B s)^T Phi_r^T lambda - Phi_phi^T lambda cancels to rounding only
    assert_agree(rewritten[backend].data, builtin[backend].data, rel=1e-12)


# A slider on ground: y and phi held by one expression constraint of two rows,
# x driven by another. Each bad case changes one line of it.
SLIDER = """
[mechanism]
name = "slider"

[parameters]
h = 0.2

[signals]
stroke = "0.1*sin(2*t)"

[[body]]
name = "block"
mass = 1.0
inertia = 0.01
q0 = [0.0, 0.2, 0.0]

[[constraint]]
name = "guide"
type = "expression"
i = "block"
phi = ["y_i - h", "phi_i"]

[[constraint]]
name = "drive"
type = "expression"
i = "block"
phi = ["x_i - stroke"]
"""

BAD = [
    ("unknown symbol", ('"y_i - h"', '"y_i - hh"'), r"constraint 'guide' key 'phi' row 1: unknown name 'hh'"),
    ("coordinate of an absent j", ('"phi_i"]', '"phi_i - phi_j"]'), r"key 'phi' row 2: unknown name 'phi_j'"),
    ("unknown body", ('i = "block"\nphi = ["y_i', 'i = "blok"\nphi = ["y_i'),
     r"constraint 'guide' key 'i': unknown body 'blok'"),
    ("no coordinate", ('"phi_i"]', '"h - 0.2"]'), r"key 'phi' row 2: depends on no coordinate \(x_i, y_i, phi_i\)"),
    ("empty", ('["y_i - h", "phi_i"]', '[]'), r"constraint 'guide' key 'phi': must be a list of expressions, one per "
     r"constraint row, not an empty list"),
    ("dependent at q0", ('"phi_i"]', '"2*y_i - 2*h + phi_i^2"]'),
     r"constraint 'guide' key 'phi': row 2 depends on row 1 at q0"),
    ("state function in a row", ('"phi_i"]', '"phi_i - omega(block)"]'),
     r"key 'phi' row 2: omega\(\) at column 9 is a state function, allowed in forces only"),
    ("state function in a signal", ('"0.1*sin(2*t)"', '"0.1*sin(2*t) + vx(block)"'),
     r"\[signals\] key 'stroke': vx\(\) at column 16 is a state function, allowed in forces only"),
    ("abs in a row", ('"y_i - h"', '"abs(y_i) - h"'),
     r"key 'phi' row 1: abs\(\) at column 1 is not differentiable at 0"),
    ("sign in a row", ('"phi_i"]', '"phi_i*sign(x_i)"]'),
     r"key 'phi' row 2: sign\(\) at column 7 is not differentiable at 0"),
    ("a driver not g(q) - f(t)", ('"x_i - stroke"', '"x_i*(1 + t) - stroke"'),
     r"constraint 'drive' key 'phi' row 1: the term .* mixes t and the coordinates"),
    ("a driver among other rows", ('"phi_i"]', '"phi_i - 0.1*t"]'),
     r"constraint 'guide' key 'phi': a row with t is a driver: give each driver row a constraint of its own"),
]


@pytest.mark.parametrize("label,change,pattern", BAD, ids=[b[0] for b in BAD])
def test_bad_expression_input_is_one_line_exit_2_naming_file_and_key(tmp_path, capsys, label, change, pattern):
    old, new = change
    assert SLIDER.count(old) == 1, old
    path = tmp_path / "bad.toml"
    path.write_text(SLIDER.replace(old, new))
    status = main(["check", str(path)])
    err = capsys.readouterr().err
    assert status == 2, err
    assert len(err.strip().splitlines()) == 1, err
    assert err.startswith(f"symid: {path}: "), err
    assert re.search(pattern, err), err


def test_the_slider_itself_is_good(tmp_path, capsys):
    path = tmp_path / "slider.toml"
    path.write_text(SLIDER)
    assert main(["check", str(path)]) == 0, capsys.readouterr().err
