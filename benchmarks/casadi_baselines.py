"""The CasADi baselines: the whole system in CasADi SX, called from Python
(`casadi-python`) and as CasADi-generated C in a C loop (`casadi-c`); and the
registry of every baseline approach.
"""

from __future__ import annotations

import ctypes
import subprocess
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks.baselines import (MAX_NEWTON, HandNumpy, Run, SympyWhole, _reaction_slots, _symbolic_reactions,
                                  symbolic_applied, symbolic_phi)
from benchmarks.systems import System


class CasadiWhole:
    """The whole system in CasADi SX; one MX Function per instant."""

    def __init__(self, system: System) -> None:
        self.s = system
        self.ng, self.nc = system.ng, system.nc
        _, self.motor_index = _reaction_slots(system)

    def _derive(self) -> dict[str, Any]:
        import casadi as ca

        ng, nc = self.ng, self.nc
        q, qd, t, lam = ca.SX.sym("q", ng), ca.SX.sym("qd", ng), ca.SX.sym("t"), ca.SX.sym("lam", nc)
        phi = ca.vertcat(*symbolic_phi(self.s, q, t, ca))
        jac = ca.jacobian(phi, q)
        phi_t = ca.jacobian(phi, t)
        jqd = ca.mtimes(jac, qd)
        gamma = -ca.mtimes(ca.jacobian(jqd, q), qd) - 2 * ca.jacobian(jqd, t) - ca.jacobian(phi_t, t)
        applied = ca.vertcat(*symbolic_applied(self.s, q, t, ca))
        reac = ca.vertcat(*_symbolic_reactions(self.s, q, jac, lam, ca))
        return {"q": q, "qd": qd, "t": t, "lam": lam, "phi": phi, "jac": jac, "nu": -phi_t,
                "gamma": gamma, "applied": applied, "reac": reac}

    def _function(self, e: dict[str, Any], tol: float) -> Any:
        import casadi as ca

        q, qd, t, lam = e["q"], e["qd"], e["t"], e["lam"]
        name = self.s.name
        f_phi = ca.Function("phi", [q, t], [e["phi"]])
        newton = ca.rootfinder("newton", "fast_newton", f_phi,
                               {"abstol": tol, "abstolStep": tol, "max_iter": MAX_NEWTON})
        f_jac = ca.Function("phi_q", [q, t], [e["jac"]])
        f_nu = ca.Function("nu", [q, t], [e["nu"]])
        f_gamma = ca.Function("gamma", [q, qd, t], [e["gamma"]])
        f_applied = ca.Function("applied", [q, t], [e["applied"]])
        f_reac = ca.Function("reac", [q, lam, t], [e["reac"]])
        mass = ca.DM([v for b in self.s.bodies for v in (b.mass, b.mass, b.inertia)])
        guess, tm = ca.MX.sym("guess", self.ng), ca.MX.sym("t")
        qs = newton(guess, tm)
        jm = f_jac(qs, tm)
        solver = ca.Linsol("lin", "qr", e["jac"].sparsity())
        qdm = solver.solve(jm, f_nu(qs, tm))
        qddm = solver.solve(jm, f_gamma(qs, qdm, tm))
        lamm = solver.solve(jm, f_applied(qs, tm) - mass * qddm, True)
        # dense outputs: generated C writes nonzeros only, and reactions have structural zeros
        outs = [ca.densify(v) for v in (qs, qdm, qddm, lamm, f_reac(qs, lamm, tm))]
        return ca.Function(f"{name}_inst", [guess, tm], outs,
                           ["guess", "t"], ["q", "qd", "qdd", "lam", "reac"])

    def setup(self, tol: float = 1e-12) -> dict[str, float]:
        tick = time.perf_counter()
        e = self._derive()
        derived = time.perf_counter()
        self.fn = self._function(e, tol)
        return {"derive": derived - tick, "generate": time.perf_counter() - derived, "compile": 0.0}

    def run(self, q0: np.ndarray, h: float, n: int, tol: float, budget_s: float) -> Run:
        q, qd, qdd = q0.copy(), np.zeros(self.ng), np.zeros(self.ng)
        out = Run(np.zeros(0))
        torque = []
        start = time.perf_counter()
        for k in range(n):
            tick = time.perf_counter()
            guess = q + h * qd + 0.5 * h * h * qdd if k else q
            res = self.fn(guess, k * h)
            q, qd, qdd = (np.asarray(r).ravel() for r in res[:3])
            torque.append(float(res[4][self.motor_index]))
            now = time.perf_counter()
            out.seconds.append(now - tick)
            if now - start > budget_s:
                break
        out.total_s = time.perf_counter() - start
        out.torque = np.array(torque)
        return out


LOOP_SOURCE = Path(__file__).with_name("casadi_loop.c")


class CasadiC(CasadiWhole):
    """The same Function generated to C, compiled with gcc -O2 and looped in C."""

    def setup(self, tol: float = 1e-12) -> dict[str, float]:
        phases = super().setup(tol)
        tick = time.perf_counter()
        self.folder = Path(tempfile.mkdtemp(prefix="symid-bench-casadi-"))
        import casadi as ca

        gen = ca.CodeGenerator("casadi_fn.c", {"with_header": True})
        gen.add(self.fn)
        gen.generate(f"{self.folder}/")
        generated = time.perf_counter()
        lib = self.folder / "loop.so"
        cmd = ["gcc", "-O2", "-fPIC", "-shared", f"-DFN={self.fn.name()}", f"-I{self.folder}",
               str(self.folder / "casadi_fn.c"), str(LOOP_SOURCE), "-o", str(lib), "-lm"]
        result = subprocess.run(cmd, capture_output=True, text=True)
        if result.returncode != 0:
            raise RuntimeError(f"compiling the CasADi C failed:\n{result.stderr[-2000:]}")
        compiled = time.perf_counter()
        self.lib = ctypes.CDLL(str(lib))
        d, i, p = ctypes.c_double, ctypes.c_int, ctypes.POINTER(ctypes.c_double)
        self.lib.bench_loop.argtypes = [d, d, ctypes.c_long, i, i, p, p, p]
        self.lib.bench_loop.restype = ctypes.c_long
        phases["generate"] += generated - tick
        phases["compile"] = compiled - generated
        return phases

    def run(self, q0: np.ndarray, h: float, n: int, tol: float, budget_s: float) -> Run:
        """n instants in one C call; total_s is the loop's own clock_gettime time."""
        p = ctypes.POINTER(ctypes.c_double)
        q = np.ascontiguousarray(q0, dtype=float)
        torque, ns = np.zeros(n), np.zeros(1)
        solved = self.lib.bench_loop(0.0, h, n, self.ng, self.motor_index, q.ctypes.data_as(p),
                                     torque.ctypes.data_as(p), ns.ctypes.data_as(p))
        out = Run(torque[:solved], total_s=float(ns[0]) * 1e-9)
        if solved < n:
            out.error = f"the generated function failed at instant {solved}"
        return out


APPROACHES = {"numpy-hand": HandNumpy, "sympy-lambdify": SympyWhole, "casadi-python": CasadiWhole,
              "casadi-c": CasadiC}
