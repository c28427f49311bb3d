"""Instructions per instant of generated C, by callgrind: a figure that does
not depend on the machine's load (the wall-clock one of a shared machine does).

Two drivers, each linked with an example's generated solver:

- `TRAJECTORY_DRIVER` (`counted`, `per_instant`): `<name>_trajectory` over N
  instants in chunks of 64; with `scales` it sets the trajectory state's
  scales (the jump check's and the conditioning screen's) as `symid solve`
  does after t0, so that the count has every check a run makes; without,
  they stay zero (no check).
- `CALLS_DRIVER` (`build`, `instructions`, `wall_us`): trajectories timed
  inside C, and `<name>_instant` called from a guess near the solution.

Two runs, N1 and N2, and (Ir(N2) - Ir(N1)) / (N2 - N1) leave out loading,
building the workspace and everything else done once.
"""

from __future__ import annotations

import re
import shutil
import subprocess
import tempfile
from pathlib import Path
from typing import Sequence

from symid import api
from symid.model.analysis import Analysis

TRAJECTORY_DRIVER = r"""
#include <stdio.h>
#include <stdlib.h>
#include "@NAME@_solver.h"

int main(int argc, char **argv)
{
    const long n = atol(argv[1]), chunk = 64;
    long done = 0, solved = 0;
    double *work = calloc(@UPPER@_WORK, sizeof(double)), *state = calloc(@UPPER@_STATE, sizeof(double));
    double *rows = calloc(chunk * @UPPER@_ROW, sizeof(double));
    int *iwork = calloc(@UPPER@_NG + 1, sizeof(int)), status = 0, k;
    const double q0[] = {@Q0@}, scales[] = {@SCALES@};
    for (k = 0; k < @UPPER@_NG; ++k) state[k] = q0[k];
    for (k = 0; k < (int)(sizeof(scales) / sizeof(double)) - 1; ++k) state[6 * @UPPER@_NG + k] = scales[k];
    while (done < n && status == 0) {
        const long m = n - done < chunk ? n - done : chunk;
        status = @NAME@_trajectory(@T0@, @H@, m, @NAME@_default_params, @TOL@, state, rows, &solved, work, iwork);
        done += solved;
    }
    printf("%d %ld\n", status, done);
    return status;
}
"""


def available() -> bool:
    """Whether valgrind and gcc are there to measure with."""
    return shutil.which("valgrind") is not None and shutil.which("gcc") is not None


def per_instant(example: str, first: int = 200, second: int = 2200, checks: bool = False) -> float:
    """Instructions per instant of the example's compiled trajectory (its own
    t0, t1 and tol, cut into `second - 1` steps so that every run is as fine);
    `checks`: with the scales of the checks set, as `symid solve` runs it."""
    return per_instant_each(example, first, second, (checks,))[0]


def per_instant_each(example: str, first: int, second: int, checks: Sequence[bool]) -> list[float]:
    """`per_instant` for each of `checks`, the solver compiled once for all."""
    study = api.prepare(api.example(example), backend="c")
    scales = run_scales(study)
    return counted_each(Path(study.evaluator.artifact), study.mechanism.name,  # type: ignore[attr-defined]
                        study.analysis, study.q0(), first, second, [scales if c else () for c in checks])


def run_scales(study: api.Study) -> list[float]:
    """The state's scales a `symid solve` run sets after t0 (state[6 NG] on):
    1 / each coordinate's scale, then each row's norm, from q(t0)."""
    head = api.prepare(study.mechanism, backend="c", steps=2).solve()
    at = [head.columns.index(f"{b.name}.{c}") for b in study.mechanism.bodies for c in ("x", "y", "phi")]
    scaling = study.evaluator.scaling(head.data[0, at], study.analysis.t0)  # type: ignore[attr-defined]
    return [*scaling.inv_col.tolist(), *scaling.row.tolist()]


def driver_source(name: str, a: Analysis, q0: Sequence[float], second: int, scales: Sequence[float] = ()) -> str:
    """TRAJECTORY_DRIVER for the solver `name`, in one pass over its @KEY@ marks: a value
    is never read again as a mark (a name such as slider_crank_counterweight
    holds T and H, which chained replaces turned into numbers)."""
    values = {"@UPPER@": name.upper(), "@NAME@": name, "@Q0@": ", ".join(repr(float(v)) for v in q0),
              "@SCALES@": ", ".join([*(repr(float(v)) for v in scales), "0.0"]),
              "@T0@": repr(float(a.t0)), "@H@": repr((a.t1 - a.t0) / (second - 1)), "@TOL@": repr(float(a.tol))}
    return re.sub("|".join(map(re.escape, values)), lambda m: values[m.group(0)], TRAJECTORY_DRIVER)


def counted(folder: Path, name: str, a: Analysis, q0: Sequence[float], first: int = 200,
            second: int = 2200, scales: Sequence[float] = ()) -> float:
    """Instructions per instant of the solver `name` built in `folder` (what
    `symid solve --backend c` leaves there), run from `q0` over `a`'s t0 to t1
    cut into `second - 1` steps: (Ir(second) - Ir(first)) / (second - first)."""
    return counted_each(folder, name, a, q0, first, second, [scales])[0]


def counted_each(folder: Path, name: str, a: Analysis, q0: Sequence[float], first: int, second: int,
                 scale_sets: Sequence[Sequence[float]]) -> list[float]:
    """`counted` for each set of scales: one driver each, the solver compiled
    once to an object they all link (each file is its own translation unit
    either way: the same machine code as compiling them together)."""
    per: list[float] = []
    with tempfile.TemporaryDirectory() as tmp:
        solver = Path(tmp) / "solver.o"
        subprocess.run(["gcc", *FLAGS, "-c", "-I", str(folder), str(folder / f"{name}_solver.c"), "-o", str(solver)],
                       check=True)
        for k, scales in enumerate(scale_sets):
            driver, exe = Path(tmp) / f"driver{k}.c", Path(tmp) / f"driver{k}"
            driver.write_text(driver_source(name, a, q0, second, scales), encoding="utf-8")
            subprocess.run(["gcc", *FLAGS, "-I", str(folder), str(driver), str(solver), "-o", str(exe), "-lm"],
                           check=True)
            counts = []
            for n in (first, second):
                out = subprocess.run(["valgrind", "--tool=callgrind", f"--callgrind-out-file={tmp}/cg.out",
                                      str(exe), str(n)], capture_output=True, text=True, check=True)
                found = re.search(r"Collected : (\d+)", out.stderr)
                if found is None or out.stdout.split() != ["0", str(n)]:
                    raise RuntimeError(f"callgrind run of {name} failed: {out.stdout} {out.stderr[-300:]}")
                counts.append(int(found.group(1)))
            per.append((counts[1] - counts[0]) / (second - first))
    return per


FLAGS = ["-O2", "-std=c99", "-fno-math-errno"]

# The driver of `build`. Modes: "traj N R" runs R trajectories of N instants
# over [T0, T1] (the check's scales zero) and prints the status, the instants
# and ns per instant; "inst M" solves M instants from the same guess near the
# solution and prints the status, the calls, the last call's Newton
# iterations and how far its q is from the trajectory's.
CALLS_DRIVER = r"""
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include "NAME_solver.h"

static const double q0[] = {Q0};

static int run(long n, double h, double *state, double *rows, double *work, int *iwork, long *done)
{
    const long chunk = 64;
    long solved = 0;
    int status = 0, k;
    memset(state, 0, sizeof(double) * UPPER_STATE);
    for (k = 0; k < UPPER_NG; ++k) state[k] = q0[k];
    *done = 0;
    while (*done < n && status == 0) {
        const long m = n - *done < chunk ? n - *done : chunk;
        status = NAME_trajectory(T0, h, m, NAME_default_params, TOL, state, rows, &solved, work, iwork);
        *done += solved;
    }
    return status;
}

int main(int argc, char **argv)
{
    const long n = atol(argv[2]);
    const long reps = argc > 3 ? atol(argv[3]) : 1;
    double *work = calloc(UPPER_WORK, sizeof(double)), *state = calloc(UPPER_STATE, sizeof(double));
    double *rows = calloc(64 * UPPER_ROW, sizeof(double));
    int *iwork = calloc(UPPER_NG + 1, sizeof(int)), status = 0;
    long done = 0, r;
    if (strcmp(argv[1], "traj") == 0) {
        struct timespec a, b;
        const double h = (T1 - T0) / (double)(n - 1);
        clock_gettime(CLOCK_MONOTONIC, &a);
        for (r = 0; r < reps && status == 0; ++r) status = run(n, h, state, rows, work, iwork, &done);
        clock_gettime(CLOCK_MONOTONIC, &b);
        printf("%d %ld %.17g\n", status, done,
               ((double)(b.tv_sec - a.tv_sec) * 1e9 + (double)(b.tv_nsec - a.tv_nsec)) / (double)(reps * n));
    } else {
        /* The solution at the instant nearest t1/3 of a 301-instant run, moved by 1e-6. */
        const long k3 = 100;
        const double h = (T1 - T0) / 300.0, t = T0 + (double)k3 * h;
        double guess[UPPER_NG], q[UPPER_NG], qd[UPPER_NG], qdd[UPPER_NG], lam[UPPER_NC], re[UPPER_NR + 1];
        int info[2], k;
        status = run(k3 + 1, h, state, rows, work, iwork, &done);
        for (k = 0; k < UPPER_NG; ++k) guess[k] = rows[((k3 % 64) * UPPER_ROW) + 1 + k] * (1.0 + 1e-6) + 1e-6;
        for (r = 0; r < n && status == 0; ++r) {
            memcpy(q, guess, sizeof q);
            status = NAME_instant(t, NAME_default_params, TOL, q, qd, qdd, lam, re, info, work, iwork);
        }
        done = r;
        {   /* how far the instant's q is from the trajectory's: both solve the same instant */
            double far = 0.0;
            for (k = 0; k < UPPER_NG; ++k) {
                const double d = q[k] - rows[((k3 % 64) * UPPER_ROW) + 1 + k];
                far = d > far ? d : (-d > far ? -d : far);
            }
            printf("%d %ld %d %.3g\n", status, done, info[0], far);
        }
    }
    return status;
}
"""


def _run(cmd: list[str], **kw: object) -> subprocess.CompletedProcess[str]:
    return subprocess.run(cmd, capture_output=True, text=True, check=True, **kw)  # type: ignore[call-overload]


def file_grid(toml: Path) -> tuple[float, float, float]:
    """t0, t1 and tol of the file's [analysis] (tol 1e-12 when absent)."""
    import tomllib
    a = tomllib.loads(toml.read_text(encoding="utf-8"))["analysis"]
    return float(a["t0"]), float(a["t1"]), float(a.get("tol", 1e-12))


def build(folder: Path, name: str, q0: str, grid: tuple[float, float, float]) -> Path:
    """The driver linked with the solver in folder."""
    t0, t1, tol = grid
    source = (CALLS_DRIVER.replace("UPPER", name.upper()).replace("NAME", name).replace("Q0", q0)
              .replace("T0", repr(t0)).replace("T1", repr(t1)).replace("TOL", repr(tol)))
    (folder / "driver.c").write_text(source, encoding="utf-8")
    exe = folder / "driver"
    _run(["gcc", *FLAGS, "-I", str(folder), str(folder / "driver.c"), str(folder / f"{name}_solver.c"),
          "-o", str(exe), "-lm"])
    return exe


def default_q0(folder: Path, name: str) -> str:
    """The header's assembled q0 (`<name>_default_q0`), as C initializer text."""
    text = (folder / f"{name}_solver.c").read_text(encoding="utf-8")
    found = re.search(rf"{name}_default_q0\[[^\]]*\] = \{{([^}}]*)\}}", text)
    if found is None:
        raise RuntimeError(f"{name}: no default_q0 in the solver")
    return found.group(1).strip()


def instructions(exe: Path, mode: str, first: int, second: int) -> float:
    """Callgrind instructions per unit of mode, from two runs."""
    counts = []
    for n in (first, second):
        out = _run(["valgrind", "--tool=callgrind", f"--callgrind-out-file={exe.parent}/cg.out",
                    str(exe), mode, str(n)])
        found = re.search(r"Collected : (\d+)", out.stderr)
        words = out.stdout.split()
        if found is None or words[:2] != ["0", str(n)]:
            raise RuntimeError(f"callgrind run of {exe} failed: {out.stdout} {out.stderr[-300:]}")
        counts.append(int(found.group(1)))
    return (counts[1] - counts[0]) / (second - first)


def wall_us(exe: Path, n: int, reps: int) -> float:
    """Microseconds per trajectory instant of one timed run."""
    out = _run([str(exe), "traj", str(n), str(reps)]).stdout.split()
    if out[0] != "0":
        raise RuntimeError(f"{exe}: status {out[0]}")
    return float(out[2]) / 1e3


