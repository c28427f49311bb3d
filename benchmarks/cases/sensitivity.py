"""Sensitivities benchmark (issue #15): what the d(COLUMN)/d(NAME) columns
cost per instant, against the same run without them.

    python -m benchmarks sensitivity [--part python|c|both] [--example slider_crank] [--instants N]
                                     [--repeats R] [--backend numpy] [--c-examples slider_crank,planetary]
                                     [--c-instants N]

1. python (`sensitivity_python.py`, any backend): the ratio with /
   without for n_p = 1, 2, 4 base parameters on each --example (comma-
   separated), measured in rounds so the machine's load shifts all alike;
   first setup (sympy derivation and lambdify) and re-parameterized setup
   (another value: nothing derived or lambdified again) apart.
2. c (generated C, `--backend c`): for the slider-crank and the planetary
   gear train (12 coordinates), the compiled solver plain and with
   sensitivities to n_p = 1, 2, 4 base parameters (default columns: the
   drivers' efforts and every reaction): instructions per instant by
   callgrind (the difference of two runs, so loading and setup are left
   out; the machine's load does not change it) and the best wall-clock
   microseconds per instant of the compiled trajectory called through
   ctypes. Target: ratio <= 1 + 0.3 n_p (one factorization serves every
   parameter).
"""

from __future__ import annotations

import argparse
import ctypes
import time
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks import callgrind
from benchmarks.cases import register
from benchmarks.cases.sensitivity_python import SMOKE_COUNTS as SMOKE_COUNTS_PYTHON, python_part
from benchmarks.run import Context
from symid import api
from symid.backends.c_backend import CEvaluator

PARAMETERS = {"slider_crank": ("L_crank", "m_rod", "n", "L_rod"),
              "planetary": ("r_planet", "m_carrier", "n_in", "r_sun")}
COUNTS = (0, 1, 2, 4)
# a smoke run's: the plain solver and the one with all four parameters (lengths,
# a mass and the driver's speed: every kind that 1 and 2 have), each built, counted
# by callgrind, timed and compared (1 and 2 take the same steps of this case)
SMOKE_COUNTS = (0, 4)


def solver(example: str, n_p: int) -> tuple[CEvaluator, object, np.ndarray]:
    """The example's compiled solver with sensitivities to its first n_p parameters (0: plain)."""
    study = api.prepare(api.example(example), backend="c", sensitivity=PARAMETERS[example][:n_p] if n_p else None)
    assert isinstance(study.evaluator, CEvaluator)
    return study.evaluator, study.mechanism, study.q0()


def instructions_per_instant(ev: CEvaluator, mech, q0: np.ndarray, first: int = 200,  # type: ignore[no-untyped-def]
                             second: int = 2200) -> float:
    """Callgrind instructions per instant of the trajectory (benchmarks.callgrind's driver)."""
    return callgrind.counted(Path(ev.artifact), mech.name, mech.analysis, q0, first, second)


# instants per trajectory call: the rows of a call stay in cache, as the c
# backend keeps them (CHUNK_BYTES), so the wider rows cost their writes only
CALL = 64


def microseconds_per_instant(ev: CEvaluator, mech, q0: np.ndarray, instants: int,  # type: ignore[no-untyped-def]
                             repeats: int) -> float:
    """Best wall-clock microseconds per instant of a run of `instants`, CALL a call."""
    a = mech.analysis
    h = (a.t1 - a.t0) / (instants - 1)
    rows = np.zeros((CALL, ev.meta["row"]))
    solved = ctypes.c_long(0)
    dbl = ctypes.POINTER(ctypes.c_double)
    best = np.inf
    for _ in range(repeats):
        state = np.zeros(ev.meta["state"])
        state[:len(q0)] = q0
        done = 0
        start = time.perf_counter()
        while done < instants:
            status = ev._trajectory(ctypes.c_double(a.t0), ctypes.c_double(h), ctypes.c_long(min(CALL, instants - done)),
                                    ev.p.ctypes.data_as(dbl), ctypes.c_double(a.tol), state.ctypes.data_as(dbl),
                                    rows.ctypes.data_as(dbl), ctypes.byref(solved), ev.work.ctypes.data_as(dbl),
                                    ev.iwork.ctypes.data_as(ctypes.POINTER(ctypes.c_int)))
            if status != 0:
                raise RuntimeError(f"{mech.name}: the trajectory stopped with status {status} at {done + solved.value}")
            done += solved.value
        best = min(best, (time.perf_counter() - start) / instants)
    return float(best * 1e6)


def generated_c(args: argparse.Namespace, smoke: bool) -> dict[str, object]:
    """Part 2: the compiled solver plain and with n_p = 1, 2, 4 parameters."""
    figures: dict[str, object] = {}
    instants, repeats = (201, 1) if smoke else (args.c_instants, args.repeats)
    first, second = (20, 60) if smoke else (200, 2200)
    counts = SMOKE_COUNTS if smoke else COUNTS
    for example in (["slider_crank"] if smoke else args.c_examples.split(",")):
        rows: dict[int, dict[str, object]] = {}
        built = {n_p: solver(example, n_p) for n_p in counts}
        for n_p, (ev, mech, q0) in built.items():
            rows[n_p] = {"parameters": list(PARAMETERS[example][:n_p]),
                         "columns": ev.meta["sens_width"] // max(1, n_p)}
            if callgrind.available():
                rows[n_p]["instructions_per_instant"] = instructions_per_instant(ev, mech, q0, first, second)
        # wall clock in rounds over every variant: a burst of load on a shared
        # machine then slows one round of all, not all the runs of one variant
        best = {n_p: float("inf") for n_p in built}
        for _ in range(repeats):
            for n_p, (ev, mech, q0) in built.items():
                best[n_p] = min(best[n_p], microseconds_per_instant(ev, mech, q0, instants, 1))
        for n_p in built:
            rows[n_p]["us_per_instant"] = best[n_p]
        plain = rows[0]
        for n_p in counts[1:]:
            r = rows[n_p]
            r["target"] = 1 + 0.3 * n_p
            r["wall_ratio"] = r["us_per_instant"] / plain["us_per_instant"]  # type: ignore[operator]
            if "instructions_per_instant" in r:
                r["instructions_ratio"] = r["instructions_per_instant"] / plain["instructions_per_instant"]  # type: ignore[operator]
            print(f"{example}, n_p = {n_p} ({', '.join(r['parameters'])}; {r['columns']} columns): "  # type: ignore[arg-type]
                  f"wall {r['wall_ratio']:.2f}x"
                  + (f", instructions {r['instructions_per_instant']:.0f} vs {plain['instructions_per_instant']:.0f} "
                     f"= {r['instructions_ratio']:.2f}x" if "instructions_ratio" in r else "")
                  + f" (target <= {r['target']:.1f}x)")
        figures[example] = {str(k): v for k, v in rows.items()}
    return {"instants": instants, "repeats": repeats, "figures": figures}


def _options(group: Any) -> None:
    group.add_argument("--part", choices=("python", "c", "both"), default="both")
    group.add_argument("--example", default="slider_crank,four_bar", help="python part: examples, comma-separated")
    group.add_argument("--instants", type=int, default=201, help="python part")
    group.add_argument("--repeats", type=int, default=3)
    group.add_argument("--backend", default="numpy", help="python part")
    group.add_argument("--c-examples", default=",".join(PARAMETERS))
    group.add_argument("--c-instants", type=int, default=20_001)


@register("sensitivity", "what the sensitivity columns cost per instant against the same run without them, on the "
          "Python path (setup too) and in generated C", options=_options, tools=("gcc",))
def sensitivity(ctx: Context) -> dict[str, Any]:
    args = ctx.options
    result: dict[str, Any] = {}
    if args.part in ("python", "both"):
        result["python"] = (python_part("slider_crank", args.backend, 21, 1, SMOKE_COUNTS_PYTHON) if ctx.smoke
                            else python_part(args.example, args.backend, args.instants, args.repeats))
    if args.part in ("c", "both"):
        result["c"] = generated_c(args, ctx.smoke)
    return result
