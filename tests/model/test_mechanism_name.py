"""The mechanism's name prefixes every identifier of the generated C; one
that starts with `_` is refused at reading, naming the key (issue 32: `_`
generated `__real`, a GCC keyword, and the compiler refused the code). A
name with a letter first, underscores anywhere after, compiles warning-free."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

from symid import api
from symid.cli import main

CRANK = api.example("slider_crank")


def _named(tmp_path: Path, name: str) -> Path:
    text = CRANK.read_text(encoding="utf-8").replace('name = "slider_crank"', f'name = "{name}"', 1)
    path = tmp_path / "m.toml"
    path.write_text(text, encoding="utf-8")
    return path


@pytest.mark.parametrize("name", ["_", "_x", "__x", "_A"])
@pytest.mark.parametrize("command", [["solve"], ["generate", "--target", "c"], ["check"]])
def test_a_name_starting_with_underscore_is_refused_at_reading(tmp_path: Path, capsys, name: str,
                                                                command: list[str]) -> None:
    path = _named(tmp_path, name)
    out = tmp_path / ("out.csv" if command[0] == "solve" else "out")  # a table's suffix is its format
    extra = ["-o", str(out)] if command[0] != "check" else []
    status = main([command[0], str(path), *command[1:], *extra])
    err = capsys.readouterr().err
    assert status == 2 and err.count("\n") == 1 and "Traceback" not in err, err
    assert f"m.toml: [mechanism] key 'name': '{name}' starts with '_'" in err, err
    assert not out.exists()


@pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
@pytest.mark.parametrize("name", ["A", "x__y", "m_"])
def test_a_name_with_a_letter_first_compiles_without_warnings(tmp_path: Path, capsys, name: str) -> None:
    path = _named(tmp_path, name)
    out = tmp_path / "gen"
    assert main(["generate", str(path), "--target", "c", "-o", str(out)]) == 0
    source = out / f"{name}_solver.c"
    run = subprocess.run(["cc", "-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic", "-c", str(source),
                          "-o", str(tmp_path / "s.o")], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-2000:]
