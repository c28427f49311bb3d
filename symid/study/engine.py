"""The batch engine of design studies: the figures of K variants of one mechanism.

`solve_figures` runs each variant (one row of base parameter values) and
keeps its figures (`symid.study.figures`). On the C backend the variants run
inside the generated solver's own loop (`symid.study.batch_c`), on threads;
on the NumPy backend all variants of a chunk advance together, vectorized
over variants (`symid.study.batch_numpy`);
the few instants that loop cannot vouch for (a failure, or a step its jump
check flags) are decided by re-running that variant through the normal solve
path, so every variant ends with the answer `symid solve --set` gives. Other
backends (and NumPy runs asking for the Python loop's stability features)
run each variant through the normal path.
"""

from __future__ import annotations

from typing import Iterator, Sequence

import numpy as np

from symid import backends
from symid.backends import Array, friction
from symid.backends.prepare import Solver, check, prepare
from symid.errors import AnalysisError
from symid.model.mechanism import Mechanism
from symid.model.params import initial_guess
from symid.numeric.stability import Notes
from symid.output.results import columns, table_rows
from symid.study.figures import STATUS, Figures, figure_names, status_of
from symid.study.memo import ByIdentity
from symid.study.variants import Measure, base_matrix, study_mechanism, variant_values
from symid.symbolic.assemble import Layout, assemble

BACKENDS = ("c", "numpy", "casadi", "reference")
# Variants below which a NumPy chunk runs each variant through the normal path
# (the module's own loop) instead of the vectorized one. A step of the
# vectorized loop costs ~3.3 ms whatever K (a few hundred array operations);
# the module's loop ~0.07 ms an instant per variant (slider-crank, 1001
# instants: K = 1 0.58 s against 3.3 s, 16 1.2 s against 4.2 s, 32 2.3 s
# against 3.4 s, 64 4.4 s against 3.4 s). A long run leaves few variants per
# chunk (`symid.study.run.CHUNK_INSTANTS`): one variant of 20001 instants took
# 82 s on the vectorized loop, 1.5 s on the module's.
NUMPY_BATCH_MIN = 32
_CHECKED: ByIdentity[Mechanism] = ByIdentity()  # per mechanism object and backend: its study mechanism


def solve_figures(mechanism: Mechanism, names: Sequence[str], base: np.ndarray, backend: str = "c",
                  workers: int | None = None) -> Figures:
    """The figures of K variants.

    Args:
        mechanism: the mechanism; its `[analysis]` (kind, t0, t1, steps, tol,
            reactions) applies to every variant.
        names: the varied base parameters; every other keeps its value.
        base: shape (K, len(names)), one variant per row.
        backend: "c" (the batch loop, on `workers` threads, default every
            core), "numpy" (vectorized over variants, one thread), "casadi"
            or "reference" (one variant at a time).

    Raises:
        InputError: an unknown or derived parameter, or `base` of the wrong shape.
    """
    mech = _CHECKED.get(mechanism, backend, lambda: _checked(mechanism, backend))
    full = base_matrix(mech, names, base)
    able = backends.capabilities(backend)
    if friction.solved(mech) and not able.batch_friction:  # each variant alone, through the Python loop
        return _normal_path(mech, full, backend)
    if mech.sizing and mech.analysis.kind == "inverse_dynamics":  # sizing reads each variant's whole table
        return _normal_path(mech, full, backend)
    order = figure_names(mech)
    if able.batch == "vectorized":
        from symid.study import batch_numpy

        if not batch_numpy.usable(mech) or len(full) < NUMPY_BATCH_MIN:
            # the Python loop's stability features, or too few variants to pay for the vectorized loop
            return _normal_path(mech, full, backend)
        vector = batch_numpy.run(mech, full)
        return _decided(mech, full, backend, order, vector.names, vector.values, vector.status, vector.t_end)
    if able.batch != "compiled":
        return _normal_path(mech, full, backend)
    from symid.study import batch_c

    batch = batch_c.run(mech, full, workers)
    return _decided(mech, full, backend, order, batch.names, batch.values, batch.status, batch.t_end)


def _checked(mechanism: Mechanism, backend: str) -> Mechanism:
    """The study's mechanism (`study_mechanism`), checked for `backend`.

    Raises:
        InputError: the backend cannot solve it, or more rows than coordinates
            (the same input error as a solve's, at the file's values).
    """
    mech = study_mechanism(mechanism)
    check(mech, backend)
    return mech


def _decided(mech: Mechanism, full: Array, backend: str, order: tuple[str, ...], names: Sequence[str],
             got: Array, codes: Array, ends: Array) -> Figures:
    """The figures of a batch loop (in its `names` order), with the variants
    it handed back (`codes` != 0) decided through the normal path."""
    values = got[:, [list(names).index(n) for n in order]] if order else np.zeros((len(full), 0))
    status = np.zeros(len(full), dtype=np.intc)
    t_end = ends.copy()
    cond = np.zeros(len(full))  # the loops hand every variant past their conditioning screen back
    retry = np.flatnonzero(codes != 0)
    if retry.size:  # rare: decided as a solve decides them
        again = _normal_path(mech, full[retry], backend)
        values[retry], status[retry], t_end[retry], cond[retry] = again.values, again.status, again.t_end, again.cond
    return Figures(order, values, status, t_end, cond)


def variant_mechanism(mech: Mechanism, row: Array) -> Mechanism:
    """`mech` with the base parameters of one variant (derived ones keep
    their definitions), e.g. for the summary lines of its results."""
    import dataclasses

    import sympy as sp

    from symid.model.params import base_names

    given = dict(zip(base_names(mech.parameters), row.tolist()))
    parameters = {n: sp.Float(given[n]) if n in given else e for n, e in mech.parameters.items()}
    return dataclasses.replace(mech, parameters=parameters)


def _normal_path(mech: Mechanism, full: Array, backend: str) -> Figures:
    """Each variant through its own evaluator and the normal solve loop."""
    layout = assemble(mech)
    header = columns(layout, mech.analysis)
    measure = Measure(mech, header)
    k = len(full)
    values = np.full((k, len(measure.names)), np.nan)
    status = np.zeros(k, dtype=np.intc)
    t_end = np.full(k, np.nan)
    notes: list[Notes] = []
    for v, (data, error) in enumerate(trajectories(mech, layout, full, backend, notes=notes)):
        status[v] = status_of(error)
        if len(data):
            values[v] = measure(data, variant_values(mech, full[v]))
            t_end[v] = data[-1, 0]
    return Figures(measure.names, values, status, t_end, np.array([n.worst_cond() for n in notes]))


def trajectories(mech: Mechanism, layout: Layout, full: Array, backend: str, solver: Solver | None = None,
                 notes: list[Notes] | None = None) -> Iterator[tuple[Array, AnalysisError | None]]:
    """Each variant's solved table (instants, columns) and its failure (None
    if it ran to t1), in order, one at a time.

    Args:
        full: (K, NP) base parameter vectors (`variants.base_matrix`).
        solver: a solver of `mech` on `backend` already built, to reuse.
        notes: if given, each variant's warnings (`Notes`) are appended to it.
    """
    width = len(columns(layout, mech.analysis))
    first = solver
    for row in full:
        try:
            values = variant_values(mech, row)
        except ValueError as exc:  # a derived parameter is not finite: nothing solved
            if notes is not None:
                notes.append(Notes(mech.analysis))
            yield np.empty((0, width)), AnalysisError(f"parameter {exc.args[0]} {exc.args[1]}: not finite")
            continue
        q0 = initial_guess(mech, values)
        kept = Notes(mech.analysis)
        if notes is not None:
            notes.append(kept)
        if first is None:  # built at the first variant's values, friction model included
            first = prepare(mech, backend, layout=layout, values=values)
            ev = first.evaluator
        else:  # the solver built once serves every variant: its parameter values change
            ev = first.with_values(values).evaluator  # (the reference backend builds one per variant)
        rows: list[Array] = []
        error = None
        try:
            for r in table_rows(ev, mech.analysis, q0, kept):
                rows.append(r)
        except AnalysisError as exc:
            error = exc
        yield np.array(rows).reshape(len(rows), width), error


__all__ = ["BACKENDS", "STATUS", "solve_figures", "trajectories"]
