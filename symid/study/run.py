"""Running a study: the variants in chunks, on this machine or a Dask cluster.

A chunk is a few hundred thousand instants (a fraction of a second on the
compiled engine), so a progress bar moves, Ctrl-C is answered promptly and
keeps every finished chunk, and a cluster task is small enough to retry.
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING, Any, Callable, Iterator, Sequence

import numpy as np

from symid.backends import Array
from symid.errors import check_signal
from symid.model.mechanism import Mechanism
from symid.study.figures import STATUS, Figures, figure_names
from symid.study.table import SweepTable
from symid.study.design import Variants

if TYPE_CHECKING:
    from distributed import Client

Engine = Callable[[Mechanism, Sequence[str], Array, str, "int | None"], Figures]
CHUNK_INSTANTS = 500_000  # instants per chunk on the batch engine: ~0.05 s at 10 M instants/s


def _engine(backend: str) -> tuple[Engine, int]:
    """The function that solves a chunk of variants on `backend`, and its chunk size in instants.

    Every variant of every sweep goes through here: the one place the engine is
    chosen. A backend with a batch path (`Capabilities.batch`: c's batch
    entry on threads, NumPy over variants) takes the batch engine
    (`symid.study.engine`) in chunks of many variants; the others (casadi,
    reference) are solved variant by variant (`symid.study.slow`).
    """
    from symid.backends import capabilities

    if capabilities(backend).batch is not None:
        from symid.study.engine import solve_figures
        return solve_figures, CHUNK_INSTANTS
    from symid.study.slow import figures_by_solving

    def slow(mechanism: Mechanism, names: Sequence[str], base: Array, backend: str,
             workers: int | None = None) -> Figures:
        return figures_by_solving(mechanism, names, base, backend)

    return slow, 1  # one variant per chunk: each is a whole Python solve


def warm(mechanism: Mechanism, backend: str) -> None:
    """Build (or load from the cache) the solver of the study's structure, once."""
    from symid.backends import Needs, capabilities

    if capabilities(backend).batch == "compiled":
        # the batch's own solver (not the normal path's evaluator: other code
        # options, another cache entry, which the chunks would then build
        # inside the solve phase), kept for every chunk of this mechanism object
        from symid.study.engine import solve_figures

        solve_figures(mechanism, (), np.zeros((0, 0)), backend, 1)
        return
    from symid.backends.prepare import prepare
    from symid.study.slow import study_analysis

    mech = study_analysis(mechanism)
    # no friction model nor reactions: only what the cache entry is keyed by is built
    prepare(mech, backend, Needs(velocity=mech.analysis.kind != "statics", friction=False))


def held_values(mechanism: Mechanism, variants: Variants, backend: str, gradients: bool = False) -> tuple[int, int]:
    """What a study holds in memory at once, in values (doubles), estimated before it starts.

    The table of finished variants (K rows: the varied parameters, the figures
    (with --gradients, and their gradients by each), status and t_end), plus
    the largest working set of one step of the engines: one variant's whole
    table (instants x columns, with --gradients its sensitivity columns too),
    which the normal path holds and to which every engine hands the variants it
    cannot vouch for, or a chunk of the NumPy batch loop (`batch_numpy.BUDGET`).

    Returns:
        (the total, the table of finished variants' share).
    """
    from symid.output.results import columns
    from symid.study.variants import study_mechanism
    from symid.symbolic.assemble import assemble

    mech = study_mechanism(mechanism)
    varied = len(variants.names)
    figures = len(figure_names(mechanism)) * (1 + varied if gradients else 1)
    table = len(variants) * (varied + figures + 2)
    width = len(columns(assemble(mech), mech.analysis)) * (1 + varied if gradients else 1)
    working = mech.analysis.steps * width
    from symid.backends import capabilities

    if capabilities(backend).batch == "vectorized":
        from symid.study.batch_numpy import BUDGET

        working = max(working, BUDGET // 8)
    return table + working, table


def check_memory(mechanism: Mechanism, variants: Variants, backend: str, what: str, gradients: bool = False) -> None:
    """Refuse, before any work, a study that would hold more than `MAX_HELD_VALUES` values (1 GiB).

    Raises:
        InputError: naming the count of variants, the instants, the values and the limit (exit 2).
    """
    from symid.errors import InputError
    from symid.io.limits import MAX_HELD_VALUES
    from symid.text import plural

    total, table = held_values(mechanism, variants, backend, gradients)
    if total > MAX_HELD_VALUES:
        raise InputError(f"{what}: {plural(len(variants), 'variant')} of {mechanism.analysis.steps} instants: about "
                         f"{total} values to hold in memory ({table} in the table of variants, the rest for one variant's "
                         f"instants), more than the {MAX_HELD_VALUES} (1 GiB) allowed (fewer variants, steps or "
                         "varied parameters)")


def per_chunk(steps: int, backend: str) -> int:
    """Variants per chunk on `backend` for runs of `steps` instants."""
    _, instants = _engine(backend)
    return max(1, instants // max(steps, 1))


class Sweep:
    """One study under way: its chunks as they finish, and the table of those finished.

    Args:
        mechanism: the study's mechanism; variants: what to vary.
        backend: "c", "numpy" (or "casadi", "reference": solved variant by variant).
        workers: threads on this machine (None: all cores); client: a Dask
            `distributed.Client` to run the chunks on instead.
    """

    def __init__(self, mechanism: Mechanism, variants: Variants, backend: str = "c",
                 workers: int | None = None, client: Client | None = None) -> None:
        self.mechanism, self.variants, self.backend = mechanism, variants, backend
        self.workers, self.client = workers, client
        self.parts: dict[int, Figures] = {}
        self.setup_s = 0.0
        self.solve_s = 0.0

    def setup(self) -> None:
        """Build or load the solver here (locally) or on every worker (cluster)."""
        start = time.perf_counter()
        if self.client is None:
            warm(self.mechanism, self.backend)
        else:
            from symid.study import cluster

            cluster.warm_workers(self.client, self.mechanism, self.backend)
        self.setup_s = time.perf_counter() - start

    def run(self) -> Iterator[int]:
        """Solve the chunks, yielding how many variants each finished."""
        start = time.perf_counter()
        try:
            if self.client is None:
                yield from self._local()
            else:
                from symid.study import cluster

                for first, figures in cluster.run_chunks(self.client, self.mechanism, self.variants,
                                                         self.backend):
                    self.parts[first] = figures
                    yield len(figures)
        finally:
            self.solve_s += time.perf_counter() - start

    def _local(self) -> Iterator[int]:
        engine, _ = _engine(self.backend)
        per = per_chunk(self.mechanism.analysis.steps, self.backend)
        names, values = self.variants.names, self.variants.values
        for first in range(0, len(values), per):
            figures = engine(self.mechanism, names, values[first:first + per], self.backend, self.workers)
            check_signal()  # a signal swallowed inside the chunk: its figures are not kept
            self.parts[first] = figures
            yield len(figures)

    def columns(self) -> tuple[str, ...]:
        """The figure columns of each part (`GradientSweep` adds the gradients')."""
        return figure_names(self.mechanism)

    def table(self) -> SweepTable:
        """The variants finished so far, in variant order."""
        names = self.columns()
        firsts = sorted(self.parts)
        if firsts:
            parts = [self.parts[f] for f in firsts]
            figures = Figures(names, np.concatenate([p.values for p in parts]),
                              np.concatenate([p.status for p in parts]), np.concatenate([p.t_end for p in parts]),
                              np.concatenate([p.cond for p in parts]))
            index = np.concatenate([np.arange(f, f + len(self.parts[f])) for f in firsts])
        else:
            figures = Figures(names, np.empty((0, len(names))), np.zeros(0, dtype=np.int8), np.zeros(0))
            index = np.zeros(0, dtype=np.int64)
        return SweepTable(self.variants.kind, self.variants.names, self.variants.values[index].reshape(
            len(index), len(self.variants.names)), figures, index)

    def instants(self) -> int:
        """Instants solved in the finished variants (a failed one: those before it stopped)."""
        a = self.mechanism.analysis
        h = (a.t1 - a.t0) / (a.steps - 1) if a.steps > 1 else 1.0
        total = 0
        for part in self.parts.values():
            ok = part.status == STATUS.index("ok")
            total += int(np.count_nonzero(ok)) * a.steps
            ends = part.t_end[~ok]
            ends = ends[np.isfinite(ends)]
            total += int(np.sum(np.rint((ends - a.t0) / h) + 1)) if a.steps > 1 else len(ends)
        return total


def solve(mechanism: Mechanism, variants: Variants, backend: str = "c", workers: int | None = None,
          client: Any = None) -> SweepTable:
    """Run a whole study and return its table (see `Sweep`).

    Raises:
        InputError: the study would hold more than `MAX_HELD_VALUES` values (`check_memory`).
    """
    check_memory(mechanism, variants, backend, mechanism.source or "sweep")
    sweep = Sweep(mechanism, variants, backend, workers, client)
    sweep.setup()
    for _ in sweep.run():
        pass
    return sweep.table()
