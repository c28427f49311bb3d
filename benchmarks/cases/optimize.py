"""Design optimization benchmark (issue #15): `symid optimize` on its exact
gradients against scipy's finite-difference gradients of the same problem.

    python -m benchmarks optimize [--steps N] [--backend B] [--figure PNG]

The problem is the bundled counterweight example's: minimize the motor's RMS
torque over the counterweight's mass and angle (`--vary m_cw=1:4 --vary
beta_cw=2.5:3.8`), from the file's values, by SLSQP with the same tolerance.
Exact: one solve with sensitivities per point. Finite differences: scipy's
2-point differences of the figure, one plain solve per point and per parameter.
Target: fewer solves with the exact gradients, the same optimum to 1e-8, and
less wall time. Each optimization runs in a worker process of its own,
timed from its start to its end (each pays its own first solve, loading and
lambdifying; neither the other's nor the imports both share), so the order
they run in does not favour the second; the compiled solvers come from a
cache that a first untimed run of each filled.

`--figure` also draws the motor torque before and after (the README's figure).
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks.cases import register
from benchmarks.run import Context
from symid import api, backends
from symid.study import optimize as opt

EXAMPLE = "slider_crank_counterweight"
VARY = ["m_cw=1:4", "beta_cw=2.5:3.8"]
OBJECTIVE = "motor.effort_rms"


def optimize(spec: dict[str, Any]) -> dict[str, Any]:
    """One optimization, in a worker process: its outcome and wall time."""
    import scipy.optimize  # noqa: F401  (here, not inside the timed run: importing it is slow)

    from symid.tools.sensitive import solver

    mech = api.load_mechanism(api.example(EXAMPLE), steps=spec["steps"])
    problem = opt.Problem(mech, OBJECTIVE, opt.parse_vary(VARY), [], solver(spec["backend"]), exact=spec["exact"])
    start = time.perf_counter()
    o = opt.run(problem)
    seconds = time.perf_counter() - start
    return {"solves": o.evaluations, "iterations": o.iterations, "seconds": seconds, "names": list(o.names),
            "p": [float(v) for v in o.p], "optimum": dict(zip(o.names, map(float, o.p))), "value": float(o.value),
            "start_value": float(o.start_value), "success": bool(o.success)}


def figure(path: Path, outcome: dict[str, Any], steps: int) -> None:
    """The motor torque over one crank turn, the file's counterweight against the optimum."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    mech = api.load_mechanism(api.example(EXAMPLE), steps=steps)
    before = api.solve(mech)
    after = api.solve(api.load_mechanism(api.example(EXAMPLE), {n: repr(float(v)) for n, v in
                                                                zip(outcome["names"], outcome["p"])}, steps=steps))
    fig, ax = plt.subplots(figsize=(7, 3.6), dpi=100)
    turn = 360.0 * before.t / (before.t[-1] - before.t[0])
    start = {n: float(mech.parameters[n]) for n in outcome["names"]}
    ax.plot(turn, before["motor.T_j"], label=f"file: m_cw = {start['m_cw']:.3g} kg, beta_cw = "
                                              f"{start['beta_cw']:.3f} (RMS {outcome['start_value']:.3f} N·m)")
    ax.plot(turn, after["motor.T_j"], label=f"optimum: m_cw = {outcome['p'][0]:.3f} kg, beta_cw = "
                                             f"{outcome['p'][1]:.3f} (RMS {outcome['value']:.3f} N·m)")
    ax.axhline(0.0, color="0.6", lw=0.8)
    ax.set_xlabel("crank angle [deg]")
    ax.set_ylabel("motor torque [N·m]")
    ax.set_title("counterweight on the crank: motor torque before and after symid optimize", fontsize=10)
    ax.legend(fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)


def _options(group: Any) -> None:
    group.add_argument("--steps", type=int, default=201, help="instants per run (the example's: 201)")
    group.add_argument("--backend", default="c")
    group.add_argument("--figure", type=Path, help="also draw the torque before and after into this PNG")


@register("optimize", "symid optimize on exact gradients against SciPy's finite differences: solves, time, the "
          "same optimum", options=_options)
def optimize_case(ctx: Context) -> dict[str, Any]:
    steps = 21 if ctx.smoke else ctx.options.steps
    if ctx.options.backend not in backends.names():  # said before any worker starts
        raise RuntimeError(f"no backend {ctx.options.backend!r}; the backends: {', '.join(backends.names())}")
    runs = {}
    cache = ctx.work / "cache"  # shared, and filled by a first untimed run of each: neither times a compile
    # smoke: no untimed first runs (they fill the cache so that no timed run pays a compile;
    # a smoke run's times mean nothing, and each optimization still runs whole in its worker)
    for timed in (True,) if ctx.smoke else (False, True):
        for label, exact in (("exact", True), ("finite_differences", False)):
            got = ctx.isolated("benchmarks.cases.optimize:optimize",
                               {"steps": steps, "backend": ctx.options.backend, "exact": exact}, 3600.0, cache)
            if got.status != "ok":
                raise RuntimeError(f"the {label} optimization {got.status}: {got.note}")
            runs[label] = got.result
    exact, fd = runs["exact"], runs["finite_differences"]
    if ctx.options.figure:
        figure(ctx.options.figure, exact, steps)
    return {"example": EXAMPLE, "vary": VARY, "objective": OBJECTIVE, "steps": steps, "backend": ctx.options.backend,
            "start": exact["start_value"], **runs,
            "relative_difference_value": abs(exact["value"] - fd["value"]) / abs(exact["value"]),
            "relative_difference_parameters": float(np.max(np.abs(np.subtract(exact["p"], fd["p"]))
                                                           / np.abs(exact["p"])))}
