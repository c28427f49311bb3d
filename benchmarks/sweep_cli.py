"""The whole `symid sweep` process, cold and cached, and on a local Dask cluster.

Figures of issue 14's targets that no in-process timing gives:

- `cold`: a fresh SYMID_CACHE (derive, generate, compile, then solve);
- `cached`: the same command again (the solver from the cache);
- `dask`: the same sweep with `--scheduler` on a scheduler and two
  single-threaded workers started here on 127.0.0.1, against `cached`
  (the target: within 1.5x of the threaded local run);
- with `--mc N`: the README's tolerance study (`--sample N`, normal scatter on
  lengths and masses) locally on every core (`mc_local`) and on the same
  cluster (`mc_dask`), and their ratio.

Each row has the process wall time, the client process's peak memory
(`peak_rss_mb`) and the sweep's own `--json` figures (setup_s, solve_s,
instants_per_s); the report has the load average at start and end. Full size
is the issue's grid: 25 rod lengths x 40 crank speeds x 1001 instants;
`--quick` is 5 x 8 x 101.

With `--against TREE --pairs N` instead: the cold and the cached process N
times, alternating TREE (e.g. a checkout of main) and this one, each cold run
in a fresh cache: a before/after comparison that a busy machine's drift
does not bias (sweep_cli_cold.json).

    python -m benchmarks.sweep_cli [--quick] [--backend c] [--no-dask] [--mc 100000]
    python -m benchmarks.sweep_cli --against /work/main --pairs 4
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any, Iterator

ROOT = Path(__file__).resolve().parents[1]
# README's tolerance study: 0.2 % (crank) and 0.1 % (rod) on lengths, 2 % on masses
TOLERANCES = ("L_crank=0.1,0.0002", "L_rod=0.3,0.0003", "m_crank=0.5,0.01", "m_rod=1,0.02", "m_slider=0.8,0.016")


def sweep(args: list[str], env: dict[str, str], cwd: Path) -> dict[str, Any]:
    """Run one `symid sweep ... --json`; its JSON report, the process wall time
    and its peak resident memory (MB)."""
    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err:
        start = time.perf_counter()
        proc = subprocess.Popen([sys.executable, "-m", "symid", "sweep", *args, "--json"], env=env, cwd=cwd,
                                stdout=out, stderr=err)
        _, status, usage = os.wait4(proc.pid, 0)  # this child's own rusage (ru_maxrss in kB on Linux)
        wall = time.perf_counter() - start
        proc.returncode = os.waitstatus_to_exitcode(status)
        out.seek(0)
        err.seek(0)
        stdout, stderr = out.read().decode(), err.read().decode(errors="replace")
    if proc.returncode != 0:
        raise SystemExit(f"symid sweep failed ({proc.returncode}): {stderr.strip()}")
    report = json.loads(stdout.strip().splitlines()[-1])
    report["process_s"] = wall
    report["process_cpu_s"] = usage.ru_utime + usage.ru_stime
    report["peak_rss_mb"] = usage.ru_maxrss / 1024
    return report


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@contextlib.contextmanager
def cluster(env: dict[str, str], cwd: Path, workers: int = 2) -> Iterator[str]:
    """A scheduler and `workers` single-threaded workers on 127.0.0.1; yields its address."""
    port = free_port()
    address = f"tcp://127.0.0.1:{port}"
    procs = [subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1",
                               "--port", str(port), "--dashboard-address", ":0"], env=env, cwd=cwd,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    try:
        for k in range(workers):
            procs.append(subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_worker", address,
                                           "--nthreads", "1", "--no-nanny", "--name", f"w{k + 1}",
                                           "--host", "127.0.0.1", "--dashboard-address", ":0"], env=env, cwd=cwd,
                                          stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        from distributed import Client

        with Client(address, timeout=60, set_as_default=False) as client:
            client.wait_for_workers(workers, timeout=120)
        yield address
    finally:
        for proc in procs:
            proc.kill()
            proc.wait()


def _usage() -> tuple[float, float]:
    import resource

    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime, r.ru_maxrss / 1024


def workers_usage(address: str) -> list[tuple[float, float]]:
    """Each worker's CPU seconds and peak resident memory (MB) so far, by name."""
    from distributed import Client

    with Client(address, timeout=60, set_as_default=False) as client:
        return [v for _, v in sorted(client.run(_usage).items())]


def on_cluster(args: list[str], env: dict[str, str], cwd: Path, address: str) -> dict[str, Any]:
    """`sweep` with `--scheduler address`, plus the CPU seconds the workers spent on it."""
    before = workers_usage(address)
    report = sweep([*args, "--scheduler", address], env, cwd)
    after = workers_usage(address)
    report["workers_cpu_s"] = sum(a[0] - b[0] for a, b in zip(after, before))
    report["workers_peak_rss_mb"] = [a[1] for a in after]
    return report


def with_cluster(env: dict[str, str], cwd: Path, run: list[str]) -> dict[str, Any]:
    """The sweep on a scheduler and two workers (`--nthreads 1`) started for it."""
    with cluster(env, cwd) as address:
        return sweep([*run, "--scheduler", address], env, cwd)


def _workers(r: dict[str, Any]) -> str:
    return f" (+ workers {r['workers_cpu_s']:.2f} s)" if "workers_cpu_s" in r else ""


def priority() -> str:
    """This process's scheduling group and its nice value (Linux autogroup), as
    measured: a busy machine's other sessions share the cores with it."""
    try:
        return Path("/proc/self/autogroup").read_text().strip()
    except OSError:
        return f"nice {os.nice(0)}"


def load() -> list[float]:
    return [round(v, 2) for v in os.getloadavg()]


def pairs(against: Path, n: int, grid: list[str], folder: Path) -> dict[str, Any]:
    """The cold and the cached grid, alternating the checkout `against` and this one."""
    import statistics

    runs: dict[str, list[dict[str, Any]]] = {"against": [], "this": []}
    for k in range(n):
        for name, tree in (("against", against), ("this", ROOT)):
            cache = folder / f"cache-{name}-{k}"
            env = {**os.environ, "SYMID_CACHE": str(cache), "PYTHONPATH": str(tree)}
            env.pop("CI", None)
            runs[name].append({"cold": sweep(grid, env, folder), "cached": sweep(grid, env, folder),
                               "load": load()[0]})
            r = runs[name][-1]
            print(f"{name:8s} cold {r['cold']['process_s']:.2f} s, cached "
                  f"{r['cached']['process_s']:.2f} s (load {r['load']})", flush=True)
    out: dict[str, Any] = {"against": str(against), "this": str(ROOT), "runs": runs}
    for name, got in runs.items():
        for kind in ("cold", "cached"):
            out[f"{name}_{kind}_median_s"] = statistics.median(r[kind]["process_s"] for r in got)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="5 x 8 variants x 101 instants")
    parser.add_argument("--backend", default="c")
    parser.add_argument("--no-dask", action="store_true", help="skip the cluster runs")
    parser.add_argument("--no-grid", action="store_true", help="skip the grid (cold, cached, dask)")
    parser.add_argument("--mc", type=int, default=0, metavar="N",
                        help="also the tolerance study of N sampled variants, locally and on the cluster")
    parser.add_argument("--against", type=Path, metavar="TREE",
                        help="compare the cold and cached grid with this checkout, alternating (see --pairs)")
    parser.add_argument("--pairs", type=int, default=3, metavar="N", help="with --against: runs of each")
    parser.add_argument("--out", default=str(ROOT / "benchmarks" / "results"))
    args = parser.parse_args()
    rods, speeds, steps = (5, 8, 101) if args.quick else (25, 40, 1001)
    folder = Path(tempfile.mkdtemp(prefix="symid-sweep-bench-"))
    env = {**os.environ, "SYMID_CACHE": str(folder / "cache"), "PYTHONPATH": str(ROOT)}
    env.pop("CI", None)
    crank = str(ROOT / "symid" / "examples" / "slider_crank.toml")
    grid = [crank, "--grid", f"L_rod=0.25:0.4:{rods}", "--grid", f"n=2:10:{speeds}", "--steps", str(steps),
            "--backend", args.backend, "-o", str(folder / "study.csv")]
    report: dict[str, Any] = {"variants": rods * speeds, "steps": steps, "backend": args.backend,
                                 "cores": os.cpu_count(), "load_average_start": load(),
                                 "priority": priority()}
    if args.against:
        report.update(pairs(args.against.resolve(), args.pairs, grid, folder))
        report["load_average_end"] = load()
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        (out / "sweep_cli_cold.json").write_text(json.dumps(report, indent=1) + "\n")
        print(" ".join(f"{k} {v:.2f}" for k, v in report.items() if k.endswith("_median_s")))
        return
    rows = []
    if not args.no_grid:
        report["cold"] = sweep(grid, env, folder)
        report["cached"] = sweep(grid, env, folder)
        rows += ["cold", "cached"]
    mc = [crank, "--sample", str(args.mc), "--seed", "1", *(a for t in TOLERANCES for a in ("--normal", t)),
          "--steps", str(steps), "--backend", args.backend, "-o", str(folder / "mc.parquet")]
    if args.mc:
        report["mc_variants"] = args.mc
        if args.no_grid:  # the solver into the cache first: the Monte Carlo is timed cached
            sweep([*mc[:1], "--sample", "2", *mc[3:]], env, folder)
        report["mc_local"] = sweep(mc, env, folder)
        rows.append("mc_local")
    if not args.no_dask:
        with cluster(env, folder) as address:
            if not args.no_grid:
                report["dask"] = on_cluster(grid, env, folder, address)
                rows.append("dask")
                for key in ("solve_s", "process_s"):
                    report[f"dask_over_local_{key[:-2]}"] = report["dask"][key] / report["cached"][key]
            if args.mc:
                report["mc_dask"] = on_cluster(mc, env, folder, address)
                rows.append("mc_dask")
                for key in ("solve_s", "process_s"):
                    report[f"mc_dask_over_local_{key[:-2]}"] = (report["mc_dask"][key]
                                                                / report["mc_local"][key])
    report["load_average_end"] = load()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    name = "sweep_cli_quick.json" if args.quick else "sweep_cli.json"
    (out / name).write_text(json.dumps(report, indent=1) + "\n")
    for key in rows:
        r = report[key]
        print(f"{key:8s} process {r['process_s']:.2f} s, setup {r['setup_s']:.2f} s, "
              f"solve {r['solve_s']:.3f} s, {r['instants_per_s']:.4g} instants/s, "
              f"cpu {r['process_cpu_s']:.2f} s{_workers(r)}, peak {r['peak_rss_mb']:.0f} MB")
    for key in sorted(k for k in report if "_over_" in k):
        print(f"{key}: {report[key]:.2f}")
    print(f"load average {report['load_average_start']} -> {report['load_average_end']}; wrote {out / name}")


if __name__ == "__main__":
    main()
