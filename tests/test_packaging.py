"""The package as pip installs it: every subpackage listed, templates inside."""

from __future__ import annotations

import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_every_subpackage_is_listed_in_pyproject() -> None:
    listed = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    found = {".".join(p.parent.relative_to(ROOT).parts) for p in (ROOT / "symid").rglob("__init__.py")}
    assert found | {"symid._templates"} == listed


def test_templates_install_as_symid_templates() -> None:
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    assert config["package-dir"]["symid._templates"] == "templates"
    patterns = config["package-data"]["symid._templates"]
    shipped = {p for pattern in patterns for p in (ROOT / "templates").glob(pattern)}
    assert shipped == set((ROOT / "templates").rglob("*.j2"))
