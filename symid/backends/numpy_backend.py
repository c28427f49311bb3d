"""The NumPy backend: the generated standalone module of the mechanism
(cached by model hash).

A run goes through the module's own loop (`_rows`: Newton, sparse LU and
outputs in straight-line scalar code, 5-8x faster than the shared Python
loop) unless the analysis asks for what only the Python loop provides
(`symid.numeric.stability.requested`: the cond column or warning level, minimum-norm
multipliers, allowed assembly-mode jumps). The Python loop still solves t0
(assembly from a rough q0, the run's scaling) and every instant the module
cannot vouch for: a failure, a Newton correction large enough for the branch
check, a pivot spread that may hide a condition number near the warning
level, or the dense fallback. Such an instant is solved, warned about or
reported exactly as by `symid.numeric.solve.run`.
"""

from __future__ import annotations

import copy
import marshal
import re
import sys
from pathlib import Path
from types import CodeType, ModuleType
from typing import TYPE_CHECKING, Iterator, Mapping

import numpy as np

from symid.model.analysis import Analysis
from symid.backends import Array, Capabilities, Needs
from symid.errors import check_signal
from symid.numeric.solve import instant_row
from symid.numeric.solve import JUMP_FLOOR, JUMP_RATIO, UNEXPLAINED, Instant, Stepper, run
from symid.numeric.stability import SCREEN, Notes, requested  # noqa: F401 (SCREEN: batch_numpy's too)

if TYPE_CHECKING:  # a cached run (symid.tools.plan) loads a generated module without sympy
    import sympy as sp

    from symid.symbolic.assemble import Layout
    from symid.codegen.flat import Options
    from symid.model.mechanism import Mechanism
    from symid.numeric.friction import FrictionModel



def build(layout: Layout, options: Options) -> Path:
    """The generated module's path, generating it if needed."""
    from symid.codegen.cache import cached, staged_entry

    mech = layout.mechanism

    def make(folder: Path) -> None:
        path = _generate(mech, options, folder)  # its sympy trees freed on return
        if TAG is not None:  # compiled once here, checked with the entry's other files
            code = compile_module(path.read_bytes(), str(staged_entry(folder) / path.name))
            _code_path(path).write_bytes(marshal.dumps(code))

    return cached(mech, options, "numpy", make, (f"{mech.name}_solver.py",)) / f"{mech.name}_solver.py"


def _generate(mech: Mechanism, options: Options, folder: Path) -> Path:
    """Derive and write the module: the code model (every instance's sympy
    expressions, 50 kB a coordinate) lives only in this call, so the memory
    it held is free again when the module is compiled."""
    from symid.codegen.model import code_model
    from symid.codegen.targets import numpy_target
    from symid.progress import stage

    stage("deriving")
    model = code_model(mech, options)
    stage("generating")
    (path,) = numpy_target.generate(model, folder)
    return path


# A top-level definition of the generated module starts a line with `def ` or
# `class ` (the template's layout: nothing at column 0 inside one); its imports
# are lines of their own at column 0 before the first one.
_TOP = re.compile(rb"^(?:def|class) ", re.M)
_IMPORT = re.compile(rb"^(?:import|from) [^\n]*$", re.M)


def compile_module(source: bytes, filename: str) -> tuple[CodeType, ...]:
    """The generated module compiled one top-level definition at a time.

    CPython's compiler holds about 110 bytes per byte of the source it
    compiles at once (syntax tree, symbol table, instruction lists): the
    module of the ladder of 1024 four-bars (10 MB) in one piece took most of
    numpy's 1.36 GiB. Compiled a definition at a time, the peak is the
    largest function's. Each piece is preceded by the module's import lines
    and blank lines, each at its line in the file, so the functions'
    bytecode is that of the whole module compiled at once (CPython compiles
    a call on an imported module's attribute differently from a method
    call) and line numbers are the file's. Run in order in one namespace,
    the pieces are the module (its imports run once a piece: bound again,
    not loaded again). A source that does not split there (a `def ` at
    column 0 inside a string: not what the template writes) is compiled whole.
    """
    starts = [0] + [m.start() for m in _TOP.finditer(source) if m.start() > 0] + [len(source)]
    head = source[:starts[1]]
    imports = [(head.count(b"\n", 0, m.start()), m.group()) for m in _IMPORT.finditer(head)]
    codes, line = [], head.count(b"\n")
    try:
        codes.append(compile(head, filename, "exec", dont_inherit=True))
        for a, b in zip(starts[1:], starts[2:]):
            piece, at, prelude = source[a:b], 0, []
            for number, text in imports:
                prelude += [b"\n" * (number - at), text]
                at = number
            prelude.append(b"\n" * (line - at))
            codes.append(compile(b"".join(prelude) + piece, filename, "exec", dont_inherit=True))
            line += piece.count(b"\n")
    except SyntaxError:
        return (compile(source, filename, "exec", dont_inherit=True),)
    return tuple(codes)


# The module's bytecode is kept in its cache entry, under the interpreter's tag
# (marshal's format is per version), and covered by the entry's sha256 list:
# importlib's own __pycache__ would be loaded unchecked.
TAG = sys.implementation.cache_tag


def _code_path(path: Path) -> Path:
    return path.with_name(f"{path.stem}.{TAG}.code")


def load_module(path: Path) -> ModuleType:
    """Import a generated module from its file (or its verified bytecode beside
    it, 30x faster to load than compiling the source), under a private name."""
    code: object = None
    if TAG is not None:
        try:
            code = marshal.loads(_code_path(path).read_bytes())
        except (OSError, EOFError, ValueError, TypeError):  # another interpreter built the entry
            code = None
    if code is None:
        code = compile_module(path.read_bytes(), str(path))
    module = ModuleType(f"symid_generated_{path.stem}")
    module.__file__ = str(path)
    for piece in code if isinstance(code, tuple) else (code,):  # compile_module's pieces, or one
        exec(piece, module.__dict__)  # noqa: S102 (our own generated module, checked against the cache's sha256)
    return module


class NumpyEvaluator:
    """Evaluator protocol over a generated NumPy module.

    Args:
        path: the generated module (`build`).
        params: parameter name -> value, for every parameter of the module.
        layout: the mechanism's layout, which names constraints in failure
            messages; None for a cached run (`symid.tools.plan`), which reruns
            the whole normal path on any failure.
        friction: the joint friction model, None without; the Python loop
            solves it (the module's own loop then stands aside).
    """

    # the module's own loop (rows, not blocks); its vectorized functions run a
    # study's variants together (symid.study.batch_numpy), but not with friction
    capabilities = Capabilities(own_loop=True, batch="vectorized", with_params=True, loads=True, setup_kb=80.0)
    layout: Layout  # None only in a planned run, which never reads it (see above)

    def __init__(self, path: Path, params: Mapping[str, float], layout: Layout | None,
                 friction: FrictionModel | None = None) -> None:
        self.layout = layout  # type: ignore[assignment]
        self.friction = friction
        self.artifact = path
        self.module = load_module(path)
        self.p = np.array([params[n] for n in self.module.PARAMS], dtype=float)
        self.p_list = self.p.tolist()

    def with_params(self, params: Mapping[str, float]) -> "NumpyEvaluator":
        """The same module with other parameter values (name -> value; the
        base ones are read): one module, many variants."""
        other = copy.copy(self)
        other.p = np.array([params[n] for n in self.module.PARAMS], dtype=float)
        other.p_list = other.p.tolist()
        other.friction = self.friction.with_params(params) if self.friction is not None else None
        return other

    # One instant at a time, the module's scalar (`math`) kernels are an order
    # of magnitude faster than its vectorized ones on arrays of one column.
    # `math` raises where an expression leaves its domain (a pole, sqrt of a
    # negative, exp overflow): then the vectorized kernel, on numpy floats,
    # gives the inf or NaN that the run reports (`symid.numeric.nonfinite`).
    def _scalar(self, name: str, *args: object) -> Array:
        try:
            return np.array(getattr(self.module, f"_{name}_s")(*args, self.p_list))
        except (ArithmeticError, ValueError):
            numeric = [np.asarray(a, dtype=float) if isinstance(a, list) else
                       (np.float64(a) if isinstance(a, float) else a) for a in args]
            with np.errstate(all="ignore"):
                return np.asarray(getattr(self.module, name)(*numeric, self.p), dtype=float).reshape(-1)

    def phi(self, q: Array, t: float) -> Array:
        return self._scalar("phi", q.tolist(), float(t))

    def phi_q(self, q: Array, t: float) -> Array:
        out = np.zeros((self.module.NC, self.module.NG))
        out[self.module.PHI_Q_ROWS, self.module.PHI_Q_COLS] = self._scalar("phi_q_values", q.tolist(), float(t))
        return out

    def phi_q_sparse(self, q: Array, t: float):  # type: ignore[no-untyped-def]
        from scipy import sparse

        m = self.module
        values = self._scalar("phi_q_values", q.tolist(), float(t))
        return sparse.csc_matrix((values, (m.PHI_Q_ROWS, m.PHI_Q_COLS)), shape=(m.NC, m.NG))

    def nu(self, q: Array, t: float) -> Array:
        return self._scalar("nu", q.tolist(), float(t))

    def gamma(self, q: Array, qd: Array, t: float) -> Array:
        return self._scalar("gamma", q.tolist(), qd.tolist(), float(t))

    def applied(self, q: Array, qd: Array | None, t: float) -> Array:
        return self._scalar("applied", q.tolist(), None if qd is None else qd.tolist(), float(t))

    def mass(self) -> Array:
        return self._scalar("mass")

    def reactions(self, q: Array, lam: Array, t: float) -> Array:
        return self._scalar("reactions", q.tolist(), lam.tolist(), float(t))

    def own_loop(self, analysis: Analysis) -> bool:
        """Whether a run of `analysis` goes through the module's loop."""
        # friction (symid.backends.friction) is solved by the Python loop only
        return not requested(analysis) and self.module.NC == self.module.NG and self.friction is None

    def rows(self, analysis: Analysis, q0: Array, notes: Notes | None = None) -> Iterator[Array]:
        """The results table row by row (q0: the guess at t0, size ng)."""
        notes = notes if notes is not None else Notes(analysis)
        if not self.own_loop(analysis):
            for instant in run(self, analysis, q0, notes):
                yield instant_row(instant, self.module.NG, analysis)
            return
        m = self.module
        stepper = Stepper(self, analysis, notes)
        first = stepper.instant(0, analysis.t0, None, [], q0)
        head = instant_row(first, self.module.NG, analysis)
        yield head
        scaling = stepper.scaling
        assert scaling is not None
        pivots = [float(scaling.dr[r] * scaling.dc[c]) for r, c in zip(m.PIVOT_ROWS, m.PIVOT_COLS)]
        check = (scaling.inv_col.tolist(), JUMP_FLOOR, JUMP_RATIO, pivots, analysis.cond_threshold / SCREEN,
                 UNEXPLAINED)
        steps, t0 = analysis.steps, analysis.t0
        h = (analysis.t1 - t0) / (steps - 1) if steps > 1 else 0.0
        past, qd, qdd = [first.q.tolist()], _listed(first.qd), _listed(first.qdd)
        width, fromiter = head.size, np.fromiter  # fromiter with a count: 2x faster than np.array
        k = 1
        while k < steps:
            try:
                for values in m._rows(t0, h, k, steps, self.p_list, analysis.tol, None, past, qd, qdd, check):
                    check_signal()  # a signal whose exception C code swallowed: not one row more
                    yield fromiter(values, float, width)
                return
            except m.SolverError as exc:
                k, past, qd, qdd = exc.k, exc.past, exc.qd, exc.qdd
            prev = Instant(t=t0 + (k - 1) * h, q=np.array(past[0]), qd=_array(qd), qdd=_array(qdd))
            out = stepper.instant(k, t0 + k * h, prev, [np.array(v) for v in reversed(past)], q0)
            yield instant_row(out, self.module.NG, analysis)
            past, qd, qdd = [out.q.tolist()] + past[:2], _listed(out.qd), _listed(out.qdd)
            k += 1


def _listed(v: Array | None) -> list[float] | None:
    return None if v is None else v.tolist()  # type: ignore[no-any-return]


def _array(v: list[float] | None) -> Array | None:
    return None if v is None else np.array(v)


class NumpyBackend:
    """Registry entry: the generated NumPy module."""

    name = "numpy"
    capabilities = NumpyEvaluator.capabilities

    def evaluator(self, layout: Layout, values: Mapping[sp.Symbol, float], needs: Needs,
                  friction: FrictionModel | None = None) -> NumpyEvaluator:
        from symid.codegen.model import options_for

        path = build(layout, options_for(layout.mechanism))
        return NumpyEvaluator(path, {s.name: v for s, v in values.items()}, layout, friction)

    def load(self, artifact: Path, name: str, params: Mapping[str, float]) -> NumpyEvaluator:
        """The module generated earlier at `artifact` (a cached run, `symid.tools.plan`)."""
        from symid.codegen.cache import loadable

        problem = loadable(artifact.parent)
        if problem is not None:
            raise FileNotFoundError(f"{artifact.parent}: {problem}")
        return NumpyEvaluator(artifact, params, None)
