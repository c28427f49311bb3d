"""The C backend: generate, compile once (cached by model hash), call through ctypes.

The compiled solver runs whole trajectories in C; Python only streams the
rows. The per-quantity functions are bound too, for `check` and the tests.
"""

from __future__ import annotations

import copy
import ctypes
import dataclasses
import json
from pathlib import Path
from typing import TYPE_CHECKING, Callable, Iterator, Mapping, TypeAlias

import numpy as np

from symid.model.analysis import Analysis
from symid.backends import Array, Capabilities, Needs
from symid.codegen.compiler import CFLAGS, _compile, find
from symid.errors import check_signal
from symid.progress import stage

if TYPE_CHECKING:  # a cached run (symid.tools.plan) loads a built solver without sympy
    from symid.numeric.stability import Scaling
    import sympy as sp

    from symid.symbolic.assemble import Layout
    from symid.codegen.flat import Options
    from symid.numeric.friction import FrictionModel
    from symid.numeric.stability import Notes

CHUNK = 1024
CHUNK_BYTES = 1 << 20  # a chunk's rows stay in cache while Python copies them out
# The optimization level of the builds (`python -m benchmarks c_level`: every
# example, gcc and clang). The solve build (the trajectory loop) compiles at
# -O1: as fast a run as at -O2, about two thirds of gcc's compile time, the
# same rows byte for byte. The study build stays at -O2 below LARGE_SOURCE:
# clang's sweep runs slower at -O1 (gcc's lanes carry their own -O1,
# templates/c/lanes.j2, clang's do not). Past LARGE_SOURCE gcc's -O2 time
# grows faster than the code, and -O1 compiles ~2.5x faster for the same run.
LARGE_SOURCE = 200_000  # bytes of generated C


def level(size: int, batch: bool) -> str:
    """The optimization level of a build of `size` bytes of C (`batch`: the study build)."""
    return "-O2" if batch and size < LARGE_SOURCE else "-O1"


def compiler() -> str:
    """The C compiler of the C backend, or an input error naming the other backends."""
    from symid.backends import names

    return find("--backend c", "other backends: " + ", ".join(n for n in names() if n != "c"))


def compile_library(source: Path, artifact: Path) -> None:
    """Compile one C file into a shared library at -O2 with `compiler()`: an input
    error (exit 2) when there is no compiler or it fails, as for a solver."""
    _compile(compiler(), ["-O2", *CFLAGS, str(source), "-o", str(artifact), "-lm"], artifact)


def chunk_rows(width: int) -> int:
    """Instants per call of the compiled loop for rows of `width` values: up
    to CHUNK, and CHUNK_BYTES of rows, so that a wide row (a large mechanism's
    reactions) is written while still in cache; at least 16."""
    return max(16, min(CHUNK, CHUNK_BYTES // (8 * width)))


def build(layout: Layout, options: Options, batch: bool = True) -> Path:
    """The folder holding the compiled solver for this model, building it if needed.

    The build compiles what the backend calls: never the set-point entries
    (`<name>_setpoint*`, for a controller's export), and the sweep's
    variants in SIMD lanes only for `batch` (a study's build, which runs
    `<name>_sweep`); without, `<name>_sweep` is the one-by-one loop and the
    build compiles in about half the time. The two are separate entries.
    """
    from symid.codegen.cache import cached

    mech = layout.mechanism

    def make(folder: Path) -> None:
        from symid.codegen.model import code_model
        from symid.codegen.render import preload
        from symid.codegen import c
        from symid.codegen.c import sweep as c_sweep

        cc = compiler()
        stage("deriving")
        # the templates compile while a child process samples the plan (forked.py)
        model = code_model(mech, options, looped=True,
                           meanwhile=lambda sample: preload(c.TEMPLATES, sample.ready))
        stage("generating")
        # studies run the batch build: their variants in SIMD lanes; no set-points (nothing here calls them)
        ctx = c.context(model, lanes=batch, setpoints=False)
        c.write(ctx, folder)
        source = folder / f"{mech.name}_solver.c"
        stage("compiling")
        chosen = level(source.stat().st_size, batch)
        _compile(cc, [chosen, *CFLAGS, str(source), "-o", str(folder / "solver.so"), "-lm"], folder / "solver.so")
        f = model.flat
        meta = {"ng": f.ng, "nc": f.nc, "nnz": len(f.jac), "nr": len(f.reactions),
                "row": len(model.row_columns), "columns": list(model.row_columns),
                "work": ctx.work, "state": ctx.state, "state_layout": ctx.state_layout.to_json(),
                "params": list(f.params),
                "rows": [r for r, _, _ in f.jac], "cols": [col for _, col, _ in f.jac],
                "sweep_figures": c_sweep.figure_names(model), "sweep_work": ctx.sweep.work,
                "sens_width": ctx.sens.width if ctx.sens else 0}
        (folder / "meta.json").write_text(json.dumps(meta))

    return cached(mech, options, "c" if batch else "c-solve", make, ("solver.so", "meta.json"))


_P = ctypes.POINTER(ctypes.c_double)
_I = ctypes.POINTER(ctypes.c_int)
_DoublePtr: TypeAlias = "ctypes._Pointer[ctypes.c_double]"  # an instance of _P


def _ptr(a: Array | None) -> _DoublePtr | None:
    """A pointer to a contiguous float array's data; None passes as NULL."""
    return a.ctypes.data_as(_P) if a is not None else None


class CEvaluator:
    """The compiled solver of one mechanism, with numeric parameter values.

    Args:
        folder: the built solver (`build`); name: the mechanism's name.
        params: parameter name -> value, for every parameter of the solver.
        layout: the mechanism's layout, which names constraints in failure
            messages; None for a cached run (`symid.tools.plan`), which reruns
            the whole normal path on any failure.
        friction: the joint friction model of the instants the Python loop
            solves (the compiled loop solves friction itself), None without.
    """

    # The compiled loop writes no cond column and screens at the default
    # cond_warn only (generated into its code), factors square systems only
    # and has no branch tracking: options asking for these are refused
    # (symid.backends.require_support). Its batch entry `<name>_sweep`
    # (symid.backends.c_batch) solves a study's variants, friction included.
    capabilities = Capabilities(own_loop=True, blocks=True, compiled_loop=True, batch="compiled",
                                batch_friction=True, with_params=True, sensitivities=True, loads=True,
                                lacks=frozenset({"cond", "cond_warn", "min_norm", "assembly_jump"}), setup_kb=18.0)
    layout: Layout  # None only in a planned run, which never reads it (see above)

    def __init__(self, folder: Path, name: str, params: Mapping[str, float], layout: Layout | None,
                 friction: FrictionModel | None = None) -> None:
        self.layout = layout  # type: ignore[assignment]
        self.friction = friction
        self.name = name
        self.artifact = folder
        self.meta = json.loads((folder / "meta.json").read_text())
        self.lib = ctypes.CDLL(str(folder / "solver.so"))
        # The per-quantity functions of output groups left out are not compiled
        # (solver.h.j2): None here. The two solvers are always there.
        self._fn: dict[str, Callable[..., object] | None] = {
            n: getattr(self.lib, f"{name}_{n}", None)
            for n in ("phi", "phi_q", "nu", "gamma", "applied", "mass", "reactions")}
        self._trajectory = self.lib[f"{name}_trajectory"]
        self._trajectory.argtypes = [ctypes.c_double, ctypes.c_double, ctypes.c_long, _P, ctypes.c_double,
                                     _P, _P, ctypes.POINTER(ctypes.c_long), _P, _I]
        self._instant = self.lib[f"{name}_instant"]
        self._instant.argtypes = [ctypes.c_double, _P, ctypes.c_double, _P, _P, _P, _P, _P, _I, _P, _I]
        self._screen_at = self.lib[f"{name}_screen_at"]
        self._screen_at.argtypes = [ctypes.c_double, _P, _P, _P, _I]
        self.p = np.array([params[n] for n in self.meta["params"]], dtype=float)
        self.work = np.zeros(self.meta["work"])
        self.iwork = np.zeros(max(1, self.meta["ng"]), dtype=np.intc)
        if self.meta.get("sens_width"):
            self._sensitivity = self.lib[f"{name}_instant_sensitivity"]
            self._sensitivity.argtypes = [ctypes.c_double, _P, ctypes.c_double, _P, _P, _I, _P, _I]

    @property
    def sensitivity_header(self) -> list[str] | None:
        """The d(COLUMN)/d(NAME) columns the compiled rows end with (None: none)."""
        width = self.meta.get("sens_width", 0)
        return list(self.meta["columns"][-width:]) if width else None

    def sensitivity_row(self, q: Array, t: float, tol: float) -> Array:
        """The sensitivity columns at the instant the Python loop solved (q):
        the compiled solver's own derivatives there, so that a row it hands
        over has the same columns as its own rows."""
        qq = np.array(q, dtype=float)
        out = np.zeros(self.meta["sens_width"])
        status = self._sensitivity(ctypes.c_double(t), _ptr(self.p), ctypes.c_double(tol), _ptr(qq), _ptr(out),
                                   None, _ptr(self.work), self.iwork.ctypes.data_as(_I))
        return out if status == 0 else np.full(out.size, np.nan)

    def with_params(self, params: Mapping[str, float]) -> "CEvaluator":
        """The same compiled solver with other parameter values (name -> value;
        the base ones are read) and its own workspace: one solver, many variants."""
        other = copy.copy(self)
        other.p = np.array([params[n] for n in self.meta["params"]], dtype=float)
        other.work = np.zeros(self.meta["work"])
        other.iwork = np.zeros(max(1, self.meta["ng"]), dtype=np.intc)
        other.friction = self.friction.with_params(params) if self.friction is not None else None
        return other

    def _call(self, name: str, *args: Array | float, size: int) -> Array:
        fn = self._fn[name]
        if fn is None:  # the TypeError calling None raised before, with a message
            raise TypeError(f"the compiled solver has no {name}(): its output group is not compiled in")
        out = np.zeros(size)
        conv = [ctypes.c_double(a) if isinstance(a, float) else _ptr(a) for a in args]
        fn(*conv, _ptr(self.p), _ptr(out)) if name != "mass" else fn(_ptr(self.p), _ptr(out))
        return out

    def phi(self, q: Array, t: float) -> Array:
        return self._call("phi", np.ascontiguousarray(q, float), float(t), size=self.meta["nc"])

    def phi_q(self, q: Array, t: float) -> Array:
        values = self._call("phi_q", np.ascontiguousarray(q, float), float(t), size=self.meta["nnz"])
        out = np.zeros((self.meta["nc"], self.meta["ng"]))
        out[self.meta["rows"], self.meta["cols"]] = values
        return out

    def phi_q_sparse(self, q: Array, t: float):  # type: ignore[no-untyped-def]
        from scipy import sparse

        values = self._call("phi_q", np.ascontiguousarray(q, float), float(t), size=self.meta["nnz"])
        return sparse.csc_matrix((values, (self.meta["rows"], self.meta["cols"])),
                                 shape=(self.meta["nc"], self.meta["ng"]))

    def scaling(self, q: Array, t: float) -> Scaling:
        """The Python loop's scales at q from Phi_q's entries (nothing nc x ng)."""
        from symid.numeric.sparse_scaling import scaling_of_entries

        values = self._call("phi_q", np.ascontiguousarray(q, float), float(t), size=self.meta["nnz"])
        return scaling_of_entries(np.array(self.meta["rows"]), np.array(self.meta["cols"]), values, q,
                                  self.meta["nc"])

    def nu(self, q: Array, t: float) -> Array:
        return self._call("nu", np.ascontiguousarray(q, float), float(t), size=self.meta["nc"])

    def gamma(self, q: Array, qd: Array, t: float) -> Array:
        return self._call("gamma", np.ascontiguousarray(q, float), np.ascontiguousarray(qd, float), float(t),
                          size=self.meta["nc"])

    def applied(self, q: Array, qd: Array | None, t: float) -> Array:
        qd_arr = np.ascontiguousarray(qd if qd is not None else np.zeros(self.meta["ng"]), float)
        return self._call("applied", np.ascontiguousarray(q, float), qd_arr, float(t), size=self.meta["ng"])

    def mass(self) -> Array:
        return self._call("mass", size=self.meta["ng"])

    def reactions(self, q: Array, lam: Array, t: float) -> Array:
        return self._call("reactions", np.ascontiguousarray(q, float), np.ascontiguousarray(lam, float),
                          float(t), size=self.meta["nr"])

    def rows(self, analysis: Analysis, q0: Array, notes: Notes | None = None) -> Iterator[Array]:
        """The rows of `blocks`, one by one."""
        for block in self.blocks(analysis, q0, notes):
            yield from block

    def blocks(self, analysis: Analysis, q0: Array, notes: Notes | None = None) -> Iterator[Array]:
        """Solve the whole run in C, up to CHUNK instants (CHUNK_BYTES of rows)
        per call, yielding each call's rows as one block, shape (rows, width)
        (`notes`: the warnings of the instants the Python loop solves).

        An instant the compiled loop cannot vouch for is solved by the Python
        loop (`symid.numeric.solve.Stepper`, over this solver's functions), as on the
        NumPy backend: a failure (not converged, singular, a value not finite),
        which it then recovers or reports with the same message as every other
        backend, and a step whose motion the rates at both ends do not explain
        (`symid.numeric.solve.unexplained`, in the scales the Python loop fixes at t0),
        which it continues in sub-steps and decides (a jump, whole turns
        followed, a singular position), and an instant whose pivots, in those
        scales, spread wider than the NumPy module's screen (`_screen` in the
        C code: the condition number may pass cond_warn), which it estimates,
        warns about or stops at as on every backend; t0, solved before the
        scales are known, is screened once they are (`_screen_at`). The
        compiled loop resumes after it.
        """
        from symid.numeric.solve import instant_row
        from symid.numeric.solve import Instant, Stepper

        ng, width = self.meta["ng"], self.meta["row"]
        chunk = chunk_rows(width)
        at = self.meta["state_layout"]  # name -> [offset, size] (symid.codegen.c.layout)
        state = np.zeros(self.meta["state"])
        q, qd, qdd, m1, m2, m3 = (state[at[k][0]:at[k][0] + at[k][1]]  # views (statics: m1, m2 are q)
                                  for k in ("q", "qd", "qdd", "m1", "m2", "m3"))
        q[:] = q0
        count_at = at["count"][0]
        times = analysis.steps
        h = (analysis.t1 - analysis.t0) / (times - 1) if times > 1 else 0.0
        buf = np.zeros((chunk, width))
        solved = ctypes.c_long(0)
        stepper = Stepper(self, analysis, notes)
        velocity = analysis.kind != "statics"
        start = 0
        while start < times:
            # t0 alone first: its assembled q fixes the scales of the jump check
            n = 1 if start == 0 else min(chunk, times - start)
            # the solver takes each instant's index from the state's count:
            # t = t0 + k h, exactly as the Python loop computes it
            status = self._trajectory(ctypes.c_double(analysis.t0), ctypes.c_double(h), ctypes.c_long(n),
                                      _ptr(self.p), ctypes.c_double(analysis.tol), _ptr(state),
                                      _ptr(buf), ctypes.byref(solved), _ptr(self.work),
                                      self.iwork.ctypes.data_as(_I))
            check_signal()  # between calls of at most CHUNK_BYTES of rows
            if start == 0 and status == 0 and solved.value == 1:
                stepper.scaling = self.scaling(q.copy(), analysis.t0)
                _set_scales(state, at, stepper.scaling)
                if self._screen_at(ctypes.c_double(analysis.t0), _ptr(self.p), _ptr(state), _ptr(self.work),
                                   self.iwork.ctypes.data_as(_I)) != 0:
                    solved.value, status, state[count_at] = 0, ILL_CONDITIONED, 0  # the Python loop solves t0
            if solved.value:
                yield buf[:solved.value].copy()
            if status != 0:  # the Python loop solves this instant, or reports why not
                k = start + solved.value
                count = int(state[count_at])
                if k == 0:
                    out = stepper.instant(0, analysis.t0, None, [], q0)
                else:
                    if stepper.scaling is None:
                        stepper.scaling = self.scaling(q.copy(), analysis.t0)
                    prev = Instant(t=analysis.t0 + (k - 1) * h, q=q.copy(), qd=qd.copy() if velocity else None,
                                   qdd=qdd.copy() if velocity else None)
                    history = [v.copy() for v in (m2, m1, q)[max(0, 3 - count):]] if not velocity else [q.copy()]
                    out = stepper.instant(k, analysis.t0 + k * h, prev, history, q0)
                row = instant_row(out, ng, analysis)
                if self.meta.get("sens_width"):
                    row = np.concatenate([row, self.sensitivity_row(out.q, out.t, analysis.tol)])
                yield row[None, :]
                # the state as the compiled loop leaves it after an instant
                if velocity:
                    m3[:], m2[:], m1[:], qd[:], qdd[:] = m2, m1, qdd, out.qd, out.qdd
                else:
                    m2[:], m1[:] = m1, q
                q[:] = out.q
                state[count_at] = count + 1
                n = solved.value + 1
            if start == 0:
                if stepper.scaling is None:
                    stepper.scaling = self.scaling(q.copy(), analysis.t0)
                _set_scales(state, at, stepper.scaling)
            start += n


ILL_CONDITIONED = 6  # the compiled solver's status: its conditioning screen tripped


def _set_scales(state: Array, at: dict[str, list[int]], scaling: Scaling) -> None:
    """The trajectory state's scales, the Python loop's from q(t0): 1 / each
    column's for the jump check, each row's norm for the conditioning screen
    (at: the state's layout, name -> [offset, size])."""
    (o, n), (ro, rn) = at["scale"], at["rscale"]
    state[o:o + n] = scaling.inv_col
    state[ro:ro + rn] = scaling.row


class CBackend:
    """Registry entry: the compiled C solver."""

    name = "c"
    capabilities = CEvaluator.capabilities

    def evaluator(self, layout: Layout, values: Mapping[sp.Symbol, float], needs: Needs,
                  friction: FrictionModel | None = None) -> CEvaluator:
        from symid.codegen.model import options_for

        options = options_for(layout.mechanism)
        if needs.sensitivity:  # computed in the compiled loop, with the factors of each instant
            options = dataclasses.replace(options, sensitivity=needs.sensitivity, sensitivity_of=needs.sensitivity_of)
        folder = build(layout, options, batch=needs.batch)
        return CEvaluator(folder, layout.mechanism.name, {s.name: v for s, v in values.items()}, layout, friction)

    def load(self, artifact: Path, name: str, params: Mapping[str, float]) -> CEvaluator:
        """The solver built earlier in `artifact` (a cached run, `symid.tools.plan`)."""
        from symid.codegen.cache import loadable

        problem = loadable(artifact)
        if problem is not None:
            raise FileNotFoundError(f"{artifact}: {problem}")
        return CEvaluator(artifact, name, params, None)
