"""Output at solver speed (#17): the slider-crank's table through a whole `symid solve`.

    python -m benchmarks output [--instants 1000000]

For each of .csv, .npz and .parquet, one `symid solve --backend c` process
writes N instants (67 columns); its wall time and peak memory (max RSS,
from wait4) are measured, and MB/s is the file's size over the whole run.
CPU seconds (user + system) are given beside wall seconds: on a shared
machine the wall time measures the neighbours as much as symid. The
baseline is `numpy.savetxt(fmt='%.17g', delimiter=',')` of the same
array (read back from the .npz), timed alone in the same run (and its
MB/s); its text must equal the CSV's rows byte for byte. The CSV is
formatted by the compiled formatter (`symid.output.compiled_csv`; the
figures say which formatter ran). The solver alone (the blocks of `Study.blocks`,
nothing written) gives the share that is not output. Targets: the CSV run
in at most half savetxt's time, the .npz run in <= 200 MB.
"""

from __future__ import annotations

import hashlib
import os
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks.cases import register
from benchmarks.run import Context
from symid import api
from symid.output.compiled_csv import BUILD_AT, formatter

MB = 1e6


def run_solve(ctx: Context, example: str, steps: int, out: Path) -> dict[str, float]:
    """One `symid solve` process: wall seconds, CPU seconds, max RSS in MB, file MB and MB/s."""
    got = ctx.process([sys.executable, "-m", "symid", "solve", example, "--backend", "c", "--steps", str(steps),
                       "-o", str(out)], 3600.0, ctx.env(ctx.work / "cache"))
    if got.status != 0:
        raise RuntimeError(f"symid solve -o {out.name} failed with status {got.status}")
    size = out.stat().st_size / MB
    return {"seconds": got.wall_s, "cpu_seconds": got.cpu_s or 0.0, "max_rss_mb": got.peak_rss_mb or 0.0,
            "file_mb": size, "mb_per_s": size / got.wall_s}


def solver_only(example: str, steps: int) -> float:
    """Seconds to solve every instant through `Study.blocks` (setup excluded, nothing written)."""
    study = api.prepare(example, "c", steps=steps)
    start = time.perf_counter()
    for _ in study.blocks():
        pass
    return time.perf_counter() - start


def digest(path: Path, skip_line: bool) -> str:
    """sha256 of a file's bytes, after its first line if skip_line."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        if skip_line:
            f.readline()
        for piece in iter(lambda: f.read(1 << 22), b""):
            h.update(piece)
    return h.hexdigest()


def _options(group: Any) -> None:
    group.add_argument("--instants", type=int, default=1_000_000)


@register("output", "the slider-crank's table through a whole `symid solve` to CSV, NPZ and Parquet: time, CPU, "
          "memory, MB/s, against numpy.savetxt", options=_options, tools=("gcc",))
def output(ctx: Context) -> dict[str, Any]:
    instants = 2001 if ctx.smoke else ctx.options.instants
    example = str(api.example("slider_crank"))
    folder = ctx.work
    # the same command first: the compiled solver is built and the run's plan
    # kept, so every timed run takes the planned path (no sympy) alike (not in a
    # smoke run, whose times mean nothing: its CSV run builds them, the others plan)
    if not ctx.smoke:
        run_solve(ctx, example, instants, folder / "warm.npz")
        (folder / "warm.npz").unlink()
    figures: dict[str, Any] = {"instants": instants, "columns": 67, "mechanism": "slider_crank",
                               "backend": "c", "cpu_count": os.cpu_count()}
    figures["csv_formatter"] = "compiled" if formatter(BUILD_AT) is not None else "numpy (no C compiler)"
    figures["solver_only_s"] = solver_only(example, instants)
    for suffix in ("csv", "npz", "parquet"):
        figures[suffix] = run_solve(ctx, example, instants, folder / f"run.{suffix}")
        r = figures[suffix]
        ctx.log(f"{suffix:8s} {r['seconds']:8.2f} s ({r['cpu_seconds']:.2f} s CPU)  {r['max_rss_mb']:7.1f} MB peak  "
                f"{r['file_mb']:8.1f} MB file  {r['mb_per_s']:7.1f} MB/s")
    (folder / "run.parquet").unlink()
    with np.load(folder / "run.npz") as archive:
        data = np.column_stack([archive[name] for name in archive.files])
    (folder / "run.npz").unlink()
    start, cpu = time.perf_counter(), time.process_time()
    np.savetxt(folder / "savetxt.csv", data, fmt="%.17g", delimiter=",")
    savetxt, savetxt_cpu = time.perf_counter() - start, time.process_time() - cpu
    del data
    savetxt_mb = (folder / "savetxt.csv").stat().st_size / MB
    same = digest(folder / "savetxt.csv", False) == digest(folder / "run.csv", True)
    figures["savetxt_s"] = savetxt
    figures["savetxt_cpu_s"] = savetxt_cpu
    figures["savetxt_mb_per_s"] = savetxt_mb / savetxt
    figures["csv_cpu_over_savetxt_cpu"] = figures["csv"]["cpu_seconds"] / savetxt_cpu
    figures["csv_text_equals_savetxt"] = same
    figures["csv_over_savetxt"] = figures["csv"]["seconds"] / savetxt
    figures["targets"] = {"csv_at_most_half_savetxt": figures["csv_over_savetxt"] <= 0.5,
                          "npz_peak_at_most_200_mb": figures["npz"]["max_rss_mb"] <= 200}
    return figures
