"""The optimization level of the C backend's builds: compile time against run time.

`symid solve --backend c` compiles the solver it builds (the cache's
`c-solve` source, `symid/backends/c_backend.py`) once per structure, and a
user waits for that compile before the first instant; a study (`symid
sweep`, `optimize`) compiles the study build (`c`: `<name>_sweep`, its
variants in SIMD lanes). Per bundled example and per level (-O1, -O2), with
each C compiler installed of `cc` and `clang`, for the solve build:

- compile_cpu_s: the compiler's CPU seconds on that source with the
  product's flags (`symid.codegen.compiler.CFLAGS`; with the timing driver
  below, a program instead of a library), the least of the repeats (CPU
  time: a shared machine's load does not add to it; each build a process of
  the harness's, `Context.process`);
- us_per_instant: the trajectory loop and `_instant` continued from the last
  solution, one instant each (`tests/c/rows_driver.c`, the timing driver,
  linked with that source at that level; the least over its repeats);
- rows_identical: the bundled run's rows (%.17g) at -O1 are those at -O2,
  byte for byte (neither level reassociates floating point; -std=c99 keeps
  products out of sums);
- and per example the ratios -O1 over -O2 of each;

and under `study` the same for the study build: its compile, and the
microseconds per variant-instant of `<name>_sweep` over K variants near the
file's parameters (the driver's `sweep` mode), with whether their
figures are the same bits at both levels (`figures_identical`).

    python -m benchmarks c_level [--examples a,b] [--repeats R] [--variants K]
"""

from __future__ import annotations

import shutil
import statistics
import subprocess
from pathlib import Path
from typing import Any, Callable

from benchmarks.cases import register
from benchmarks.processes import ROOT
from benchmarks.run import Context
from symid import api
from symid.codegen.compiler import CFLAGS
from symid.model.mechanism import Mechanism

DRIVER = ROOT / "tests" / "c" / "rows_driver.c"
LEVELS = ("-O1", "-O2")
COMPILE_CAP_S = 600.0


def _out(command: list[Any]) -> str:
    return subprocess.run([str(c) for c in command], check=True, capture_output=True, text=True).stdout


def _build(ctx: Context, cc: str, level: str, built: Path, name: str, exe: Path, repeats: int) -> float:
    """The driver linked with the built source at `level`, with the product's flags (a
    position-independent program instead of a library): the least CPU seconds of
    `repeats` builds (the driver is a page of C beside the solver's thousands of lines)."""
    flags = [f for f in CFLAGS if f != "-shared"]
    command = [cc, level, *flags, f"-I{built}", f'-DSOLVER_H="{name}_solver.h"', f"-DP={name}",
               f"-DPU={name.upper()}", str(DRIVER), str(built / f"{name}_solver.c"), "-lm", "-o", str(exe)]
    cpu = []
    for _ in range(repeats):
        got = ctx.process(command, COMPILE_CAP_S)
        if got.status != 0 or got.cpu_s is None:
            raise RuntimeError(f"{cc} {level} failed on {name}_solver.c with status {got.status}")
        cpu.append(got.cpu_s)
    return round(min(cpu), 3)


def _levels(ctx: Context, mech: Mechanism, built: Path, cc: str, repeats: int, timed: str, same: str,
            run: Callable[[Path, list[str]], tuple[Any, str]]) -> dict[str, Any]:
    """One build's figures at each level: the compile's CPU seconds, `timed` (what
    `run(exe, [t0, h, n])` times) and `same`: whether what it prints is the same bits."""
    name, a = mech.name, mech.analysis
    n = min(a.steps, 64) if ctx.smoke else a.steps
    grid = [repr(a.t0), repr((a.t1 - a.t0) / (a.steps - 1)), str(n)]
    out: dict[str, Any] = {"source_bytes": (built / f"{name}_solver.c").stat().st_size, "compile_cpu_s": {},
                           timed: {}}
    printed: dict[str, str] = {}
    for level in LEVELS:
        exe = ctx.work / f"{built.name}-{cc}{level}"
        out["compile_cpu_s"][level] = _build(ctx, cc, level, built, name, exe, repeats)
        out[timed][level], printed[level] = run(exe, grid)
    out[same] = printed["-O1"] == printed["-O2"]
    return out


def _ratio(by_level: dict[str, Any], part: str | None = None) -> float:
    """-O1's figure over -O2's (`part` of each, if given)."""
    one, two = by_level["-O1"], by_level["-O2"]
    return round(one[part] / two[part] if part else one / two, 3)


def example(ctx: Context, name: str, cc: str, repeats: int) -> dict[str, Any]:
    """One example's solve build with one compiler: each level's compile and run."""
    mech = api.load_mechanism(api.example(name))
    built = Path(api.prepare(mech, backend="c").evaluator.artifact)  # type: ignore[attr-defined]

    def run(exe: Path, grid: list[str]) -> tuple[dict[str, float], str]:
        q0 = _out([exe, "describe"]).splitlines()[2].split()
        loop, instant = (float(v) for v in _out([exe, "time", *grid, *q0]).split())
        return {"trajectory": loop, "instant": instant}, _out([exe, "rows", *grid, *q0])

    out = _levels(ctx, mech, built, cc, repeats, "us_per_instant", "rows_identical", run)
    out["o1_over_o2"] = {"compile": _ratio(out["compile_cpu_s"]),
                         **{k: _ratio(out["us_per_instant"], k) for k in ("trajectory", "instant")}}
    return out


def study(ctx: Context, name: str, cc: str, repeats: int, variants: int) -> dict[str, Any]:
    """One example's study build with one compiler: each level's compile and sweep."""
    from symid.backends import Needs
    from symid.backends.prepare import prepare

    mech = api.load_mechanism(api.example(name))
    solver = prepare(mech, "c", Needs(velocity=True, reactions=True, batch=True, friction=False))
    built = Path(solver.evaluator.artifact)  # type: ignore[attr-defined]
    lanes: list[int] = []

    def run(exe: Path, grid: list[str]) -> tuple[float, str]:
        first, figures = _out([exe, "sweep", *grid, str(variants)]).split("\n", 1)
        us, width = first.split()
        lanes.append(int(width))
        return float(us), figures

    out = _levels(ctx, mech, built, cc, repeats, "us_per_variant_instant", "figures_identical", run)
    out["lanes"] = lanes[-1]
    out["o1_over_o2"] = {"compile": _ratio(out["compile_cpu_s"]), "sweep": _ratio(out["us_per_variant_instant"])}
    return out


def _options(group: Any) -> None:
    group.add_argument("--examples", help="comma-separated (default: every bundled example)")
    group.add_argument("--repeats", type=int, default=3, help="compiles per level (the least is kept)")
    group.add_argument("--variants", type=int, default=64, help="variants of the study build's sweep")


@register("c_level", "the C backend's solve and study builds at -O1 and -O2, per example and compiler: the "
          "compile's CPU seconds, us per instant (per variant-instant of the sweep), the results bit for bit",
          options=_options, tools=("cc",))
def c_level(ctx: Context) -> dict[str, Any]:
    names = (ctx.options.examples.split(",") if ctx.options.examples
             else ["slider_crank"] if ctx.smoke else api.examples())
    compilers = ["cc"] + (["clang"] if shutil.which("clang") and not ctx.smoke else [])
    repeats = 1 if ctx.smoke else ctx.options.repeats
    variants = 8 if ctx.smoke else ctx.options.variants
    out: dict[str, Any] = {"flags": list(CFLAGS), "compilers": {}}
    for cc in compilers:
        results = {name: example(ctx, name, cc, repeats) for name in names}
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
