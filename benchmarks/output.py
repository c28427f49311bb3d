"""Output at solver speed (#17): the slider-crank's table through a whole `symid solve`.

    python -m benchmarks.output [--instants 1000000] [--folder DIR]

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
Writes benchmarks/results/output.json.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from symid import api
from symid.output.compiled_csv import BUILD_AT, formatter

RESULTS = Path(__file__).parent / "results" / "output.json"
MB = 1e6


def run_solve(example: str, steps: int, out: Path) -> dict[str, float]:
    """One `symid solve` process: wall seconds, max RSS in MB, file MB and MB/s."""
    start = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", "symid", "solve", example, "--backend", "c", "--steps",
                             str(steps), "-o", str(out)], stdout=subprocess.DEVNULL)
    _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    wall = time.perf_counter() - start
    if proc.returncode != 0:
        raise SystemExit(f"symid solve -o {out.name} failed with status {proc.returncode}")
    size = out.stat().st_size / MB
    return {"seconds": wall, "cpu_seconds": usage.ru_utime + usage.ru_stime, "max_rss_mb": usage.ru_maxrss * 1024 / MB,
            "file_mb": size, "mb_per_s": size / wall}


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


def main(argv: list[str] | None = None) -> dict[str, Any]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--instants", type=int, default=1_000_000)
    parser.add_argument("--folder", type=Path, help="scratch folder (default: a temporary one, removed after)")
    args = parser.parse_args(argv)
    example = str(api.example("slider_crank"))
    with tempfile.TemporaryDirectory(dir=args.folder) as scratch:
        folder = Path(scratch)
        # the same command first: the compiled solver is built and the run's plan
        # kept, so every timed run takes the planned path (no sympy) alike
        run_solve(example, args.instants, folder / "warm.npz")
        (folder / "warm.npz").unlink()
        figures: dict[str, Any] = {"instants": args.instants, "columns": 67, "mechanism": "slider_crank",
                                   "backend": "c", "cpu_count": os.cpu_count(),
                                   "load_average": os.getloadavg()}
        figures["csv_formatter"] = "compiled" if formatter(BUILD_AT) is not None else "numpy (no C compiler)"
        figures["solver_only_s"] = solver_only(example, args.instants)
        for suffix in ("csv", "npz", "parquet"):
            figures[suffix] = run_solve(example, args.instants, folder / f"run.{suffix}")
            print(f"{suffix:8s} {figures[suffix]['seconds']:8.2f} s ({figures[suffix]['cpu_seconds']:.2f} s CPU)  {figures[suffix]['max_rss_mb']:7.1f} MB peak  "
                  f"{figures[suffix]['file_mb']:8.1f} MB file  {figures[suffix]['mb_per_s']:7.1f} MB/s", flush=True)
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
    figures["load_average_end"] = os.getloadavg()
    figures["csv_cpu_over_savetxt_cpu"] = figures["csv"]["cpu_seconds"] / savetxt_cpu
    figures["csv_text_equals_savetxt"] = same
    figures["csv_over_savetxt"] = figures["csv"]["seconds"] / savetxt
    figures["targets"] = {"csv_at_most_half_savetxt": figures["csv_over_savetxt"] <= 0.5,
                          "npz_peak_at_most_200_mb": figures["npz"]["max_rss_mb"] <= 200}
    print(f"solver alone {figures['solver_only_s']:.2f} s; numpy.savetxt {savetxt:.2f} s, "
          f"{figures['savetxt_mb_per_s']:.1f} MB/s (text {'identical' if same else 'DIFFERENT'}); "
          f"CSV formatter: {figures['csv_formatter']}; symid CSV / savetxt = {figures['csv_over_savetxt']:.2f} "
          f"wall, {figures['csv_cpu_over_savetxt_cpu']:.2f} CPU time (load average {os.getloadavg()[0]:.1f})")
    RESULTS.parent.mkdir(exist_ok=True)
    RESULTS.write_text(json.dumps(figures, indent=2) + "\n")
    print(f"wrote {RESULTS}")
    return figures


if __name__ == "__main__":
    main()
