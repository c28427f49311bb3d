"""The batch engine of design studies (issue 14, point 3): how fast the
compiled sweep solves many variants, on one and two threads.

- grid: slider-crank, 25 rod lengths x 40 crank speeds = 1000 variants x 1001
  instants, c backend (`symid.study.engine.solve_figures`), 1 and 2 threads:
  instants per second of the solve phase (the solver already built), and
  how many of the sweep's groups of variants solved side by side in SIMD
  lanes were abandoned to the one-by-one path (a lane parting from its
  neighbours: a failure, a dense fallback, an unexplained jump).
- anchor: the CasADi-generated C loop of the benchmark's slider-crank
  (`benchmarks.casadi_baselines.CasadiC`, one Function per instant, gcc -O2),
  1001 instants at the default parameters, one thread: its time per instant,
  times the grid's instants (what the grid would cost that way).
- numpy: the same grid of 1000 variants at S instants (default 101) on the
  numpy backend: the loop vectorized over variants (`symid.study.batch_numpy`,
  what `solve_figures` runs) against the per-variant loop it replaced (each
  variant through the generated module's own trajectory loop,
  `engine._normal_path`), instants per second of each.
- monte carlo: N variants (normal scatter, 1 % SD, on the lengths and masses)
  x 1001 instants on 2 threads: time and the process's peak memory; N below
  1e5 is extrapolated linearly to 1e5 (the work is per variant).

    python -m benchmarks sweep_engine [--mc N] [--grid-steps S] [--numpy-steps S] [--no-casadi]
"""

from __future__ import annotations

import os
import resource
import shutil
import time
from typing import Any

import numpy as np

from benchmarks.cases import register
from benchmarks.run import Context
from symid import api
from symid.study import batch_c
from symid.study.engine import solve_figures
from symid.study.variants import base_matrix, study_mechanism

MC_TARGET = 100_000


def _timed(mech: Any, names: tuple[str, ...], base: np.ndarray, workers: int) -> dict[str, Any]:
    """The solve phase (the C calls, on `workers` threads) and the whole call."""
    study = study_mechanism(mech)
    full = base_matrix(study, names, base)
    tick = time.perf_counter()
    batch = batch_c.run(study, full, workers)
    whole = time.perf_counter() - tick
    instants = int(batch.solved.sum())
    return {"workers": workers, "variants": len(base), "instants": instants, "solve_s": batch.solve_s,
            "whole_call_s": whole, "instants_per_s": instants / batch.solve_s,
            "instants_per_cpu_s": instants / batch.cpu_s, "failed": int(np.count_nonzero(batch.status))}


def lanes(mech: Any) -> tuple[int, int]:
    """(variants a group of the compiled sweep's lanes, groups abandoned so far
    to the one-by-one path) of the study's loaded solver (`<name>_sweep_lanes`)."""
    import ctypes

    study = study_mechanism(mech)
    folder = batch_c._load(study).folder
    fn = ctypes.CDLL(str(folder / "solver.so"))[f"{study.name}_sweep_lanes"]  # the loaded library: its counter
    fn.argtypes, fn.restype = [ctypes.POINTER(ctypes.c_long)], ctypes.c_long
    abandoned = ctypes.c_long(0)
    width = fn(ctypes.byref(abandoned))
    return int(width), int(abandoned.value)


def grid(steps: int, n_rods: int = 25, n_speeds: int = 40) -> dict[str, Any]:
    """The rods x speeds grid of the slider-crank on 1 and 2 threads, the best of two runs each."""
    mech = api.load_mechanism(api.example("slider_crank"), steps=steps)
    rods = np.linspace(0.2, 0.5, n_rods)
    speeds = np.linspace(1.0, 10.0, n_speeds)
    base = np.array([(r, n) for r in rods for n in speeds])
    names = ("L_rod", "n")
    solve_figures(mech, names, base[:2], "c", workers=1)  # build (or load) the solver: not the solve phase
    width, before = lanes(mech)
    runs = [_timed(mech, names, base, w) for w in (1, 2, 1, 2)]
    abandoned = (lanes(mech)[1] - before) / len(runs)  # per run of the grid (chunks: whole groups)
    best = {w: min((r for r in runs if r["workers"] == w), key=lambda r: r["solve_s"]) for w in (1, 2)}
    return {"steps": steps, "threads_1": best[1], "threads_2": best[2], "lanes": width,
            "groups": len(base) // width, "groups_abandoned": abandoned}


def numpy_grid(steps: int, variants: int = 1000) -> dict[str, Any]:
    """The grid on the numpy backend: vectorized over variants vs one variant at a time."""
    from symid.study import batch_numpy
    from symid.study.engine import _normal_path

    mech = api.load_mechanism(api.example("slider_crank"), steps=steps)
    study = study_mechanism(mech)
    rods, speeds = np.linspace(0.2, 0.5, 25), np.linspace(1.0, 10.0, 40)
    base = np.array([(r, n) for r in rods for n in speeds])[:variants]
    full = base_matrix(study, ("L_rod", "n"), base)
    batch_numpy.run(study, full[:2])  # build (or load) the module: not the solve phase
    tick = time.perf_counter()
    vector = batch_numpy.run(study, full)
    vector_s = time.perf_counter() - tick
    tick = time.perf_counter()
    loop = _normal_path(study, full, "numpy")
    loop_s = time.perf_counter() - tick
    instants = len(base) * steps
    kept = vector.status == 0
    with np.errstate(invalid="ignore"):  # a figure zero by construction (the motor's reaction force): 0 / 0
        rel = np.abs(vector.values[kept] - loop.values[kept]) / np.abs(loop.values[kept]).max(axis=0)
    return {"variants": len(base), "steps": steps, "vectorized_s": vector_s, "per_variant_s": loop_s,
            "vectorized_instants_per_s": instants / vector_s, "per_variant_instants_per_s": instants / loop_s,
            "speedup": loop_s / vector_s, "handed_back": int(np.count_nonzero(~kept)),
            "max_rel_difference": float(np.nanmax(rel, initial=0.0))}


def casadi_anchor(steps: int) -> dict[str, Any]:
    from benchmarks import systems
    from benchmarks.casadi_baselines import CasadiC

    system = systems.slider_crank()
    approach = CasadiC(system)
    try:
        approach.setup()
        h = 2 * np.pi / systems.OMEGA / (steps - 1)  # one crank revolution, as the sweep's runs
        best = float("inf")
        for _ in range(5):
            run = approach.run(system.q0(), h, steps, 1e-12, 60.0)
            best = min(best, run.total_s / max(1, len(run.torque)))
    finally:
        shutil.rmtree(approach.folder, ignore_errors=True)
    return {"us_per_instant_1_thread": best * 1e6, "instants": steps}


def monte_carlo(n: int, steps: int, workers: int = 2) -> dict[str, Any]:
    mech = api.load_mechanism(api.example("slider_crank"), steps=steps)
    names = ("L_crank", "L_rod", "m_crank", "m_rod", "m_slider")
    nominal = np.array([0.1, 0.3, 0.5, 1.0, 0.8])
    rng = np.random.default_rng(0)
    base = nominal * (1 + 0.01 * rng.standard_normal((n, len(names))))
    solve_figures(mech, names, base[:2], "c", workers=1)
    rss_before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    tick, cpu = time.perf_counter(), time.process_time()
    figures = solve_figures(mech, names, base, "c", workers=workers)
    seconds, cpu_s = time.perf_counter() - tick, time.process_time() - cpu
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    p99 = float(np.percentile(figures.values[:, figures.names.index("motor.effort_peak")], 99))
    return {"variants": n, "steps": steps, "workers": workers, "seconds": seconds, "cpu_s": cpu_s,
            "instants_per_s": n * steps / seconds, "seconds_at_1e5": seconds * MC_TARGET / n,
            "peak_rss_mb": peak, "peak_rss_mb_before": rss_before,
            "failed": int(np.count_nonzero(figures.status)), "p99_motor_peak_torque": p99}


def _options(group: Any) -> None:
    group.add_argument("--mc", type=int, default=MC_TARGET, help="Monte Carlo variants (default 1e5)")
    group.add_argument("--grid-steps", type=int, default=1001)
    group.add_argument("--numpy-steps", type=int, default=101, help="instants of the numpy grid (0: leave it out)")
    group.add_argument("--no-casadi", action="store_true", help="leave out the CasADi C anchor")


@register("sweep_engine", "the compiled sweep's solve phase on 1 and 2 threads against CasADi's C loop; the numpy "
          "batch against its per-variant loop; a Monte Carlo's time and memory", options=_options, tools=("gcc",))
def sweep_engine(ctx: Context) -> dict[str, Any]:
    args = ctx.options
    steps = 21 if ctx.smoke else args.grid_steps
    out: dict[str, Any] = {"cpus": os.cpu_count()}
    out["grid"] = g = grid(steps, *((2, 4) if ctx.smoke else (25, 40)))
    for w in (1, 2):
        r = g[f"threads_{w}"]
        ctx.log(f"grid {r['variants']} variants x {g['steps']} instants, {w} thread(s): solve {r['solve_s']:.3f} s, "
                f"{r['instants_per_s'] / 1e6:.2f} M instants/s; {r['failed']} failed")
    if not args.no_casadi:
        out["casadi_c"] = c = casadi_anchor(steps)
        grid_s = c["us_per_instant_1_thread"] * 1e-6 * g["threads_1"]["instants"]
        c["grid_seconds_1_thread"] = grid_s
        c["sweep_speedup_2_threads"] = grid_s / 2 / g["threads_2"]["solve_s"]  # CasADi's loop on 2 ideal threads
    numpy_steps = min(args.numpy_steps, 11) if ctx.smoke else args.numpy_steps
    if numpy_steps:
        out["numpy"] = numpy_grid(numpy_steps, 4 if ctx.smoke else 1000)
    out["monte_carlo"] = monte_carlo(8 if ctx.smoke else args.mc, 21 if ctx.smoke else 1001)
    return out
