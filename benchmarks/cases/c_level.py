"""The optimization level of the C backend's builds: compile time against run time.

`symid solve --backend c` compiles the solver it builds (the cache's
`c-solve` source, `symid/backends/c_backend.py`) once per structure, and a
user waits for that compile before the first instant; a study (`symid
sweep`, `optimize`) compiles the study build (`c`: `<name>_sweep`, its
variants in SIMD lanes). Per bundled example and per level (-O1, -O2), with
each C compiler installed of `cc` and `clang`, for the solve build:

- compile_cpu_s: the compiler's CPU seconds on that source with the
  product's flags (`symid.codegen.compiler.CFLAGS`), the least of the
  repeats (CPU time: a shared machine's load does not add to it);
- us_per_instant: the trajectory loop and `_instant` continued from the last
  solution, one instant each (`tests/c/rows_driver.c` linked with that
  source at that level; the least over its repeats);
- rows_identical: the bundled run's rows (%.17g) at -O1 are those at -O2,
  byte for byte (neither level reassociates floating point; -std=c99 keeps
  products out of sums);
- and per example the ratios -O1 over -O2 of each;

and under `study` the same for the study build: its compile, and the
microseconds per variant-instant of `<name>_sweep` over K variants near the
file's parameters (benchmarks/cases/sweep_driver.c), with whether their
figures are the same bits at both levels (`figures_identical`).

    python -m benchmarks c_level [--examples a,b] [--repeats R] [--variants K]
"""

from __future__ import annotations

import resource
import shutil
import statistics
import subprocess
from pathlib import Path
from typing import Any

from benchmarks.cases import register
from benchmarks.processes import ROOT
from benchmarks.run import Context
from symid import api
from symid.codegen.compiler import CFLAGS

DRIVER = ROOT / "tests" / "c" / "rows_driver.c"
SWEEP_DRIVER = Path(__file__).resolve().parent / "sweep_driver.c"
LEVELS = ("-O1", "-O2")


def _cpu(args: list[str]) -> float:
    """Run a command; the CPU seconds (user + system) it took."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run(args, check=True, capture_output=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime


def example(ctx: Context, name: str, cc: str, repeats: int) -> dict[str, Any]:
    """One example's figures with one compiler: each level's compile and run."""
    built = Path(api.prepare(api.example(name), backend="c").evaluator.artifact)  # type: ignore[attr-defined]
    source = built / f"{name}_solver.c"
    a = api.load_mechanism(api.example(name)).analysis
    n = min(a.steps, 64) if ctx.smoke else a.steps
    h = (a.t1 - a.t0) / (a.steps - 1)
    out: dict[str, Any] = {"source_bytes": source.stat().st_size, "compile_cpu_s": {}, "us_per_instant": {}}
    rows: dict[str, str] = {}
    for level in LEVELS:
        lib = ctx.work / f"{name}-{cc}{level}.so"
        out["compile_cpu_s"][level] = round(min(_cpu([cc, level, *CFLAGS, str(source), "-o", str(lib), "-lm"])
                                                for _ in range(repeats)), 3)
        exe = ctx.work / f"{name}-{cc}{level}"
        subprocess.run([cc, "-std=c99", level, "-fno-math-errno", f"-I{built}", f'-DSOLVER_H="{name}_solver.h"',
                        f"-DP={name}", f"-DPU={name.upper()}", str(DRIVER), str(source), "-lm", "-o", str(exe)],
                       check=True)
        q0 = subprocess.run([str(exe), "describe"], check=True, capture_output=True, text=True).stdout.splitlines()[2]
        args = [repr(a.t0), repr(h), str(n), *q0.split()]
        loop, instant = (float(v) for v in subprocess.run([str(exe), "time", *args], check=True, capture_output=True,
                                                          text=True).stdout.split())
        out["us_per_instant"][level] = {"trajectory": loop, "instant": instant}
        rows[level] = subprocess.run([str(exe), "rows", *args], check=True, capture_output=True, text=True).stdout
    out["rows_identical"] = rows["-O1"] == rows["-O2"]
    c, us = out["compile_cpu_s"], out["us_per_instant"]
    out["o1_over_o2"] = {"compile": round(c["-O1"] / c["-O2"], 3),
                         **{k: round(us["-O1"][k] / us["-O2"][k], 3) for k in ("trajectory", "instant")}}
    return out


def study(ctx: Context, name: str, cc: str, repeats: int, variants: int) -> dict[str, Any]:
    """One example's study build with one compiler: each level's compile and sweep."""
    from symid.backends import Needs
    from symid.backends.prepare import prepare

    mech = api.load_mechanism(api.example(name))
    solver = prepare(mech, "c", Needs(velocity=True, reactions=True, batch=True, friction=False))
    built = Path(solver.evaluator.artifact)  # type: ignore[attr-defined]
    source = built / f"{name}_solver.c"
    a = mech.analysis
    n = min(a.steps, 64) if ctx.smoke else a.steps
    h = (a.t1 - a.t0) / (a.steps - 1)
    out: dict[str, Any] = {"source_bytes": source.stat().st_size, "compile_cpu_s": {}, "us_per_variant_instant": {}}
    figures: dict[str, str] = {}
    for level in LEVELS:
        lib = ctx.work / f"{name}-study-{cc}{level}.so"
        out["compile_cpu_s"][level] = round(min(_cpu([cc, level, *CFLAGS, str(source), "-o", str(lib), "-lm"])
                                                for _ in range(repeats)), 3)
        exe = ctx.work / f"{name}-study-{cc}{level}"
        subprocess.run([cc, "-std=c99", level, "-fno-math-errno", f"-I{built}", f'-DSOLVER_H="{name}_solver.h"',
                        f"-DP={name}", f"-DPU={name.upper()}", str(SWEEP_DRIVER), str(source), "-lm", "-o", str(exe)],
                       check=True)
        ran = subprocess.run([str(exe), str(variants), repr(a.t0), repr(h), str(n)], check=True, capture_output=True,
                             text=True).stdout.split("\n", 1)
        us, lanes = ran[0].split()
        out["us_per_variant_instant"][level] = float(us)
        out["lanes"] = int(lanes)
        figures[level] = ran[1]
    out["figures_identical"] = figures["-O1"] == figures["-O2"]
    c, us = out["compile_cpu_s"], out["us_per_variant_instant"]
    out["o1_over_o2"] = {"compile": round(c["-O1"] / c["-O2"], 3), "sweep": round(us["-O1"] / us["-O2"], 3)}
    return out


def _options(group: Any) -> None:
    group.add_argument("--examples", help="comma-separated (default: every bundled example)")
    group.add_argument("--repeats", type=int, default=3, help="compiles per level (the least is kept)")
    group.add_argument("--variants", type=int, default=64, help="variants of the study build's sweep")


@register("c_level", "the C backend's solve and study builds at -O1 and -O2, per example and compiler: the "
          "compile's CPU seconds, us per instant (per variant-instant of the sweep), the results bit for bit", options=_options, tools=("cc",))
def c_level(ctx: Context) -> dict[str, Any]:
    names = (ctx.options.examples.split(",") if ctx.options.examples
             else ["slider_crank"] if ctx.smoke else api.examples())
    compilers = ["cc"] + (["clang"] if shutil.which("clang") and not ctx.smoke else [])
    repeats = 1 if ctx.smoke else ctx.options.repeats
    variants = 8 if ctx.smoke else ctx.options.variants
    out: dict[str, Any] = {"flags": list(CFLAGS), "compilers": {}}
    for cc in compilers:
        results = out["compilers"][cc] = {name: example(ctx, name, cc, repeats) for name in names}
        for name, r in results.items():
            ratio = r["o1_over_o2"]
            ctx.log(f"{cc:5s} {name:28s} -O1/-O2: compile {ratio['compile']:.2f}, trajectory "
                    f"{ratio['trajectory']:.2f}, instant {ratio['instant']:.2f}; rows identical {r['rows_identical']}")
        studies = {name: study(ctx, name, cc, repeats, variants) for name in names}
        for name, r in studies.items():
            ratio = r["o1_over_o2"]
            ctx.log(f"{cc:5s} {name:28s} study build -O1/-O2: compile {ratio['compile']:.2f}, sweep "
                    f"{ratio['sweep']:.2f} ({r['lanes']} lanes); figures identical {r['figures_identical']}")
        ratios = [r["o1_over_o2"] for r in results.values()]
        swept = [r["o1_over_o2"] for r in studies.values()]
        out["compilers"][cc] = {"examples": results, "study": studies, "summary": {
            "compile_median": statistics.median(x["compile"] for x in ratios),
            "trajectory_median": statistics.median(x["trajectory"] for x in ratios),
            "trajectory_worst": max(x["trajectory"] for x in ratios),
            "rows_identical": all(r["rows_identical"] for r in results.values()),
            "study_compile_median": statistics.median(x["compile"] for x in swept),
            "sweep_median": statistics.median(x["sweep"] for x in swept),
            "sweep_worst": max(x["sweep"] for x in swept),
            "figures_identical": all(r["figures_identical"] for r in studies.values())}}
    return out
