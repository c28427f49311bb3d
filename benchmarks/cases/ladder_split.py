"""Where an instant of the ladder's compiled trajectory goes: each part timed alone.

The ladder of N four-bars (benchmarks/ladder.py) is built as `symid solve
--backend c` builds it (the cache's source and flags); a harness appended to
that source runs the trajectory for a few instants (so that work holds the
factors, sines and bases of a solved configuration), then times each part an
instant calls, alone in a loop (best of 5 rounds): the factorization, the
three solves and the transposed one (the sparse LU: chains of dependent
operations along the ladder, so their time is latency, not work), the
kernels (Phi twice, Phi_q, nu, gamma, applied, mass, reactions) and the
sines and cosines; and the whole trajectory's us per instant in the same
process. Per instant: each part times the number of calls an instant makes;
what the parts leave of the whole is the O(NG) bookkeeping (predictor,
correction, checks) and the writing of the rows.

The LU's time bounds the flop rate from above whatever else gets faster:
`floor_gflops` is the instant's flops (benchmarks/scale.py's count) over
the LU's time alone.

    python -m benchmarks ladder_split                 # N = 512
    python -m benchmarks ladder_split --ladders 64 512
"""

from __future__ import annotations

import json
import subprocess
import tempfile
from pathlib import Path
from typing import Any

from benchmarks import ladder
from benchmarks.cases import register, scale
from benchmarks.run import Context

# part -> (C statement timed, calls per instant)
PARTS = {
    "factor": ("(memcpy(lu, saved, sizeof saved), P_sparse_factor(lu))", 1),
    "solve": ("(memcpy(y, rhs, sizeof rhs), P_sparse_solve_in(lu, y, x))", 3),
    "solve_t": ("P_sparse_solve_t(lu, rhs, x)", 1),
    "phi": ("P_phi_k(q, tr, t, pp, b)", 2),
    "phi_q": ("P_phi_q_k(q, tr, t, pp, lu)", 1),
    "nu": ("P_nu_k(q, tr, t, pp, b)", 1),
    "gamma": ("P_gamma_k(q, tr, qd, t, pp, b)", 1),
    "applied": ("P_applied_k(q, tr, qd, t, pp, b)", 1),
    "mass": ("P_mass_k(pp, b)", 1),
    "reactions": ("P_reactions_k(q, tr, lam, t, pp, reac)", 1),
    "trig_near": ("P_trig_near(q, tr, base)", 1),
    "copy_phi_q": ("memcpy(lu, saved, sizeof saved)", -1),  # taken off factor
    "copy_rhs": ("memcpy(y, rhs, sizeof rhs)", -3),  # taken off the solves
}
LU = ("factor", "solve", "solve_t", "copy_phi_q", "copy_rhs")
HARNESS = r"""
#include <stdio.h>
#include <time.h>
static double hn_now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return t.tv_sec + 1e-9 * t.tv_nsec;
}
#define HN_TIME(label, stmt) do { double best = 1e30; int r, k; for (r = 0; r < 5; ++r) { double t0 = hn_now(); \
    for (k = 0; k < reps; ++k) { stmt; } t0 = (hn_now() - t0) / reps * 1e6; if (t0 < best) best = t0; } \
    printf("%s %.4f\n", label, best); } while (0)
static double hn_work[WORK], hn_state[STATE], hn_rows[64 * ROW], saved[P_LU_SIZE_], rhs[P_NG_];
static int hn_iwork[P_NG_ + 1];
int main(void)
{
    double *work = hn_work, *lu = work + P_OFF_LU_, *pp = work + P_OFF_PREP_, *tr = P_VEC_(work, 9);
    double *y = P_VEC_(work, 0), *x = P_VEC_(work, 1), *b = P_VEC_(work, 3), *qd = P_VEC_(work, 5);
    double *lam = P_VEC_(work, 7), *reac = P_VEC_(work, 8), *base = P_VEC_(work, 10), *q = hn_state;
    const double h = 1.0 / 1000, t = 20 * h;
    const int reps = REPS;
    long solved, done = 0;
    int k, round;
    double best = 1e30;
    memcpy(hn_state, P_default_q0, sizeof(double) * P_NG_);
    if (P_trajectory(0.0, h, 20, P_default_params, 1e-12, hn_state, hn_rows, &solved, work, hn_iwork) != 0) return 3;
    for (round = 0; round < 5; ++round) {  /* the whole instant, in chunks of 64 as symid runs it */
        double t0 = hn_now();
        for (done = 0; done < INSTANTS; done += 64)
            if (P_trajectory(0.0, h, 64, P_default_params, 1e-12, hn_state, hn_rows, &solved, work, hn_iwork) != 0) return 3;
        t0 = (hn_now() - t0) / done * 1e6;
        if (t0 < best) best = t0;
    }
    printf("instant %.4f\n", best);
    for (k = 0; k < P_NG_; ++k) rhs[k] = 1e-3 * (k % 7 - 3);
    P_phi_q_k(q, tr, t, pp, lu);
    memcpy(saved, lu, sizeof saved);
    (void)x; (void)b; (void)qd; (void)lam; (void)reac; (void)base; (void)y;
PARTS
    return 0;
}
"""


def measure(n: int, reps: int, instants: int) -> dict[str, Any]:
    """The split of ladder n's instant (us per instant per part)."""
    from symid import api
    from symid.backends import c_backend
    with tempfile.TemporaryDirectory(prefix="symid-split-") as tmp:
        folder = Path(tmp)
        study = api.prepare(ladder.write(n, folder, steps=1001), backend="c")
        built = Path(study.evaluator.artifact)  # type: ignore[attr-defined]
        p = ladder.name(n)
        meta = json.loads((built / "meta.json").read_text())
        source = (built / f"{p}_solver.c").read_text()
        parts = "\n".join(f'    HN_TIME("{k}", {stmt.replace("P_", p + "_")});' for k, (stmt, _) in PARTS.items())
        P = p.upper()
        harness = (HARNESS.replace("PARTS", parts).replace("WORK", str(meta["work"])).replace("STATE", str(meta["state"]))
                   .replace("64 * ROW", f"64 * {meta['row']}").replace("REPS", str(reps))
                   .replace("INSTANTS", str(instants)).replace("P_LU_SIZE_", f"{P}_LU_SIZE").replace("P_NG_", f"{P}_NG")
                   .replace("P_OFF_LU_", f"{P}_OFF_LU").replace("P_OFF_PREP_", f"{P}_OFF_PREP")
                   .replace("P_VEC_", f"{P}_VEC").replace("P_", p + "_"))
        main = folder / "split.c"
        main.write_text("#define _POSIX_C_SOURCE 199309L\n" + source + harness)
        level = c_backend.level(len(source.encode()), batch=False)  # as the cache compiles it
        subprocess.run(["gcc", level, "-std=c99", "-fno-math-errno", "-I", str(built), str(main),
                        "-o", str(folder / "split"), "-lm"], check=True)
        out = subprocess.run([str(folder / "split")], capture_output=True, text=True, check=True).stdout
    alone = {line.split()[0]: float(line.split()[1]) for line in out.splitlines()}
    per = {k: round(alone[k] * calls, 3) for k, (_, calls) in PARTS.items()}
    lu = sum(per[k] for k in LU)
    kernels = sum(per[k] for k in ("phi", "phi_q", "nu", "gamma", "applied", "mass", "reactions"))
    flops = scale.count_flops(source, p)
    return {"n": n, "ng": meta["ng"], "us_per_instant": alone["instant"], "per_instant_us": per,
            "lu_us": round(lu, 2), "kernels_us": round(kernels, 2), "trig_us": per["trig_near"],
            "rest_us": round(alone["instant"] - lu - kernels - per["trig_near"], 2),
            "flops_per_instant": flops, "gflops": round(flops / (alone["instant"] * 1e3), 3),
            "floor_gflops": round(flops / (lu * 1e3), 3)}


def _options(group: Any) -> None:
    group.add_argument("--ladders", type=int, nargs="+", default=[512])
    group.add_argument("--reps", type=int, default=400, help="calls per timed round of a part")
    group.add_argument("--instants", type=int, default=640, help="instants per timed round of the trajectory")


@register("ladder_split", "where an instant of the ladder's compiled trajectory goes: the LU, the kernels, the "
          "sines, the rest, each timed alone", options=_options, tools=("gcc",))
def ladder_split(ctx: Context) -> dict[str, Any]:
    args = ctx.options
    ladders, reps, instants = ((2,), 5, 64) if ctx.smoke else (args.ladders, args.reps, args.instants)
    rows = []
    for n in ladders:
        row = measure(n, reps, instants)
        rows.append(row)
        ctx.log(f"ladder {n:5d} ng {row['ng']:5d}  {row['us_per_instant']:.2f} us/instant: LU {row['lu_us']:.2f} us, "
                f"kernels {row['kernels_us']:.2f}, trig {row['trig_us']:.2f}, rest {row['rest_us']:.2f}")
    return {"rows": rows}
