"""The SIMD forms of the trajectory's O(NG) passes (templates/c/simd.j2):
the predictor, the correction with its max, maxabsN, the row's finite check,
the jump check, the mass term and the sines and cosines give the scalar
code's rows, state and answers bit for bit, in AVX (where the processor has
it) and in SSE2 (<P>_NO_AVX) against the scalar code (<P>_NO_SIMD), all
three built from one source, non-finite values included; and a ladder large
enough to use them by default is solved to its closed-form motor torque."""

from __future__ import annotations

import ctypes
import dataclasses
import os
import platform
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from symid import api
from symid.codegen.model import code_model
from symid.codegen import c as c_target
from csolver import run_in_cuts
from runshare import key_of, shared_dir

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from benchmarks import ladder  # noqa: E402
from tiers import first_quick

DP = ctypes.POINTER(ctypes.c_double)
FLAGS = ["-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", "-pedantic", "-fPIC", "-shared"]
HARNESS = """
double test_maxabs(const double *v);
double test_maxabs(const double *v) {{ return {p}_maxabs{ng}(v); }}
double test_correct(double *q, double *dq);
double test_correct(double *q, double *dq) {{ return {p}_correct(q, dq); }}
int test_unexplained(const double *v, double h);
int test_unexplained(const double *v, double h)
{{
    return {p}_unexplained(v, v + {ng}, v + {ng2}, v + {ng3}, v + {ng4}, v + {ng5}, h, v + {ng6});
}}
"""

pytestmark = [
    pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler"),
    pytest.mark.skipif(platform.machine().lower() not in ("x86_64", "amd64"), reason="SSE2 is x86-64's"),
]


def _context(example: str | Path, kind: str | None = None, straight: int = 0) -> c_target.CContext:
    """The C context of a bundled example (or a mechanism file) with every
    O(NG) pass past `straight` values (0: all in SIMD), without the set-point
    entries (the runs compared here never call them: a tenth of each compile)."""
    analysis = {"kind": kind} if kind else {}
    path = example if isinstance(example, Path) else api.example(example)
    ctx = c_target.context(code_model(api.load_mechanism(path, **analysis)), setpoints=False)
    return dataclasses.replace(ctx, checks=dataclasses.replace(ctx.checks, straight=straight, looped=True))


FORMS = {"avx": [], "sse2": ["NO_AVX"], "scalar": ["NO_SIMD"]}  # the macros each form defines


def _build(ctx: c_target.CContext, folder: Path, form: str, share: pytest.TempPathFactory,
           cc: str = "cc") -> ctypes.CDLL:
    """The solver in one of FORMS, compiled by cc, with a harness reaching its
    static passes; built once per run for the same text, form and compiler
    (runshare: two tests compare the same builds), copied into folder (a
    library of its own: a second handle of one path would share its state)."""
    c_target.write(ctx, folder)
    p, ng = ctx.name, ctx.ng
    source = folder / f"{p}_solver.c"
    text = source.read_text()
    assert f"#define {p.upper()}_SIMD 1" in text  # the SSE2 forms are there to be compared
    extra = HARNESS.format(p=p, ng=ng, **{f"ng{k}": k * ng for k in range(2, 7)}) if ctx.velocity else ""
    source.write_text(text + extra)
    define = [f"-D{p.upper()}_{m}" for m in FORMS[form]]
    command = [os.path.realpath(shutil.which(cc) or cc), *FLAGS, *define]

    def build(into: Path) -> None:
        subprocess.run([*command, f"-I{folder}", str(source), "-o", str(into / "s.so"), "-lm"], check=True)

    built = shared_dir(share, key_of("simd build", command, source, source.with_suffix(".h")), build)
    return ctypes.CDLL(shutil.copy2(built / "s.so", folder / "s.so"))


SIMD_CASES = [(e, k) for e in ("slider_crank", "four_bar", "excavator", "ladder_5") for k in ("inverse_dynamics", "statics")]


# the quick tier: the slider-crank's inverse dynamics (the passes are the same code for every mechanism and kind)
@pytest.mark.parametrize("example, kind", first_quick(SIMD_CASES, ids=[f"{e}-{k}" for e, k in SIMD_CASES]))
def test_simd_passes_give_the_scalar_codes_rows_and_state_bitwise(tmp_path: Path, tmp_path_factory, example: str,
                                                                  kind: str) -> None:
    # the ladder of 5: 11 bodies, so the four-body AVX pass of the sines and cosines runs, with a tail
    ctx = _context(ladder.write(5, tmp_path, steps=61) if example == "ladder_5" else example, kind)
    libs = {form: _build(ctx, tmp_path / form, form, tmp_path_factory) for form in FORMS}
    for cuts in ([60], [1, 1, 2, 3, 5, 8, 40]):
        want = run_in_cuts(libs["scalar"], ctx, cuts)
        for form in ("avx", "sse2"):
            got = run_in_cuts(libs[form], ctx, cuts)
            assert got[0].tobytes() == want[0].tobytes(), (form, cuts)
            assert got[1].tobytes() == want[1].tobytes(), (form, cuts)


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("clang") is None, reason="no clang")
def test_clangs_build_of_the_simd_passes_gives_gccs_scalar_rows(tmp_path: Path, tmp_path_factory) -> None:
    """The AVX passes are GCC vector extensions, whose shuffle clang spells differently."""
    ctx = _context(ladder.write(5, tmp_path, steps=61))
    clang = _build(ctx, tmp_path / "clang", "avx", tmp_path_factory, "clang")
    scalar = _build(ctx, tmp_path / "scalar", "scalar", tmp_path_factory)  # the bitwise test's own scalar build
    got, want = run_in_cuts(clang, ctx, [60]), run_in_cuts(scalar, ctx, [60])
    assert got[0].tobytes() == want[0].tobytes()
    assert got[1].tobytes() == want[1].tobytes()


# slow: three builds of the slider-crank's checks; the SIMD passes' bitwise test stays in the quick tier
@pytest.mark.slow
def test_simd_checks_answer_as_the_scalar_ones_with_non_finite_values(tmp_path: Path, tmp_path_factory) -> None:
    ctx = _context("slider_crank")  # ng 9: two SSE2 pairs and a scalar tail (the bitwise test's builds)
    ng = ctx.ng
    libs = [_build(ctx, tmp_path / form, form, tmp_path_factory) for form in FORMS]
    for lib in libs:
        lib.test_maxabs.argtypes, lib.test_maxabs.restype = [DP], ctypes.c_double
        lib.test_correct.argtypes, lib.test_correct.restype = [DP, DP], ctypes.c_double
        lib.test_unexplained.argtypes, lib.test_unexplained.restype = [DP, ctypes.c_double], ctypes.c_int
    rng = np.random.default_rng(17)
    specials = [np.nan, np.inf, -np.inf, 0.0, -0.0, 1e308]
    for trial in range(300):
        v = rng.standard_normal(7 * ng) * 10.0 ** rng.integers(-3, 3)
        for _ in range(rng.integers(0, 3)):
            v[rng.integers(7 * ng)] = specials[rng.integers(len(specials))]
        if trial % 3 == 0:
            v[6 * ng:] = np.abs(v[6 * ng:])  # the scales: zeros and positives, as the jump check has them
            v[6 * ng + rng.integers(ng)] = 0.0
        answers = []
        for lib in libs:
            q, dq = v[:ng].copy(), v[ng:2 * ng].copy()
            step = lib.test_correct(q.ctypes.data_as(DP), dq.ctypes.data_as(DP))
            largest = lib.test_maxabs(v.ctypes.data_as(DP))
            # a NaN's payload is not an answer: NaN or the value's bits
            answers.append(["nan" if np.isnan(x) else np.float64(x).tobytes() for x in (largest, step)]
                           + [q.tobytes(), dq.tobytes(), lib.test_unexplained(v.ctypes.data_as(DP), 0.01)])
        assert answers[0] == answers[2] and answers[1] == answers[2], (trial, v)


@pytest.mark.slow  # compiles a 25-body ladder; the SIMD passes' bitwise test stays in the quick tier
def test_ladder_solved_with_simd_passes_gives_the_closed_form_torque(tmp_path: Path) -> None:
    n = 12  # ng 75: past checks.straight, so the cache's build uses the SSE2 forms
    lad = ladder.Ladder(n)
    results = api.solve(ladder.write(n, tmp_path, steps=81), backend="c")
    assert results.error is None
    torque = results["motor.T_j"]
    want = lad.torque(results.t)
    # the ladder's closed-form torque against a tol 1e-12 solve of ng coordinates: rounding grows with the chain, 1e-9 leaves room
    assert np.max(np.abs(torque - want)) <= 1e-9 * np.max(np.abs(want))
