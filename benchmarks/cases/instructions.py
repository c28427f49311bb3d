"""Instructions per instant of every example's generated C (callgrind: the
machine's load does not move them), and its wall clock.

Per bundled example:

- ir_instant: callgrind instructions per trajectory instant, the checks'
  scales zero (no jump check, no conditioning screen), and
  ir_instant_with_checks with them set as `symid solve` sets them after t0;
  checks_ratio is the second over the first (`benchmarks.callgrind`'s
  trajectory driver, the solver the c backend builds);
- ir_call: instructions per `<name>_instant` call from a guess near the
  solution (the solution at t1/3 moved by 1e-6), and that call's Newton
  iterations (the solver `symid generate --target c` writes);
- us_instant: wall-clock microseconds per trajectory instant (median of
  rounds; the machine is shared, the load averages are in the result).

    python -m benchmarks instructions [--examples a,b] [--rounds R]
"""

from __future__ import annotations

import statistics
import subprocess
import sys
from typing import Any

from benchmarks import callgrind
from benchmarks.cases import register
from benchmarks.run import Context
from symid import api


def example(ctx: Context, name: str, rounds: int) -> dict[str, Any]:
    """Every figure of one example."""
    first, second = (20, 60) if ctx.smoke else (200, 2200)
    calls = (5, 15) if ctx.smoke else (50, 550)
    n_wall, reps = (101, 2) if ctx.smoke else (2001, 100)
    plain, checked = callgrind.per_instant_each(name, first, second, (False, True))
    folder = ctx.work / name
    toml = api.example(name)
    subprocess.run([sys.executable, "-m", "symid", "generate", str(toml), "--target", "c", "-o", str(folder)],
                   check=True, capture_output=True)
    exe = callgrind.build(folder, name, callgrind.default_q0(folder, name), callgrind.file_grid(toml))
    walls = [callgrind.wall_us(exe, n_wall, reps) for _ in range(rounds)]
    return {"ir_instant": plain, "ir_instant_with_checks": checked, "checks_ratio": checked / plain,
            "ir_call": callgrind.instructions(exe, "inst", *calls),
            "call_iterations": int(callgrind._run([str(exe), "inst", "1"]).stdout.split()[2]),
            "us_instant": statistics.median(walls), "trajectory_instants": [first, second],
            "instant_calls": list(calls), "wall_instants_x_reps": [n_wall, reps], "rounds": rounds}


def _options(group: Any) -> None:
    group.add_argument("--examples", help="comma-separated (default: every bundled example)")
    group.add_argument("--rounds", type=int, default=7, help="wall-clock rounds per example")


@register("instructions", "callgrind instructions per trajectory instant (with and without the checks) and per "
          "_instant call, and us per instant, of every example's generated C", options=_options,
          tools=("gcc", "valgrind"))
def instructions(ctx: Context) -> dict[str, Any]:
    names = (ctx.options.examples.split(",") if ctx.options.examples
             else ["slider_crank"] if ctx.smoke else api.examples())
    out: dict[str, Any] = {"flags": callgrind.FLAGS, "examples": {}}
    for name in names:
        row = out["examples"][name] = example(ctx, name, 1 if ctx.smoke else ctx.options.rounds)
        ctx.log(f"{name:24s} {row['ir_instant']:8.0f} Ir/instant ({row['ir_instant_with_checks']:.0f} with the "
                f"checks), {row['ir_call']:8.0f} Ir/call, {row['us_instant']:.2f} us/instant")
    return out
