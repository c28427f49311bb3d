"""A generated C solver as the tests load it with ctypes: compiled strictly
(Solver), instrumented with counters (instrumented), run in several calls
(run_in_cuts); its status codes, and the slider-crank's two assembly modes
in closed form."""

from __future__ import annotations

import ctypes
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from cbuild import STRICT, export_library
from symid.codegen.model import CodeModel, code_model
from symid.codegen import c as c_target
from symid.io.reader import load, loads

OPTIONAL = ("qd", "qdd", "lam", "reactions")
OK, NONFINITE, BAD_ARGUMENT = 0, 3, 5
DP = ctypes.POINTER(ctypes.c_double)
IP = ctypes.POINTER(ctypes.c_int)


class Solver:
    """One generated C solver compiled strictly into a shared library."""

    def __init__(self, text: str | Path, folder: Path, share: pytest.TempPathFactory | None = None) -> None:
        """text: a mechanism's text, or its file (read as `symid generate`
        reads it: the header's parameter comments are the file's). share: the
        library built once per run for the same generated text and header
        (cbuild.export_library, the text being an export's: an example's
        file gives its export's object), linked into folder."""
        mech = load(text) if isinstance(text, Path) else loads(text, "mech.toml")
        model = code_model(mech)
        self.name, self.folder, self.ctx = model.name, folder, c_target.context(model)
        c_target.write(self.ctx, folder)  # c_target.generate's files, of the context built once
        self.q0 = np.array(model.q0, dtype=float)
        self.p = np.array(model.flat.defaults, dtype=float)
        self.analysis = mech.analysis
        if share is not None:
            export_library(share, folder / f"{self.name}_solver.c", folder)
        else:
            subprocess.run(["cc", *STRICT, "-fPIC", "-shared", str(folder / f"{self.name}_solver.c"), "-o",
                            str(folder / "s.so"), "-lm"], check=True)
        self.lib = ctypes.CDLL(str(folder / "s.so"))
        # getattr keeps the function object (and its argtypes); indexing makes a new one
        self.instant_fn, self.trajectory_fn = getattr(self.lib, f"{self.name}_instant"), \
            getattr(self.lib, f"{self.name}_trajectory")
        self.instant_fn.argtypes = [ctypes.c_double, DP, ctypes.c_double, DP, DP, DP, DP, DP,
                                                     IP, DP, IP]
        self.trajectory_fn.argtypes = [ctypes.c_double, ctypes.c_double, ctypes.c_long, DP,
                                                        ctypes.c_double, DP, DP, ctypes.POINTER(ctypes.c_long),
                                                        DP, IP]

    def instant(self, t: float = 0.05, tol: float = 1e-12, null: tuple[str, ...] = (), q: np.ndarray | None = None,
                info: np.ndarray | None = None) -> tuple[int, dict[str, np.ndarray]]:
        """<name>_instant from q0 (or q) with the pointers named in `null` (or
        "info") NULL; the status and the outputs given (q always)."""
        sizes = {"qd": self.ctx.ng, "qdd": self.ctx.ng, "lam": self.ctx.nc, "reactions": self.ctx.nr}
        out = {"q": (self.q0 if q is None else q).astype(float).copy()}
        out.update({k: np.full(n, -7.0) for k, n in sizes.items() if k not in null})
        work, iwork = np.full(self.ctx.work, -7.0), np.full(self.ctx.ng, -7, np.intc)
        ptr = lambda k: out[k].ctypes.data_as(DP) if k in out else None  # noqa: E731
        status = self.instant_fn(
            t, self.p.ctypes.data_as(DP), tol, ptr("q"), *(ptr(k) for k in OPTIONAL),
            None if "info" in null or info is None else info.ctypes.data_as(IP), work.ctypes.data_as(DP),
            iwork.ctypes.data_as(IP))
        return status, out

    def trajectory(self, t0: float, h: float, n: int, tol: float = 1e-12) -> tuple[int, int, np.ndarray]:
        """<name>_trajectory from q0: status, rows solved, the state's guess."""
        state, rows = np.zeros(self.ctx.state), np.zeros((max(n, 1), self.ctx.row_width))
        state[: self.ctx.ng] = self.q0
        work, iwork, solved = np.zeros(self.ctx.work), np.zeros(self.ctx.ng, np.intc), ctypes.c_long(-7)
        status = self.trajectory_fn(
            t0, h, n, self.p.ctypes.data_as(DP), tol, state.ctypes.data_as(DP), rows.ctypes.data_as(DP),
            ctypes.byref(solved), work.ctypes.data_as(DP), iwork.ctypes.data_as(IP))
        return status, solved.value, state[: self.ctx.ng]


def slider_crank_mode(theta: float, sign: float, crank: float = 0.1, rod: float = 0.3) -> np.ndarray:
    """The slider-crank at crank angle theta, closed form: the piston on the
    +x side (sign = 1, the bundled assembly mode) or the -x side (sign = -1)."""
    ax, ay = crank * np.cos(theta), crank * np.sin(theta)
    bx = ax + sign * np.sqrt(rod ** 2 - ay ** 2)
    psi = np.arctan2(-ay, bx - ax)
    return np.array([ax / 2, ay / 2, theta, (ax + bx) / 2, ay / 2, psi, bx, 0.0, 0.0])


# the counters the test adds; `test_error[i]`: max_k |prediction - solution| of instant i
COUNTERS = """
long test_factorizations, test_iterations;
int test_force_dense;
double *test_error;
static double test_guess[{P}_NG];
"""
INSTRUMENTED_FLAGS =  ["-std=c99", "-O2", "-fPIC", "-shared"]


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
    subprocess.run(["cc", *INSTRUMENTED_FLAGS, str(source), "-o", str(folder / "s.so"), "-lm"], check=True)
    return ctypes.CDLL(str(folder / "s.so")), c_target.context(model), model


def run_in_cuts(lib: ctypes.CDLL, ctx: dict[str, Any], cuts: list[int]) -> tuple[np.ndarray, np.ndarray]:
    """Rows and final state of one run of sum(cuts) instants, one call per cut."""
    p = ctx.name
    traj = lib[f"{p}_trajectory"]
    traj.argtypes = [ctypes.c_double, ctypes.c_double, ctypes.c_long, DP, ctypes.c_double, DP, DP,
                     ctypes.POINTER(ctypes.c_long), DP, ctypes.POINTER(ctypes.c_int)]
    traj.restype = ctypes.c_int
    ng, n = ctx.ng, sum(cuts)
    params = np.array([float(v) for v in ctx.defaults])
    state = np.zeros(ctx.state)
    state[:ng] = ctx.d.q0
    state[6 * ng:7 * ng] = 1.0  # the jump check on, unit scales
    rows = np.zeros((n, ctx.row_width))
    work, iwork = np.zeros(ctx.work), np.zeros(ng, dtype=np.intc)
    solved, done = ctypes.c_long(0), 0
    h = 0.2 / (n - 1)
    for m in cuts:
        status = traj(0.0, h, m, params.ctypes.data_as(DP), 1e-12, state.ctypes.data_as(DP),
                      rows[done:].ctypes.data_as(DP), ctypes.byref(solved), work.ctypes.data_as(DP),
                      iwork.ctypes.data_as(ctypes.POINTER(ctypes.c_int)))
        assert status == 0 and solved.value == m
        done += m
    return rows, state
