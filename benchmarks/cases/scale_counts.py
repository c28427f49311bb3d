"""Counts for benchmarks/scale.py that do not depend on the machine's load.

- vector_flops: the floating-point operations of an instant's O(NG) vector
  work, which the count of the generated kernels and LU (scale.count_flops)
  leaves out but the instant does all the same: the predictor, the Newton
  correction and its step size, the residual's size, the check that the
  motion is explained, the mass term, the angles' rotations and the
  finiteness check of every output. Written from solver.c.j2 (per value:
  + - * each count one; comparisons and fabs none).
- instructions_per_instant: callgrind's count of the compiled trajectory,
  from two runs of different length (their difference leaves out loading
  and the first instant). libc's memcpy is counted as valgrind counts
  `rep movsb`, per byte moved, which overstates it.
"""

from __future__ import annotations

import re
import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np

# per coordinate: predictor (Taylor to h^5: 6 mul, 5 add), correct (2 sub),
# unexplained (4 add or sub, 3 mul, the scale once: the motion's product only
# past the mismatch's floor), mass term (mul, sub), the finite check of q, qd,
# qdd (1 add each: the exact test only when the sum is not finite), maxabs of
# q and dq (1 add each)
PER_COORD = 11 + 2 + 8 + 2 + 3 + 2
PER_ROW = 1 + 1  # maxabs of the residual; the finite check of lambda
PER_REACTION = 1  # the finite check
# trig_near (the angle's change, its square, sin d and cos d - 1 by their
# series: 9 and 7, the rotation: 6) and trig_step (2 products and sums, a sign)
PER_BODY = 2 + 9 + 7 + 6 + 5


def vector_flops(ng: int, nc: int, nr: int, nb: int) -> int:
    """Floating-point operations of an instant's vector work (see the module's docstring)."""
    return PER_COORD * ng + PER_ROW * nc + PER_REACTION * nr + PER_BODY * nb


DRIVER = r"""
#include <dlfcn.h>
#include <stdio.h>
#include <stdlib.h>
typedef int (*traj_t)(double, double, long, const double *, double, double *, double *, long *, double *, int *);
int main(int argc, char **argv)
{
    const long n = atol(argv[3]), chunk = 64, ng = atol(argv[4]);
    void *lib = dlopen(argv[1], RTLD_NOW);
    char sym[256];
    long done = 0, solved = 0, k;
    int status = 0;
    double *work, *state, *rows, *q0;
    int *iwork;
    traj_t traj;
    const double *p;
    FILE *f;
    if (lib == NULL) return 9;
    snprintf(sym, sizeof sym, "%s_trajectory", argv[2]);
    traj = (traj_t)dlsym(lib, sym);
    snprintf(sym, sizeof sym, "%s_default_params", argv[2]);
    p = (const double *)dlsym(lib, sym);
    work = calloc(atol(argv[5]), sizeof(double));
    state = calloc(atol(argv[6]), sizeof(double));
    rows = calloc(chunk * atol(argv[7]), sizeof(double));
    iwork = calloc(ng + 1, sizeof(int));
    q0 = calloc(ng, sizeof(double));
    f = fopen(argv[8], "rb");
    if (f == NULL || fread(q0, sizeof(double), ng, f) != (size_t)ng) return 8;
    fclose(f);
    for (k = 0; k < ng; ++k) state[k] = q0[k];
    while (done < n && status == 0) {
        const long m = n - done < chunk ? n - done : chunk;
        status = traj(atof(argv[9]), atof(argv[10]), m, p, atof(argv[11]), state, rows, &solved, work, iwork);
        done += solved;
    }
    printf("%d %ld\n", status, done);
    return status;
}
"""


def available() -> bool:
    """Whether valgrind and gcc are there to count with."""
    return shutil.which("valgrind") is not None and shutil.which("gcc") is not None


def instructions_per_instant(so: Path, name: str, sizes: dict[str, int], q0: np.ndarray, t0: float, h: float,
                             tol: float, first: int = 20, second: int = 120) -> float:
    """Instructions per instant of `<name>_trajectory` in the built solver
    `so` (sizes: its work, state and row lengths), from q0 at t0 by steps h."""
    counts = []
    with tempfile.TemporaryDirectory() as tmp:
        driver, exe, qfile = Path(tmp) / "driver.c", Path(tmp) / "driver", Path(tmp) / "q0.bin"
        driver.write_text(DRIVER, encoding="utf-8")
        np.asarray(q0, dtype=np.float64).tofile(qfile)
        subprocess.run(["gcc", "-O2", str(driver), "-o", str(exe), "-ldl"], check=True)
        for n in (first, second):
            args = [str(so), name, str(n), str(len(q0)), str(sizes["work"]), str(sizes["state"]), str(sizes["row"]),
                    str(qfile), repr(t0), repr(h), repr(tol)]
            out = subprocess.run(["valgrind", "--tool=callgrind", f"--callgrind-out-file={tmp}/cg.out", str(exe),
                                  *args], capture_output=True, text=True)
            found = re.search(r"Collected : (\d+)", out.stderr)
            if found is None or out.stdout.split() != ["0", str(n)]:
                raise RuntimeError(f"callgrind run of {name} failed: {out.stdout} {out.stderr[-300:]}")
            counts.append(int(found.group(1)))
    return (counts[1] - counts[0]) / (second - first)
