"""The C example of docs/c-export.md (`symid help c-export`) runs as written: its C
block is docs/c_example/main.c, and its build line, which the README repeats,
compiles that block against `symid generate`'s output."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from symid import api

ROOT = Path(__file__).resolve().parents[2]
PAGE = (ROOT / "docs" / "c-export.md").read_text(encoding="utf-8")
README = (ROOT / "README.md").read_text(encoding="utf-8")
needs_cc = pytest.mark.skipif(shutil.which("cc") is None or shutil.which("make") is None,
                              reason="no C compiler or make")


def _c_block() -> str:
    blocks = re.findall(r"^```c\n(.*?)^```$", PAGE, re.M | re.S)
    assert len(blocks) == 1, "docs/c-export.md has one C snippet"
    return blocks[0]


def test_c_export_page_snippet_is_docs_c_example_main_c() -> None:
    assert _c_block() == (ROOT / "docs" / "c_example" / "main.c").read_text(encoding="utf-8")


@needs_cc
def test_c_export_page_snippet_builds_with_its_commands_and_prints_the_motor_torque(tmp_path: Path) -> None:
    for text in (PAGE, README):  # the README's tutorial gives the same two lines
        generate = re.search(r'^    (symid generate "\$\(symid example slider_crank\)" --target c -o sc/)$', text, re.M)
        build = re.search(r"^    (make -C sc && cc .* -o main && \./main)$", text, re.M)
        assert generate and build, "the generate and build lines"
        assert build.group(1) == re.search(r"^    (make -C sc && cc .* -o main && \./main)$", PAGE, re.M).group(1)
    api.generate(api.example("slider_crank"), "c", tmp_path / "sc")  # what the generate line does
    (tmp_path / "main.c").write_text(_c_block())
    run = subprocess.run(["sh", "-c", build.group(1)], cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    printed = np.loadtxt(run.stdout.splitlines()[-11:])
    expected = api.solve(api.example("slider_crank"), backend="reference", steps=11)
    assert np.array_equal(printed[:, 0], expected.t)
    torque = expected["motor.T_j"]
    # the README's program and the reference solve the same equations to tol 1e-12: rounding of the peak
    assert np.max(np.abs(printed[:, 1] - torque)) <= 1e-12 * np.max(np.abs(torque))
