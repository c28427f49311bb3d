"""Time one mechanism on one backend: setup and the cost of one instant.

`symid bench` prints what `bench()` returns; `benchmarks/run.py` calls it for
every backend. The instants are the mechanism's own time grid (`[analysis]`
t0, t1, steps): asking for more instants than the grid has runs the whole
grid again from q0 (a fresh run, identical physics) until enough are timed.

What is timed:
- setup_s: from the file to the first solved instant, in a fresh cache
  unless `cold=False`. Split into derive_s (time inside sympy derivation
  and the flat system build), compile_s (time inside compiler processes)
  and generate_s (the rest: elimination plan, rendering, lambdify,
  loading, first instant).
- us_per_instant: a compiled backend (C) is timed on its own trajectory
  loop called over the whole grid at once (`<name>_trajectory`, no Python
  per instant): the median over runs of run time / instants. A Python
  backend is timed instant by instant through `Study.rows()`: the median.
- max_residual: max |Phi(q, t)| over the first run's instants (the later
  runs repeat it).
"""

from __future__ import annotations

import contextlib
import ctypes
import functools
import importlib
import os
import shutil
import tempfile
import time
from pathlib import Path
from typing import Any, Callable, Iterator, Sequence

import numpy as np

from symid import api
from symid.backends.c_backend import CEvaluator, chunk_rows
from symid.errors import AnalysisError
from symid.model.mechanism import Mechanism

# (module, attribute, phase): wrapped while preparing, time counted once per
# outermost call. A renamed attribute only loses its share of the split.
PHASES: tuple[tuple[str, str, str], ...] = (
    ("symid.symbolic.assemble", "derive_constraint", "derive"),
    ("symid.symbolic.assemble", "derive_force", "derive"),
    ("symid.codegen.flat", "build", "derive"),
    ("symid.codegen.model", "build", "derive"),
    ("subprocess", "run", "compile"),
)


class _Phases:
    """Accumulate wall time per phase of wrapped functions, outermost call only."""

    def __init__(self) -> None:
        self.seconds = {"derive": 0.0, "compile": 0.0}
        self.depth = 0
        self.found: set[str] = set()

    def wrap(self, fn: Callable[..., Any], phase: str) -> Callable[..., Any]:
        @functools.wraps(fn)
        def timed(*args: Any, **kwargs: Any) -> Any:
            if self.depth:
                return fn(*args, **kwargs)
            self.depth += 1
            tick = time.perf_counter()
            try:
                return fn(*args, **kwargs)
            finally:
                self.seconds[phase] += time.perf_counter() - tick
                self.depth -= 1
        return timed

    @contextlib.contextmanager
    def active(self) -> Iterator["_Phases"]:
        saved = []
        for module_name, attr, phase in PHASES:
            try:
                module = importlib.import_module(module_name)
            except ImportError:
                continue
            fn = getattr(module, attr, None)
            if fn is None:
                continue
            self.found.add(phase)
            saved.append((module, attr, fn))
            setattr(module, attr, self.wrap(fn, phase))
        try:
            yield self
        finally:
            for module, attr, fn in saved:
                setattr(module, attr, fn)


@contextlib.contextmanager
def _fresh_cache(cold: bool) -> Iterator[None]:
    """Point SYMID_CACHE at an empty temporary folder for the duration."""
    if not cold:
        yield
        return
    before = os.environ.get("SYMID_CACHE")
    folder = tempfile.mkdtemp(prefix="symid-bench-cache-")
    os.environ["SYMID_CACHE"] = folder
    try:
        yield
    finally:
        if before is None:
            os.environ.pop("SYMID_CACHE", None)
        else:
            os.environ["SYMID_CACHE"] = before
        shutil.rmtree(folder, ignore_errors=True)


# (start, n, state) -> (rows, solved, status, seconds of the C call)
_Runner = Callable[[int, int, np.ndarray], tuple[np.ndarray, int, int, float]]


def _trajectory(study: api.Study) -> _Runner | None:
    """A runner over the compiled `<name>_trajectory`, or None for Python backends.

    The runner (start, n, state) solves n <= chunk instants of the grid
    from `start` and returns (rows, solved, status, seconds of the C call);
    chunk: what `symid solve` asks of the loop a call (c_backend.chunk_rows).
    """
    if not study.evaluator.capabilities.compiled_loop:
        return None
    ev = study.evaluator
    assert isinstance(ev, CEvaluator)  # the only evaluator with a compiled loop
    meta = ev.meta
    fn = ev.lib[f"{study.mechanism.name}_trajectory"]  # a function of its own, typed below
    a = study.analysis
    dbl, ptr = ctypes.c_double, ctypes.POINTER(ctypes.c_double)
    fn.argtypes = [dbl, dbl, ctypes.c_long, ptr, dbl, ptr, ptr, ctypes.POINTER(ctypes.c_long), ptr,
                   ctypes.POINTER(ctypes.c_int)]
    h = (a.t1 - a.t0) / (a.steps - 1) if a.steps > 1 else 0.0
    buf = np.zeros((chunk_rows(meta["row"]), meta["row"]))
    solved = ctypes.c_long(0)
    count = meta["state_layout"]["count"][0]  # the instants the state has solved (symid.codegen.c.layout)
    # pointers made once: each conversion costs about a microsecond
    p, buf_p, work, iwork = (ev.p.ctypes.data_as(ptr), buf.ctypes.data_as(ptr), ev.work.ctypes.data_as(ptr),
                             ev.iwork.ctypes.data_as(ctypes.POINTER(ctypes.c_int)))
    solved_p = ctypes.byref(solved)

    def run(start: int, n: int, state: np.ndarray) -> tuple[np.ndarray, int, int, float]:
        # the solver reads the index of the next instant from the state's count
        assert int(state[count]) == start, "the state must be the one this run has advanced"
        state_p = state.ctypes.data_as(ptr)
        tick = time.perf_counter()
        status = fn(a.t0, h, n, p, a.tol, state_p, buf_p, solved_p, work, iwork)
        return buf, solved.value, int(status), time.perf_counter() - tick

    return run


def _columns_of(study: api.Study, keep: Sequence[str]) -> dict[str, int]:
    cols = study.columns()
    return {name: cols.index(name) for name in keep if name in cols}


def bench(mechanism: Mechanism | str | Path, backend: str, instants: int | None = None, tol: float | None = None,
          cold: bool = True, budget_s: float = 60.0, keep: Sequence[str] = (),
          set_values: dict[str, str] | None = None, **analysis: Any) -> dict[str, Any]:
    """Time one mechanism on one backend.

    Args:
        mechanism: a Mechanism or a file path.
        instants: how many instants to time (default: the grid's steps).
        tol: Newton tolerance (default: the file's).
        cold: build in an empty cache (True) or use the user's cache.
        budget_s: stop timing after this many seconds (at least 2 instants).
        keep: result columns of the first run to return under "kept".
        analysis: other `[analysis]` overrides (t0, t1, steps...).

    Returns:
        A JSON-ready dict: backend, mechanism, ng, nc, instants, setup_s,
        derive_s, generate_s, compile_s, us_per_instant, max_residual,
        newton_tol, method, and "error" if the analysis failed.
    """
    if tol is not None:
        analysis["tol"] = tol
    phases = _Phases()
    with _fresh_cache(cold):
        start = time.perf_counter()
        with phases.active():
            study = api.prepare(mechanism, backend, set_values, **analysis)
        traj = _trajectory(study)
        out: dict[str, Any] = {
            "mechanism": study.mechanism.name, "backend": backend, "ng": study.layout.ng, "nc": study.layout.nc,
            "steps": study.analysis.steps, "newton_tol": study.analysis.tol,
        }
        wanted = instants or study.analysis.steps
        columns = _columns_of(study, keep)
        if traj is not None:
            result = _time_compiled(study, traj, wanted, budget_s, start, columns)
        else:
            result = _time_python(study, None, wanted, budget_s, start, columns)
    setup = result.pop("setup_s")
    split = {k: round(v, 6) if k in phases.found else None for k, v in phases.seconds.items()}
    out.update({"setup_s": setup, "derive_s": split["derive"], "compile_s": split["compile"],
                "generate_s": setup - sum(v for v in split.values() if v is not None)})
    out.update(result)
    return out


def _residual(study: api.Study, rows: np.ndarray) -> float:
    """max |Phi| over rows whose columns start with t, q."""
    ng, ev = study.layout.ng, study.evaluator
    worst = 0.0
    for r in rows:
        worst = max(worst, float(np.max(np.abs(ev.phi(r[1:1 + ng], float(r[0]))))))
    return worst


def _time_compiled(study: api.Study, run: _Runner, wanted: int, budget_s: float, start: float,
                   keep: dict[str, int]) -> dict[str, Any]:
    """Runs of the whole grid through the compiled loop, as many instants a
    call as `symid solve` asks (c_backend.chunk_rows: a wide row is written
    while in cache, as in a run)."""
    steps, ng = study.analysis.steps, study.layout.ng
    state = np.zeros(study.evaluator.meta["state"])  # type: ignore[attr-defined]
    chunk = chunk_rows(study.evaluator.meta["row"])  # type: ignore[attr-defined]
    q0 = study.q0()
    at = study.evaluator.meta["state_layout"]["q"][0]  # type: ignore[attr-defined]
    state[at:at + ng] = q0
    _, solved, status, _ = run(0, 1, state)  # the first instant: part of setup, as for every approach
    setup = time.perf_counter() - start
    per_run: list[float] = []
    timed, residual = 0, 0.0
    kept: dict[str, list[float]] = {k: [] for k in keep}
    error = None if status == 0 else "the first instant failed"
    began = time.perf_counter()
    while error is None and timed < wanted and (not per_run or time.perf_counter() - began < budget_s):
        state[:] = 0.0
        state[at:at + ng] = q0
        n_run = min(steps, wanted - timed)
        seconds, done, first = 0.0, 0, not per_run
        while done < n_run:
            n = min(chunk, n_run - done)
            rows, solved, status, dt = run(done, n, state)
            seconds += dt
            if first:
                residual = max(residual, _residual(study, rows[:solved]))
                for name, col in keep.items():
                    kept[name].extend(rows[:solved, col].tolist())
            done += solved
            if status != 0:
                error = f"the compiled solver stopped (status {status}) at instant {done}"
                break
        if done:
            per_run.append(seconds / done)
        timed += done
    return {
        "setup_s": setup, "instants": timed, "runs": len(per_run),
        "us_per_instant": 1e6 * float(np.median(per_run)) if per_run else None,
        "method": "compiled trajectory loop (ctypes, whole grid per run), median over runs",
        "max_residual": residual, "kept": {k: v for k, v in kept.items()}, "error": error,
    }


def _time_python(study: api.Study, _: None, wanted: int, budget_s: float, start: float,
                 keep: dict[str, int]) -> dict[str, Any]:
    """Instant by instant through Study.rows(); the first row closes setup."""
    ng = study.layout.ng
    seconds: list[float] = []
    first_rows: list[np.ndarray] = []
    kept: dict[str, list[float]] = {k: [] for k in keep}
    setup: float | None = None
    began, error, timed, runs = start, None, 0, 0
    while timed < wanted and error is None:
        produced = 0
        tick = time.perf_counter()
        try:
            for row in study.rows():
                now = time.perf_counter()
                if setup is None:
                    setup, began = now - start, now
                else:
                    seconds.append(now - tick)
                if runs == 0:
                    first_rows.append(row[:1 + ng].copy())
                    for name, col in keep.items():
                        kept[name].append(float(row[col]))
                timed += 1
                produced += 1
                if timed >= wanted or (len(seconds) >= 2 and now - began > budget_s):
                    break
                tick = time.perf_counter()
        except AnalysisError as exc:
            error = f"t = {exc.time}: {exc}"
        runs += 1
        if produced == 0 or time.perf_counter() - began > budget_s:
            break
    return {
        "setup_s": setup if setup is not None else time.perf_counter() - start,
        "instants": timed, "runs": runs,
        "us_per_instant": 1e6 * float(np.median(seconds)) if seconds else None,
        "method": "Study.rows(), median over instants (the first is in setup)",
        "max_residual": _residual(study, np.array(first_rows)) if first_rows else None,
        "kept": kept, "error": error,
    }


def text(result: dict[str, Any]) -> str:
    """The human-readable summary `symid bench` prints without --json."""
    def fmt(v: Any, unit: str = "") -> str:
        return "n/a" if v is None else f"{v:.4g}{unit}"

    lines = [
        f"{result['mechanism']} on {result['backend']}: ng = {result['ng']}, nc = {result['nc']}",
        f"  setup      {fmt(result['setup_s'], ' s')} (derive {fmt(result['derive_s'], ' s')}, "
        f"generate {fmt(result['generate_s'], ' s')}, compile {fmt(result['compile_s'], ' s')})",
        f"  instant    {fmt(result['us_per_instant'], ' us')} ({result['instants']} instants; {result['method']})",
        f"  residual   max |Phi| = {fmt(result['max_residual'])} (Newton tol {result['newton_tol']:g})",
    ]
    if result.get("error"):
        lines.append(f"  stopped:   {result['error']}")
    return "\n".join(lines)

