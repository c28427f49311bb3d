"""The overview's workers: each measures one cell in a process of its own
(`Context.isolated` calls `worker(spec)`); each returns a JSON-able dict that
the overview (`overview.py`) collects.
"""

from __future__ import annotations

import shutil
import time
from pathlib import Path
from typing import Any, Callable

import numpy as np


def exact_torque(mech: dict[str, Any]) -> np.ndarray:
    """The exact motor torque on the mechanism's grid (one period)."""
    from benchmarks import ladder, systems

    t = np.arange(mech["steps"]) * mech["h"]
    if mech["key"] == "slider_crank":
        return systems.slider_crank_torque(t)
    return ladder.Ladder(mech["n"]).torque(t)


def _system(mech: dict[str, Any]):  # type: ignore[no-untyped-def]
    from benchmarks import systems

    return systems.slider_crank() if mech["key"] == "slider_crank" else systems.ladder(mech["n"])


def worker_symid(spec: dict[str, Any]) -> dict[str, Any]:
    from symid.tools.bench import bench

    mech = spec["mech"]
    res = bench(mech["file"], spec["backend"], instants=spec["instants"], budget_s=spec["budget_s"],
                keep=("motor.T_j",), cold=spec.get("cold", True), steps=mech["steps"], t1=mech["t1"])
    np.save(spec["torque"], np.array(res.pop("kept")["motor.T_j"]))
    return res


def worker_baseline(spec: dict[str, Any]) -> dict[str, Any]:
    from benchmarks.casadi_baselines import APPROACHES, CasadiC

    mech = spec["mech"]
    system = _system(mech)
    approach = APPROACHES[spec["approach"]](system)
    q0, h, steps = system.q0(), mech["h"], mech["steps"]
    tick = time.perf_counter()
    phases = approach.setup()
    setup = time.perf_counter() - tick
    out: dict[str, Any] = {"ng": system.ng, "nc": system.nc}
    try:
        if isinstance(approach, CasadiC):
            setup += approach.run(q0, h, 1, 1e-12, spec["budget_s"]).total_s
            per_run, torque, timed, began, error = [], None, 0, time.perf_counter(), None
            while timed < spec["instants"] and (not per_run or time.perf_counter() - began < spec["budget_s"]):
                r = approach.run(q0, h, min(steps, spec["instants"] - timed), 1e-12, spec["budget_s"])
                torque = r.torque if torque is None else torque
                if len(r.torque):
                    per_run.append(r.total_s / len(r.torque))
                timed += len(r.torque)
                if r.error:
                    error = r.error
                    break
            out.update(us_per_instant=1e6 * float(np.median(per_run)) if per_run else None, instants=timed,
                       method="C loop over whole runs, clock_gettime inside C, median over runs", error=error)
        else:
            r = approach.run(q0, h, min(steps, spec["instants"]), 1e-12, spec["budget_s"])
            torque = r.torque
            setup += r.seconds[0] if r.seconds else 0.0
            rest = r.seconds[1:]
            out.update(us_per_instant=1e6 * float(np.median(rest)) if rest else None, instants=len(r.seconds),
                       method="Python loop, median over instants (the first is in setup)", error=r.error,
                       mean_iterations=float(np.mean(r.iterations[1:])) if len(r.iterations) > 1 else None)
    finally:
        folder = getattr(approach, "folder", None)
        if folder is not None:
            shutil.rmtree(folder, ignore_errors=True)
    out.update(setup_s=setup, derive_s=phases["derive"], compile_s=phases["compile"],
               generate_s=setup - phases["derive"] - phases["compile"])
    np.save(spec["torque"], np.asarray(torque if torque is not None else [], dtype=float))
    return out


def worker_sweep(spec: dict[str, Any]) -> dict[str, Any]:
    """Predictor order x tolerance (both drivers) and the tolerance through
    `api.prepare(tol=...)` on each symid backend; torques saved for the parent."""
    from benchmarks.cases import overview_predictor as sweep
    from symid import api, backends
    from symid.tools.bench import bench

    mech, folder = spec["mech"], Path(spec["folder"])
    study = api.prepare(mech["file"], "c", steps=mech["steps"], t1=mech["t1"])
    out: dict[str, Any] = {"predictor": [], "tolerance": []}
    for driver, fn in sweep.DRIVERS.items():
        for order in spec["orders"]:
            for tol in spec["tolerances"]:
                r = fn(study, order, tol, spec["instants"])
                path = folder / f"{driver}-{order}-{tol:g}.npy"
                np.save(path, np.array(r["torque"]))
                its = r["iterations"][1:]
                out["predictor"].append({
                    "driver": driver, "order": order, "tol": tol, "error": r["error"], "torque": str(path),
                    "mean_iterations": float(np.mean(its)) if its else None,
                    "us_per_instant": 1e6 * float(np.median(r["seconds"][1:])) if len(r["seconds"]) > 1 else None})
    for backend in backends.names():
        for tol in spec["tolerances"]:
            try:
                r = bench(mech["file"], backend, instants=spec["instants"], tol=tol, cold=False,
                          budget_s=spec["budget_s"], keep=("motor.T_j",), steps=mech["steps"], t1=mech["t1"])
            except Exception as exc:  # a backend that cannot build this mechanism: recorded, not fatal
                out["tolerance"].append({"backend": backend, "tol": tol, "failed": f"{type(exc).__name__}: {exc}"})
                break
            path = folder / f"prepare-{backend}-{tol:g}.npy"
            np.save(path, np.array(r.pop("kept")["motor.T_j"]))
            out["tolerance"].append({"backend": backend, "tol": tol, "us_per_instant": r["us_per_instant"],
                                     "max_residual": r["max_residual"], "error": r["error"], "torque": str(path)})
    return out


def worker_paired(spec: dict[str, Any]) -> dict[str, Any]:
    """symid-c's trajectory and the casadi-c loop in one process, each round
    one whole grid of each in turn: per round, us per instant of both and
    their ratio (casadi-c / symid-c)."""
    from benchmarks.casadi_baselines import APPROACHES
    from symid import api
    from symid.backends.c_backend import chunk_rows
    from symid.tools.bench import _trajectory

    mech = spec["mech"]
    study = api.prepare(mech["file"], "c", steps=mech["steps"], t1=mech["t1"])
    runner = _trajectory(study)
    assert runner is not None
    system = _system(mech)
    casadi = APPROACHES["casadi-c"](system)
    casadi.setup()
    q0, h, steps = system.q0(), mech["h"], mech["steps"]
    state = np.zeros(study.evaluator.meta["state"])  # type: ignore[attr-defined]
    chunk = chunk_rows(study.evaluator.meta["row"])  # type: ignore[attr-defined]
    ours, theirs = [], []
    try:
        for _ in range(spec["rounds"]):
            state[:] = 0.0
            state[:study.layout.ng] = study.q0()
            seconds, done = 0.0, 0
            while done < steps:
                _, solved, status, dt = runner(done, min(chunk, steps - done), state)
                seconds += dt
                done += solved
                if status != 0:
                    raise RuntimeError(f"symid-c stopped at instant {done}")
            ours.append(1e6 * seconds / steps)
            r = casadi.run(q0, h, steps, 1e-12, spec["budget_s"])
            if r.error or len(r.torque) < steps:
                raise RuntimeError(f"casadi-c: {r.error or 'stopped early'}")
            theirs.append(1e6 * r.total_s / steps)
    finally:
        folder = getattr(casadi, "folder", None)
        if folder is not None:
            shutil.rmtree(folder, ignore_errors=True)
    ratios = [b / a for a, b in zip(ours, theirs)]
    return {"rounds": len(ours), "instants_per_round": steps, "symid_c_us": float(np.median(ours)),
            "casadi_c_us": float(np.median(theirs)), "ratio": float(np.median(ratios)),
            "ratio_range": [float(min(ratios)), float(max(ratios))]}


def worker_study(spec: dict[str, Any]) -> dict[str, Any]:
    from benchmarks.cases.design_study import worker_study as study

    return study(spec)


def worker(spec: dict[str, Any]) -> dict[str, Any]:
    fn: Callable[[dict[str, Any]], dict[str, Any]] = {
        "symid": worker_symid, "baseline": worker_baseline, "sweep": worker_sweep, "paired": worker_paired,
        "study": worker_study}[spec["kind"]]
    return fn(spec)
