"""Tests of `symid.tools.show` and `symid derive`: readable, exact, LaTeX and Jupyter.

Truth is the hand definitions of the notation (s_i = A_i s'_i, a_i = A_i v'_i,
d = d_ij and its rate, written here again) and finite differences of Phi.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

from symid import api
from symid.symbolic import symbols as s
from symid.cli import main
from symid.symbolic.constraints import TYPES
from symid.symbolic.derive import derive_constraint
from symid.errors import InputError
from symid.io.reader import load
from symid.tools.notation import display_names, latex, pretty
from symid.tools.show import Derivation, _abbreviations, abbreviate, derive_mechanism, derive_type, mechanism_system

# every type with rows of its own (an expression constraint's are its file's: tests/test_expression_elements)
VARIANTS = [(n, {"coordinate": "phi"} if n == "coordinate_driver" else {}) for n in sorted(TYPES)
            if TYPES[n].shape is None]


def vid(v: tuple[str, dict]) -> str:
    return v[0]


def rot(phi: sp.Expr) -> sp.Matrix:
    return sp.Matrix([[sp.cos(phi), -sp.sin(phi)], [sp.sin(phi), sp.cos(phi)]])


def back_substitution() -> dict[sp.Symbol, sp.Expr]:
    """The display variables in terms of the generic symbols, from their definitions."""
    sym = lambda n: sp.Symbol(n, real=True)  # noqa: E731
    out: dict[sp.Symbol, sp.Expr] = {}
    for name, key, role in (("s", "si", "i"), ("s", "sj", "j"), ("a", "vi", "i"), ("a", "vj", "j")):
        g = rot(s.q(role)[2]) * sp.Matrix(s.point(key))
        out.update({sym(f"_{name}_{role}x"): g[0], sym(f"_{name}_{role}y"): g[1]})
    p = {r: sp.Matrix(s.q(r)[:2]) + rot(s.q(r)[2]) * sp.Matrix(s.point("s" + r)) for r in "ij"}
    d = p["j"] - p["i"]
    d_dot = sp.Matrix([sum(sp.diff(e, q) * qd for r in "ij" for q, qd in zip(s.q(r), s.qd(r))) for e in d])
    out.update({sym("_d_x"): d[0], sym("_d_y"): d[1], sym("_dd_x"): d_dot[0], sym("_dd_y"): d_dot[1]})
    return out


@pytest.mark.parametrize("variant", VARIANTS, ids=vid)
def test_every_type_is_shown_in_unicode_and_latex(variant):
    shown = derive_type(*variant)
    text, tex = shown.text(), shown.latex()
    roles = derive_constraint(variant[0], tuple(variant[1].items())).roles
    for label in ["\u03a6 =", "\u03bd = -\u03a6_t", "\u03b3 ="] + [f"F_on_{r}" for r in roles] + [f"T_on_{r}" for r in roles]:
        assert label in text
    assert tex.startswith("\\begin{aligned}") and tex.endswith("\\end{aligned}")
    assert tex.count("{") == tex.count("}")
    assert all(f"T_{{\\text{{on }}{r}}}" in tex for r in roles)
    assert not re.search(r"[\u0370-\u03ff\u1d62\u2c7c]", tex), "Unicode left in the LaTeX"
    assert shown._repr_latex_() == "$$\n" + tex + "\n$$"


@pytest.mark.parametrize("variant", VARIANTS, ids=vid)
def test_abbreviated_display_is_an_exact_change_of_variables(variant):
    der = derive_constraint(variant[0], tuple(variant[1].items()))
    subs, _ = _abbreviations(der)
    back = back_substitution()
    quantities = [der.phi, der.nu, der.gamma, *der.jac.values(), *der.reactions.values()]
    rng = np.random.default_rng(11)
    for m in quantities:
        diff = abbreviate(m, subs).xreplace(back) - m
        for _ in range(5):  # exact identity, checked at random points (simplify is slow on roots)
            point = {x: sp.Float(rng.uniform(-2, 2), 30) for x in diff.free_symbols}
            # an identity evaluated with 30 digits: zero to 1e-20
            assert np.abs(np.array(diff.xreplace(point).evalf(30), dtype=complex)).max() < 1e-20


def test_hand_notation_gives_the_notes_blocks():
    text = derive_type("revolute").text()
    assert "where s\u1d62 = A\u1d62 s\u2032\u1d62" in text
    assert "-s\u1d62x" in text and "s\u2c7cx" in text  # Phi_phi_i = -B_i s'_i = [s_iy, -s_ix]
    rr = derive_type("revolute_revolute").text()
    assert "F_on_i (at P\u1d62)" in rr and "2\u22c5dx\u22c5\u03bb" in rr


def test_driver_is_shown_as_f_of_t_and_its_derivatives():
    shown = derive_type("relative_angle_driver")
    assert "f(t)" in shown.text() and "\u03bd = -\u03a6_t = f\u2032(t)" in shown.text()
    assert "\u03b3 = f\u2033(t)" in shown.text()
    assert "f''(t)" in shown.latex()


@pytest.mark.parametrize("name, uni, tex", [
    ("phid_i", "\u03c6\u0307\u1d62", r"\dot{\phi}_{i}"), ("x_j", "x\u2c7c", "x_{j}"),
    ("six", "s\u2032\u1d62x", "s'_{ix}"), ("vjy", "v\u2032\u2c7cy", "v'_{jy}"),
    ("theta0", "\u03b8\u2080", r"\theta_{0}"), ("lambda2", "\u03bb\u2082", r"\lambda_{2}"),
    ("fdd", "f\u2033(t)", "f''(t)"), ("phi_crank", "\u03c6_crank", r"\phi_{\mathrm{crank}}"),
    ("yd_connecting_rod", "y\u0307_connecting_rod", r"\dot{y}_{\mathrm{connecting\_rod}}"),
])
def test_symbol_table_names_display_in_the_notes_notation(name, uni, tex):
    assert display_names(name) == (uni, tex)
    x = sp.Symbol(name, real=True)
    assert pretty(x) == uni and latex(x) == tex


def test_unknown_type_and_missing_variant_are_input_errors():
    with pytest.raises(InputError, match="unknown constraint type 'hinge'.*revolute"):
        derive_type("hinge")
    with pytest.raises(InputError, match="coordinate"):
        derive_type("coordinate_driver")


def test_mechanism_derivation_shows_the_block_structure():
    shown = derive_mechanism(api.example("slider_crank"))
    text, tex = shown.text(), shown.latex()
    table = text.split("\u00b7 zero)\n", 1)[1].split("\n\n", 1)[0].splitlines()
    assert table[0].split() == ["rows", "crank", "connecting_rod", "slider"]
    assert table[1].split() == ["main_bearing", "1-2", "B1", "\u00b7", "\u00b7"]
    assert table[2].split() == ["crank_pin", "3-4", "B2", "B3", "\u00b7"]
    assert table[5].split() == ["motor", "9", "B7", "\u00b7", "\u00b7"]
    assert "B7 = \u03a6_q[motor, crank] = [0  0  1]" in text
    for label in ("\u03b3[crank_pin]", "Q^A[slider]", "diag M[crank]"):
        assert label in text
    array = tex.split(r"\begin{array}{ccc|ccc|ccc}", 1)[1].split(r"\end{array}", 1)[0]
    assert array.count(r"\hline") == 4 and array.count(r"\\") == 9


@pytest.mark.parametrize("name", ["slider_crank", "planetary", "slider_pendulum"])
def test_mechanism_phi_q_equals_finite_differences_of_phi(name):
    sysm = mechanism_system(load(api.example(name)))
    mech = sysm.mechanism
    params = {sp.Symbol(k, real=True): v for k, v in mech.parameters.items()}
    for _ in range(len(params)):
        params = {k: v.xreplace(params) for k, v in params.items()}
    phi = sp.Matrix.vstack(*sysm.phi.values()).xreplace(params)
    jac = sysm.phi_q().xreplace(params)
    rng = np.random.default_rng(5)
    point = {x: rng.uniform(-1, 1) for x in sysm.coords} | {s.T: 0.3}
    f = sp.lambdify([list(sysm.coords), s.T], phi, "numpy")
    q0 = np.array([point[x] for x in sysm.coords])
    h = 1e-6
    fd = np.column_stack([(f(q0 + h * e, 0.3) - f(q0 - h * e, 0.3)).ravel() / (2 * h) for e in np.eye(len(q0))])
    exact = np.array(jac.xreplace(point).evalf(), dtype=float)
    # central differences: truncation O(h^2) and cancellation, 1e-7 with room
    np.testing.assert_allclose(exact, fd, atol=1e-7)


def test_mechanism_applied_forces_and_mass():
    sysm = mechanism_system(load(api.example("slider_crank")))
    m, g = sp.Symbol("m_slider", real=True), sp.Rational(-981, 100)
    force = -sp.Symbol("F_gas", real=True) * sp.sin(sp.Symbol("omega", real=True) * s.T)
    assert sp.simplify(sysm.applied["slider"] - sp.Matrix([force, m * g, 0])) == sp.zeros(3, 1)
    assert sysm.mass["slider"][0] == m


def test_derive_command_prints_a_type_a_mechanism_and_latex(capsys):
    assert main(["derive", "gear"]) == 0
    assert "T_on_i = K\u22c5\u03bb" in capsys.readouterr().out
    assert main(["derive", "pin_in_slot", "--latex"]) == 0
    assert capsys.readouterr().out.startswith("\\begin{aligned}")
    assert main(["derive", str(api.example("planetary"))]) == 0
    assert "gear rows relate angles only" in capsys.readouterr().out


def test_derive_command_refuses_unknown_subjects_in_one_line(capsys):
    assert main(["derive", "hinge"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "neither a constraint type nor a mechanism file" in err
    assert main(["derive", "missing.toml"]) == 2
    assert "missing.toml" in capsys.readouterr().err


def test_derivation_is_plain_data_for_the_api():
    shown = derive_type("gear")
    assert isinstance(shown, Derivation)
    values = {item.label.split()[0]: item.value for item in shown.items}
    assert values["T_on_i"] == s.scalar("K") * s.lam(1)[0]


def test_derive_page_example_matches_the_derivation():
    section = (Path(__file__).parents[2] / "docs" / "derive.md").read_text(encoding="utf-8")
    shown = section.split("```\n", 1)[1].split("```", 1)[0]
    actual = [line.rstrip() for line in derive_type("revolute_revolute").text().splitlines()]
    one_line = [line for line in shown.splitlines() if " = " in line and not re.search("[\u239b-\u23a6]", line)]
    assert len(one_line) >= 6 and all(line in actual for line in one_line)


def test_driver_symbols_become_f_of_t_and_its_derivatives_for_the_api():
    from symid.tools.show import with_functions

    f = sp.Function("f", real=True)(s.T)
    gamma = with_functions(derive_constraint("relative_angle_driver").gamma[0])
    assert gamma == sp.Derivative(f, (s.T, 2))
    assert with_functions(s.F_SERIES[0] + s.F_SERIES[1]) == f + sp.Derivative(f, s.T)
