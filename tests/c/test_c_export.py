"""The generated C as an embedded or C++ caller uses it: every optional
output and info may be NULL, invalid scalars return BAD_ARGUMENT, a nominal
run raises no floating-point exception but inexact, and the source compiles
as C++17 and links from a C++ program."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from cbuild import STRICT, needs_cc
from csolver import BAD_ARGUMENT, NONFINITE, OK, OPTIONAL, Solver
from symid import api

EXAMPLES = ("slider_crank", "four_bar")


@pytest.fixture(scope="module")
def solvers(tmp_path_factory) -> dict[str, Solver]:
    if shutil.which("cc") is None:
        pytest.skip("no C compiler")
    return {name: Solver(api.example(name), tmp_path_factory.mktemp(name), share=tmp_path_factory)  # the export's
            for name in EXAMPLES}


@needs_cc
@pytest.mark.parametrize("null", [(k,) for k in OPTIONAL] + [OPTIONAL, OPTIONAL + ("info",)])
@pytest.mark.parametrize("example", EXAMPLES)
def test_null_optional_outputs_leave_the_others_as_a_full_call_computes(solvers, example: str,
                                                                        null: tuple[str, ...]) -> None:
    solver = solvers[example]
    status, full = solver.instant(info=np.zeros(2, np.intc))
    assert status == OK
    status, some = solver.instant(null=null, info=np.zeros(2, np.intc))
    assert status == OK
    assert set(some) == {"q", *OPTIONAL} - set(null)
    for key, value in some.items():
        assert np.array_equal(value, full[key]), key


@needs_cc
def test_q_and_lambda_only_solver_takes_null_rates_and_reactions(solvers, tmp_path: Path) -> None:
    """The issue's case: outputs q and lambda, qd, qdd, reactions and info NULL
    (qdot and qddot are intermediates of lambda); lambda as the full solver's."""
    text = api.example("slider_crank").read_text().replace(
        'kind = "inverse_dynamics"', 'kind = "inverse_dynamics"\noutputs = ["q", "lambda"]')
    lean = Solver(text, tmp_path)
    assert lean.ctx.has == {"qdot": 0, "qddot": 0, "lambda": 1, "reactions": 0}
    status, got = lean.instant(null=("qd", "qdd", "reactions", "info"))
    assert status == OK
    _, full = solvers["slider_crank"].instant()
    scale = np.max(np.abs(full["lam"]))
    # the same solve with fewer outputs computed: the multipliers to rounding of their peak
    assert np.max(np.abs(got["lam"] - full["lam"])) <= 1e-12 * scale
    assert np.max(np.abs(got["q"] - full["q"])) <= 1e-14


@needs_cc
@pytest.mark.parametrize("example", EXAMPLES)
def test_info_is_written_fully_on_success_and_on_failure(solvers, example: str) -> None:
    solver = solvers[example]
    for q, tol, expected in ((None, 1e-12, OK), (np.full(solver.ctx.ng, np.nan), 1e-12, NONFINITE),
                             (None, -1.0, BAD_ARGUMENT)):
        info = np.full(2, -7, np.intc)
        status, _ = solver.instant(q=q, tol=tol, info=info)
        assert status == expected
        assert info[0] >= 0 and info[1] in (0, 1), (expected, info)
        if expected == OK:
            assert info[0] >= 1  # the guess q0 is not the solution at t = 0.05


@needs_cc
@pytest.mark.parametrize("t, tol", [(0.05, np.nan), (0.05, np.inf), (0.05, 0.0), (0.05, -1e-12), (np.nan, 1e-12),
                                    (np.inf, 1e-12)])
def test_instant_invalid_scalar_returns_bad_argument_and_leaves_q(solvers, t: float, tol: float) -> None:
    solver = solvers["slider_crank"]
    status, out = solver.instant(t=t, tol=tol)
    assert status == BAD_ARGUMENT
    assert np.array_equal(out["q"], solver.q0)


@needs_cc
@pytest.mark.parametrize("t0, h, n, tol", [(0.0, 1e-3, -1, 1e-12), (0.0, np.nan, 5, 1e-12), (0.0, np.inf, 5, 1e-12),
                                           (0.0, 1e-3, 5, np.nan), (0.0, 1e-3, 5, np.inf), (0.0, 1e-3, 5, 0.0),
                                           (np.nan, 1e-3, 5, 1e-12)])
def test_trajectory_invalid_scalar_returns_bad_argument_and_solves_nothing(solvers, t0: float, h: float, n: int,
                                                                           tol: float) -> None:
    solver = solvers["slider_crank"]
    status, solved, q = solver.trajectory(t0, h, n, tol)
    assert (status, solved) == (BAD_ARGUMENT, 0)
    assert np.array_equal(q, solver.q0)


@needs_cc
def test_valid_trajectory_call_still_solves(solvers) -> None:
    """The checks reject only what is invalid: the same call with valid scalars solves."""
    assert solvers["slider_crank"].trajectory(0.0, 1e-3, 5)[:2] == (OK, 5)


FE_HARNESS = """#define _GNU_SOURCE
#include <fenv.h>
#include <stdio.h>

#include "{p}_solver.h"

/* A whole trajectory and instants (all outputs, and every optional one NULL)
   with invalid, division-by-zero and overflow trapping: SIGFPE on any. At
   the end, no flag but inexact (underflow included) may be raised. */
int main(void)
{{
    static double work[{P}_WORK], rows[{steps} * {P}_ROW], state[{P}_STATE];
    static int iwork[{P}_IWORK];
    double q[{P}_NG] = {{ {q0} }}, qd[{P}_NG], qdd[{P}_NG], lam[{P}_NC], reactions[{P}_NR + 1];
    long solved = 0;
    int info[2], k, status;
    for (k = 0; k < {P}_NG; ++k) state[k] = q[k];
    feclearexcept(FE_ALL_EXCEPT);
    feenableexcept(FE_INVALID | FE_DIVBYZERO | FE_OVERFLOW);
    status = {p}_trajectory({t0}, {h}, {steps}, {p}_default_params, 1e-12, state, rows, &solved, work, iwork);
    if (status != {P}_OK || solved != {steps}) return 10 + status;
    status = {p}_instant({t}, {p}_default_params, 1e-12, q, qd, qdd, lam, reactions, info, work, iwork);
    if (status != {P}_OK) return 20 + status;
    status = {p}_instant({t}, {p}_default_params, 1e-12, q, NULL, NULL, NULL, NULL, NULL, work, iwork);
    if (status != {P}_OK) return 30 + status;
    if (fetestexcept(FE_ALL_EXCEPT & ~FE_INEXACT)) return 40;
    printf("%.17g\\n", rows[({steps} - 1) * {P}_ROW + {P}_ROW - 1]);
    return 0;
}}
"""


@needs_cc
@pytest.mark.parametrize("example", EXAMPLES)
def test_nominal_run_raises_no_floating_point_exception_but_inexact(solvers, example: str) -> None:
    solver = solvers[example]
    a = solver.analysis
    steps = a.steps
    h = (a.t1 - a.t0) / (steps - 1)
    harness = solver.folder / "fe.c"
    harness.write_text(FE_HARNESS.format(p=solver.name, P=solver.name.upper(), steps=steps,
                                         q0=", ".join(repr(float(v)) for v in solver.q0), t0=repr(a.t0), h=repr(h),
                                         t=repr(a.t0 + 0.3 * (a.t1 - a.t0))))
    exe = solver.folder / "fe"
    subprocess.run(["cc", "-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", f"-I{solver.folder}", str(harness),
                    str(solver.folder / f"{solver.name}_solver.c"), "-lm", "-o", str(exe)], check=True)
    run = subprocess.run([str(exe)], capture_output=True, text=True)
    assert run.returncode == 0, f"exit {run.returncode} (negative: killed by that signal; 40: a flag raised)"


CXX_CALLER = """#include <array>
#include <cstdio>

#include "slider_crank_solver.h"

// The slider-crank of docs/c-export.md from C++: each instant of one revolution
// continued from the last, printing t and the motor torque.
int main()
{
    static std::array<double, SLIDER_CRANK_WORK> work;
    static std::array<int, SLIDER_CRANK_IWORK> iwork;
    std::array<double, SLIDER_CRANK_NG> q = {0.05, 0.0, 0.0, 0.25, 0.0, 0.0, 0.4, 0.0, 0.0};
    std::array<double, SLIDER_CRANK_NR> reactions{};
    for (int k = 0; k <= 10; ++k) {
        const double t = 0.02 * k;
        const int status = slider_crank_instant(t, slider_crank_default_params, 1e-12, q.data(), nullptr, nullptr,
                                                nullptr, reactions.data(), nullptr, work.data(), iwork.data());
        if (status != SLIDER_CRANK_OK) return 1;
        std::printf("%.17g %.17g\\n", t, reactions[SLIDER_CRANK_NR - 1]);
    }
    return 0;
}
"""


@pytest.mark.slow  # a C++ compile of the export; the export's C tests stay in the quick tier
@needs_cc
def test_cxx_program_compiles_the_source_and_links_the_c_object(tmp_path: Path) -> None:
    if shutil.which("g++") is None:
        pytest.skip("no g++: the C++ compile and link are not checked")
    api.generate(api.example("slider_crank"), "c", tmp_path)
    source = tmp_path / "slider_crank_solver.c"
    # the source itself as C++17, strictly
    result = subprocess.run(["g++", "-std=c++17", "-O2", "-Wall", "-Wextra", "-Werror", "-x", "c++", "-c",
                             str(source), "-o", str(tmp_path / "cxx.o")], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    # the C object (gcc) linked from a C++ caller: the header's C linkage
    subprocess.run(["gcc", *STRICT, "-c", str(source), "-o", str(tmp_path / "c.o")], check=True)
    (tmp_path / "main.cpp").write_text(CXX_CALLER)
    expected = api.solve(api.example("slider_crank"), backend="reference", steps=11)
    torque = expected["motor.T_j"]
    for obj in ("c.o", "cxx.o"):
        exe = tmp_path / f"main_{obj[:-2]}"
        result = subprocess.run(["g++", "-std=c++17", "-Wall", "-Wextra", "-Werror", f"-I{tmp_path}",
                                 str(tmp_path / "main.cpp"), str(tmp_path / obj), "-lm", "-o", str(exe)],
                                capture_output=True, text=True)
        assert result.returncode == 0, result.stderr
        printed = np.loadtxt(subprocess.run([str(exe)], check=True, capture_output=True, text=True).stdout.splitlines())
        # t = t0 + k h in double on both sides, printed to 17 digits: at most an ulp of t <= 0.2
        assert np.allclose(printed[:, 0], expected.t, rtol=0, atol=1e-15)
        assert np.max(np.abs(printed[:, 1] - torque)) <= 1e-10 * np.max(np.abs(torque)), obj
