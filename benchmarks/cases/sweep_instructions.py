"""Instructions per instant of the compiled sweep against the plain
trajectory loop, by callgrind (a figure that the machine's load does not
move): the issue-14 grid's first K variants (rod length x crank speed) of the
slider-crank, each 1001 instants, once through `<name>_sweep` (figures
accumulated in C; its variants side by side in SIMD lanes), once through the
same sweep compiled with `<NAME>_NO_LANES` (one variant at a time, the same
figures bit for bit), and once through `<name>_trajectory` variant by variant
in chunks of 64 rows (what `symid solve` runs, no figures). Two sizes K1 < K2
(multiples of the lanes) and (Ir(K2) - Ir(K1)) / ((K2 - K1) instants) leave
out loading and setup. A lane's instruction does the work of several
variants: its count is not comparable with a scalar one as time is. Part of
the overview's design study (`design_study.py`).
"""

from __future__ import annotations

import re
import shutil
import subprocess
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

COMMON = r"""
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "NAME_solver.h"

static const double PARAMS[] = {@PARAMS@};   /* K variants x NP */
static const double Q0[] = {@Q0@};          /* K variants x NG */
"""

SWEEP = COMMON + r"""
int main(int argc, char **argv)
{
    const long k = atol(argv[1]), n = atol(argv[2]);
    double *work = calloc(UPPER_SWEEP_WORK, sizeof(double)), *fig = calloc(k * UPPER_SWEEP_FIGURES + 1, sizeof(double));
    double *t_end = calloc(k, sizeof(double));
    int *iwork = calloc(UPPER_NG + 1, sizeof(int)), *status = calloc(k, sizeof(int));
    long *solved = calloc(k, sizeof(long)), v, total = 0;
    NAME_sweep(k, PARAMS, @T0@, @H@, n, @TOL@, fig, status, t_end, solved, work, iwork);
    for (v = 0; v < k; ++v) total += status[v] ? -1 : solved[v];
    printf("%ld\n", total);
    return 0;
}
"""

PLAIN = COMMON + r"""
int main(int argc, char **argv)
{
    const long k = atol(argv[1]), n = atol(argv[2]), chunk = 64;
    double *work = calloc(UPPER_WORK, sizeof(double)), *state = calloc(UPPER_STATE, sizeof(double));
    double *rows = calloc(chunk * UPPER_ROW, sizeof(double));
    int *iwork = calloc(UPPER_NG + 1, sizeof(int)), status = 0;
    long v, total = 0;
    for (v = 0; v < k; ++v) {
        long done = 0, solved = 0;
        memset(state, 0, sizeof(double) * UPPER_STATE);
        memcpy(state, Q0 + v * UPPER_NG, sizeof(double) * UPPER_NG);
        status = 0;
        while (done < n && status == 0) {
            const long m = n - done < chunk ? n - done : chunk;
            status = NAME_trajectory(@T0@, @H@, m, PARAMS + v * UPPER_NP, @TOL@, state, rows, &solved, work, iwork);
            done += solved;
        }
        total += status ? -1 : done;
    }
    printf("%ld\n", total);
    return 0;
}
"""


def _grid(k: int) -> np.ndarray:
    rods, speeds = np.linspace(0.2, 0.5, 25), np.linspace(1.0, 10.0, 40)
    return np.array([(r, s) for r in rods for s in speeds])[:k]


def available() -> bool:
    """Whether valgrind and gcc are there to measure with."""
    return shutil.which("valgrind") is not None and shutil.which("gcc") is not None


def per_instant(k1: int = 4, k2: int = 12, steps: int = 1001) -> dict[str, Any]:
    """Instructions per instant of the sweep and of the plain loop, and their ratio."""
    import sympy as sp

    from symid import api
    from symid.backends.c_backend import build
    from symid.codegen.model import options_for
    from symid.study.variants import base_matrix, study_mechanism, variant_values
    from symid.symbolic.assemble import assemble

    mech = study_mechanism(api.load_mechanism(api.example("slider_crank"), steps=steps))
    folder = build(assemble(mech), options_for(mech))
    full = base_matrix(mech, ("L_rod", "n"), _grid(k2))
    q0 = [float(sp.sympify(x).subs(variant_values(mech, row))) for row in full for b in mech.bodies for x in b.q0]
    a = mech.analysis
    name = mech.name
    text = {"@T0@": repr(float(a.t0)), "@H@": repr((a.t1 - a.t0) / (steps - 1)), "@TOL@": repr(float(a.tol)),
            "@PARAMS@": ", ".join(repr(float(v)) for v in full.ravel()), "@Q0@": ", ".join(map(repr, q0))}
    out: dict[str, Any] = {"variants": [k1, k2], "steps": steps}
    with tempfile.TemporaryDirectory() as tmp:
        for label, source, flags in (("sweep", SWEEP, []), ("sweep_scalar", SWEEP, [f"-D{name.upper()}_NO_LANES"]),
                                     ("plain", PLAIN, [])):
            for key, value in text.items():
                source = source.replace(key, value)
            source = source.replace("UPPER", name.upper()).replace("NAME", name)
            driver, exe = Path(tmp) / f"{label}.c", Path(tmp) / label
            driver.write_text(source, encoding="utf-8")
            subprocess.run(["gcc", "-O2", "-std=c99", "-fno-math-errno", *flags, "-I", str(folder), str(driver),
                            str(folder / f"{name}_solver.c"), "-o", str(exe), "-lm"], check=True)
            counts = []
            for k in (k1, k2):
                run = subprocess.run(["valgrind", "--tool=callgrind", f"--callgrind-out-file={tmp}/cg.out",
                                      str(exe), str(k), str(steps)], capture_output=True, text=True, check=True)
                found = re.search(r"Collected : (\d+)", run.stderr)
                if found is None or run.stdout.split() != [str(k * steps)]:
                    raise RuntimeError(f"callgrind run of the {label} driver failed: {run.stdout} {run.stderr[-300:]}")
                counts.append(int(found.group(1)))
            out[f"{label}_instructions_per_instant"] = (counts[1] - counts[0]) / ((k2 - k1) * steps)
    out["sweep_over_plain"] = out["sweep_instructions_per_instant"] / out["plain_instructions_per_instant"]
    out["lanes_over_scalar"] = out["sweep_instructions_per_instant"] / out["sweep_scalar_instructions_per_instant"]
    return out
