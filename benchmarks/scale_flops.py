"""Issue 17's flop rate of the ladder: the generated code before and after
the runs (symid/codegen/c/lu_runs.py, loop_runs.py), per ladder,
by benchmarks/scale.py's measurements in a fresh process each: callgrind's
instructions per instant (a figure the machine's load does not change),
flops per instruction, us per instant and GFLOP/s (wall clock: compare
ratios from one run on a loaded machine), and the generated source's size.

    python -m benchmarks.scale_flops                    # N = 64
    python -m benchmarks.scale_flops --ladders 64 128 512

Writes benchmarks/results/scale_flops.json (--out to change). The flops are
scale.py's count of the generated code (its docstring says what is counted);
the runs do the same operations as the tables they replace, save that a run's
member constants are computed once per run instead of once per member.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from benchmarks import scale

OUT = scale.ROOT / "benchmarks" / "results" / "scale_flops.json"
FIGURES = ("ng", "us_per_instant", "instructions_per_instant", "flops_per_instant", "vector_flops_per_instant",
           "flops_per_instruction", "gflops", "gflops_with_vector_work", "source_kb", "text_kb", "setup_s",
           "lu_tables", "lu_runs", "max_residual")


def compare(n: int, instants: int, cap_s: float) -> dict[str, Any]:
    """One ladder before and after the runs, and the ratios."""
    rows = {form: scale.run_one(n, form, instants, cap_s) for form in ("before_runs", "auto")}
    out: dict[str, Any] = {"n": n}
    for form, row in rows.items():
        out[form] = {k: row.get(k) for k in FIGURES} if not row.get("error") else {"error": row["error"]}
    before, after = out["before_runs"], out["auto"]
    for key in ("instructions_per_instant", "us_per_instant"):
        if before.get(key) and after.get(key):
            out[f"{key}_ratio"] = round(before[key] / after[key], 3)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.scale_flops", description=__doc__.splitlines()[0])
    ap.add_argument("--ladders", type=int, nargs="+", default=[64])
    ap.add_argument("--instants", type=int, default=2000)
    ap.add_argument("--cap", type=float, default=1800.0, help="seconds before a run is stopped")
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args(argv)
    rows = []
    for n in args.ladders:
        row = compare(n, args.instants, args.cap)
        rows.append(row)
        for form in ("before_runs", "auto"):
            r = row[form]
            print(f"ladder {n:4d} {form:11s} " + ("error: " + str(r["error"]) if "error" in r else
                  f"{r['instructions_per_instant']} instr/instant  {r['flops_per_instruction']} flop/instr  "
                  f"{r['us_per_instant']:.1f} us  {r['gflops']} GFLOP/s ({r['gflops_with_vector_work']} with "
                  f"vector work)  src {r['source_kb']} KB"), flush=True)
        print(f"ladder {n:4d} ratios before/after: instructions {row.get('instructions_per_instant_ratio')}, "
              f"time {row.get('us_per_instant_ratio')}", flush=True)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"rows": rows}, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
