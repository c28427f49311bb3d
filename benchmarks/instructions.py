"""Instructions per instant of a generated C trajectory, by callgrind: a
figure that does not depend on the machine's load (the wall-clock one of a
shared machine does).

The example's solver (as `symid solve --backend c` builds it) is linked with
a small driver that runs `<name>_trajectory` over N instants in chunks of 64;
two runs, N1 and N2 instants, and (Ir(N2) - Ir(N1)) / (N2 - N1) leaves out
loading, building the workspace and everything else done once. With
`scales` the driver sets the trajectory state's scales (the jump check's
and the conditioning screen's) as `symid solve` does after t0, so that the
count has every check a run makes; without, they stay zero (no check).
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

DRIVER = r"""
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
    study = api.prepare(api.example(example), backend="c")
    return counted(Path(study.evaluator.artifact), study.mechanism.name,  # type: ignore[attr-defined]
                   study.analysis, study.q0(), first, second, run_scales(study) if checks else ())


def run_scales(study: api.Study) -> list[float]:
    """The state's scales a `symid solve` run sets after t0 (state[6 NG] on):
    1 / each coordinate's scale, then each row's norm, from q(t0)."""
    head = api.prepare(study.mechanism, backend="c", steps=2).solve()
    at = [head.columns.index(f"{b.name}.{c}") for b in study.mechanism.bodies for c in ("x", "y", "phi")]
    scaling = study.evaluator.scaling(head.data[0, at], study.analysis.t0)  # type: ignore[attr-defined]
    return [*scaling.inv_col.tolist(), *scaling.row.tolist()]


def driver_source(name: str, a: Analysis, q0: Sequence[float], second: int, scales: Sequence[float] = ()) -> str:
    """DRIVER for the solver `name`, in one pass over its @KEY@ marks: a value
    is never read again as a mark (a name such as slider_crank_counterweight
    holds T and H, which chained replaces turned into numbers)."""
    values = {"@UPPER@": name.upper(), "@NAME@": name, "@Q0@": ", ".join(repr(float(v)) for v in q0),
              "@SCALES@": ", ".join([*(repr(float(v)) for v in scales), "0.0"]),
              "@T0@": repr(float(a.t0)), "@H@": repr((a.t1 - a.t0) / (second - 1)), "@TOL@": repr(float(a.tol))}
    return re.sub("|".join(map(re.escape, values)), lambda m: values[m.group(0)], DRIVER)


def counted(folder: Path, name: str, a: Analysis, q0: Sequence[float], first: int = 200,
            second: int = 2200, scales: Sequence[float] = ()) -> float:
    """Instructions per instant of the solver `name` built in `folder` (what
    `symid solve --backend c` leaves there), run from `q0` over `a`'s t0 to t1
    cut into `second - 1` steps: (Ir(second) - Ir(first)) / (second - first)."""
    source = driver_source(name, a, q0, second, scales)
    counts = []
    with tempfile.TemporaryDirectory() as tmp:
        driver, exe = Path(tmp) / "driver.c", Path(tmp) / "driver"
        driver.write_text(source, encoding="utf-8")
        subprocess.run(["gcc", "-O2", "-std=c99", "-fno-math-errno", "-I", str(folder), str(driver),
                        str(folder / f"{name}_solver.c"), "-o", str(exe), "-lm"], check=True)
        for n in (first, second):
            out = subprocess.run(["valgrind", "--tool=callgrind", f"--callgrind-out-file={tmp}/cg.out",
                                  str(exe), str(n)], capture_output=True, text=True, check=True)
            found = re.search(r"Collected : (\d+)", out.stderr)
            if found is None or out.stdout.split() != ["0", str(n)]:
                raise RuntimeError(f"callgrind run of {name} failed: {out.stdout} {out.stderr[-300:]}")
            counts.append(int(found.group(1)))
    return (counts[1] - counts[0]) / (second - first)
