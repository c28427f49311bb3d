"""Design optimization benchmark (issue #15): `symid optimize` on its exact
gradients against scipy's finite-difference gradients of the same problem.

    python -m benchmarks.optimize [--steps N] [--backend B] [--out benchmarks/results] [--figure PNG]

The problem is the bundled counterweight example's: minimize the motor's RMS
torque over the counterweight's mass and angle (`--vary m_cw=1:4 --vary
beta_cw=2.5:3.8`), from the file's values, by SLSQP with the same tolerance.
Exact: one solve with sensitivities per point. Finite differences: scipy's
2-point differences of the figure, one plain solve per point and per parameter.
Target: fewer solves with the exact gradients, the same optimum to 1e-8, and
less wall time. Each optimization runs in a fresh process of its own, timed
from its start to its end (each pays its own first solve, loading and
lambdifying; neither the other's nor the imports both share), so the order
they run in does not favour the second.

Prints both, writes `optimize.json`; `--figure` also draws the motor torque
before and after (the README's figure).
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
from concurrent.futures import ProcessPoolExecutor
import os
import platform
import time
from pathlib import Path

import numpy as np
import scipy
import scipy.optimize  # noqa: F401  (here, not inside the first timed run: importing it takes ~2 s)

from symid import api
from symid.study import optimize as opt
from symid.tools.sensitive import solver

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE = "slider_crank_counterweight"
VARY = ["m_cw=1:4", "beta_cw=2.5:3.8"]
OBJECTIVE = "motor.effort_rms"


def optimize(steps: int, backend: str, exact: bool) -> tuple[opt.Outcome, float]:
    """The outcome and the wall time of one optimization."""
    mech = api.load_mechanism(api.example(EXAMPLE), steps=steps)
    problem = opt.Problem(mech, OBJECTIVE, opt.parse_vary(VARY), [], solver(backend), exact=exact)
    start = time.perf_counter()
    outcome = opt.run(problem)
    return outcome, time.perf_counter() - start


def fresh(steps: int, backend: str, exact: bool) -> tuple[opt.Outcome, float]:
    """`optimize` in a new process (spawned: nothing solved, loaded or lambdified yet)."""
    with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as pool:
        return pool.submit(optimize, steps, backend, exact).result()


def figure(path: Path, outcome: opt.Outcome, steps: int) -> None:
    """The motor torque over one crank turn, the file's counterweight against the optimum."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    mech = api.load_mechanism(api.example(EXAMPLE), steps=steps)
    before = api.solve(mech)
    after = api.solve(api.load_mechanism(api.example(EXAMPLE), {n: repr(float(v)) for n, v in
                                                                zip(outcome.names, outcome.p)}, steps=steps))
    fig, ax = plt.subplots(figsize=(7, 3.6), dpi=100)
    turn = 360.0 * before.t / (before.t[-1] - before.t[0])
    start = {n: float(mech.parameters[n]) for n in outcome.names}
    ax.plot(turn, before["motor.T_j"], label=f"file: m_cw = {start['m_cw']:.3g} kg, beta_cw = "
                                              f"{start['beta_cw']:.3f} (RMS {outcome.start_value:.3f} N·m)")
    ax.plot(turn, after["motor.T_j"], label=f"optimum: m_cw = {outcome.p[0]:.3f} kg, beta_cw = "
                                             f"{outcome.p[1]:.3f} (RMS {outcome.value:.3f} N·m)")
    ax.axhline(0.0, color="0.6", lw=0.8)
    ax.set_xlabel("crank angle [deg]")
    ax.set_ylabel("motor torque [N·m]")
    ax.set_title("counterweight on the crank: motor torque before and after symid optimize", fontsize=10)
    ax.legend(fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)


def main(argv: list[str] | None = None) -> dict[str, object]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=201, help="instants per run (the example's: 201)")
    parser.add_argument("--backend", default="c")
    parser.add_argument("--out", default=str(ROOT / "benchmarks" / "results"))
    parser.add_argument("--figure", help="also draw the torque before and after into this PNG")
    args = parser.parse_args(argv)
    exact, exact_s = fresh(args.steps, args.backend, True)
    fd, fd_s = fresh(args.steps, args.backend, False)
    value_diff = abs(exact.value - fd.value) / abs(exact.value)
    p_diff = float(np.max(np.abs(exact.p - fd.p) / np.abs(exact.p)))
    result: dict[str, object] = {
        "example": EXAMPLE, "vary": VARY, "objective": OBJECTIVE, "steps": args.steps, "backend": args.backend,
        "start": exact.start_value,
        "exact": {"solves": exact.evaluations, "iterations": exact.iterations, "seconds": exact_s,
                  "optimum": dict(zip(exact.names, map(float, exact.p))), "value": exact.value,
                  "success": exact.success},
        "finite_differences": {"solves": fd.evaluations, "iterations": fd.iterations, "seconds": fd_s,
                               "optimum": dict(zip(fd.names, map(float, fd.p))), "value": fd.value,
                               "success": fd.success},
        "relative_difference_value": value_diff, "relative_difference_parameters": p_diff,
        "machine": {"platform": platform.platform(), "cpu_count": os.cpu_count(),
                    "python": platform.python_version(), "numpy": np.__version__, "scipy": scipy.__version__},
    }
    print(f"{EXAMPLE}, {args.steps} instants on {args.backend}: minimize {OBJECTIVE} over {' '.join(VARY)} "
          f"from {exact.start_value:.6g}")
    for label, o, s in (("exact gradients", exact, exact_s), ("finite differences", fd, fd_s)):
        where = ", ".join(f"{n} = {v:.12g}" for n, v in zip(o.names, o.p))
        print(f"  {label}: {o.evaluations} solves, {o.iterations} iterations, {s:.2f} s: {where}, "
              f"{OBJECTIVE} = {o.value:.15g}")
    print(f"  same optimum: figure within {value_diff:.1e}, parameters within {p_diff:.1e} (relative)")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "optimize.json").write_text(json.dumps(result, indent=2) + "\n")
    if args.figure:
        figure(Path(args.figure), exact, args.steps)
    return result


if __name__ == "__main__":
    main()
