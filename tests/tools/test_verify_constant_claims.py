"""Found trying symid as a new user: a wrong claim about a mechanism's entry
that has no free symbols (parameters stand for their values) printed an
empty 'counterexample:' line; it now says the claim fails at every point."""

from __future__ import annotations

from pathlib import Path

from symid import cli

GEARS = """
[mechanism]
name = "gears"

[parameters]
TL = 1.5

[[body]]
name = "g1"
mass = 0.3
inertia = 1e-4
q0 = [0.0, 0.0, 0.0]

[[constraint]]
name = "b1"
type = "revolute"
i = "ground"
j = "g1"
si = [0.0, 0.0]
sj = [0.0, 0.0]

[[constraint]]
name = "motor"
type = "relative_angle_driver"
i = "ground"
j = "g1"
f = "t"

[[force]]
name = "load"
type = "torque"
body = "g1"
T = "TL"
"""

CLAIM = """
[claim]
mechanism = "gears.toml"

[[entry]]
quantity = "Q_A"
body = "g1"
value = [0, 0, "-TL"]
"""


def test_a_constant_wrong_claim_says_it_fails_everywhere(tmp_path: Path, capsys) -> None:
    (tmp_path / "gears.toml").write_text(GEARS)
    (tmp_path / "claim.toml").write_text(CLAIM)
    assert cli.main(["verify", str(tmp_path / "claim.toml")]) == 1
    out = capsys.readouterr().out
    assert "derived - claimed = 3" in out
    assert "counterexample: \n" not in out + "\n" and not any(line.rstrip().endswith("counterexample:")
                                                            for line in out.splitlines())
    assert "counterexample: any values" in out
    assert "there derived = [0, 0, 1.5], claimed = [0, 0, -1.5]" in out
