"""`symid derive TYPE --option KEY=VALUE`: an option the type has no variant
choice for is refused naming it (exit 2), not ignored (issue 32: accepted)."""

from __future__ import annotations

import pytest

from symid.cli import main
from symid.errors import InputError
from symid.tools.show import derive_type


@pytest.mark.parametrize(("args", "said"), [
    (["revolute", "--option", "coordinate=phi"],
     "derive revolute: option 'coordinate' does not apply to revolute (it has no variant options)"),
    (["gear", "--option", "ratio=2"], "derive gear: option 'ratio' does not apply to gear"),
    (["coordinate_driver", "--option", "coordinate=phi", "--option", "body=crank"],
     "derive coordinate_driver: option 'body' does not apply to coordinate_driver (its options: coordinate)"),
])
def test_an_option_that_does_not_apply_is_one_line_exit_2(args: list[str], said: str, capsys) -> None:
    assert main(["derive", *args]) == 2
    captured = capsys.readouterr()
    assert captured.err.count("\n") == 1 and said in captured.err, captured.err
    assert captured.out == ""


def test_the_api_refuses_it_too() -> None:
    with pytest.raises(InputError, match="option 'coordinate' does not apply to revolute"):
        derive_type("revolute", {"coordinate": "x"})


def test_an_option_that_applies_is_taken(capsys) -> None:
    assert main(["derive", "coordinate_driver", "--option", "coordinate=phi"]) == 0
    assert "\u03a6" in capsys.readouterr().out
