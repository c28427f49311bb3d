"""Design studies (issue 14) in the overview and its report (not a case of its own).

One worker process (`study` kind, `overview_workers.py`) measures, on the
slider-crank grid of rod lengths x crank speeds:

- the compiled sweep's solve phase on 1 and 2 threads (`sweep_engine.grid`);
- the CasADi-generated C loop over one variant's instants, one thread
  (`sweep_engine.casadi_anchor`), times the grid's instants: the grid that
  way on two ideal threads;
- CasADi's instant Function mapped over the variants,
  `Function.map(K, "thread", 2)`, called from Python once per instant
  (`casadi_map`), at `map_steps` instants;
- instructions per instant of the sweep against the plain trajectory loop
  (callgrind, `sweep_instructions`), when valgrind is there.

The parent (`run_study`) adds the whole `symid sweep` process, cold and
cached, and the same sweep through Dask on two local workers
(`sweep_cli`), with the load average at start and end.
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np

TARGETS = {"instants_per_s": 10e6, "casadi_c_speedup": 10.0, "casadi_map_speedup": 10.0, "dask_over_local": 1.5,
           "cached_process_s": 2.0, "cold_process_s": 4.0}


def worker_study(spec: dict[str, Any]) -> dict[str, Any]:
    """The in-process figures (see the module's docstring)."""
    from benchmarks import casadi_map
    from benchmarks.cases import sweep_engine, sweep_instructions

    out: dict[str, Any] = {"load_average_start": list(os.getloadavg())}
    out["grid"] = g = sweep_engine.grid(spec["steps"], spec["rods"], spec["speeds"])
    out["casadi_c"] = c = sweep_engine.casadi_anchor(spec["steps"])
    c["grid_seconds_2_ideal_threads"] = c["us_per_instant_1_thread"] * 1e-6 * g["threads_1"]["instants"] / 2
    rods, speeds = np.linspace(0.2, 0.5, spec["rods"]), np.linspace(1.0, 10.0, spec["speeds"])
    base = np.array([(r, s) for r in rods for s in speeds])[:spec["map_variants"]]
    mapped = casadi_map.run_mapped(base, spec["map_steps"])
    mapped.pop("motor_peak")
    out["casadi_map"] = mapped
    if spec.get("instructions") and sweep_instructions.available():
        out["instructions"] = sweep_instructions.per_instant()
    out["load_average_end"] = list(os.getloadavg())
    return out


def run_study(cfg: Any, ctx: Any) -> dict[str, Any]:
    """The study worker, then (unless `cfg.study_processes` is off) the processes."""
    spec = {"kind": "study", "steps": cfg.study_steps, "rods": cfg.study_rods, "speeds": cfg.study_speeds,
            "map_variants": cfg.study_map_variants, "map_steps": cfg.study_map_steps,
            "instructions": cfg.study_processes}
    got = ctx.isolated("benchmarks.cases.overview_workers:worker", spec, 4 * cfg.cap_s)
    out: dict[str, Any] = {"status": got.status, "note": got.note, **got.result}
    ctx.log(f"design study: {got.status} {got.note}")
    if cfg.study_processes:
        out["processes"] = processes(cfg, ctx)
        ctx.log(f"design study processes: {out['processes']}")
    return out


def processes(cfg: Any, ctx: Any) -> dict[str, Any]:
    """`symid sweep` cold (an empty cache), cached, and on a local Dask cluster."""
    from benchmarks.cases import sweep_cli
    from symid import api

    work = ctx.work
    env = ctx.env(work / "study-cache")
    run = [str(api.example("slider_crank")), "--grid", f"L_rod=0.2:0.5:{cfg.study_rods}",
           "--grid", f"n=1:10:{cfg.study_speeds}", "--steps", str(cfg.study_steps), "-o", str(work / "study.csv")]
    out: dict[str, Any] = {"cold": sweep_cli.sweep(ctx, run, env), "cached": sweep_cli.sweep(ctx, run, env)}
    try:
        out["dask"] = sweep_cli.with_cluster(ctx, env, run)
        out["dask_over_local_solve"] = out["dask"]["solve_s"] / out["cached"]["solve_s"]
    except (SystemExit, OSError, RuntimeError) as exc:  # a cluster that does not start: recorded, not fatal
        out["dask"] = {"failed": str(exc)[:300]}
    return out


def _g(v: Any) -> str:
    return "–" if v is None else f"{v:.3g}" if isinstance(v, float) else str(v)


def markdown(study: dict[str, Any] | None) -> list[str]:
    """The report's section on design studies (nothing if the run had none)."""
    if not study:
        return []
    if study.get("status") != "ok":
        return [f"**Design study**: {study.get('status')} {study.get('note', '')}", ""]
    g, c, m = study["grid"], study["casadi_c"], study["casadi_map"]
    t1, t2 = g["threads_1"], g["threads_2"]
    instants = t1["instants"]
    lines = [f"**Design study: slider-crank, {t1['variants']} variants (rod length x crank speed) x {g['steps']} "
             f"instants** (load average {_g(study['load_average_start'][0])} at start, "
             f"{_g(study['load_average_end'][0])} at end)", "",
             "| approach | threads | seconds for the grid | M instants/s | us per instant |", "|---|---|---|---|---|"]

    def row(name: str, threads: int, seconds: float, note: str = "") -> None:
        lines.append(f"| {name}{note} | {threads} | {_g(seconds)} | {_g(instants / seconds / 1e6)} | "
                     f"{_g(1e6 * seconds / instants)} |")

    row("symid sweep (C batch, figures in C)", 1, t1["solve_s"])
    row("symid sweep (C batch, figures in C)", 2, t2["solve_s"])
    row("CasADi-generated C loop", 1, c["us_per_instant_1_thread"] * 1e-6 * instants,
        f" ({c['instants']} instants, x grid)")
    row("CasADi-generated C loop", 2, c["grid_seconds_2_ideal_threads"],
        f" (1 thread, {c['instants']} instants, x grid / 2)")
    row("CasADi Function.map(K, \"thread\", 2) from Python", 2, m["us_per_instant"] * 1e-6 * instants,
        f" (K = {m['variants']}, {m['steps']} instants, per instant x grid)")
    lines += ["", f"One thread against one thread (the load moves a second thread's share): CasADi C loop time / "
              f"sweep time {_g(c['us_per_instant_1_thread'] * 1e-6 * instants / t1['solve_s'])}."]
    ins = study.get("instructions")
    if ins:
        scalar = ins.get("sweep_scalar_instructions_per_instant")
        lanes = f" (variants side by side in SIMD lanes; one at a time {_g(scalar)})" if scalar else ""
        lines += ["", f"Instructions per instant (callgrind): sweep {_g(ins['sweep_instructions_per_instant'])}{lanes}, "
                  f"plain trajectory loop {_g(ins['plain_instructions_per_instant'])} "
                  f"(ratio {_g(ins['sweep_over_plain'])})."]
    proc = study.get("processes")
    if proc:
        lines += ["", "| `symid sweep` process | wall s | setup s | solve s | M instants/s |", "|---|---|---|---|---|"]
        for key in ("cold", "cached", "dask"):
            r = proc.get(key, {})
            if "process_s" in r:
                lines.append(f"| {key} | {_g(r['process_s'])} | {_g(r['setup_s'])} | {_g(r['solve_s'])} | "
                             f"{_g(r['instants_per_s'] / 1e6)} |")
            elif r:
                lines.append(f"| {key} | failed: {r.get('failed', '')} | | | |")
    return lines + [""]


def targets(study: dict[str, Any] | None) -> list[dict[str, Any]]:
    """Issue 14's benchmark targets, as `report.targets` rows."""
    if not study or study.get("status") != "ok":
        return []
    rows: list[dict[str, Any]] = []

    def add(name: str, measured: float | None, limit: float, at_least: bool = False, note: str = "") -> None:
        met = None if measured is None else (measured >= limit if at_least else measured <= limit)
        rows.append({"target": name, "measured": measured, "limit": limit, "met": met, "note": note})

    g, c, m = study["grid"], study["casadi_c"], study["casadi_map"]
    t2 = g["threads_2"]
    add("design study grid, C sweep on 2 threads (instants/s)", t2["instants_per_s"], TARGETS["instants_per_s"],
        at_least=True)
    add("design study: CasADi C loop (2 ideal threads) time / sweep time", c["grid_seconds_2_ideal_threads"]
        / t2["solve_s"], TARGETS["casadi_c_speedup"], at_least=True)
    add("design study: CasADi map(thread, 2) from Python time / sweep time",
        m["us_per_instant"] * 1e-6 * t2["instants"] / t2["solve_s"], TARGETS["casadi_map_speedup"], at_least=True)
    proc = study.get("processes") or {}
    for key, limit in (("cached", "cached_process_s"), ("cold", "cold_process_s")):
        if "process_s" in proc.get(key, {}):
            add(f"`symid sweep` of the grid, whole process, {key} (s)", proc[key]["process_s"], TARGETS[limit])
    if "dask_over_local_solve" in proc:
        add("design study through Dask (2 local workers) / threaded local, solve phase",
            proc["dask_over_local_solve"], TARGETS["dask_over_local"])
    return rows
