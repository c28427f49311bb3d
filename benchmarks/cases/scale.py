"""Scale: the ladder of N four-bars (ng = 6N + 3) from N = 64 to 1024, C backend.

Per ladder and code form (`auto`: symid's own limits; `unrolled`: straight-line
code; `looped`: family loops, straight-line LU; `compact`: family loops and
the LU on index tables; `before_runs`: auto with no runs, the code as it was
before c_lu_runs and c_loop_runs), in a fresh process and a fresh
cache: cold setup split by stage (derive, generate, compile; see
`symid.tools.bench`), the process's peak memory (the Python process's and,
separately, the largest compiler process's), the generated source and
machine-code sizes, us per instant on the compiled trajectory loop, and a
flop rate: the floating-point operations the generated code does per
instant, counted in its source (each looped kernel's body times its trip
count; an instant: two Phi, one Phi_q and factorization, three solves,
nu, gamma, applied, mass and reactions, the trajectory's usual one Newton
correction), over the measured time; and the same with the instant's O(NG)
vector work counted too (predictor, correction, checks: see
benchmarks/scale_counts.py), with callgrind's instructions per instant (a
figure the machine's load does not change) and flops per instruction. An
instant of the ladder is mostly not arithmetic: its LU steps have one or two
entries each and its rows are long, so its flop rate is far below a dense
kernel's.

With the forms `before_runs` and `auto` both, the ratios of their
instructions and time per instant (before / after, measured in the same run).

    python -m benchmarks scale                      # N = 64 128 256, auto
    python -m benchmarks scale --ladders 512 1024 --forms auto unrolled compact
    python -m benchmarks scale --ladders 64 --forms before_runs auto
    python -m benchmarks scale --ladders 64 --numpy 64 256 1024   # and numpy's setup memory (issue 31)

The targets of issue 17 are checked from the auto form's figures.
"""

from __future__ import annotations

import json
import math
import os
import re
import resource
import subprocess
import tempfile
from pathlib import Path
from typing import Any

from benchmarks.cases import register
from benchmarks.run import Context

# (LOOP_MIN, LU_TABLES_MIN) per code form; auto: symid's own limits
FORMS: dict[str, tuple[int, int] | None] = {"auto": None, "unrolled": (10 ** 9, 10 ** 9), "looped": (0, 10 ** 9),
                                            "compact": (0, 0), "before_runs": None}

# what one instant of the trajectory loop calls, per generated function
PER_INSTANT = {"phi": 2, "phi_q": 1, "sparse_factor": 1, "sparse_forward": 3, "sparse_back": 3,
               "sparse_t_forward": 1, "sparse_t_back": 1, "nu": 1, "gamma": 1, "applied": 1, "mass": 1,
               "reactions": 1, "trig": 0}
_OPS = re.compile(r" [-+] |[*/]|[-+*/]= |\b(?:sin|cos|sqrt|fabs|fmax|fmin)\(")


def _ops(code: str) -> int:
    """Floating-point operations in statements: index arithmetic (inside
    brackets) and integer declarations left out."""
    total = 0
    for line in code.splitlines():
        line = line.strip()
        if not line.endswith(";") or "int " in line or line.startswith(("return", "(void)")) or "=" not in line:
            continue
        rhs = re.sub(r"\[[^\]]*\]", "", line.split("=", 1)[1] if "+=" not in line and "-=" not in line
                     and "*=" not in line else line)
        total += len(_OPS.findall(rhs))
    return total


def _macro(source: str, prefix: str, key: str) -> int:
    m = re.search(rf"#define {prefix.upper()}_LU_{key} (\d+)", source)
    return int(m.group(1)) if m else 0


def _table_lu_flops(source: str, prefix: str) -> float:
    """An instant's LU operations where the LU loops over index tables (the
    loops' trip counts are in the tables, not in the code): factor once,
    solve three times, solve transposed once. Per step: the threshold test
    (a max per L entry, a product), the reciprocal, L's scaling, two per
    update; the solves: two per L entry, three per U entry (the sum of the
    step it reads is scaled there), one scaling per step."""
    steps, below, right, above = (_macro(source, prefix, k) for k in ("STEPS", "BELOW", "RIGHT", "ABOVE"))
    m = re.search(rf"{prefix}_lu_update\[(\d+)\] = ", source)
    updates = int(m.group(1)) if m and "_lu_update[1] = { 0 }" not in source else 0
    if f"{prefix.upper()}_LU_UPDATES " in source:  # the same plan as runs of code (c_lu_runs)
        updates = _macro(source, prefix, "UPDATES")
    factor = 3 * below + 2 * steps + 2 * updates
    solve = 2 * below + 3 * right + steps
    solve_t = 3 * above + steps + 2 * below
    return factor + 3 * solve + solve_t


_FOR = re.compile(r"for \((\w) = 0; \1 < (\d+); \+\+\1\) \{")


def _looped_ops(body: str) -> float:
    """A function's operations, each statement's times the trip counts of
    the fixed-count loops around it (a looped kernel's loop over members,
    or its runs of members: `for (m = 0; m < 1024; ++m) {`)."""
    total, trips = 0.0, [1]  # trips: the product of the trip counts per open brace
    for line in body.splitlines():
        loop = _FOR.search(line)
        total += trips[-1] * _ops(line)
        for ch in line:
            if ch == "{":
                trips.append(trips[-1] * (int(loop.group(2)) if loop else 1))
                loop = None
            elif ch == "}" and len(trips) > 1:
                trips.pop()
    return total


def count_flops(source: str, prefix: str) -> float:
    """Floating-point operations of one instant, counted in the generated source."""
    per: dict[str, float] = {}
    for m in re.finditer(rf"^static (?:void|int) {prefix}_(\w+?)(?:_k\d+|_L\d+|\d+)?\((.*?)^}}", source,
                         re.S | re.M):
        per[m.group(1)] = per.get(m.group(1), 0.0) + _looped_ops(m.group(2))
    tabled = f"{prefix}_lu_update[" in source or f"{prefix.upper()}_LU_UPDATES " in source
    return (sum(per.get(name, 0.0) * k for name, k in PER_INSTANT.items() if not (tabled and "sparse" in name))
            + (_table_lu_flops(source, prefix) if tabled else 0.0))


def child(n: int, form: str, instants: int, folder: Path) -> dict[str, Any]:
    """One cold setup and timing, in this (fresh) process."""
    from benchmarks import ladder
    from benchmarks.cases import scale_counts
    from symid.codegen.c import loops as c_loops
    from symid.codegen.c import lu as c_lu
    from symid.tools.bench import bench

    # No limit is raised: the memory estimate (symid.backends.footprint) lets
    # the C setup take every ladder here, as `symid bench` does. The code forms
    # other than auto patch the generator's thresholds: a form the product
    # offers no user is measured only this way (the default, auto, patches nothing).
    limits = FORMS[form]
    if limits is not None:
        c_loops.LOOP_MIN, c_lu.LU_TABLES_MIN = limits
    if form == "before_runs":  # auto, as before the runs (c_lu_runs, c_loop_runs): tables and straight-line code
        from symid.codegen.c import loop_runs as c_loop_runs
        from symid.codegen.c import lu_runs as c_lu_runs
        c_lu_runs.LITERAL_MAX = c_loop_runs.LITERAL_MAX = -1
        c_lu.rolled = lambda passes: None  # type: ignore[assignment]
    path = ladder.write(n, folder / "mech", steps=1001)
    os.environ["SYMID_CACHE"] = str(folder / "cache")
    result = bench(path, "c", instants=instants, cold=False, budget_s=20.0)
    source = next((folder / "cache").rglob("*_solver.c"))
    so = source.with_name("solver.so")
    flops = count_flops(source.read_text(), ladder.name(n))
    meta = json.loads((so.parent / "meta.json").read_text())
    vector = scale_counts.vector_flops(meta["ng"], meta["nc"], meta["nr"], meta["ng"] // 3)
    us = result.get("us_per_instant")
    instructions = None
    if scale_counts.available():
        instructions = scale_counts.instructions_per_instant(
            so, ladder.name(n), meta, ladder.Ladder(n).q_exact(0.0), 0.0, 1.0 / 1000, result["newton_tol"])
    result.update({
        "vector_flops_per_instant": vector,
        "instructions_per_instant": round(instructions) if instructions else None,
        "flops_per_instruction": round((flops + vector) / instructions, 3) if instructions else None,
        "gflops_with_vector_work": round((flops + vector) / (us * 1e3), 3) if us else None,
        "n": n, "form": form, "looped": "_L0_body" in source.read_text(), "lu_tables": "_lu_update[" in source.read_text(),
        "lu_runs": "_LU_UPDATES " in source.read_text(),
        "source_kb": round(source.stat().st_size / 1024, 1),
        "text_kb": round(_text_bytes(so) / 1024, 1) if so.is_file() else None,
        "flops_per_instant": flops,
        "gflops": round(flops / (us * 1e3), 3) if us else None,
        "peak_python_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1),
        # compiler processes; a forked child counts the Python image it started from
        "peak_compiler_mb": round(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024, 1),
    })
    return result


def _text_bytes(so: Path) -> int:
    """The machine code's size (.text), from `size`; 0 where it is not installed."""
    try:
        out = subprocess.run(["size", "-A", str(so)], capture_output=True, text=True, check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        return 0
    return sum(int(line.split()[1]) for line in out.splitlines() if line.startswith(".text"))


def child_entry(spec: dict[str, Any]) -> dict[str, Any]:
    """The worker's side of `run_one` (a fresh process, `Context.isolated`)."""
    return child(spec["n"], spec["form"], spec["instants"], Path(spec["folder"]))


def run_one(ctx: Context, n: int, form: str, instants: int, cap_s: float) -> dict[str, Any]:
    """One ladder in one form, cold, in a process of its own."""
    folder = Path(tempfile.mkdtemp(prefix=f"scale-{n}-{form}-", dir=ctx.work))
    got = ctx.isolated("benchmarks.cases.scale:child_entry",
                       {"n": n, "form": form, "instants": instants, "folder": str(folder)}, cap_s)
    if got.status != "ok":
        return {"n": n, "form": form, "error": got.note or got.status}
    return {**got.result, "process_s": round(got.wall_s, 2), "peak_process_mb": got.peak_rss_mb}


def numpy_row(ctx: Context, n: int, instants: int, cap_s: float) -> dict[str, Any]:
    """`symid bench` on the ladder with the numpy backend, cold, as a user runs
    it (issue 31: its peak memory at N = 1024 at most 1 GB): the command's
    JSON, its wall time and peak resident memory (through launch.py)."""
    import sys

    from benchmarks import ladder

    folder = Path(tempfile.mkdtemp(prefix=f"scale-numpy-{n}-", dir=ctx.work))
    path = ladder.write(n, folder, steps=1001)
    with tempfile.TemporaryFile() as out:
        got = ctx.process([sys.executable, "-m", "symid", "bench", str(path), "--backend", "numpy", "--instants",
                           str(instants), "--json"], cap_s, stdout=out)
        out.seek(0)
        stdout = out.read().decode(errors="replace")
    if got.status != 0 or not stdout.strip():
        return {"n": n, "form": "numpy", "error": f"symid bench exited with status {got.status}"}
    return {**json.loads(stdout), "n": n, "form": "numpy", "process_s": round(got.wall_s, 2),
            "peak_process_mb": got.peak_rss_mb}


def targets(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Issue 17's targets from the auto form's figures (None: not measured)."""
    auto = {r["n"]: r for r in rows if r.get("form") == "auto" and not r.get("error")}
    out: dict[str, Any] = {}
    if 64 in auto and 1024 in auto:
        ratio = auto[1024]["setup_s"] / auto[64]["setup_s"]
        out["setup_ratio_1024_64"] = round(ratio, 2)
        out["setup_ratio_target"] = round(1.2 * 6147 / 387, 2)
        out["peak_mb_1024"] = max(auto[1024]["peak_python_mb"], auto[1024]["peak_compiler_mb"])
    ns = sorted(auto)
    if len(ns) >= 2:
        a, b = auto[ns[0]], auto[ns[-1]]
        out[f"setup_exponent_{ns[0]}_{ns[-1]}"] = round(math.log(b["setup_s"] / a["setup_s"]) / math.log(b["ng"] / a["ng"]), 3)
    if 512 in auto:
        out["gflops_512"] = auto[512]["gflops"]
        out["gflops_512_with_vector_work"] = auto[512].get("gflops_with_vector_work")
    numpy = {r["n"]: r for r in rows if r.get("form") == "numpy" and not r.get("error")}
    if 1024 in numpy:  # issue 31: numpy at the ladder of 1024 within 1 GB
        out["numpy_peak_mb_1024"] = numpy[1024]["peak_process_mb"]
        out["numpy_peak_target_mb"] = 1024
    return out


def ratios(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Per ladder measured in both forms: before_runs / auto of instructions and time per instant."""
    by = {(r["n"], r["form"]): r for r in rows if not r.get("error")}
    out: dict[str, Any] = {}
    for (n, form), after in by.items():
        before = by.get((n, "before_runs"))
        if form != "auto" or before is None:
            continue
        for key in ("instructions_per_instant", "us_per_instant"):
            if before.get(key) and after.get(key):
                out[f"ladder_{n}_{key}_before_over_after"] = round(before[key] / after[key], 3)
    return out


def _options(group: Any) -> None:
    group.add_argument("--ladders", type=int, nargs="+", default=[64, 128, 256])
    group.add_argument("--forms", nargs="+", choices=sorted(FORMS), default=["auto"])
    group.add_argument("--instants", type=int, default=2000)
    group.add_argument("--cap", type=float, default=1800.0, help="seconds before a run is stopped")
    group.add_argument("--numpy", type=int, nargs="*", default=[], metavar="N",
                       help="also these ladders on the numpy backend, `symid bench` as a user runs it")


@register("scale", "the ladder from N = 64 up on the C backend: cold setup by stage, memory, code size, us and "
          "instructions per instant, flop rate; code forms compared", options=_options, tools=("gcc",))
def scale(ctx: Context) -> dict[str, Any]:
    args = ctx.options
    ladders, instants = ((2,), 50) if ctx.smoke else (args.ladders, args.instants)
    rows = []
    for n in ladders:
        for form in args.forms:
            row = run_one(ctx, n, form, instants, args.cap)
            rows.append(row)
            if row.get("error"):
                ctx.log(f"ladder {n:5d} {form:8s} error: {row['error']}")
                continue
            ctx.log(f"ladder {n:5d} {form:8s} ng {row['ng']:5d}  setup {row['setup_s']:7.2f} s  "
                    f"{row['us_per_instant']:.2f} us  {row['instructions_per_instant']} instr/instant")
    for n in (2,) if ctx.smoke else args.numpy:
        row = numpy_row(ctx, n, 5 if ctx.smoke else 20, args.cap)
        rows.append(row)
        ctx.log(f"ladder {n:5d} numpy    " + (f"error: {row['error']}" if row.get("error") else
                f"ng {row['ng']:5d}  setup {row['setup_s']:7.2f} s  peak {row['peak_process_mb']:.0f} MB"))
    return {"rows": rows, "targets": targets(rows), "ratios": ratios(rows)}
