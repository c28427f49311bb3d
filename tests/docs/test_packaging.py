"""The package as pip installs it: every subpackage listed, templates inside."""

from __future__ import annotations

import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_every_subpackage_is_listed_in_pyproject() -> None:
    listed = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    found = {".".join(p.parent.relative_to(ROOT).parts) for p in (ROOT / "symid").rglob("__init__.py")}
    assert found | {"symid._templates", "symid._docs"} == listed


def test_templates_install_as_symid_templates() -> None:
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    assert config["package-dir"]["symid._templates"] == "templates"
    patterns = config["package-data"]["symid._templates"]
    shipped = {p for pattern in patterns for p in (ROOT / "templates").glob(pattern)}
    assert shipped == set((ROOT / "templates").rglob("*.j2"))


def test_docs_install_as_symid_docs() -> None:
    """Every page of docs/ ships, so `symid help PAGE` works from an installed package."""
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    assert config["package-dir"]["symid._docs"] == "docs"
    patterns = config["package-data"]["symid._docs"]
    shipped = {p for pattern in patterns for p in (ROOT / "docs").glob(pattern)}
    assert set((ROOT / "docs").glob("*.md")) <= shipped
    assert ROOT / "docs" / "c_example" / "main.c" in shipped
