"""A study's variants through the compiled solver's batch entry
(`symid.backends.c_batch`), its solver built once per mechanism object.

The solver comes from `symid.backends.prepare`, like every other; the batch
entry is bound in the library its evaluator loaded, so a study loads the
compiled solver once.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, cast

from symid.backends import Array, Needs
from symid.backends import c_batch
from symid.backends.c_backend import CEvaluator
from symid.backends.c_batch import _D, _I, _L, Batch  # noqa: F401 (_D, _I, _L: the tests call the entry as run does)
from symid.backends.prepare import Solver, needs_of, prepare
from symid.model.mechanism import Mechanism
from symid.study.memo import ByIdentity


@dataclass(frozen=True)
class Compiled:
    """The loaded solver of a study: its `<name>_sweep`, meta.json, folder and the solver itself."""

    sweep: Any
    meta: dict[str, Any]
    folder: Path
    solver: Solver | None = None


_LOADED: ByIdentity[Compiled] = ByIdentity()  # per study mechanism object


def _load(mechanism: Mechanism) -> Compiled:
    needs: Needs = needs_of(mechanism)
    solver = prepare(mechanism, "c", Needs(velocity=needs.velocity, reactions=needs.reactions, batch=True,
                                                friction=False))
    evaluator = cast(CEvaluator, solver.evaluator)
    return Compiled(c_batch.entry(evaluator), evaluator.meta, evaluator.artifact, solver)


def run(mechanism: Mechanism, full: Array, workers: int | None = None) -> Batch:
    """Solve the variants `full` (K, NP base parameters) in C on `workers` threads
    (default: every core); `mechanism` is the study's (`study_mechanism`),
    its solver built or loaded once per mechanism object."""
    solver = _LOADED.get(mechanism, "c", lambda: _load(mechanism))
    return c_batch.run(solver.sweep, solver.meta, solver.folder, mechanism.name, mechanism.analysis, full, workers)
