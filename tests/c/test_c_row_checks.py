"""The trajectory's bookkeeping at sizes fixed when the C is generated
(templates/c/checks.j2, unroll.j2): the finite check over the row's blocks
looks at every value an instant computed, in the row or not; maxabsN is
max |v| with NaN kept; and the written-out code with its history left in the
rows gives the same rows and state, bit for bit, as the loop form with the
history copied into state every instant (the form of the code before them),
whether the run is one call or many."""

from __future__ import annotations

import ctypes
import dataclasses
import shutil
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from cbuild import STRICT, strict_library
from csolver import DP, run_in_cuts
from symid import api
from symid.codegen.model import code_model
from symid.codegen import c as c_target
from tiers import diagonal

FLAGS = ["-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", "-pedantic", "-fPIC", "-shared"]
HARNESS = """
int test_row_finite(const double *row, const double *qn, const double *qdn, const double *qddn, const double *lam,
                    const double *reac);
int test_row_finite(const double *row, const double *qn, const double *qdn, const double *qddn, const double *lam,
                    const double *reac)
{{
    return {p}_row_finite(row, qn, qdn, qddn, lam, reac);
}}
{maxabs}
"""
MAXABS = """
double test_maxabs{n}(const double *v);
double test_maxabs{n}(const double *v)
{{
    return {p}_maxabs{n}(v);
}}
"""


def _build(ctx: c_target.CContext, folder: Path, share: pytest.TempPathFactory) -> ctypes.CDLL:
    """The solver of a context, with a harness reaching its static checks,
    compiled with FLAGS (cbuild.strict_library's: once per run for one text)."""
    assert FLAGS == [*STRICT, "-fPIC", "-shared"]
    c_target.write(ctx, folder)
    p = ctx.name
    source = folder / f"{p}_solver.c"
    maxabs = "".join(MAXABS.format(p=p, n=n) for n in ctx.checks.maxabs)
    source.write_text(source.read_text() + HARNESS.format(p=p, maxabs=maxabs))
    return ctypes.CDLL(str(strict_library(share, source, folder)))


def _context(outputs: list[str] | None = None, kind: str | None = None) -> c_target.CContext:
    return _context_of(tuple(outputs) if outputs else None, kind)


@cache  # one derivation per analysis in this process (a frozen record: the tests replace, never mutate)
def _context_of(outputs: tuple[str, ...] | None, kind: str | None) -> c_target.CContext:
    analysis: dict[str, Any] = {}
    if outputs:
        analysis["outputs"] = list(outputs)
    if kind:
        analysis["kind"] = kind
    return c_target.context(code_model(api.load_mechanism(api.example("slider_crank"), **analysis)))


@pytest.fixture(autouse=True)
def _compiler() -> None:
    if shutil.which("cc") is None:
        pytest.skip("no C compiler")


@pytest.mark.parametrize("outputs, bad", [pytest.param(*p.values, id=f"{'+'.join(p.values[0] or ['all'])}-{p.values[1]}", marks=p.marks)
                                          for p in diagonal([None, ["q", "lambda"], ["q", "qddot", "reactions"]], [np.inf, -np.inf, np.nan])])
def test_row_finite_rejects_a_non_finite_value_in_any_checked_slot(tmp_path, tmp_path_factory, outputs,
                                                                  bad: float) -> None:
    ctx = _context(outputs)
    lib = _build(ctx, tmp_path, tmp_path_factory)
    f = lib.test_row_finite
    f.argtypes = [DP] * 6
    f.restype = ctypes.c_int
    ng, nc, nr = ctx.ng, ctx.nc, ctx.nr
    sizes = {"qn": ng, "qdn": ng, "qddn": ng, "lam": nc, "reac": nr}  # every group computed (inverse dynamics)
    rng = np.random.default_rng(14)
    row = rng.standard_normal(ctx.row_width) * 1e3
    apart = {var: rng.standard_normal(sizes[var]) for var, offset, _ in ctx.outputs if offset is None}

    def check() -> bool:
        ptrs = [row[offset:].ctypes.data_as(DP) if offset is not None else apart[var].ctypes.data_as(DP)
                for var, offset, _ in ctx.outputs]
        return bool(f(row.ctypes.data_as(DP), *ptrs))

    assert check()
    missed = []
    for var, offset, _ in ctx.outputs:
        held, start = (row, offset) if offset is not None else (apart[var], 0)
        for k in range(start, start + sizes[var]):
            kept = held[k]
            held[k] = bad
            if check():
                missed.append((var, k - start))
            held[k] = kept
    assert missed == [], f"slots taken as finite while holding {bad}: {missed}"
    row[0] = bad  # t is not an output the check looks at: it is written after it
    assert check()
    big = np.finfo(float).max  # finite values whose plain sum overflows: the exact test clears them
    row[:] = big
    for v in apart.values():
        v[:] = -big
    assert check()


def test_maxabs_is_the_largest_magnitude_and_keeps_nan(tmp_path, tmp_path_factory) -> None:
    ctx = _context()
    lib = _build(ctx, tmp_path, tmp_path_factory)
    rng = np.random.default_rng(3)
    for n in ctx.checks.maxabs:
        f = getattr(lib, f"test_maxabs{n}")
        f.argtypes = [DP]
        f.restype = ctypes.c_double
        for _ in range(20):
            v = rng.standard_normal(n) * 10.0 ** rng.integers(-5, 5)
            assert f(v.ctypes.data_as(DP)) == np.max(np.abs(v))
        for k in range(n):
            for bad, want in ((np.nan, np.isnan), (-np.inf, np.isposinf)):
                v = rng.standard_normal(n)
                v[k] = bad
                assert want(f(v.ctypes.data_as(DP))), (n, k, bad)


@pytest.mark.parametrize("kind", ["inverse_dynamics", "statics"])
def test_written_out_code_gives_the_loop_forms_rows_and_state_bitwise(tmp_path, tmp_path_factory, kind: str) -> None:
    ctx = _context(kind=kind)
    assert ctx.checks.rolling
    looped = dataclasses.replace(ctx, checks=dataclasses.replace(ctx.checks, straight=0, rolling=False, looped=True))
    new, old = _build(ctx, tmp_path / "new", tmp_path_factory), _build(looped, tmp_path / "old", tmp_path_factory)
    for cuts in ([60], [1, 1, 2, 3, 5, 8, 40], [7] * 8 + [4]):
        got, want = run_in_cuts(new, ctx, cuts), run_in_cuts(old, looped, cuts)
        assert got[0].tobytes() == want[0].tobytes(), cuts
        assert got[1].tobytes() == want[1].tobytes(), cuts
