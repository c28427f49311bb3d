"""Sensitivities on the Python path (issue #15; the python part of the
`sensitivity` case): per instant, first setup and re-parameterized setup, apart.

- per instant: the table with d(COLUMN)/d(NAME) columns (default columns)
  for n_p = 1, 2, 4 base parameters against the same table without them
  (the backend's own loop, what `symid solve` runs), best of R, in rounds
  over the variants so the machine's load shifts all alike; the target is
  1 + 0.3 n_p.
- first setup: the sensitivity derivation and lambdify from cold caches,
  plus the first run (n_p = 1 also pays the families' own derivation,
  which later counts share, as one process would).
- re-parameterized setup: another value of the first parameter (file
  reloaded, prepared, the sensitivity evaluator built): wall clock and the
  lambdify calls it made (0: the structure was reused).
"""

from __future__ import annotations

import platform
import time

import numpy as np

from symid import api
from symid.model.params import base_names
from symid.numeric import sensitivity_build
from symid.output import sensitivity as columns
from symid.symbolic import sensitivity as symbolic

COUNTS = (1, 2, 4)
# a smoke run's: n_p = 2, the first (it derives the families too) and the one re-parameterized,
# and 4, whose masses add the inertia's derivatives to the lengths' (1 is one of 2's lengths)
SMOKE_COUNTS = (2, 4)


def _cold() -> None:
    """Empty the process's derivation and lambdify caches (a first setup)."""
    sensitivity_build._KERNELS.clear()
    sensitivity_build._STRUCTURES.clear()
    symbolic._constraint.cache_clear()
    symbolic._force.cache_clear()


def example_figures(example: str, backend: str, instants: int, repeats: int,
                    counts: tuple[int, ...] = COUNTS) -> dict[str, object]:
    """The figures of one example (see the module's docstring)."""
    path = api.example(example)
    names = base_names(api.load_mechanism(path).parameters)
    studies = {0: api.prepare(path, backend, steps=instants)}
    setup = {}
    for n_p in counts:
        _cold()
        start = time.perf_counter()
        studies[n_p] = api.prepare(path, backend, steps=instants, sensitivity=names[:n_p])
        list(studies[n_p].rows())
        setup[n_p] = time.perf_counter() - start
    best = dict.fromkeys(studies, np.inf)
    for _ in range(repeats):
        for n_p, study in studies.items():
            start = time.perf_counter()
            sum(1 for _ in study.rows())
            best[n_p] = min(best[n_p], time.perf_counter() - start)
    # re-parameterized: another value of the first parameter, structure built above
    value = studies[2].values[next(s for s in studies[2].values if str(s) == names[0])]
    before = sensitivity_build.BUILDS["lambdify"]
    start = time.perf_counter()
    other = api.prepare(api.load_mechanism(path, {names[0]: repr(1.1 * value)}), backend, steps=instants,
                        sensitivity=names[:2])
    columns.evaluator_for(other.layout, other.values, other.sensitivity, other.analysis)
    reparam = time.perf_counter() - start
    built = sensitivity_build.BUILDS["lambdify"] - before
    plain = best[0] / instants * 1e6
    out: dict[str, object] = {"plain_us_per_instant": plain,
                              "reparameterized_setup_s": reparam, "reparameterized_lambdify_calls": built}
    for n_p in counts:
        ratio = best[n_p] / best[0]
        out[f"n_p={n_p}"] = {"parameters": list(names[:n_p]), "us_per_instant": best[n_p] / instants * 1e6,
                             "ratio": ratio, "target": 1 + 0.3 * n_p, "first_setup_s": setup[n_p]}
        print(f"{example} on {backend}: n_p = {n_p}: {ratio:.2f}x the plain instant ({best[n_p] / instants * 1e6:.0f} "
              f"vs {plain:.0f} us; target <= {1 + 0.3 * n_p:.1f}x); first setup {setup[n_p]:.2f} s")
    print(f"{example}: re-parameterized setup {reparam * 1e3:.0f} ms, {built} lambdify calls")
    return out


def python_part(examples: str, backend: str, instants: int, repeats: int,
                counts: tuple[int, ...] = COUNTS) -> dict[str, object]:
    """Every example's figures."""
    return {"backend": backend, "instants": instants, "machine": platform.machine(),
            "examples": {e: example_figures(e, backend, instants, repeats, counts) for e in examples.split(",")}}
