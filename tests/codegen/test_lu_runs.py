"""The tabled sparse LU and the looped kernels emitted as runs of
straight-line code (c_lu_runs, c_loop_runs): the runs are found where the
statements repeat with fixed strides, they keep every statement in its
order, and the solver built from them gives bitwise the results of the
index-table form."""

from __future__ import annotations

import random
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

from symid import api
from symid.codegen.model import code_model
from symid.codegen import c as c_target
from symid.codegen.c import loop_runs as c_loop_runs
from symid.codegen.c import loops as c_loops
from symid.codegen.c import lu as c_lu
from symid.codegen.c import lu_runs as c_lu_runs
from symid.codegen.c.lu_runs import Run, segments
from symid.codegen.render import render
from symid.io.reader import loads

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from benchmarks import ladder  # noqa: E402

needs_cc = pytest.mark.skipif(shutil.which("cc") is None and shutil.which("gcc") is None, reason="no C compiler")


def _expand(segs: list[Run | c_lu_runs.Op]) -> list[c_lu_runs.Op]:
    """The statements the segments stand for, in order."""
    out: list[c_lu_runs.Op] = []
    for s in segs:
        if isinstance(s, Run):
            for r in range(s.count):
                out += [(text, tuple(b + r * d for b, d in zip(base, stride)))
                        for (text, base), stride in zip(s.body, s.strides)]
        else:
            out.append(s)
    return out


@pytest.mark.parametrize("seed", range(4))
def test_segments_stand_for_every_statement_in_order(seed: int) -> None:
    """Periodic stretches (two kinds of statement, per-entry strides) between
    random ones: expanding the runs gives back the statements, and the
    periodic stretches are runs."""
    rng = random.Random(seed)
    ops: list[c_lu_runs.Op] = []
    for _ in range(3):
        ops += [("a{0}{1}", (rng.randrange(100), rng.randrange(100))) for _ in range(rng.randrange(6))]
        period = [("a{0}{1}" if rng.random() < 0.5 else "b{0}", tuple(rng.randrange(50) for _ in range(2)))
                  for _ in range(rng.randrange(1, 7))]
        strides = [tuple(rng.randrange(-3, 6) for _ in range(2)) for _ in period]
        ops += [(text, tuple(b + r * d for b, d in zip(base, stride))[:text.count("{")])
                for r in range(rng.randrange(5, 30)) for (text, base), stride in zip(period, strides)]
    ops = [(text, ints[:text.count("{")]) for text, ints in ops]
    segs = segments(ops)
    assert _expand(segs) == ops
    assert sum(s.count * len(s.body) for s in segs if isinstance(s, Run)) >= 0.5 * len(ops)


def test_a_stride_that_changes_ends_the_run() -> None:
    ops = [("x[{0}]", (2 * r,)) for r in range(10)] + [("x[{0}]", (100 + 3 * r,)) for r in range(10)]
    segs = segments(ops)
    assert [(s.count, s.strides) for s in segs if isinstance(s, Run)][:1] == [(10, ((2,),))]
    assert _expand(segs) == ops


# how each form is asked for: (LU_TABLES_MIN, runs' LITERAL_MAX, the folded LU rolled), and what its source shows
FORMS = {
    "straight": (10 ** 9, -1, False, "_sparse_factor0("),
    "rolled": (10 ** 9, c_lu_runs.LITERAL_MAX, True, "int r;"),
    "tables": (0, -1, False, "_lu_update["),
    "table runs": (0, c_lu_runs.LITERAL_MAX, False, "_LU_UPDATES "),
}


def _solve(mech_text: str, monkeypatch: pytest.MonkeyPatch, tmp_path: Path, form: str) -> np.ndarray:
    tables_min, literal_max, roll, shows = FORMS[form]
    monkeypatch.setattr(c_lu, "LU_TABLES_MIN", tables_min)
    monkeypatch.setattr(c_lu_runs, "LITERAL_MAX", literal_max)
    monkeypatch.setattr(c_loop_runs, "LITERAL_MAX", literal_max)
    monkeypatch.setattr(c_lu, "rolled", c_lu_runs.rolled if roll else lambda passes: None)
    monkeypatch.setenv("SYMID_CACHE", str(tmp_path / form.replace(" ", "_")))
    mech = loads(mech_text, "ladder_10.toml")
    source = render("c/solver.c.j2", **c_target.context(code_model(mech, looped=True)).namespace())
    assert shows in source and ("_L1_body[" in source) == (literal_max < 0)
    got = api.solve(mech, backend="c")
    assert got.error is None
    return got.data


@pytest.mark.slow  # every form compiled (41 s under load)
@needs_cc
def test_lu_and_loop_forms_give_bitwise_the_same_results(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """A ladder of 10 with its revolutes looped (LOOP_MIN 0): the folded
    straight-line LU, the same rolled into runs, the index tables and the
    tables as runs (loops as runs or on tables alike) agree to the bit in
    every column, multipliers and some reactions included."""
    monkeypatch.setattr(c_loops, "LOOP_MIN", 0)
    text = ladder.toml(ladder.Ladder(10, x0=0.3), steps=30).replace(
        'kind = "inverse_dynamics"', 'kind = "inverse_dynamics"\nreactions = ["pivot3", "left2", "motor"]')
    results = {form: _solve(text, monkeypatch, tmp_path, form) for form in FORMS}
    for form, data in results.items():
        assert data.shape == results["straight"].shape and np.array_equal(data, results["straight"]), form
