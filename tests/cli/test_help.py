"""Help that helps: every argument explained, defaults and choices shown, examples, --version."""

from __future__ import annotations

import argparse

import pytest

from symid.cli import main

from symid.cli.entry import build_parser


def _subcommands() -> dict[str, argparse.ArgumentParser]:
    parser = build_parser()
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(action.choices)


SUBCOMMANDS = _subcommands()


def test_version_prints_the_package_version(capsys) -> None:
    from importlib.metadata import version

    with pytest.raises(SystemExit) as exit_:
        main(["--version"])
    assert exit_.value.code == 0
    assert capsys.readouterr().out.strip() == f"symid {version('symid')}"


@pytest.mark.parametrize("name", sorted(SUBCOMMANDS))
def test_every_argument_of_every_subcommand_has_help_text(name: str) -> None:
    for action in SUBCOMMANDS[name]._actions:
        assert action.help and action.help.strip(), f"symid {name}: {action.dest} has no help text"


@pytest.mark.parametrize("name", sorted(SUBCOMMANDS))
def test_every_subcommand_help_has_examples_choices_and_defaults(name: str) -> None:
    parser = SUBCOMMANDS[name]
    text = parser.format_help()
    assert "examples:" in text and f"\n  symid {name}" in text
    for action in parser._actions:
        for choice in action.choices or ():
            assert str(choice) in text
        if action.default not in (None, False, [], argparse.SUPPRESS) and action.option_strings:
            assert "default" in parser._get_formatter()._get_help_string(action), action.dest


def test_solve_help_gives_the_default_of_every_analysis_option(capsys) -> None:
    with pytest.raises(SystemExit):
        main(["solve", "--help"])
    out = " ".join(capsys.readouterr().out.split())
    for option, default in (("--t0", "else 0"), ("--t1", "else 1"), ("--steps", "else 1001"),
                            ("--tol", "else 1e-12"), ("--backend", "default: numpy")):
        assert default in out.split(option, 2)[2][:300], option


def test_derive_without_a_variant_says_how_to_give_it(capsys) -> None:
    assert main(["derive", "coordinate_driver"]) == 2
    err = capsys.readouterr().err
    assert "must be one of x, y, phi" in err and "--option coordinate=" in err


def test_generate_without_target_shows_the_syntax(capsys) -> None:
    assert main(["generate", "x.toml"]) == 2
    assert "--target c|numpy|casadi" in capsys.readouterr().err
