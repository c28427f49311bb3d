"""Joint friction benchmark (issue #16): what friction costs in generated C,
and how fast its Newton converges.

    python -m benchmarks friction [--instants N] [--repeats R]

1. cost: microseconds per instant of the compiled C loop (`symid solve
   --backend c`'s trajectory, rows streamed to Python and dropped) on the
   bundled slider-crank with friction in every joint (three pins and the
   guide, `slider_crank_friction.toml`) against the frictionless one
   (`slider_crank.toml`), same instants; best of R rounds of both. Target: <= 2x.
   With valgrind, also instructions per instant by callgrind
   (`benchmarks.callgrind`), which the machine's load does not change.
2. iterations: the friction Newton's iterations per instant on the bundled
   example (the Python loop, the same rule as the C), its maximum. Target: <= 3.
"""

from __future__ import annotations

import time
from collections import Counter
from typing import Any

import numpy as np

from benchmarks import callgrind
from benchmarks.cases import register
from benchmarks.run import Context
from symid import api
from symid.numeric.solve import run


def per_instant(examples: tuple[str, ...], instants: int, repeats: int) -> dict[str, float]:
    """Best microseconds per instant of the C backend's whole run, per example;
    the examples alternate round by round, so that the machine's load shifts all alike."""
    studies = {e: api.prepare(api.example(e), backend="c", steps=instants) for e in examples}
    best = dict.fromkeys(examples, np.inf)
    for _ in range(repeats):
        for e, study in studies.items():
            start = time.perf_counter()
            count = sum(1 for _ in study.evaluator.rows(study.analysis, study.q0()))  # type: ignore[attr-defined]
            best[e] = min(best[e], (time.perf_counter() - start) / count)
    return {e: float(v * 1e6) for e, v in best.items()}


def iterations(example: str, steps: int | None = None) -> dict[int, int]:
    """Friction Newton iterations -> instants, over the example's own run (or its span in `steps` instants)."""
    study = api.prepare(api.example(example), backend="reference", **({} if steps is None else {"steps": steps}))
    return dict(sorted(Counter(i.friction.iterations for i in run(study.evaluator, study.analysis,
                                                                  study.q0())).items()))


def _options(group: Any) -> None:
    group.add_argument("--instants", type=int, default=100_001)
    group.add_argument("--repeats", type=int, default=5)


@register("friction", "joint friction in generated C: us and instructions per instant with and without it; the "
          "friction Newton's iterations", options=_options, tools=("gcc",))
def friction(ctx: Context) -> dict[str, Any]:
    instants, repeats = (201, 1) if ctx.smoke else (ctx.options.instants, ctx.options.repeats)
    us = per_instant(("slider_crank", "slider_crank_friction"), instants, repeats)
    plain, with_friction = us["slider_crank"], us["slider_crank_friction"]
    # smoke: the run's span in 21 instants, not 201 (the reference backend's: 10 ms an instant)
    counts = iterations("slider_crank_friction", 21 if ctx.smoke else None)
    out: dict[str, Any] = {
        "instants": instants, "repeats": repeats,
        "c_us_per_instant_frictionless": plain, "c_us_per_instant_friction": with_friction,
        "ratio": with_friction / plain, "ratio_target": 2.0,
        "newton_iterations": {str(k): v for k, v in counts.items()}, "max_newton_iterations": max(counts),
        "iterations_target": 3}
    if callgrind.available():
        first, second = (20, 60) if ctx.smoke else (200, 2200)
        ir = {e: callgrind.per_instant(e, first, second) for e in ("slider_crank", "slider_crank_friction")}
        out.update(c_instructions_per_instant_frictionless=ir["slider_crank"],
                   c_instructions_per_instant_friction=ir["slider_crank_friction"],
                   instructions_ratio=ir["slider_crank_friction"] / ir["slider_crank"])
    return out
