"""Messages a person reads: short numbers, singular and plural, the option or
key a value came from, the real fault named, claims in derive's own notation."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from symid import api
from symid.cli import main
from symid.text import number, plural
from symid.tools.verify import verify

SLIDER_CRANK = str(api.example("slider_crank"))


def test_number_drops_the_rounding_of_a_grid_time() -> None:
    assert number(0.1 * 0.5) == "0.05" and number(0.050000000000000003) == "0.05"
    assert number(1 / 3) == "0.333333333333"
    assert number(1e-20) == "1e-20"


def test_plural_is_singular_for_one() -> None:
    assert plural(1, "Newton iteration") == "1 Newton iteration"
    assert plural(0, "value") == "0 values" and plural(3, "instant") == "3 instants"


def test_failure_time_is_shown_with_the_digits_that_matter(tmp_path: Path, capsys) -> None:
    out = tmp_path / "f.csv"
    status = main(["solve", SLIDER_CRANK, "--set", "L_rod=0.05", "--t1", "0.2", "--steps", "201",
                   "--backend", "reference", "-o", str(out)])
    assert status == 3
    err = capsys.readouterr().err
    shown = re.search(r"t = (\S+):", err).group(1)  # type: ignore[union-attr]
    assert shown == "0.017"
    assert "the 17 instants before it are in" in err


def test_check_says_one_newton_iteration_in_the_singular(capsys) -> None:
    assert main(["check", SLIDER_CRANK]) == 0
    out = capsys.readouterr().out
    assert "Newton iteration" in out and "1 Newton iterations" not in out


@pytest.mark.parametrize(("option", "value", "named"), [
    ("--tol", "0", "--tol: must be a finite number > 0"), ("--steps", "0", "--steps: must be a whole number"),
    ("--t1", "-1", "--t1: must be greater than t0 = 0")])
def test_a_bad_command_line_value_names_the_option(option: str, value: str, named: str, tmp_path: Path,
                                                     capsys) -> None:
    assert main(["solve", SLIDER_CRANK, option, value, "-o", str(tmp_path / "x.csv")]) == 2
    err = capsys.readouterr().err
    assert named in err and "[analysis]" not in err


def test_a_bad_file_value_names_the_key(tmp_path: Path, capsys) -> None:
    path = tmp_path / "m.toml"
    path.write_text(Path(SLIDER_CRANK).read_text().replace("[analysis]", "[analysis]\ntol = 0", 1))
    assert main(["solve", str(path), "-o", str(tmp_path / "x.csv")]) == 2
    assert "[analysis] key 'tol': must be positive" in capsys.readouterr().err


@pytest.mark.parametrize(("q0", "message"), [
    ('["r", 0]', "key 'q0': has 2 values, 3 expected"),
    ('["r", 0, 0]', "key 'q0': unknown name 'r'"),
    ('[true, 0, 0]', "key 'q0': must be a number or an expression string, not a boolean"),
    ('"0, 0, 0"', "key 'q0': must be a list of 3 numbers or expressions, not a string")])
def test_q0_errors_name_the_real_fault(q0: str, message: str, tmp_path: Path, capsys) -> None:
    text = Path(SLIDER_CRANK).read_text()
    path = tmp_path / "m.toml"
    path.write_text(re.sub(r'q0 = \["L_crank/2", 0.0, 0.0\]', lambda _: f"q0 = {q0}", text, count=1))
    assert main(["check", str(path)]) == 2
    assert message in capsys.readouterr().err


@pytest.mark.slow  # derives and verifies a mechanism (29 s under load)
def test_a_claim_may_use_the_names_derive_prints(tmp_path: Path, capsys) -> None:
    assert main(["derive", "revolute_revolute"]) == 0
    shown = capsys.readouterr().out
    assert "dx" in shown and "sᵢx" in shown
    claims = tmp_path / "rr.toml"
    claims.write_text('[claim]\ntype = "revolute_revolute"\n\n'
                      '[[entry]]\nquantity = "Phi"\nvalue = "dx^2 + dy^2 - L^2"\n\n'
                      '[[entry]]\nquantity = "Phi_q"\nbody = "i"\nvalue = ["-2*dx", "-2*dy", "2*(dx*s_iy - dy*s_ix)"]\n\n'
                      '[[entry]]\nquantity = "gamma"\nvalue = "2*(-dx*s_ix*phid_i^2 + dx*s_jx*phid_j^2 - '
                      'dy*s_iy*phid_i^2 + dy*s_jy*phid_j^2 - dxd^2 - dyd^2)"\n\n'
                      '[[entry]]\nquantity = "gamma"\nvalue = "-2*(dxd^2 + dyd^2)"\n')
    report = verify(claims)
    assert [o.equal for o in report.outcomes] == [True, True, True, False]


def test_unknown_claim_name_lists_every_allowed_name(tmp_path: Path) -> None:
    from symid.errors import InputError

    claims = tmp_path / "bad.toml"
    claims.write_text('[claim]\ntype = "revolute_revolute"\n\n[[entry]]\nquantity = "Phi"\nvalue = "dz"\n')
    with pytest.raises(InputError) as info:
        verify(claims)
    listed = str(info.value).split("allowed: ", 1)[1]
    assert "..." not in listed and "yd_j" in listed and "dxd" in listed


def test_a_claim_define_replaces_a_derive_name(tmp_path: Path) -> None:
    claims = tmp_path / "own.toml"
    claims.write_text('[claim]\ntype = "revolute_revolute"\n\n[define]\ndx = "x_j - x_i"\n\n'
                      '[[entry]]\nquantity = "Phi"\nvalue = "dx^2 + dy^2 - L^2"\n')
    assert [o.equal for o in verify(claims).outcomes] == [False]  # its own dx, without the points
