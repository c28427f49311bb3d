"""Tests of `symid.tools.verify` and `symid verify`: claim files against the derivation.

A wrong claim must be caught at the right entry with a counterexample that is
valid on its own: the derivation (from `derive_constraint`, substituted here)
and the claim (written here in sympy) differ at the reported point, and the
point satisfies the claim's condition.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest
import sympy as sp

from symid.symbolic import symbols as s
from symid.tools import verify as verify_module
from symid.cli import main
from symid.symbolic.derive import derive_constraint
from symid.errors import InputError
from symid.tools.verify import Report, bundled, verify, verify_text

CLAIMS = {p.stem: p for p in bundled()}
REFERENCE_TABLE = {"revolute", "revolute_revolute", "parallel", "pin_in_slot",
                   "relative_angle_driver", "gear", "gear_on_link"}


def sym(name: str) -> sp.Symbol:
    return sp.Symbol(name, real=True)


def at(expr: sp.Basic, point: dict[str, sp.Expr]) -> sp.Matrix:
    """`expr` at a report's point (names -> values), numerically."""
    m = sp.Matrix([expr]) if not isinstance(expr, sp.MatrixBase) else expr
    missing = {x.name for x in m.free_symbols} - set(point)
    assert not missing, f"point leaves {missing} free"
    return m.xreplace({x: point[x.name] for x in m.free_symbols}).evalf(30)


def mutated(name: str, old: str, new: str) -> str:
    text = CLAIMS[name].read_text()
    assert text.count(old) == 1, old
    return text.replace(old, new)


def only_failure(report: Report) -> int:
    failed = [o.index for o in report.outcomes if not o.equal]
    assert len(failed) == 1, report.text()
    return failed[0]


# -- the bundled claims ---------------------------------------------------------------

def test_bundled_claims_cover_every_entry_of_the_reference_table():
    assert set(CLAIMS) == REFERENCE_TABLE


@pytest.mark.parametrize("name", sorted(CLAIMS))
def test_every_bundled_claim_verifies(name):
    report = verify(CLAIMS[name])
    assert report.ok and report.exit_status == 0, report.text()
    assert all(o.method == "symbolic" for o in report.outcomes), report.text()
    assert report.text().endswith(f"all {len(report.outcomes)} entries hold")


def test_notes_reactions_are_claimed_at_consistent_configurations():
    for name in ("parallel", "pin_in_slot"):
        conditions = {o.label: o.condition for o in verify(CLAIMS[name]).outcomes}
        assert conditions["T_on_i"].startswith("consistent: ") and "alpha > 0" in conditions["T_on_i"]


# -- wrong claims are caught, at the right entry, with a valid counterexample ---------

def test_wrong_sign_is_caught_with_a_valid_counterexample():
    text = mutated("revolute_revolute", 'value = ["2*d_x*lambda", "2*d_y*lambda"]',
                   'value = ["2*d_x*lambda", "-2*d_y*lambda"]')
    report = verify_text(text, "wrong_sign.toml")
    index = only_failure(report)
    bad = report.outcomes[index - 1]
    assert bad.label == "F_on_i" and bad.wrong == ((1, 0),) and report.exit_status == 1
    derived = derive_constraint("revolute_revolute").reactions["i"][:2, :]
    d_y = (s.global_point("j", "sj") - s.global_point("i", "si"))[1]
    claimed = sp.Matrix([derived[0], -2 * d_y * s.lam(1)[0]])
    d_at, c_at = at(derived, bad.point), at(claimed, bad.point)
    # the claim differs from the derivation (1e-6) in one entry and agrees exactly, to rounding, in the other
    assert abs(d_at[1] - c_at[1]) > 1e-6 and abs(d_at[0] - c_at[0]) < 1e-20
    assert [float(v) for v in d_at] == pytest.approx(bad.derived_at)
    assert [float(v) for v in c_at] == pytest.approx(bad.claimed_at)
    assert sp.simplify(bad.difference[1] - 4 * d_y * s.lam(1)[0]) == 0


def test_missing_term_is_caught_with_a_valid_counterexample():
    text = mutated("revolute", 'value = ["s_j_x*phid_j^2 - s_i_x*phid_i^2", "s_j_y*phid_j^2 - s_i_y*phid_i^2"]',
                   'value = ["s_j_x*phid_j^2", "s_j_y*phid_j^2 - s_i_y*phid_i^2"]')
    report = verify_text(text, "missing_term.toml")
    bad = report.outcomes[only_failure(report) - 1]
    assert bad.label == "gamma" and bad.wrong == ((0, 0),)
    phi_i, phid_i = s.q("i")[2], s.qd("i")[2]
    s_ix = sym("six") * sp.cos(phi_i) - sym("siy") * sp.sin(phi_i)
    assert sp.simplify(bad.difference[0] + s_ix * phid_i ** 2) == 0  # exactly the missing term
    derived = derive_constraint("revolute").gamma[0]
    claimed = (sym("sjx") * sp.cos(s.q("j")[2]) - sym("sjy") * sp.sin(s.q("j")[2])) * s.qd("j")[2] ** 2
    assert abs(at(derived, bad.point)[0] - at(claimed, bad.point)[0]) > 1e-6


def test_wrong_body_block_is_caught_with_a_valid_counterexample():
    text = mutated("revolute_revolute", 'value = ["-2*d_x", "-2*d_y", "-2*(d_x*Bs_i_x + d_y*Bs_i_y)"]',
                   'value = ["-2*d_x", "-2*d_y", "-2*(d_x*Bs_j_x + d_y*Bs_j_y)"]')
    report = verify_text(text, "wrong_block.toml")
    bad = report.outcomes[only_failure(report) - 1]
    assert bad.label == "Phi_q, body i" and bad.wrong == ((0, 2),)
    assert "#2 Phi_q, body i: NOT EQUAL" in report.text()
    derived = derive_constraint("revolute_revolute").jac["i"][0, 2]
    d = s.global_point("j", "sj") - s.global_point("i", "si")
    claimed = -2 * (d.T * s.B("j") * s.point("sj"))[0]  # body j's B s' in body i's block
    assert abs(at(derived, bad.point)[0] - at(claimed, bad.point)[0]) > 1e-6


@pytest.mark.slow  # three verifications of mutated claims; verify's other outcomes stay in the quick tier
def test_consistent_condition_is_meant_and_its_counterexamples_are_consistent():
    general = mutated("parallel", 'value = "norm(a_i_x, a_i_y)*norm(a_j_x, a_j_y)*lambda"\ncondition = "consistent"',
                      'value = "norm(a_i_x, a_i_y)*norm(a_j_x, a_j_y)*lambda"\ncondition = "general"')
    assert only_failure(verify_text(general, "general.toml")) == 7  # not true in general
    flipped = mutated("parallel", 'value = "norm(a_i_x, a_i_y)*norm(a_j_x, a_j_y)*lambda"',
                      'value = "-norm(a_i_x, a_i_y)*norm(a_j_x, a_j_y)*lambda"')
    report = verify_text(flipped, "flipped.toml")
    bad = report.outcomes[only_failure(report) - 1]
    a_i, a_j = s.A("i") * s.vector("vi"), s.A("j") * s.vector("vj")
    assert abs(at(a_i[0] * a_j[1] - a_i[1] * a_j[0], bad.point)[0]) < 1e-20  # parallel ...
    assert at(a_i.dot(a_j), bad.point)[0] > 0  # ... and pointing the same way
    assert bad.point["alpha"] > 0


def test_pin_in_slot_counterexample_puts_the_pin_ahead_on_the_slot():
    text = mutated("pin_in_slot", 'value = "norm(a_x, a_y)*norm(d_x, d_y)*lambda"', 'value = "norm(d_x, d_y)*lambda"')
    report = verify_text(text, "slot.toml")
    bad = report.outcomes[only_failure(report) - 1]
    d = s.global_point("j", "sj") - s.global_point("i", "si")
    a = s.A("i") * s.vector("vi")
    # Phi of the chosen point is zero: rounding of a 30-digit evaluation
    assert abs(at(derive_constraint("pin_in_slot").phi[0], bad.point)[0]) < 1e-20
    assert at(a.dot(d), bad.point)[0] > 0


@pytest.mark.slow  # two numeric verifications of a claim; verify's other outcomes stay in the quick tier
def test_inconclusive_simplification_falls_back_to_seeded_numeric_testing(monkeypatch):
    monkeypatch.setattr(verify_module, "_simplified", lambda e: e)
    report = verify(CLAIMS["revolute_revolute"])
    assert report.ok
    assert {o.method for o in report.outcomes} >= {"numeric, 24 seeded random points"}
    assert verify(CLAIMS["revolute_revolute"]).outcomes == report.outcomes  # seeded: repeatable


def test_custom_condition_substitutes_new_positive_symbols():
    text = """
[claim]
type = "revolute_revolute"
[[entry]]
quantity = "Phi"
value = "0"
[entry.condition]
positive = ["th"]  # a new symbol: the direction of the link
[entry.condition.substitute]
x_j = "x_i + six*cos(phi_i) - siy*sin(phi_i) - sjx*cos(phi_j) + sjy*sin(phi_j) + L*cos(th)"
y_j = "y_i + six*sin(phi_i) + siy*cos(phi_i) - sjx*sin(phi_j) - sjy*cos(phi_j) + L*sin(th)"
"""
    report = verify_text(text, "custom.toml")
    assert report.ok and report.outcomes[0].condition.startswith("where x_j = ")


def test_driver_function_may_be_written_f_of_t():
    text = ('[claim]\ntype = "relative_angle_driver"\n[[entry]]\nquantity = "Phi"\n'
            'value = "phi_j - phi_i - C - f(t)"\n[[entry]]\nquantity = "gamma"\nvalue = "fdd(t)"\n')
    assert verify_text(text).ok


# -- whole mechanisms ------------------------------------------------------------------

MECHANISM = """
[claim]
mechanism = "slider_crank"
[[entry]]
quantity = "Phi_q"
constraint = "main_bearing"
body = "crank"
value = [["1", "0", "L_crank/2*sin(phi_crank)"], ["0", "1", "-L_crank/2*cos(phi_crank)"]]
[[entry]]
quantity = "Q_A"
body = "slider"
value = ["-F_gas*sin(omega*t)", "-9.81*m_slider", 0]
[[entry]]
quantity = "M"
body = "crank"
value = [["m_crank", 0, 0], [0, "m_crank", 0], [0, 0, "m_crank*L_crank^2/12"]]
[[entry]]
quantity = "Phi"
constraint = "crank_pin"
value = [0, 0]
condition = "consistent"
[[entry]]
quantity = "Phi"
constraint = "crank_pin"
value = [0, 0]
"""


def test_mechanism_claims_use_body_names_and_parameter_values():
    report = verify_text(MECHANISM, "mech.toml")
    assert [o.equal for o in report.outcomes] == [True, True, True, True, False]
    assert report.outcomes[3].method == "numeric, 5 solved configurations"
    assert report.outcomes[4].label == "Phi, constraint crank_pin"


# -- malformed files: exit status 2, one clear line --------------------------------------

HEAD = '[claim]\ntype = "gear"\n'
MALFORMED = [
    ("[claim\n", r"bad\.toml: TOML syntax error"),
    ('[[entry]]\nquantity = "Phi"\nvalue = 0\n', r"bad\.toml: \[claim\]: must be a table"),
    ('[claim]\ntype = "gear"\nmechanism = "x.toml"\n[[entry]]\nquantity = "Phi"\nvalue = 0\n',
     r"\[claim\]: give exactly one of 'type' and 'mechanism'"),
    ('[claim]\ntype = "cog"\n[[entry]]\nquantity = "Phi"\nvalue = 0\n', r"\[claim\] key 'type': unknown constraint type 'cog'"),
    (HEAD, r"no \[\[entry\]\]"),
    (HEAD + '[[entry]]\nquantity = "Psi"\nvalue = 0\n', r"entry #1: key 'quantity': unknown quantity 'Psi'"),
    (HEAD + '[[entry]]\nquantity = "Phi"\n', r"entry #1: missing key 'value'"),
    (HEAD + '[[entry]]\nquantity = "Phi_q"\nbody = "m"\nvalue = 0\n', r"entry #1: key 'body': 'm' is not one of i, j"),
    (HEAD + '[[entry]]\nquantity = "Phi_q"\nbody = "i"\nvalue = [0, 0]\n', r"entry #1 key 'value': expected 1 x 3"),
    (HEAD + '[[entry]]\nquantity = "Phi"\nvalue = "phi_q + 1"\n', r"entry #1 key 'value': unknown name 'phi_q'"),
    (HEAD + '[[entry]]\nquantity = "Phi"\nvalue = "__import__(\'os\')"\n', r"entry #1 key 'value': "),
    (HEAD + '[[entry]]\nquantity = "Phi"\nvalue = 0\ncondition = "sometimes"\n', r"entry #1 key 'condition': must be"),
    (HEAD + '[[entry]]\nquantity = "Phi"\nvalue = 0\ncolour = 1\n', r"entry #1 key 'colour': unknown key"),
    (HEAD + '[define]\nK = "1"\n[[entry]]\nquantity = "Phi"\nvalue = 0\n', r"\[define\] key 'K': is a name of the symbol table"),
    (HEAD + '[[entry]]\nquantity = "Phi_q"\nvalue = { m = [0, 0, 1] }\n', r"entry #1 key 'value': unknown block 'm'"),
]


@pytest.mark.parametrize("text, message", MALFORMED)
def test_malformed_claim_files_are_input_errors_naming_file_and_entry(text, message, tmp_path, capsys):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(InputError, match=message):
        verify(path)
    assert main(["verify", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"symid: {path}")


# -- the command line --------------------------------------------------------------------

def test_verify_command_exit_status_is_0_when_all_hold_and_1_when_any_does_not(tmp_path, capsys):
    assert main(["verify", "--bundled"]) == 0
    out = capsys.readouterr().out
    assert out.count("entries hold") == len(CLAIMS) and "NOT EQUAL" not in out
    wrong = tmp_path / "wrong.toml"
    wrong.write_text(mutated("gear", 'value = "K*lambda"', 'value = "-K*lambda"'))
    assert main(["verify", str(wrong), str(CLAIMS["gear"])]) == 1
    out = capsys.readouterr().out
    assert re.search(r"#6 T_on_i: NOT EQUAL .*\n.*element \[1, 1\]: derived - claimed = 2\*K\*lambda", out)
    assert "counterexample: K = " in out


def test_claim_file_may_name_a_mechanism_file_next_to_it(tmp_path):
    from symid import api

    (tmp_path / "m.toml").write_text(Path(api.example("planetary")).read_text())
    (tmp_path / "c.toml").write_text('[claim]\nmechanism = "m.toml"\n[[entry]]\nquantity = "gamma"\n'
                                     'constraint = "sun_planet_mesh"\nvalue = 0\n')
    assert verify(tmp_path / "c.toml").ok


def test_derive_page_verify_example_gives_the_verdicts_shown(tmp_path, capsys, monkeypatch):
    section = (Path(__file__).parents[2] / "docs" / "derive.md").read_text(encoding="utf-8")
    claim = section.split("```toml\n", 1)[1].split("```", 1)[0]
    shown = section.split("$ symid verify gear_homework.toml\n", 1)[1].split("$ echo", 1)[0]
    (tmp_path / "gear_homework.toml").write_text(claim)
    monkeypatch.chdir(tmp_path)
    assert main(["verify", "gear_homework.toml"]) == 1
    out = capsys.readouterr().out

    def verdicts(text: str) -> list[str]:
        return [line for line in text.splitlines() if re.match(r"\s+#\d", line) or "entries" in line]
    assert verdicts(out) == verdicts(shown) and len(verdicts(out)) == 3


def test_blocks_may_be_claimed_whole_split_or_by_body():
    text = """
[claim]
type = "gear_on_link"
[[entry]]
quantity = "Phi_q"
value = [[0, 0, "-K", 0, 0, 1, 0, 0, "K - 1"]]
[[entry]]
quantity = "Phi_r"
body = "k"
value = [0, 0]
[[entry]]
quantity = "Phi_phi"
body = "i"
value = "-K"
[[entry]]
quantity = "T_on"
body = "k"
value = "(1 - K)*lambda"
[[entry]]
quantity = "Phi_q"
value = { k = [0, 0, "K - 1"] }
"""
    report = verify_text(text)
    assert report.ok and [o.label for o in report.outcomes] == [
        "Phi_q", "Phi_r, body k", "Phi_phi, body i", "T_on_k", "Phi_q"]


def test_mechanism_whole_quantities_are_assembled_in_row_and_body_order():
    text = """
[claim]
mechanism = "planetary"
[[entry]]
quantity = "Q_A"
value = [0, "-9.81*m_sun", 0, 0, "-9.81*m_carrier", "T_load", 0, "-9.81*m_planet", 0, 0, "-9.81*m_pinion", 0]
[[entry]]
quantity = "gamma"
value = [0, 0, 0, 0, "-phid_carrier^2*(r_sun + r_planet)*cos(phi_carrier)",
         "-phid_carrier^2*(r_sun + r_planet)*sin(phi_carrier)", 0, 0, 0, 0, 0, 0]
"""
    assert verify_text(text).ok
