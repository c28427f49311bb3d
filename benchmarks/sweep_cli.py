"""The whole `symid sweep` process, cold and cached, and on a local Dask cluster.

Three figures of issue 14's targets that no in-process timing gives:

- `cold`: a fresh SYMID_CACHE (derive, generate, compile, then solve);
- `cached`: the same command again (the solver from the cache);
- `dask`: the same sweep with `--scheduler` on a scheduler and two
  single-threaded workers started here on 127.0.0.1, against `cached`
  (the target: within 1.5x of the threaded local run).

Each row has the process wall time and the sweep's own `--json` figures
(setup_s, solve_s, instants_per_s). Full size is the issue's grid: 25 rod
lengths x 40 crank speeds x 1001 instants; `--quick` is 5 x 8 x 101.

    python -m benchmarks.sweep_cli [--quick] [--backend c] [--no-dask]
"""

from __future__ import annotations

import argparse
import json
import os
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def sweep(args: list[str], env: dict[str, str], cwd: Path) -> dict[str, object]:
    """Run one `symid sweep ... --json`; its JSON report and the process wall time."""
    start = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "symid", "sweep", *args, "--json"], env=env, cwd=cwd,
                          capture_output=True, text=True, timeout=3600)
    wall = time.perf_counter() - start
    if proc.returncode != 0:
        raise SystemExit(f"symid sweep failed ({proc.returncode}): {proc.stderr.strip()}")
    report = json.loads(proc.stdout.strip().splitlines()[-1])
    report["process_s"] = wall
    return report


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def with_cluster(env: dict[str, str], cwd: Path, run: list[str]) -> dict[str, object]:
    """The sweep on a scheduler and two workers (`--nthreads 1`) started for it."""
    port = free_port()
    address = f"tcp://127.0.0.1:{port}"
    procs = [subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1",
                               "--port", str(port), "--dashboard-address", ":0"], env=env, cwd=cwd,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    try:
        for name in ("w1", "w2"):
            procs.append(subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_worker", address,
                                           "--nthreads", "1", "--no-nanny", "--name", name, "--host", "127.0.0.1",
                                           "--dashboard-address", ":0"], env=env, cwd=cwd,
                                          stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        from distributed import Client

        with Client(address, timeout=60, set_as_default=False) as client:
            client.wait_for_workers(2, timeout=120)
        return sweep([*run, "--scheduler", address], env, cwd)
    finally:
        for proc in procs:
            proc.kill()
            proc.wait()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="5 x 8 variants x 101 instants")
    parser.add_argument("--backend", default="c")
    parser.add_argument("--no-dask", action="store_true", help="skip the cluster run")
    parser.add_argument("--out", default=str(ROOT / "benchmarks" / "results"))
    args = parser.parse_args()
    rods, speeds, steps = (5, 8, 101) if args.quick else (25, 40, 1001)
    folder = Path(tempfile.mkdtemp(prefix="symid-sweep-bench-"))
    env = {**os.environ, "SYMID_CACHE": str(folder / "cache"), "PYTHONPATH": str(ROOT)}
    env.pop("CI", None)
    crank = str(ROOT / "symid" / "examples" / "slider_crank.toml")
    run = [crank, "--grid", f"L_rod=0.25:0.4:{rods}", "--grid", f"n=2:10:{speeds}", "--steps", str(steps),
           "--backend", args.backend, "-o", str(folder / "study.csv")]
    report: dict[str, object] = {"variants": rods * speeds, "steps": steps, "backend": args.backend,
                                 "cores": os.cpu_count()}
    report["cold"] = sweep(run, env, folder)
    report["cached"] = sweep(run, env, folder)
    if not args.no_dask:
        report["dask"] = with_cluster(env, folder, run)
        report["dask_over_local_solve"] = report["dask"]["solve_s"] / report["cached"]["solve_s"]  # type: ignore[index]
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    name = "sweep_cli_quick.json" if args.quick else "sweep_cli.json"
    (out / name).write_text(json.dumps(report, indent=1) + "\n")
    for key in ("cold", "cached", "dask"):
        if key in report:
            r = report[key]
            print(f"{key:7s} process {r['process_s']:.2f} s, setup {r['setup_s']:.2f} s, "  # type: ignore[index]
                  f"solve {r['solve_s']:.3f} s, {r['instants_per_s']:.4g} instants/s")  # type: ignore[index]
    print(f"wrote {out / name}")


if __name__ == "__main__":
    main()
