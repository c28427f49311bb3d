"""Issue 19's last target: no example's instant slower in double precision
than before the issue's work (commit 70f3024, the parent of its first
change), measured against the code of this checkout.

Both versions' double-precision C solvers are generated here (`symid
generate FILE --target c`, each version's own code: the old one from a
temporary detached worktree of 70f3024) and linked with one driver:

- instructions per trajectory instant by callgrind, (Ir(N2) - Ir(N1)) /
  (N2 - N1) as benchmarks/instructions.py does (load-independent);
- instructions per `_instant` call from a guess near the solution (the
  solution at t1/3 moved by 1e-6), by the same difference of two runs;
- wall clock, us per trajectory instant, old and new interleaved over
  several rounds (medians; the machine is shared, so the load average is
  printed beside it and the ratio is the figure to read).

Each version's p is its own header's `default_params` (the file's values in
its own parameter order: the old one holds derived parameters as inputs,
the new one only base ones); q0 is the assembled configuration of the file
(the new header's `default_q0`), the same for both. The jump check's scales
are zero in both, as in benchmarks/instructions.py: both versions run the
check at every step whatever its scales (measured with unit scales: the same
Ir per instant to 1 in 2000), so this is the cost symid's c backend pays too.

    python -m benchmarks.embedded_regression [--quick] [--rounds R]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

OLD_COMMIT = "70f3024"
EXAMPLES = ("excavator", "four_bar", "planetary", "quick_return", "slider_crank", "slider_pendulum")
ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "benchmarks" / "results" / "embedded_regression.json"
FLAGS = ["-O2", "-std=c99", "-fno-math-errno"]

# One driver for both versions (their real type is double; the old header
# names it `double` directly). Modes: "traj N R" runs R trajectories of N
# instants over [T0, T1]; "inst M" solves M instants from the same guess.
DRIVER = r"""
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


def old_tree(tmp: Path) -> Path:
    """A detached worktree of OLD_COMMIT under tmp (removed by `drop_old_tree`)."""
    where = tmp / "old"
    _run(["git", "-C", str(ROOT), "worktree", "add", "--detach", str(where), OLD_COMMIT])
    return where


def drop_old_tree(where: Path) -> None:
    """Remove the temporary worktree (and its registration)."""
    subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(where)],
                   capture_output=True, check=False)


def generate(tree: Path, example: str, out: Path, cache: Path) -> Path:
    """The example's double-precision C solver by `tree`'s own symid."""
    env = dict(os.environ, PYTHONPATH=str(tree), SYMID_CACHE=str(cache))
    # symid is installed editable from another checkout: make sure `tree`'s own is the one run.
    where = _run([sys.executable, "-c", "import symid; print(symid.__file__)"], env=env, cwd=str(tree))
    if not Path(where.stdout.strip()).resolve().is_relative_to(tree.resolve()):
        raise RuntimeError(f"symid of {tree} not first on the path: {where.stdout.strip()}")
    _run([sys.executable, "-m", "symid", "generate", str(tree / "symid" / "examples" / f"{example}.toml"),
          "--target", "c", "-o", str(out)], env=env, cwd=str(tree))
    return out


def _file_grid(toml: Path) -> tuple[float, float, float]:
    """t0, t1 and tol of the file's [analysis] (tol 1e-12 when absent)."""
    import tomllib
    a = tomllib.loads(toml.read_text(encoding="utf-8"))["analysis"]
    return float(a["t0"]), float(a["t1"]), float(a.get("tol", 1e-12))


def build(folder: Path, name: str, q0: str, grid: tuple[float, float, float]) -> Path:
    """The driver linked with the solver in folder."""
    t0, t1, tol = grid
    source = (DRIVER.replace("UPPER", name.upper()).replace("NAME", name).replace("Q0", q0)
              .replace("T0", repr(t0)).replace("T1", repr(t1)).replace("TOL", repr(tol)))
    (folder / "driver.c").write_text(source, encoding="utf-8")
    exe = folder / "driver"
    _run(["gcc", *FLAGS, "-I", str(folder), str(folder / "driver.c"), str(folder / f"{name}_solver.c"),
          "-o", str(exe), "-lm"])
    return exe


def default_q0(folder: Path, name: str) -> str:
    """The new header's assembled q0, as C initializer text."""
    text = (folder / f"{name}_solver.c").read_text(encoding="utf-8")
    found = re.search(rf"{name}_default_q0\[[^\]]*\] = \{{([^}}]*)\}}", text)
    if found is None:
        raise RuntimeError(f"{name}: no default_q0 in the new solver")
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


def measure(quick: bool, rounds: int) -> dict[str, object]:
    """Every example's figures, old and new."""
    first, second = (100, 400) if quick else (200, 2200)
    inst = (20, 120) if quick else (50, 550)
    n_wall, reps = (501, 4) if quick else (2001, 100)
    table: dict[str, dict[str, float]] = {}
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        old = old_tree(tmp)
        try:
            for example in EXAMPLES:
                new_dir = generate(ROOT, example, tmp / "new" / example, tmp / "cache-new")
                old_dir = generate(old, example, tmp / "old70" / example, tmp / "cache-old")
                q0 = default_q0(new_dir, example)
                grid = _file_grid(ROOT / "symid" / "examples" / f"{example}.toml")
                exes = {v: build(d, example, q0, grid) for v, d in (("old", old_dir), ("new", new_dir))}
                row: dict[str, float] = {}
                for v, exe in exes.items():
                    row[f"{v}_ir_instant"] = instructions(exe, "traj", first, second)
                    row[f"{v}_ir_call"] = instructions(exe, "inst", *inst)
                    # the call's Newton iterations: the same in both, or the Ir compare unlike work
                    row[f"{v}_call_iterations"] = int(_run([str(exe), "inst", "1"]).stdout.split()[2])
                walls: dict[str, list[float]] = {"old": [], "new": []}
                for _ in range(rounds):
                    for v in ("old", "new"):
                        walls[v].append(wall_us(exes[v], n_wall, reps))
                for v in ("old", "new"):
                    row[f"{v}_us_instant"] = statistics.median(walls[v])
                row["ir_ratio"] = row["new_ir_instant"] / row["old_ir_instant"]
                row["call_ratio"] = row["new_ir_call"] / row["old_ir_call"]
                row["wall_ratio"] = statistics.median(n / o for n, o in zip(walls["new"], walls["old"]))
                table[example] = row
                print(f"{example:16s} {row['old_ir_instant']:9.0f} {row['new_ir_instant']:9.0f} "
                      f"{row['ir_ratio']:6.3f}  {row['old_ir_call']:9.0f} {row['new_ir_call']:9.0f} "
                      f"{row['call_ratio']:6.3f}  {row['old_us_instant']:7.2f} {row['new_us_instant']:7.2f} "
                      f"{row['wall_ratio']:6.3f}", flush=True)
        finally:
            drop_old_tree(old)
    head = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"],
                          capture_output=True, text=True, check=False).stdout.strip()
    return {"old_commit": OLD_COMMIT, "new_commit": head, "flags": FLAGS, "quick": quick,
            "rounds": rounds, "loadavg": list(os.getloadavg()),
            "trajectory_instants": [first, second], "instant_calls": list(inst),
            "wall_instants_x_reps": [n_wall, reps], "examples": table}


def main(argv: list[str] | None = None) -> int:
    """Print the table and write the JSON."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small counts (a check that it runs)")
    parser.add_argument("--rounds", type=int, default=7, help="interleaved wall-clock rounds")
    args = parser.parse_args(argv)
    if shutil.which("valgrind") is None or shutil.which("gcc") is None:
        print("embedded_regression: valgrind and gcc are needed", file=sys.stderr)
        return 2
    print(f"load average {os.getloadavg()[0]:.2f}; old = {OLD_COMMIT}, gcc {' '.join(FLAGS)}")
    print(f"{'example':16s} {'Ir/inst':>9s} {'(new)':>9s} {'ratio':>6s}  {'Ir/call':>9s} {'(new)':>9s} "
          f"{'ratio':>6s}  {'us/inst':>7s} {'(new)':>7s} {'ratio':>6s}")
    result = measure(args.quick, args.rounds)
    print(f"load average after: {result['loadavg']}")
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(json.dumps(result, indent=2) + "\n", encoding="utf-8")
    print(f"wrote {RESULTS.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
