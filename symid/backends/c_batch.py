"""Many variants through the compiled solver's batch entry point `<name>_sweep`.

Python's work is one ctypes call per chunk of variants: the C loop solves
every instant and accumulates the figures. ctypes releases the GIL for the
call, so chunks run on a pool of threads, one workspace each. A variant is
independent of its neighbours (each starts from a fresh state), so the
figures do not depend on how the variants are cut into chunks or threads.
The entry is bound in the library the solver's evaluator loaded (`entry`).
"""

from __future__ import annotations

import ctypes
import os
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from symid.backends import Array
from symid.backends.c_backend import CEvaluator
from symid.model.analysis import Analysis

_D = ctypes.POINTER(ctypes.c_double)
_I = ctypes.POINTER(ctypes.c_int)
_L = ctypes.POINTER(ctypes.c_long)
# variants per ctypes call: small enough that the threads share the work
# evenly and a chunk's figures stay in cache, large enough that the call
# (a few microseconds) is nothing beside a chunk's solve (16 slider-crank
# variants of 1001 instants: about 5 ms)
MAX_CHUNK = 64
# chunks per worker: while the last chunk of a call runs the other threads
# idle, up to a chunk's time; with four a worker, `symid sweep`'s calls of
# 499 slider-crank variants on two threads were cut into 63-variant chunks,
# about 25 ms each in a call of about 100 ms per thread
CHUNKS_PER_WORKER = 16


@dataclass
class Batch:
    """What the C loop returned for K variants (figures in the C code's order).

    Attributes:
        names: figure names in `values`' column order; values: (K, len(names));
        status: (K,) the compiled solver's status codes (0 ok); solved: (K,)
        instants solved; t_end: (K,) the last one's time (NaN if none);
        solve_s, cpu_s: wall and CPU seconds of the solve phase (the C calls).
    """

    names: tuple[str, ...]
    values: Array
    status: Array
    solved: Array
    t_end: Array
    folder: Path
    solve_s: float = 0.0
    cpu_s: float = 0.0


def chunks(k: int, workers: int) -> list[tuple[int, int]]:
    """[start, stop) ranges covering 0..k: about CHUNKS_PER_WORKER per worker, at most MAX_CHUNK each."""
    size = max(1, min(MAX_CHUNK, -(-k // (CHUNKS_PER_WORKER * max(1, workers)))))
    return [(s, min(k, s + size)) for s in range(0, k, size)]


def entry(evaluator: CEvaluator) -> Any:
    """The batch entry `<name>_sweep` of the library `evaluator` loaded, typed for ctypes."""
    sweep = evaluator.lib[f"{evaluator.name}_sweep"]
    sweep.argtypes = [ctypes.c_long, _D, ctypes.c_double, ctypes.c_double, ctypes.c_long, ctypes.c_double,
                      _D, _I, _D, _L, _D, _I]
    sweep.restype = ctypes.c_int
    return sweep


def run(sweep: Any, meta: dict[str, Any], folder: Path, name: str, a: Analysis, full: Array,
        workers: int | None = None) -> Batch:
    """Solve the variants `full` (K, NP base parameters) of the analysis `a` in C
    on `workers` threads (default: every core) through the entry `sweep`
    (`entry`) of the solver in `folder` (its meta.json: `meta`), named `name`."""
    h = (a.t1 - a.t0) / (a.steps - 1) if a.steps > 1 else 0.0
    k = len(full)
    p = np.ascontiguousarray(full, dtype=float)
    names = tuple(meta["sweep_figures"])
    values = np.full((k, len(names)), np.nan)
    status = np.zeros(k, dtype=np.intc)
    solved = np.zeros(k, dtype=np.dtype(ctypes.c_long))
    t_end = np.full(k, np.nan)
    workers = workers or os.cpu_count() or 1

    def call(span: tuple[int, int]) -> int:
        s, e = span
        work = np.zeros(meta["sweep_work"])
        iwork = np.zeros(max(1, meta["ng"]), dtype=np.intc)
        return int(sweep(e - s, p[s:].ctypes.data_as(_D) if p.shape[1] else None, a.t0, h, a.steps, a.tol,
                         values[s:].ctypes.data_as(_D), status[s:].ctypes.data_as(_I),
                         t_end[s:].ctypes.data_as(_D), solved[s:].ctypes.data_as(_L),
                         work.ctypes.data_as(_D), iwork.ctypes.data_as(_I)))

    spans = chunks(k, workers)
    tick, cpu = time.perf_counter(), time.process_time()
    if workers == 1:
        codes = [call(span) for span in spans]
    else:
        pool = ThreadPoolExecutor(max_workers=workers)
        try:
            codes = list(pool.map(call, spans))
        finally:  # on Ctrl-C, chunks not started are dropped (a running one ends within its few ms)
            pool.shutdown(wait=True, cancel_futures=True)
    solve_s, cpu_s = time.perf_counter() - tick, time.process_time() - cpu
    if any(codes):  # only arguments symid checked can be refused: a bug, not an input
        raise RuntimeError(f"{name}_sweep refused its arguments (status {max(codes)})")
    return Batch(names, values, status, solved, t_end, folder, solve_s, cpu_s)
