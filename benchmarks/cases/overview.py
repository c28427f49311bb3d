"""The overview: every symid backend and three baselines on the slider-crank
and the ladder family, in one run (`python -m benchmarks overview`).

Every cell (approach x mechanism) runs in a worker process of its own, so
each setup is cold (fresh interpreter, empty SYMID_CACHE), peak memory is that
process's alone, and a cell that passes the cap is killed and reported
"stopped"; larger sizes of that approach are not tried.

Measured per (approach, mechanism):
- setup_s, split into derive / generate / compile (see `symid.tools.bench`); it
  ends with the first solved instant, for every approach.
- us_per_instant: the median; compiled loops over whole runs of the grid,
  Python loops instant by instant, with a time budget.
- error: max |tau - tau_exact| / max |tau_exact| of the motor torque over the
  instants of the first period solved (exact: `ladder.Ladder.torque`,
  `systems.slider_crank_torque`).
- peak_rss_mb: the worker's peak resident set (the interpreter and its
  imports included, compiler processes not).

Then the predictor and tolerance sweeps, symid-c against casadi-c paired in
one process (the ratios: separate cells run minutes apart on a machine whose
speed drifts), `symid solve` processes, and the design study
(`design_study.py`). Also writes overview.md and three PNGs
(`overview_report.py`).
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks.cases import register
from benchmarks.cases.design_study import run_study
from benchmarks.cases.overview_workers import exact_torque
from benchmarks.processes import timed_process
from benchmarks.run import Context

WORKER = "benchmarks.cases.overview_workers:worker"
BASELINES = ("numpy-hand", "sympy-lambdify", "casadi-python", "casadi-c")
COMPILED = ("symid-c", "casadi-c")
TOLERANCES = (1e-6, 1e-8, 1e-10, 1e-12, 1e-14)
ORDERS = (0, 1, 2, 5)


@dataclass(frozen=True)
class Config:
    """Sizes and budgets of one run."""

    ladders: tuple[int, ...] = (1, 4, 16, 64, 256)
    steps: int = 1001              # instants per period (error over one period)
    compiled_instants: int = 20020  # 20 periods for the compiled loops
    budget_s: float = 10.0         # timing budget of one cell
    cap_s: float = 90.0            # a cell past this is stopped
    total_s: float = 14 * 60.0     # the whole run's budget
    reserve_s: float = 240.0       # kept for the sweeps and processes: cells not started
                                   # by total_s - reserve_s are skipped
    # (mechanism, instants per period): the coarse slider-crank grid (3.6 degrees
    # of crank per step) is where the predictor's order shows
    sweep_mechs: tuple[tuple[str, int], ...] = (("slider_crank", 1001), ("slider_crank", 101), ("ladder_16", 1001))
    sweep_instants: int = 1001
    tolerances: tuple[float, ...] = TOLERANCES
    orders: tuple[int, ...] = ORDERS
    stream_instants: int = 1_000_001
    solve_runs: int = 3
    jobs: int = 1
    # symid-c against casadi-c in one process, whole grids alternated: the
    # ratio targets are read from these (separate cells run minutes apart)
    paired_mechs: tuple[str, ...] = ("slider_crank", "ladder_64")
    paired_rounds: int = 21
    # the design study (issue 14, design_study.py): rods x speeds variants x steps
    # instants; CasADi's map over map_variants at map_steps; processes: callgrind, `symid sweep`, Dask
    study_rods: int = 25
    study_speeds: int = 40
    study_steps: int = 1001
    study_map_variants: int = 1000
    study_map_steps: int = 101
    study_processes: bool = True
    # smoke runs only (a check that every part runs, whose figures mean nothing):
    symid_ladder_cells: bool = True  # symid's own backends on the ladders too (not just the slider-crank)
    fill_cache: bool = True        # an untimed `symid solve` first, so the timed ones are cached


# the smoke run checks that every cell runs, on a machine however loaded: no
# run budget skips a cell (its cap only stops a hung one)
SMOKE = Config(ladders=(1,), steps=101, compiled_instants=40, budget_s=0.5, cap_s=600.0, total_s=float("inf"), reserve_s=0.0,
               sweep_mechs=(("slider_crank", 101),), sweep_instants=15, tolerances=(1e-6, 1e-12), orders=(0, 2),
               stream_instants=2001, solve_runs=1, jobs=2, paired_mechs=("slider_crank",), paired_rounds=3,
               study_rods=2, study_speeds=2, study_steps=21, study_map_variants=4, study_map_steps=21,
               study_processes=False, symid_ladder_cells=False, fill_cache=False)
# The smoke run's sizes: a period in 101 instants (the full run's coarse sweep
# grid: the Python loops and the 30-digit exact torque do a tenth of a full
# run's); symid on the slider-crank only, in the cells, the sweep and the pair
# (the solvers the solve processes use too), its backends in cells (the
# same worker as on a ladder; tests/tools/test_bench.py checks each of them on a
# ladder file against Ladder.torque to 1e-13), the baselines on both (their own
# description of the ladder, systems.ladder, is checked here only); every worker,
# a cold measurement in a real run, shares the run's cache (Context.cache: each
# solver is built once for all, not again from the same text); no untimed
# `symid solve` before the timed one.


# --- mechanisms --------------------------------------------------------------------

def mechanisms(cfg: Config, folder: Path) -> list[dict[str, Any]]:
    """The run's mechanisms, smallest first: key, file, ng, grid (t1, steps, h)."""
    from benchmarks import ladder
    from symid import api

    out = [{"key": "slider_crank", "file": str(api.example("slider_crank")), "ng": 9, "t1": 0.2}]
    for n in cfg.ladders:
        out.append({"key": ladder.name(n), "n": n, "file": str(ladder.write(n, folder, cfg.steps)),
                    "ng": ladder.Ladder(n).ng, "t1": ladder.Ladder(n).t1})
    for m in out:
        m["steps"] = cfg.steps
        m["h"] = m["t1"] / (cfg.steps - 1)
    return out


# --- the parent -------------------------------------------------------------------


def _error(torque: np.ndarray, exact: np.ndarray) -> tuple[float | None, int]:
    n = min(len(torque), len(exact))
    if n == 0:
        return None, 0
    diff = np.abs(torque[:n] - exact[:n])
    worst = float(np.max(diff)) if np.all(np.isfinite(diff)) else math.inf
    return worst / float(np.max(np.abs(exact))), n


def approaches() -> list[tuple[str, str, str]]:
    """(label, kind, backend-or-approach) of everything measured."""
    from symid import backends

    return [(f"symid-{b}", "symid", b) for b in backends.names()] + [(b, "baseline", b) for b in BASELINES]


def run_cells(cfg: Config, mechs: list[dict[str, Any]], exact: dict[str, np.ndarray], ctx: Context,
              deadline: float) -> list[dict[str, Any]]:
    """Every approach on every mechanism, smallest first; an approach stopped
    at one size is not tried at larger ones."""
    stopped: dict[str, str] = {}
    cells: list[dict[str, Any]] = []
    jobs: list[tuple[dict[str, Any], dict[str, Any]]] = []
    for mech in mechs:
        for label, kind, name in approaches():
            if kind == "symid" and mech["key"] != "slider_crank" and not cfg.symid_ladder_cells:
                continue
            cell: dict[str, Any] = {"approach": label, "kind": kind, "mechanism": mech["key"], "ng": mech["ng"]}
            cells.append(cell)
            compiled = label in COMPILED
            # smoke: symid's cells from the run's shared cache too (`symid bench`'s cold
            # build in a cache of its own is what tests/tools/test_bench.py runs in-process)
            spec = {"kind": kind, "mech": mech, "backend": name, "approach": name, "cold": not ctx.smoke,
                    "instants": cfg.compiled_instants if compiled else cfg.steps,
                    "budget_s": cfg.budget_s, "torque": str(ctx.work / f"{label}-{mech['key']}.npy")}
            jobs.append((cell, spec))

    def one(cell: dict[str, Any], spec: dict[str, Any]) -> None:
        label = cell["approach"]
        if label in stopped:
            cell.update(status="stopped", note=f"not run: stopped at {stopped[label]}")
            return
        if time.time() > deadline:
            cell.update(status="skipped", note="not run: the run's time budget was spent")
            return
        got = ctx.isolated(WORKER, spec, cfg.cap_s)
        cell.update(got.result, status=got.status, wall_s=got.wall_s, peak_rss_mb=got.peak_rss_mb)
        if got.note:
            cell["note"] = got.note
        if got.status == "stopped":
            stopped[label] = f"{cell['mechanism']} (ng = {cell['ng']})"
        if got.status == "ok":
            torque = np.load(spec["torque"])
            cell["error_rel"], cell["error_instants"] = _error(torque, exact[cell["mechanism"]])
            if cell.get("error"):
                cell["status"], cell["note"] = "failed", str(cell["error"])[:300]
        ctx.log(f"{label:16s} {cell['mechanism']:13s} {cell['status']:8s} "
            f"setup {_fmt(cell.get('setup_s'))} s, {_fmt(cell.get('us_per_instant'))} us, "
            f"err {_fmt(cell.get('error_rel'))}, {_fmt(cell.get('peak_rss_mb'))} MB {cell.get('note', '')}")

    if cfg.jobs <= 1:
        for cell, spec in jobs:
            one(cell, spec)
    else:  # smoke runs only: timings from parallel workers are not comparable
        from concurrent.futures import ThreadPoolExecutor

        by_mech: dict[str, list[tuple[dict[str, Any], dict[str, Any]]]] = {}
        for cell, spec in jobs:
            by_mech.setdefault(cell["mechanism"], []).append((cell, spec))
        with ThreadPoolExecutor(cfg.jobs) as pool:
            for group in by_mech.values():
                list(pool.map(lambda cs: one(*cs), group))
    return cells


def run_sweeps(cfg: Config, mechs: list[dict[str, Any]], exact: dict[str, np.ndarray],
               ctx: Context) -> dict[str, Any]:
    out = {}
    for base, steps in cfg.sweep_mechs:
        mech = dict(next(m for m in mechs if m["key"] == base), steps=steps)
        mech["h"] = mech["t1"] / (steps - 1)
        key = base if steps == cfg.steps else f"{base}, {steps} steps"
        truth = exact[base] if steps == cfg.steps else exact_torque(mech)
        folder = ctx.work / f"sweep-{base}-{steps}"
        folder.mkdir()
        spec = {"kind": "sweep", "mech": mech, "folder": str(folder), "instants": min(cfg.sweep_instants, steps),
                "tolerances": list(cfg.tolerances), "orders": list(cfg.orders), "budget_s": cfg.budget_s / 2}
        got = ctx.isolated(WORKER, spec, 4 * cfg.cap_s)
        if got.status != "ok":
            out[key] = {"status": got.status, "note": got.note}
            ctx.log(f"sweep {key}: {got.status} {got.note}")
            continue
        for row in got.result["predictor"] + got.result["tolerance"]:
            if "torque" in row:
                row["error_rel"], row["error_instants"] = _error(np.load(row.pop("torque")), truth)
        out[key] = {"status": "ok", "ng": mech["ng"], "steps": steps, **got.result}
        ctx.log(f"sweep {key}: {len(got.result['predictor'])} predictor points, "
            f"{len(got.result['tolerance'])} tolerance points in {got.wall_s:.0f} s")
    return out


def run_paired(cfg: Config, mechs: list[dict[str, Any]], ctx: Context) -> dict[str, Any]:
    out = {}
    for key in cfg.paired_mechs:
        mech = next((m for m in mechs if m["key"] == key), None)
        if mech is None:
            continue
        got = ctx.isolated(WORKER, {"kind": "paired", "mech": mech, "rounds": cfg.paired_rounds,
                                    "budget_s": cfg.cap_s}, 4 * cfg.cap_s)
        out[key] = {"status": got.status, "note": got.note, "ng": mech["ng"], **got.result}
        ctx.log(f"paired {key}: {got.status} {got.note} {got.result}")
    return out


def run_processes(cfg: Config, ctx: Context) -> dict[str, Any]:
    """`symid solve` as a user runs it: whole-process time when cached, and
    the peak memory of streaming many instants to CSV."""
    from symid import api

    env = ctx.env(ctx.work / "solve-cache")
    file = str(api.example("slider_crank"))
    csv = str(ctx.work / "solve.csv")
    out: dict[str, Any] = {"solve_1001": {}}
    for backend in ("numpy", "c"):
        cmd = [sys.executable, "-m", "symid", "solve", file, "--backend", backend, "--steps", "1001", "-o", csv]
        if cfg.fill_cache:
            timed_process(cmd, env, 300)  # fills the cache
        walls = [timed_process(cmd, env, 300) for _ in range(cfg.solve_runs)]
        out["solve_1001"][backend] = {"wall_s": float(np.median([w for w, _, _ in walls])),
                                      "peak_rss_mb": max((r for _, r, _ in walls if r), default=None),
                                      "status": max(s for _, _, s in walls)}
        ctx.log(f"symid solve slider_crank 1001 instants, {backend}, {'cached' if cfg.fill_cache else 'cache not filled first'}: "
                f"{out['solve_1001'][backend]}")
    cmd = [sys.executable, "-m", "symid", "solve", file, "--backend", "c", "--steps", str(cfg.stream_instants),
           "-o", csv]
    wall, rss, status = timed_process(cmd, env, 600)
    out["stream"] = {"instants": cfg.stream_instants, "backend": "c", "output": "CSV", "wall_s": wall,
                     "peak_rss_mb": rss, "status": status}
    ctx.log(f"streaming {cfg.stream_instants} instants to CSV (c): {out['stream']}")
    Path(csv).unlink(missing_ok=True)
    return out


def _fmt(v: Any) -> str:
    return "-" if v is None else f"{v:.3g}" if isinstance(v, float) else str(v)


def _options(group: Any) -> None:
    group.add_argument("--skip-processes", action="store_true", help="leave out the symid solve processes")


def _report(result: dict[str, Any], out: Path) -> list[Path]:
    from benchmarks.cases import overview_report

    machine = {**result["machine"], **{k: result[k] for k in ("load_average_start", "load_average_end", "run_s")}}
    figures = {**result["figures"], "machine": machine}
    (out / "overview.md").write_text(overview_report.markdown(figures), encoding="utf-8")
    return [out / "overview.md", *overview_report.plots(figures, out)]


@register("overview", "every backend and three baselines on the slider-crank and ladders: setup, us per instant, "
          "error, memory; sweeps, paired C ratios, solve processes, the design study", options=_options,
          report=_report, tools=("gcc",))
def overview(ctx: Context) -> dict[str, Any]:
    cfg = SMOKE if ctx.smoke else Config()
    mechs = mechanisms(cfg, ctx.work / "mechanisms")
    exact = {m["key"]: exact_torque(m) for m in mechs}
    ctx.log("exact torques ready")
    cells = run_cells(cfg, mechs, exact, ctx, ctx.started + cfg.total_s - cfg.reserve_s)
    sweeps = run_sweeps(cfg, mechs, exact, ctx)
    paired = run_paired(cfg, mechs, ctx)
    processes = {} if ctx.options.skip_processes else run_processes(cfg, ctx)
    study = run_study(cfg, ctx)
    return {"config": {**cfg.__dict__, "smoke": ctx.smoke},
            "mechanisms": [{k: v for k, v in m.items() if k != "file"} for m in mechs],
            "cells": cells, "sweeps": sweeps, "paired": paired, "processes": processes, "study": study}
