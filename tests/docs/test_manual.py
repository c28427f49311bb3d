"""The mechanism file's manual (docs/mechanism-file.md) and `symid help`.

The manual is checked against symid's registries, so a new type or key that
it does not describe fails here.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from symid.tools import manual
from symid.cli import main
from symid.symbolic.constraints import TYPES as CONSTRAINTS
from symid.symbolic.forces import TYPES as FORCES
from symid.io.reader import ANALYSIS_KEYS, BODY_KEYS, MECHANISM_KEYS, TOP_KEYS

ROOT = Path(__file__).resolve().parents[2]
MANUAL = (ROOT / "docs" / "mechanism-file.md").read_text(encoding="utf-8")
TYPES = {**CONSTRAINTS, **FORCES}


def _top_section(title: str) -> str:
    match = re.search(rf"^## {re.escape(title)}\n(.*?)(?=^## |\Z)", MANUAL, re.M | re.S)
    assert match, f"no section '## {title}'"
    return match.group(1)


@pytest.mark.parametrize("name", sorted(TYPES))
def test_manual_describes_every_type_and_each_of_its_keys(name: str) -> None:
    text = manual.section(MANUAL, name)
    assert text, f"no '### {name}' section"
    for key in TYPES[name].keys:
        assert f"`{key.name}`" in text, f"{name}: key '{key.name}' not described"
        if not key.required and key.default is not None:
            default = str(key.default).lower() if isinstance(key.default, bool) else str(key.default)
            assert f"`{default}`" in text, f"{name}: default of '{key.name}' not given"


@pytest.mark.parametrize("name", sorted(CONSTRAINTS))
def test_manual_has_an_example_of_every_constraint_type(name: str) -> None:
    assert f'type = "{name}"' in manual.section(MANUAL, name)


@pytest.mark.parametrize(("section", "keys"), [
    ("[mechanism]", MECHANISM_KEYS), ("[analysis]", ANALYSIS_KEYS), ("[[body]]", BODY_KEYS)])
def test_manual_describes_every_key_of_the_fixed_sections(section: str, keys: tuple[str, ...]) -> None:
    text = _top_section(section)
    for key in keys:
        assert f"| `{key}` |" in text, f"{section} key '{key}' not in its table"


def test_manual_names_every_top_level_section() -> None:
    for key in TOP_KEYS:
        assert f"[{key}]" in MANUAL


def test_manual_examples_are_valid_toml() -> None:
    import tomllib

    for block in re.findall(r"```toml\n(.*?)```", MANUAL, re.S):
        tomllib.loads(block)


def test_help_format_prints_the_manual(capsys) -> None:
    assert main(["help", "format"]) == 0
    assert capsys.readouterr().out == MANUAL


@pytest.mark.parametrize("name", ["revolute", "gear_on_link", "rack_and_pinion", "coordinate_driver", "spring_damper"])
def test_help_type_lists_keys_defaults_and_columns(name: str, capsys) -> None:
    assert main(["help", name]) == 0
    out = capsys.readouterr().out
    for key in TYPES[name].keys:
        assert re.search(rf"^  {key.name} +\S", out, re.M)
    if name in CONSTRAINTS:
        roles = CONSTRAINTS[name].roles
        assert "reaction columns: " + " ".join(f"C.{c}_{r}" for r in roles for c in ("Fx", "Fy", "T")) in out


def test_help_of_an_unknown_topic_lists_the_topics(capsys) -> None:
    assert main(["help", "revolut"]) == 2
    err = capsys.readouterr().err
    assert "unknown help topic 'revolut'" in err and "revolute" in err and "format" in err


def test_every_docs_page_named_by_symid_is_reachable_by_help(capsys) -> None:
    named = {m for p in (ROOT / "symid").rglob("*.py")
             for m in re.findall(r"docs/([\w-]+)\.md", p.read_text(encoding="utf-8"))}
    assert "claims" in named  # `symid verify --help` names it
    for page in named:
        assert main(["help", page]) == 0
        assert capsys.readouterr().out == (ROOT / "docs" / f"{page}.md").read_text(encoding="utf-8")


def test_readme_links_the_manual_not_a_path_outside_the_repository() -> None:
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert "shared/reference" not in readme
    assert "docs/mechanism-file.md" in readme


# what the manual says is built must be built: nothing shipped is called
# "not implemented", and each friction family's page and key list name the key
NOT_BUILT = re.compile(r"not (yet )?implemented|not yet in this version|refused as unknown", re.I)


def test_manual_says_nothing_shipped_is_missing() -> None:
    assert not NOT_BUILT.search(MANUAL), NOT_BUILT.search(MANUAL)
    for title in ("Joint friction", "Design studies"):
        assert _top_section(title)
    assert "symid sweep" in MANUAL and "--sensitivity" in MANUAL and "symid optimize" in MANUAL


@pytest.mark.parametrize("name", sorted(__import__("symid.model.friction", fromlist=["FAMILIES"]).FAMILIES))
def test_help_of_a_friction_family_lists_the_friction_key_and_columns(name: str, capsys) -> None:
    assert "| `friction` |" in manual.section(MANUAL, name)
    assert main(["help", name]) == 0
    out = capsys.readouterr().out
    assert re.search(r"^  friction +inline table", out, re.M) and "C.friction C.friction_power" in out
    assert not NOT_BUILT.search(out)


def test_the_manuals_friction_and_statics_claims_hold(tmp_path) -> None:
    """A file with friction keys (the bundled example) solves in statics with
    no friction columns and in inverse dynamics with them, last."""
    from symid import api

    path = api.example("slider_crank_friction")
    statics = api.solve(api.load_mechanism(path, kind="statics", steps=3))
    assert statics.error is None and not [c for c in statics.columns if ".friction" in c]
    dynamics = api.solve(api.load_mechanism(path, steps=3))
    friction = [c for c in dynamics.columns if ".friction" in c]
    assert friction and dynamics.columns[-len(friction):] == friction
    assert "Statics has no friction columns" in _top_section("Joint friction")
