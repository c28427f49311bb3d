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
