"""The code's layout: imports run one way, from the command line down to the
model, and no module grows past what one reading holds."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PACKAGE = ROOT / "symid"

# Bottom to top. A module may import its own layer and any layer below it.
# The base modules (plain standard library: errors and exit statuses, message
# text, the setup status line) and the package itself are beneath every layer.
BASE = ("errors", "text", "progress")
LAYERS = ("model", "symbolic", "io", "numeric", "codegen", "backends", "output", "study", "api", "tools", "cli", "__main__")
MAX_LINES = 400


def layer_of(module: str) -> int:
    """The layer index of a `symid...` module name; -1 for the base (errors, the package)."""
    parts = module.split(".")
    if len(parts) == 1 or parts[1] in BASE:
        return -1
    return LAYERS.index(parts[1])


def module_name(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports(path: Path) -> list[tuple[int, str]]:
    """Every `symid` module the file imports, at any depth (functions and
    TYPE_CHECKING blocks included): (line, module)."""
    found = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] == "symid":
            base = node.module
            for alias in node.names:  # `from symid import api` imports symid.api
                candidate = f"{base}.{alias.name}"
                sub = PACKAGE.joinpath(*candidate.split(".")[1:])
                found.append((node.lineno, candidate if sub.with_suffix(".py").exists() or sub.is_dir() else base))
        elif isinstance(node, ast.Import):
            found += [(node.lineno, a.name) for a in node.names if a.name.split(".")[0] == "symid"]
    return found


SOURCES = sorted(PACKAGE.rglob("*.py"))


def test_every_module_belongs_to_a_layer() -> None:
    for path in SOURCES:
        layer_of(module_name(path))  # ValueError names a folder no layer holds


def test_base_modules_import_no_layer() -> None:
    for name in BASE:
        path = PACKAGE / f"{name}.py"
        assert [m for _, m in imports(path) if layer_of(m) >= 0] == [], path


def test_no_module_imports_a_higher_layer() -> None:
    upward = []
    for path in SOURCES:
        here = module_name(path)
        for line, target in imports(path):
            if layer_of(target) > layer_of(here):
                upward.append(f"{path.relative_to(ROOT)}:{line} imports {target}")
    assert not upward, "imports that run up the layers:\n" + "\n".join(upward)


@pytest.mark.parametrize("folder", ["symid", "benchmarks"])
def test_no_module_is_longer_than_one_reading(folder: str) -> None:
    long = {str(p.relative_to(ROOT)): n for p in sorted((ROOT / folder).rglob("*.py"))
            if (n := len(p.read_text().splitlines())) > MAX_LINES}
    assert not long, f"modules over {MAX_LINES} lines: {long}"


def test_the_checker_sees_an_upward_import(tmp_path: Path) -> None:
    planted = tmp_path / "planted.py"
    planted.write_text("def f():\n    from symid.cli.entry import main\n    from symid import api\n")
    assert [layer_of(m) for _, m in imports(planted)] == [LAYERS.index("cli"), LAYERS.index("api")]
    assert layer_of("symid.model.mechanism") < layer_of("symid.cli.entry")
