"""Issue 14's compiled instant: callgrind instructions per instant of the
generated trajectory loop, this checkout against a base commit (default
67db78c, before the loop's checks were fixed in size at generation), a
figure the machine's load does not move:

- every example: the trajectory driver of benchmarks/embedded_regression
  (chunks of 64 rows, the file's parameters, jump-check scales zero), each
  version's own `symid generate` output;
- the slider-crank sweep: the drivers of benchmarks/sweep_instructions
  (the issue-14 grid's first variants through `<name>_sweep`, and through
  `<name>_trajectory` variant by variant), each version's solver.

Both versions are compiled with the same gcc flags (FLAGS of
embedded_regression: -O2) and the same drivers, and their rows are the same
bits (tests/c/test_c_row_checks.py checks the written-out forms against the
loop forms; every example's rows on the c backend, in five output sets, were
compared bit for bit with the base's when the change was made).

    python -m benchmarks.bookkeeping [--base COMMIT] [--quick]

Prints the table and writes benchmarks/results/bookkeeping.json (not with --quick).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

from benchmarks import embedded_regression as er
from benchmarks import sweep_instructions as si

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "benchmarks" / "results" / "bookkeeping.json"
BASE = "67db78c"


def _tree(tmp: Path, commit: str) -> Path:
    where = tmp / "base"
    er._run(["git", "-C", str(ROOT), "worktree", "add", "--detach", str(where), commit])
    return where


def _sweep_sources(k: int, steps: int) -> dict[str, str]:
    """The sweep and plain drivers' C for the grid's first k variants (this checkout's parameter order)."""
    import sympy as sp

    from symid import api
    from symid.study.variants import base_matrix, study_mechanism, variant_values

    mech = study_mechanism(api.load_mechanism(api.example("slider_crank"), steps=steps))
    full = base_matrix(mech, ("L_rod", "n"), si._grid(k))
    q0 = [float(sp.sympify(x).subs(variant_values(mech, row))) for row in full for b in mech.bodies for x in b.q0]
    a = mech.analysis
    text = {"@T0@": repr(float(a.t0)), "@H@": repr((a.t1 - a.t0) / (steps - 1)), "@TOL@": repr(float(a.tol)),
            "@PARAMS@": ", ".join(repr(float(v)) for v in full.ravel()), "@Q0@": ", ".join(map(repr, q0))}
    out = {}
    for label, source in (("sweep", si.SWEEP), ("plain", si.PLAIN)):
        for key, value in text.items():
            source = source.replace(key, value)
        out[label] = source.replace("UPPER", "SLIDER_CRANK").replace("NAME", "slider_crank")
    return out


def _sweep_counts(folder: Path, sources: dict[str, str], k1: int, k2: int, steps: int) -> dict[str, float]:
    """Instructions per instant of the sweep and plain drivers linked with the solver in folder."""
    out = {}
    for label, source in sources.items():
        driver, exe = folder / f"{label}.c", folder / label
        driver.write_text(source, encoding="utf-8")
        # the scalar instant's bookkeeping: the sweep one variant at a time (its SIMD lanes,
        # which a base without them ignores the macro of, are sweep_instructions' figure)
        er._run(["gcc", *er.FLAGS, "-DSLIDER_CRANK_NO_LANES", "-I", str(folder), str(driver),
                 str(folder / "slider_crank_solver.c"), "-o", str(exe), "-lm"])
        counts = []
        for k in (k1, k2):
            run = er._run(["valgrind", "--tool=callgrind", f"--callgrind-out-file={folder}/cg.out", str(exe),
                           str(k), str(steps)])
            found = re.search(r"Collected : (\d+)", run.stderr)
            if found is None or run.stdout.split() != [str(k * steps)]:
                raise RuntimeError(f"callgrind run of the {label} driver failed: {run.stdout} {run.stderr[-300:]}")
            counts.append(int(found.group(1)))
        out[label] = (counts[1] - counts[0]) / ((k2 - k1) * steps)
    return out


def measure(base: str, quick: bool) -> dict[str, Any]:
    first, second = (100, 400) if quick else (200, 2200)
    k1, k2, steps = (2, 4, 301) if quick else (4, 12, 1001)
    sources = _sweep_sources(k2, steps)
    table: dict[str, dict[str, float]] = {}
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        old = _tree(tmp, base)
        try:
            for example in er.EXAMPLES:
                dirs = {"base": er.generate(old, example, tmp / "base-out" / example, tmp / "cache-base"),
                        "new": er.generate(ROOT, example, tmp / "new-out" / example, tmp / "cache-new")}
                q0 = er.default_q0(dirs["new"], example)
                grid = er._file_grid(ROOT / "symid" / "examples" / f"{example}.toml")
                row = {f"{v}_ir_instant": er.instructions(er.build(d, example, q0, grid), "traj", first, second)
                       for v, d in dirs.items()}
                if example == "slider_crank":
                    for v, d in dirs.items():
                        for label, ir in _sweep_counts(d, sources, k1, k2, steps).items():
                            row[f"{v}_ir_{label}"] = ir
                row["ratio"] = row["new_ir_instant"] / row["base_ir_instant"]
                table[example] = row
                print(f"{example:16s} {row['base_ir_instant']:8.0f} {row['new_ir_instant']:8.0f} {row['ratio']:6.3f}",
                      flush=True)
        finally:
            er.drop_old_tree(old)
    head = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"],
                          capture_output=True, text=True, check=False).stdout.strip()
    return {"base_commit": base, "new_commit": head, "flags": er.FLAGS, "quick": quick,
            "trajectory_instants": [first, second], "sweep_variants": [k1, k2], "sweep_steps": steps,
            "loadavg": list(os.getloadavg()), "examples": table}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.bookkeeping", description=__doc__.splitlines()[0])
    parser.add_argument("--base", default=BASE, help=f"the commit to compare with (default {BASE})")
    parser.add_argument("--quick", action="store_true", help="small counts (a check that it runs)")
    args = parser.parse_args(argv)
    if shutil.which("valgrind") is None or shutil.which("gcc") is None:
        print("bookkeeping: valgrind and gcc are needed", file=sys.stderr)
        return 2
    print(f"instructions per trajectory instant, base {args.base} vs this checkout, gcc {' '.join(er.FLAGS)}")
    print(f"{'example':16s} {'base':>8s} {'new':>8s} {'ratio':>6s}")
    result = measure(args.base, args.quick)
    sc = result["examples"]["slider_crank"]
    print(f"slider-crank sweep: {sc['base_ir_sweep']:.0f} -> {sc['new_ir_sweep']:.0f} instructions per instant; "
          f"plain trajectory loop {sc['base_ir_plain']:.0f} -> {sc['new_ir_plain']:.0f}")
    if args.quick:  # a check that it runs: its counts are not the figures
        return 0
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(json.dumps(result, indent=2) + "\n", encoding="utf-8")
    print(f"wrote {RESULTS.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
