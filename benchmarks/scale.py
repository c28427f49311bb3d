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

    python -m benchmarks.scale                      # N = 64 128 256, auto
    python -m benchmarks.scale --ladders 512 1024 --forms auto unrolled compact

Writes benchmarks/results/scale.json (--out to change) and prints a table;
the targets of issue 17 are checked from the auto form's figures.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "benchmarks" / "results" / "scale.json"
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
    sys.path.insert(0, str(ROOT))
    from benchmarks import ladder, scale_counts
    from symid.codegen.c import lu as c_lu
    from symid.codegen.c import loops as c_loops
    from symid.tools.bench import bench

    from symid.io import reader

    # The file reader's limit (1000 bodies, symid.io.limits) is set by the
    # Python backends' dense checks; the C setup measured here has none, and
    # the ladder of 1024 has 2049 bodies.
    reader.MAX_BODIES = max(reader.MAX_BODIES, 2 * n + 1)
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


def run_one(n: int, form: str, instants: int, cap_s: float) -> dict[str, Any]:
    with tempfile.TemporaryDirectory(prefix="symid-scale-") as tmp:
        env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1",
               "PYTHONPATH": os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH", "")) if p)}
        cmd = [sys.executable, "-m", "benchmarks.scale", "--child", str(n), form, str(instants), tmp]
        start = time.perf_counter()
        try:
            done = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=cap_s)
        except subprocess.TimeoutExpired:
            return {"n": n, "form": form, "error": f"stopped after {cap_s:.0f} s"}
        if done.returncode != 0:
            return {"n": n, "form": form, "error": done.stderr.strip().splitlines()[-1:] or "failed"}
        out: dict[str, Any] = json.loads(done.stdout.strip().splitlines()[-1])
        out["process_s"] = round(time.perf_counter() - start, 2)
        return out


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
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.scale", description=__doc__.splitlines()[0])
    ap.add_argument("--ladders", type=int, nargs="+", default=[64, 128, 256])
    ap.add_argument("--forms", nargs="+", choices=sorted(FORMS), default=["auto"])
    ap.add_argument("--instants", type=int, default=2000)
    ap.add_argument("--cap", type=float, default=1800.0, help="seconds before a run is stopped")
    ap.add_argument("--out", type=Path, default=OUT)
    ap.add_argument("--child", nargs=4, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        n, form, instants, folder = args.child
        print(json.dumps(child(int(n), form, int(instants), Path(folder))))
        return 0
    rows = []
    for n in args.ladders:
        for form in args.forms:
            row = run_one(n, form, args.instants, args.cap)
            rows.append(row)
            if row.get("error"):
                print(f"ladder {n:5d} {form:8s} error: {row['error']}", flush=True)
                continue
            print(f"ladder {n:5d} {form:8s} ng {row['ng']:5d}  setup {row['setup_s']:7.2f} s (derive "
                  f"{row['derive_s']:.2f}, generate {row['generate_s']:.2f}, compile {row['compile_s']:.2f})  "
                  f"peak {row['peak_python_mb']:.0f}/{row['peak_compiler_mb']:.0f} MB  src {row['source_kb']:.0f} KB  "
                  f"text {row['text_kb']} KB  {row['us_per_instant']:.2f} us  {row['gflops']} GFLOP/s "
                  f"({row['gflops_with_vector_work']} with vector work)  {row['instructions_per_instant']} instr/instant",
                  flush=True)
    report = {"rows": rows, "targets": targets(rows)}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(report, indent=1) + "\n")
    print(json.dumps(report["targets"]))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
