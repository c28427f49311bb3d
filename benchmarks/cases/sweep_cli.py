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

Each row has the process wall time, CPU time, the client process's peak
memory (`peak_rss_mb`) and the sweep's own `--json` figures (setup_s,
solve_s, instants_per_s). Full size is the issue's grid: 25 rod lengths x 40
crank speeds x 1001 instants.

    python -m benchmarks sweep_cli [--backend c] [--no-dask] [--no-grid] [--mc 100000]
"""

from __future__ import annotations

import contextlib
import json
import os
import socket
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any, Iterator

from benchmarks.cases import register
from benchmarks.processes import ROOT
from benchmarks.run import Context

CAP_S = 1800.0  # one sweep process; a hang is stopped, not waited for
# README's tolerance study: 0.2 % (crank) and 0.1 % (rod) on lengths, 2 % on masses
TOLERANCES = ("L_crank=0.1,0.0002", "L_rod=0.3,0.0003", "m_crank=0.5,0.01", "m_rod=1,0.02", "m_slider=0.8,0.016")


def sweep(ctx: Context, args: list[str], env: dict[str, str]) -> dict[str, Any]:
    """Run one `symid sweep ... --json` as a user runs it; its JSON report, the
    process wall time, CPU time and peak resident memory (MB)."""
    with tempfile.TemporaryFile() as out:
        got = ctx.process([sys.executable, "-m", "symid", "sweep", *args, "--json"], CAP_S, env, stdout=out,
                          cwd=ctx.work)
        out.seek(0)
        stdout = out.read().decode(errors="replace")
    if got.status != 0 or not stdout.strip():
        raise RuntimeError(f"symid sweep {' '.join(args)} failed with status {got.status}")
    report: dict[str, Any] = json.loads(stdout.strip().splitlines()[-1])
    report.update(process_s=got.wall_s, process_cpu_s=got.cpu_s, peak_rss_mb=got.peak_rss_mb)
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


def on_cluster(ctx: Context, args: list[str], env: dict[str, str], address: str) -> dict[str, Any]:
    """`sweep` with `--scheduler address`, plus the CPU seconds the workers spent on it."""
    before = workers_usage(address)
    report = sweep(ctx, [*args, "--scheduler", address], env)
    after = workers_usage(address)
    report["workers_cpu_s"] = sum(a[0] - b[0] for a, b in zip(after, before))
    report["workers_peak_rss_mb"] = [a[1] for a in after]
    return report


def with_cluster(ctx: Context, env: dict[str, str], run: list[str]) -> dict[str, Any]:
    """The sweep on a scheduler and two workers (`--nthreads 1`) started for it."""
    with cluster(env, ctx.work) as address:
        return sweep(ctx, [*run, "--scheduler", address], env)


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


def _options(group: Any) -> None:
    group.add_argument("--backend", default="c")
    group.add_argument("--no-dask", action="store_true", help="skip the cluster runs")
    group.add_argument("--no-grid", action="store_true", help="skip the grid (cold, cached, dask)")
    group.add_argument("--mc", type=int, default=0, metavar="N",
                       help="also the tolerance study of N sampled variants, locally and on the cluster")


@register("sweep_cli", "the whole `symid sweep` process: cold, cached, on a local Dask cluster; the tolerance study",
          options=_options)
def sweep_cli(ctx: Context) -> dict[str, Any]:
    args = ctx.options
    rods, speeds, steps = (2, 2, 21) if ctx.smoke else (25, 40, 1001)
    mc_n = min(args.mc, 8) if ctx.smoke else args.mc
    env = ctx.env(ctx.work / "cache")
    env.pop("CI", None)
    crank = str(ROOT / "symid" / "examples" / "slider_crank.toml")
    grid = [crank, "--grid", f"L_rod=0.25:0.4:{rods}", "--grid", f"n=2:10:{speeds}", "--steps", str(steps),
            "--backend", args.backend, "-o", str(ctx.work / "study.csv")]
    report: dict[str, Any] = {"variants": rods * speeds, "steps": steps, "backend": args.backend,
                              "cores": os.cpu_count(), "priority": priority()}
    if not args.no_grid:
        report["cold"] = sweep(ctx, grid, env)
        report["cached"] = sweep(ctx, grid, env)
    mc = [crank, "--sample", str(mc_n), "--seed", "1", *(a for t in TOLERANCES for a in ("--normal", t)),
          "--steps", str(steps), "--backend", args.backend, "-o", str(ctx.work / "mc.parquet")]
    if mc_n:
        report["mc_variants"] = mc_n
        if args.no_grid:  # the solver into the cache first: the Monte Carlo is timed cached
            sweep(ctx, [*mc[:1], "--sample", "2", *mc[3:]], env)
        report["mc_local"] = sweep(ctx, mc, env)
    if not args.no_dask:  # smoke: one worker, the same steps (a second only starts another interpreter)
        with cluster(env, ctx.work, 1 if ctx.smoke else 2) as address:
            if not args.no_grid:
                report["dask"] = on_cluster(ctx, grid, env, address)
                for key in ("solve_s", "process_s"):
                    report[f"dask_over_local_{key[:-2]}"] = report["dask"][key] / report["cached"][key]
            if mc_n:
                report["mc_dask"] = on_cluster(ctx, mc, env, address)
                for key in ("solve_s", "process_s"):
                    report[f"mc_dask_over_local_{key[:-2]}"] = (report["mc_dask"][key]
                                                                / report["mc_local"][key])
    return report
