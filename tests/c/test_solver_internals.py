"""What only the numbers' last digits or the run time would show: the
trajectory predictors' order, the work per instant (factorizations and
Newton iterations) on smooth motion, and the C dense pivoting fallback on
general matrices.

The C solver is built from the generated source with counters added in the
test (text edits that must each apply exactly once), so the product code is
what runs; the predictors are checked by their error's order in the step h,
which a wrong coefficient lowers, not by comparing against a copy of them.
"""

from __future__ import annotations

import ctypes
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from symid import api
from symid.numeric import solve as solve_module
from symid.codegen.model import CodeModel, code_model
from symid.codegen.targets import c as c_target
from symid.io.reader import load

needs_cc = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
FLAGS = ["-std=c99", "-O2", "-fPIC", "-shared"]
DP = ctypes.POINTER(ctypes.c_double)

# the counters the test adds; `test_error[i]`: max_k |prediction - solution| of instant i
COUNTERS = """
long test_factorizations, test_iterations;
int test_force_dense;
double *test_error;
static double test_guess[{P}_NG];
"""

# the dense fallback alone, on a matrix given row-major: x = A^-1 b, z = A^-T b
DENSE_HARNESS = """
int test_dense(const double *a, const double *b, double *x, double *z);
int test_dense(const double *a, const double *b, double *x, double *z)
{{
    double lu[{P}_NG * {P}_NG];
    int perm[{P}_NG], status;
    memcpy(lu, a, sizeof lu);
    status = {p}_dense_factor(lu, perm);
    if (status != {P}_OK) return status;
    {p}_dense_solve(lu, perm, b, x);
    {p}_dense_solve_t(lu, perm, b, z);
    return status;
}}
"""


def _edit(text: str, old: str, new: str) -> str:
    assert text.count(old) == 1, f"the generated C no longer holds exactly one {old!r}"
    return text.replace(old, new)


def instrumented(model: CodeModel, folder: Path, harness: str = "") -> tuple[ctypes.CDLL, dict, CodeModel]:
    """The generated C solver of `model`, counting factorizations and Newton
    iterations, recording each instant's prediction error, able to be forced
    onto the dense fallback; `harness` is appended (it may call the solver's
    static functions). Returns (library, context, code model)."""
    c_target.generate(model, folder)
    p, P = model.name, model.name.upper()
    source = folder / f"{p}_solver.c"
    text = source.read_text()
    text = _edit(text, f'#include "{p}_solver.h"\n', f'#include "{p}_solver.h"\n' + COUNTERS.format(P=P))
    test = f"({p}_sparse_factor(lu) == 0) && ({p}_pivots_spread(lu) == 0)"
    text = _edit(text, f"    *dense = 0;\n    if ({test}) {{",
                 f"    ++test_factorizations;\n    *dense = 0;\n"
                 f"    if (!test_force_dense && {test}) {{")
    call = f"        status = {p}_newton(t, pp, tol, qn, tr, info, work, iwork, &dense, (i > 0) ? 1 : 0);\n"
    text = _edit(text, call,
                 f"        memcpy(test_guess, qn, sizeof test_guess);\n{call}"
                 f"        test_iterations += info[0];\n"
                 f"        if (test_error && status == {P}_OK)\n"
                 f"            for (int k = 0; k < {P}_NG; ++k)\n"
                 f"                test_error[i] = fmax(test_error[i], fabs(test_guess[k] - qn[k]));\n")
    source.write_text(text + harness)
    subprocess.run(["cc", *FLAGS, str(source), "-o", str(folder / "s.so"), "-lm"], check=True)
    return ctypes.CDLL(str(folder / "s.so")), c_target.context(model), model


class Counted:
    """One trajectory call of an instrumented solver and what it counted."""

    def __init__(self, lib: ctypes.CDLL, ctx: dict, model: CodeModel, h: float, n: int, dense: bool = False) -> None:
        ctypes.c_long.in_dll(lib, "test_factorizations").value = 0
        ctypes.c_long.in_dll(lib, "test_iterations").value = 0
        ctypes.c_int.in_dll(lib, "test_force_dense").value = int(dense)
        self.error = np.zeros(n)
        ctypes.c_void_p.in_dll(lib, "test_error").value = self.error.ctypes.data
        f = getattr(lib, f"{model.name}_trajectory")
        f.argtypes = [ctypes.c_double, ctypes.c_double, ctypes.c_long, DP, ctypes.c_double, DP, DP,
                      ctypes.POINTER(ctypes.c_long), DP, ctypes.POINTER(ctypes.c_int)]
        state, self.rows = np.zeros(ctx["state"]), np.zeros((n, ctx["row_width"]))
        state[: ctx["ng"]] = model.q0
        p = np.array(model.flat.defaults, dtype=float)
        work, iwork, solved = np.zeros(ctx["work"]), np.zeros(ctx["ng"], np.intc), ctypes.c_long(0)
        ptr = lambda a: a.ctypes.data_as(DP)  # noqa: E731
        status = f(0.0, h, n, ptr(p), 1e-12, ptr(state), ptr(self.rows), ctypes.byref(solved), ptr(work),
                   iwork.ctypes.data_as(ctypes.POINTER(ctypes.c_int)))
        ctypes.c_void_p.in_dll(lib, "test_error").value = None
        assert status == 0 and solved.value == n
        self.factorizations = ctypes.c_long.in_dll(lib, "test_factorizations").value / n
        self.iterations = ctypes.c_long.in_dll(lib, "test_iterations").value / n


@pytest.fixture(scope="module")
def slider_crank_c(tmp_path_factory) -> tuple[ctypes.CDLL, dict, CodeModel]:
    if shutil.which("cc") is None:
        pytest.skip("no C compiler")
    model = code_model(load(api.example("slider_crank")))
    return instrumented(model, tmp_path_factory.mktemp("c"), DENSE_HARNESS.format(p=model.name, P=model.name.upper()))


def order(errors: dict[float, float]) -> float:
    """The observed order of the prediction error between the two step sizes."""
    (h1, e1), (h2, e2) = sorted(errors.items())
    return float(np.log(e2 / e1) / np.log(h2 / h1))


# -- the C trajectory ----------------------------------------------------------------

@needs_cc
def test_c_trajectory_factors_once_and_corrects_once_per_instant_on_smooth_motion(slider_crank_c) -> None:
    """The README's promise: from the h^5 predictor one chord correction
    suffices, and Phi_q is factored once, at the solution (1.000 measured
    on this grid; a wrong predictor coefficient needs a second iteration)."""
    run = Counted(*slider_crank_c, h=1e-4, n=2000)
    assert run.factorizations <= 1.01
    assert run.iterations <= 1.01


@needs_cc
def test_c_predictor_error_scales_as_h5_or_better(slider_crank_c) -> None:
    """The Taylor predictor to h^5 (the derivatives past qddot from the last
    four accelerations) has a local error O(h^6): halving h divides it by
    ~64. Over the same second half of the run at h and h/2."""
    errors = {}
    for h, n in ((0.01, 21), (0.005, 41)):
        run = Counted(*slider_crank_c, h=h, n=n)
        errors[h] = float(np.max(run.error[n // 2:]))
    assert min(errors.values()) > 1e-11, "the errors must stand above the Newton tolerance to be measured"
    assert order(errors) >= 5.0, errors


@needs_cc
def test_c_statics_predictor_extrapolates_quadratically(tmp_path: Path) -> None:
    """Statics: q from the parabola through the last three positions, local
    error O(h^3): halving h divides it by ~8."""
    model = code_model(load(api.example("slider_crank"), analysis={"kind": "statics"}))
    built = instrumented(model, tmp_path)
    errors = {}
    for h, n in ((0.01, 21), (0.005, 41)):
        errors[h] = float(np.max(Counted(*built, h=h, n=n).error[n // 2:]))
    assert order(errors) >= 2.7, errors


def _general_matrices(rng: np.random.Generator, n: int) -> list[np.ndarray]:
    """Matrices that need row exchanges: dense normal ones, permutations with
    tiny diagonals (a pivot-less LU divides by 1e-14), rows scaled over 12
    decades, and a sparse pattern with a zero diagonal."""
    out = []
    for _ in range(10):
        out.append(rng.normal(size=(n, n)))
        perm = np.eye(n)[rng.permutation(n)] * rng.uniform(1, 3, size=n)
        out.append(perm + 1e-14 * np.diag(rng.normal(size=n)) + 1e-3 * rng.normal(size=(n, n)))
        out.append(rng.normal(size=(n, n)) * np.logspace(-6, 6, n)[:, None])
        sparse = rng.normal(size=(n, n)) * (rng.random((n, n)) < 0.35)
        np.fill_diagonal(sparse, 0.0)
        out.append(sparse + np.eye(n)[::-1])
    return out


@needs_cc
def test_c_dense_fallback_factors_general_matrices_like_numpy(slider_crank_c) -> None:
    """The pivoting fallback alone (the fixed sparse order never factors
    these): A x = b and A^T z = b agree with numpy.linalg.solve to within
    the conditioning, and a singular matrix is refused."""
    lib, ctx, _ = slider_crank_c
    n = ctx["ng"]
    f = lib.test_dense
    f.argtypes = [DP, DP, DP, DP]
    ptr = lambda a: a.ctypes.data_as(DP)  # noqa: E731
    rng = np.random.default_rng(12)
    for a in _general_matrices(rng, n):
        b = rng.normal(size=n)
        x, z = np.zeros(n), np.zeros(n)
        assert f(ptr(np.ascontiguousarray(a)), ptr(b), ptr(x), ptr(z)) == 0
        cond = np.linalg.cond(a)
        for got, m in ((x, a), (z, a.T)):
            want = np.linalg.solve(m, b)
            assert np.max(np.abs(got - want)) <= 1e-13 * cond * np.max(np.abs(want)), (got, want)
    singular = rng.normal(size=(n, n))
    singular[3] = 2.0 * singular[5]
    assert f(ptr(singular), ptr(b), ptr(x), ptr(z)) == 2  # _SINGULAR


@needs_cc
def test_c_trajectory_forced_through_the_dense_fallback_is_the_sparse_one(slider_crank_c) -> None:
    """Every factorization of a whole trajectory through the pivoting
    fallback: the same rows (q, rates, multipliers, reactions) as the fixed
    sparse order, to rounding, and still one factorization per instant."""
    sparse_run = Counted(*slider_crank_c, h=1e-3, n=200)
    dense_run = Counted(*slider_crank_c, h=1e-3, n=200, dense=True)
    scale = np.maximum(np.max(np.abs(sparse_run.rows), axis=0), 1e-3)
    assert np.max(np.abs(dense_run.rows - sparse_run.rows) / scale) <= 1e-11
    assert dense_run.factorizations == sparse_run.factorizations


# -- the Python loop and the NumPy module's loop ----------------------------------------

def _record_python_loop(monkeypatch: pytest.MonkeyPatch, study) -> list[tuple[float, int]]:
    """(max |guess - solution|, iterations) of each Newton solve of the Python loop."""
    seen: list[tuple[float, int]] = []
    newton = solve_module.newton

    def recording(ev, q, t, tol, scaling=None, max_iterations=solve_module.MAX_NEWTON):
        out, it = newton(ev, q, t, tol, scaling, max_iterations)
        seen.append((float(np.max(np.abs(out - q))), it))
        return out, it

    monkeypatch.setattr(solve_module, "newton", recording)
    return seen


def _record_numpy_module(monkeypatch: pytest.MonkeyPatch, study) -> list[tuple[float, int]]:
    """The same for the generated NumPy module's own loop."""
    seen: list[tuple[float, int]] = []
    module = study.evaluator.module
    instant = module._instant

    def recording(t, p, q, tol, m, mixed=None):
        out = instant(t, p, q, tol, m, mixed)
        seen.append((max(abs(a - b) for a, b in zip(out[0], q)), out[5]))
        return out

    monkeypatch.setattr(module, "_instant", recording)
    return seen


LOOPS = {"python": ("reference", _record_python_loop), "numpy": ("numpy", _record_numpy_module)}


@pytest.mark.parametrize("kind", ("inverse_dynamics", "statics"))
@pytest.mark.parametrize("loop", sorted(LOOPS))
def test_python_and_numpy_loop_predictors_are_third_order(loop: str, kind: str, monkeypatch) -> None:
    """Both loops predict by Taylor to h^2 from q, qdot, qddot (statics: the
    parabola through the last three positions): local error O(h^3), so
    halving h divides it by ~8, and Newton then needs few iterations."""
    backend, record = LOOPS[loop]
    errors, iterations = {}, {}
    for h, n in ((0.008, 21), (0.004, 41)):
        study = api.prepare(api.example("slider_crank"), backend, kind=kind, steps=n, t1=(n - 1) * h)
        with monkeypatch.context() as patch:
            seen = record(patch, study)
            result = study.solve()
        assert result.error is None and len(result.t) == n
        assert len(seen) >= n - 1  # every instant after t0 went through the recorded solve
        late = seen[n // 2:]
        errors[h] = max(e for e, _ in late)
        iterations[h] = sum(it for _, it in late) / len(late)
    assert order(errors) >= 2.7, errors
    assert max(iterations.values()) <= 4.0, iterations  # 3.0 measured
