"""The benchmark: every symid backend and three baselines on the slider-crank
and the ladder family, in one process and one run.

    python -m benchmarks.run            # full run, writes benchmarks/results/
    python -m benchmarks.run --smoke --out DIR   # tiny sizes, a few instants

Every measurement runs in its own worker process (`--worker SPEC`), so each
setup is cold (fresh interpreter, empty SYMID_CACHE), peak memory is that
process's alone, and a cell that passes the cap is killed (its process group,
by id) and reported "stopped"; larger sizes of that approach are not tried.

Measured per (approach, mechanism):
- setup_s, split into derive / generate / compile (see `symid.bench`); it
  ends with the first solved instant, for every approach.
- us_per_instant: the median; compiled loops over whole runs of the grid,
  Python loops instant by instant, with a time budget.
- error: max |tau - tau_exact| / max |tau_exact| of the motor torque over the
  instants of the first period solved (exact: `ladder.Ladder.torque`,
  `systems.slider_crank_torque`).
- peak_rss_mb: the worker's peak resident set, read by a small launcher
  (`launch.py`, os.wait4's ru_maxrss of its one child): the interpreter and
  its imports included, compiler processes (gcc) not.

BLAS is pinned to one thread for every approach (the generated C is single
threaded), so the comparison is per core.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
RESULTS = Path(__file__).resolve().parent / "results"
THREADS = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
BASELINES = ("numpy-hand", "sympy-lambdify", "casadi-python", "casadi-c")
COMPILED = ("symid-c", "casadi-c")
TOLERANCES = (1e-6, 1e-8, 1e-10, 1e-12, 1e-14)
ORDERS = (0, 1, 2, 5)


@dataclass(frozen=True)
class Config:
    """Sizes and budgets of one run."""

    ladders: tuple[int, ...] = (1, 4, 16, 64, 256)
    steps: int = 1001              # instants per period (error over one period)
    compiled_instants: int = 20020  # 20 periods for the compiled loops
    budget_s: float = 10.0         # timing budget of one cell
    cap_s: float = 90.0            # a cell past this is stopped
    total_s: float = 14 * 60.0     # the whole run's budget
    reserve_s: float = 240.0       # kept for the sweeps and processes: cells not started
                                   # by total_s - reserve_s are skipped
    # (mechanism, instants per period): the coarse slider-crank grid (3.6 degrees
    # of crank per step) is where the predictor's order shows
    sweep_mechs: tuple[tuple[str, int], ...] = (("slider_crank", 1001), ("slider_crank", 101), ("ladder_16", 1001))
    sweep_instants: int = 1001
    tolerances: tuple[float, ...] = TOLERANCES
    orders: tuple[int, ...] = ORDERS
    stream_instants: int = 1_000_001
    solve_runs: int = 3
    jobs: int = 1
    # symid-c against casadi-c in one process, whole grids alternated: the
    # ratio targets are read from these (separate cells run minutes apart)
    paired_mechs: tuple[str, ...] = ("slider_crank", "ladder_64")
    paired_rounds: int = 21


SMOKE = Config(ladders=(1,), steps=1001, compiled_instants=40, budget_s=0.5, cap_s=50.0, total_s=50.0, reserve_s=0.0,
               sweep_mechs=(("ladder_1", 1001),), sweep_instants=15, tolerances=(1e-6, 1e-12), orders=(0, 2),
               stream_instants=2001, solve_runs=1, jobs=2, paired_mechs=("ladder_1",), paired_rounds=3)


# --- mechanisms --------------------------------------------------------------------

def mechanisms(cfg: Config, folder: Path) -> list[dict[str, Any]]:
    """The run's mechanisms, smallest first: key, file, ng, grid (t1, steps, h)."""
    from benchmarks import ladder
    from symid import api

    out = [{"key": "slider_crank", "file": str(api.example("slider_crank")), "ng": 9, "t1": 0.2}]
    for n in cfg.ladders:
        out.append({"key": ladder.name(n), "n": n, "file": str(ladder.write(n, folder, cfg.steps)),
                    "ng": ladder.Ladder(n).ng, "t1": ladder.Ladder(n).t1})
    for m in out:
        m["steps"] = cfg.steps
        m["h"] = m["t1"] / (cfg.steps - 1)
    return out


def exact_torque(mech: dict[str, Any]) -> np.ndarray:
    """The exact motor torque on the mechanism's grid (one period)."""
    from benchmarks import ladder, systems

    t = np.arange(mech["steps"]) * mech["h"]
    if mech["key"] == "slider_crank":
        return systems.slider_crank_torque(t)
    return ladder.Ladder(mech["n"]).torque(t)


def _system(mech: dict[str, Any]):  # type: ignore[no-untyped-def]
    from benchmarks import systems

    return systems.slider_crank() if mech["key"] == "slider_crank" else systems.ladder(mech["n"])


# --- workers (each in its own process) ----------------------------------------------

def worker_symid(spec: dict[str, Any]) -> dict[str, Any]:
    from symid.bench import bench

    mech = spec["mech"]
    res = bench(mech["file"], spec["backend"], instants=spec["instants"], budget_s=spec["budget_s"],
                keep=("motor.T_j",), cold=True, steps=mech["steps"], t1=mech["t1"])
    np.save(spec["torque"], np.array(res.pop("kept")["motor.T_j"]))
    return res


def worker_baseline(spec: dict[str, Any]) -> dict[str, Any]:
    from benchmarks import baselines

    mech = spec["mech"]
    system = _system(mech)
    approach = baselines.APPROACHES[spec["approach"]](system)
    q0, h, steps = system.q0(), mech["h"], mech["steps"]
    tick = time.perf_counter()
    phases = approach.setup()
    setup = time.perf_counter() - tick
    out: dict[str, Any] = {"ng": system.ng, "nc": system.nc}
    try:
        if isinstance(approach, baselines.CasadiC):
            setup += approach.run(q0, h, 1, 1e-12, spec["budget_s"]).total_s
            per_run, torque, timed, began, error = [], None, 0, time.perf_counter(), None
            while timed < spec["instants"] and (not per_run or time.perf_counter() - began < spec["budget_s"]):
                r = approach.run(q0, h, min(steps, spec["instants"] - timed), 1e-12, spec["budget_s"])
                torque = r.torque if torque is None else torque
                if len(r.torque):
                    per_run.append(r.total_s / len(r.torque))
                timed += len(r.torque)
                if r.error:
                    error = r.error
                    break
            out.update(us_per_instant=1e6 * float(np.median(per_run)) if per_run else None, instants=timed,
                       method="C loop over whole runs, clock_gettime inside C, median over runs", error=error)
        else:
            r = approach.run(q0, h, min(steps, spec["instants"]), 1e-12, spec["budget_s"])
            torque = r.torque
            setup += r.seconds[0] if r.seconds else 0.0
            rest = r.seconds[1:]
            out.update(us_per_instant=1e6 * float(np.median(rest)) if rest else None, instants=len(r.seconds),
                       method="Python loop, median over instants (the first is in setup)", error=r.error,
                       mean_iterations=float(np.mean(r.iterations[1:])) if len(r.iterations) > 1 else None)
    finally:
        folder = getattr(approach, "folder", None)
        if folder is not None:
            shutil.rmtree(folder, ignore_errors=True)
    out.update(setup_s=setup, derive_s=phases["derive"], compile_s=phases["compile"],
               generate_s=setup - phases["derive"] - phases["compile"])
    np.save(spec["torque"], np.asarray(torque if torque is not None else [], dtype=float))
    return out


def worker_sweep(spec: dict[str, Any]) -> dict[str, Any]:
    """Predictor order x tolerance (both drivers) and the tolerance through
    `api.prepare(tol=...)` on each symid backend; torques saved for the parent."""
    from benchmarks import sweep
    from symid import api, backends
    from symid.bench import bench

    mech, folder = spec["mech"], Path(spec["folder"])
    study = api.prepare(mech["file"], "c", steps=mech["steps"], t1=mech["t1"])
    out: dict[str, Any] = {"predictor": [], "tolerance": []}
    for driver, fn in sweep.DRIVERS.items():
        for order in spec["orders"]:
            for tol in spec["tolerances"]:
                r = fn(study, order, tol, spec["instants"])
                path = folder / f"{driver}-{order}-{tol:g}.npy"
                np.save(path, np.array(r["torque"]))
                its = r["iterations"][1:]
                out["predictor"].append({
                    "driver": driver, "order": order, "tol": tol, "error": r["error"], "torque": str(path),
                    "mean_iterations": float(np.mean(its)) if its else None,
                    "us_per_instant": 1e6 * float(np.median(r["seconds"][1:])) if len(r["seconds"]) > 1 else None})
    for backend in backends.names():
        for tol in spec["tolerances"]:
            try:
                r = bench(mech["file"], backend, instants=spec["instants"], tol=tol, cold=False,
                          budget_s=spec["budget_s"], keep=("motor.T_j",), steps=mech["steps"], t1=mech["t1"])
            except Exception as exc:  # a backend that cannot build this mechanism: recorded, not fatal
                out["tolerance"].append({"backend": backend, "tol": tol, "failed": f"{type(exc).__name__}: {exc}"})
                break
            path = folder / f"prepare-{backend}-{tol:g}.npy"
            np.save(path, np.array(r.pop("kept")["motor.T_j"]))
            out["tolerance"].append({"backend": backend, "tol": tol, "us_per_instant": r["us_per_instant"],
                                     "max_residual": r["max_residual"], "error": r["error"], "torque": str(path)})
    return out


def worker_paired(spec: dict[str, Any]) -> dict[str, Any]:
    """symid-c's trajectory and the casadi-c loop in one process, each round
    one whole grid of each in turn: per round, us per instant of both and
    their ratio (casadi-c / symid-c)."""
    from benchmarks import baselines
    from symid import api
    from symid.bench import CHUNK, _trajectory

    mech = spec["mech"]
    study = api.prepare(mech["file"], "c", steps=mech["steps"], t1=mech["t1"])
    runner = _trajectory(study)
    assert runner is not None
    system = _system(mech)
    casadi = baselines.APPROACHES["casadi-c"](system)
    casadi.setup()
    q0, h, steps = system.q0(), mech["h"], mech["steps"]
    state = np.zeros(study.evaluator.meta["state"])  # type: ignore[attr-defined]
    ours, theirs = [], []
    try:
        for _ in range(spec["rounds"]):
            state[:] = 0.0
            state[:study.layout.ng] = study.q0()
            seconds, done = 0.0, 0
            while done < steps:
                _, solved, status, dt = runner(done, min(CHUNK, steps - done), state)
                seconds += dt
                done += solved
                if status != 0:
                    raise RuntimeError(f"symid-c stopped at instant {done}")
            ours.append(1e6 * seconds / steps)
            r = casadi.run(q0, h, steps, 1e-12, spec["budget_s"])
            if r.error or len(r.torque) < steps:
                raise RuntimeError(f"casadi-c: {r.error or 'stopped early'}")
            theirs.append(1e6 * r.total_s / steps)
    finally:
        folder = getattr(casadi, "folder", None)
        if folder is not None:
            shutil.rmtree(folder, ignore_errors=True)
    ratios = [b / a for a, b in zip(ours, theirs)]
    return {"rounds": len(ours), "instants_per_round": steps, "symid_c_us": float(np.median(ours)),
            "casadi_c_us": float(np.median(theirs)), "ratio": float(np.median(ratios)),
            "ratio_range": [float(min(ratios)), float(max(ratios))]}


def worker(spec: dict[str, Any]) -> dict[str, Any]:
    kind = spec["kind"]
    tick = time.perf_counter()
    fn: Callable[[dict[str, Any]], dict[str, Any]] = {
        "symid": worker_symid, "baseline": worker_baseline, "sweep": worker_sweep, "paired": worker_paired}[kind]
    out = fn(spec)
    out["worker_s"] = time.perf_counter() - tick
    return out


# --- the parent -------------------------------------------------------------------

@dataclass
class Spawned:
    status: str          # "ok", "failed" or "stopped"
    result: dict[str, Any]
    wall_s: float
    peak_rss_mb: float | None
    note: str = ""


LAUNCH = Path(__file__).with_name("launch.py")


def launch(cmd: list[str], cap_s: float, env: dict[str, str], stdout: Any, stderr: Any,
           ) -> tuple[float, float | None, int, bool]:
    """(wall s, peak RSS MB, exit status, stopped) of one command run through
    `launch.py` in its own process group, the group killed (by id) past cap_s."""
    with tempfile.NamedTemporaryFile(suffix=".json", delete=False) as f:
        report = Path(f.name)
    tick = time.perf_counter()
    proc = subprocess.Popen([sys.executable, str(LAUNCH), str(report), *cmd], stdout=stdout, stderr=stderr,
                            env=env, cwd=ROOT, start_new_session=True)
    stopped = threading.Event()

    def stop() -> None:
        stopped.set()
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass

    timer = threading.Timer(cap_s, stop)
    timer.start()
    proc.wait()
    timer.cancel()
    wall = time.perf_counter() - tick
    try:
        measured = json.loads(report.read_text())
        rss, code = measured["maxrss_mb"], measured["status"]
    except (OSError, ValueError, KeyError):
        rss, code = None, proc.returncode
    report.unlink(missing_ok=True)
    return wall, rss, code, stopped.is_set()


def spawn(spec: dict[str, Any], cap_s: float, env: dict[str, str]) -> Spawned:
    """Run one worker; its last stdout line is its JSON result."""
    cmd = [sys.executable, "-m", "benchmarks.run", "--worker", json.dumps(spec)]
    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err:
        wall, rss, code, stopped = launch(cmd, cap_s, env, out, err)
        if stopped:
            return Spawned("stopped", {}, wall, rss, f"stopped after {cap_s:.0f} s")
        out.seek(0)
        err.seek(0)
        lines = out.read().decode(errors="replace").strip().splitlines()
        if code != 0 or not lines:
            tail = err.read().decode(errors="replace").strip().splitlines()
            return Spawned("failed", {}, wall, rss, tail[-1][:300] if tail else f"exit {code}")
        return Spawned("ok", json.loads(lines[-1]), wall, rss)


def _env(cache: Path) -> dict[str, str]:
    env = {**os.environ, **THREADS, "SYMID_CACHE": str(cache)}
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(ROOT), env.get("PYTHONPATH", "")) if p)
    return env


def _error(torque: np.ndarray, exact: np.ndarray) -> tuple[float | None, int]:
    n = min(len(torque), len(exact))
    if n == 0:
        return None, 0
    diff = np.abs(torque[:n] - exact[:n])
    worst = float(np.max(diff)) if np.all(np.isfinite(diff)) else math.inf
    return worst / float(np.max(np.abs(exact))), n


def approaches() -> list[tuple[str, str, str]]:
    """(label, kind, backend-or-approach) of everything measured."""
    from symid import backends

    return [(f"symid-{b}", "symid", b) for b in backends.names()] + [(b, "baseline", b) for b in BASELINES]


def run_cells(cfg: Config, mechs: list[dict[str, Any]], exact: dict[str, np.ndarray], work: Path,
              deadline: float, log: Callable[[str], None]) -> list[dict[str, Any]]:
    """Every approach on every mechanism, smallest first; an approach stopped
    at one size is not tried at larger ones."""
    stopped: dict[str, str] = {}
    cells: list[dict[str, Any]] = []
    jobs: list[tuple[dict[str, Any], dict[str, Any]]] = []
    for mech in mechs:
        for label, kind, name in approaches():
            cell: dict[str, Any] = {"approach": label, "kind": kind, "mechanism": mech["key"], "ng": mech["ng"]}
            cells.append(cell)
            compiled = label in COMPILED
            spec = {"kind": kind, "mech": mech, "backend": name, "approach": name,
                    "instants": cfg.compiled_instants if compiled else cfg.steps,
                    "budget_s": cfg.budget_s, "torque": str(work / f"{label}-{mech['key']}.npy")}
            jobs.append((cell, spec))

    def one(cell: dict[str, Any], spec: dict[str, Any]) -> None:
        label = cell["approach"]
        if label in stopped:
            cell.update(status="stopped", note=f"not run: stopped at {stopped[label]}")
            return
        if time.time() > deadline:
            cell.update(status="skipped", note="not run: the run's time budget was spent")
            return
        cache = Path(tempfile.mkdtemp(prefix="cache-", dir=work))
        got = spawn(spec, cfg.cap_s, _env(cache))
        shutil.rmtree(cache, ignore_errors=True)
        cell.update(got.result, status=got.status, wall_s=got.wall_s, peak_rss_mb=got.peak_rss_mb)
        if got.note:
            cell["note"] = got.note
        if got.status == "stopped":
            stopped[label] = f"{cell['mechanism']} (ng = {cell['ng']})"
        if got.status == "ok":
            torque = np.load(spec["torque"])
            cell["error_rel"], cell["error_instants"] = _error(torque, exact[cell["mechanism"]])
            if cell.get("error"):
                cell["status"], cell["note"] = "failed", str(cell["error"])[:300]
        log(f"{label:16s} {cell['mechanism']:13s} {cell['status']:8s} "
            f"setup {_fmt(cell.get('setup_s'))} s, {_fmt(cell.get('us_per_instant'))} us, "
            f"err {_fmt(cell.get('error_rel'))}, {_fmt(cell.get('peak_rss_mb'))} MB {cell.get('note', '')}")

    if cfg.jobs <= 1:
        for cell, spec in jobs:
            one(cell, spec)
    else:  # smoke runs only: timings from parallel workers are not comparable
        from concurrent.futures import ThreadPoolExecutor

        by_mech: dict[str, list[tuple[dict[str, Any], dict[str, Any]]]] = {}
        for cell, spec in jobs:
            by_mech.setdefault(cell["mechanism"], []).append((cell, spec))
        with ThreadPoolExecutor(cfg.jobs) as pool:
            for group in by_mech.values():
                list(pool.map(lambda cs: one(*cs), group))
    return cells


def run_sweeps(cfg: Config, mechs: list[dict[str, Any]], exact: dict[str, np.ndarray], work: Path,
               log: Callable[[str], None]) -> dict[str, Any]:
    out = {}
    for base, steps in cfg.sweep_mechs:
        mech = dict(next(m for m in mechs if m["key"] == base), steps=steps)
        mech["h"] = mech["t1"] / (steps - 1)
        key = base if steps == cfg.steps else f"{base}, {steps} steps"
        truth = exact[base] if steps == cfg.steps else exact_torque(mech)
        folder = work / f"sweep-{base}-{steps}"
        folder.mkdir()
        cache = Path(tempfile.mkdtemp(prefix="cache-", dir=work))
        spec = {"kind": "sweep", "mech": mech, "folder": str(folder), "instants": min(cfg.sweep_instants, steps),
                "tolerances": list(cfg.tolerances), "orders": list(cfg.orders), "budget_s": cfg.budget_s / 2}
        got = spawn(spec, 4 * cfg.cap_s, _env(cache))
        shutil.rmtree(cache, ignore_errors=True)
        if got.status != "ok":
            out[key] = {"status": got.status, "note": got.note}
            log(f"sweep {key}: {got.status} {got.note}")
            continue
        for row in got.result["predictor"] + got.result["tolerance"]:
            if "torque" in row:
                row["error_rel"], row["error_instants"] = _error(np.load(row.pop("torque")), truth)
        out[key] = {"status": "ok", "ng": mech["ng"], "steps": steps, **got.result}
        log(f"sweep {key}: {len(got.result['predictor'])} predictor points, "
            f"{len(got.result['tolerance'])} tolerance points in {got.wall_s:.0f} s")
    return out


def run_paired(cfg: Config, mechs: list[dict[str, Any]], work: Path, log: Callable[[str], None]) -> dict[str, Any]:
    out = {}
    for key in cfg.paired_mechs:
        mech = next((m for m in mechs if m["key"] == key), None)
        if mech is None:
            continue
        cache = Path(tempfile.mkdtemp(prefix="cache-", dir=work))
        got = spawn({"kind": "paired", "mech": mech, "rounds": cfg.paired_rounds, "budget_s": cfg.cap_s},
                    4 * cfg.cap_s, _env(cache))
        shutil.rmtree(cache, ignore_errors=True)
        out[key] = {"status": got.status, "note": got.note, "ng": mech["ng"], **got.result}
        log(f"paired {key}: {got.status} {got.note} {got.result}")
    return out


def _timed_process(cmd: list[str], env: dict[str, str], cap_s: float) -> tuple[float, float | None, int]:
    """(wall s, peak RSS MB, exit status) of one process, killed past cap_s."""
    wall, rss, code, _ = launch(cmd, cap_s, env, subprocess.DEVNULL, subprocess.DEVNULL)
    return wall, rss, code


def run_processes(cfg: Config, work: Path, log: Callable[[str], None]) -> dict[str, Any]:
    """`symid solve` as a user runs it: whole-process time when cached, and
    the peak memory of streaming many instants to CSV."""
    from symid import api

    cache = work / "solve-cache"
    env = _env(cache)
    file = str(api.example("slider_crank"))
    csv = str(work / "solve.csv")
    out: dict[str, Any] = {"solve_1001": {}}
    for backend in ("numpy", "c"):
        cmd = [sys.executable, "-m", "symid", "solve", file, "--backend", backend, "--steps", "1001", "-o", csv]
        _timed_process(cmd, env, 300)  # fills the cache
        walls = [_timed_process(cmd, env, 300) for _ in range(cfg.solve_runs)]
        out["solve_1001"][backend] = {"wall_s": float(np.median([w for w, _, _ in walls])),
                                      "peak_rss_mb": max((r for _, r, _ in walls if r), default=None),
                                      "status": max(s for _, _, s in walls)}
        log(f"symid solve slider_crank 1001 instants, {backend}, cached: {out['solve_1001'][backend]}")
    cmd = [sys.executable, "-m", "symid", "solve", file, "--backend", "c", "--steps", str(cfg.stream_instants),
           "-o", csv]
    wall, rss, status = _timed_process(cmd, env, 600)
    out["stream"] = {"instants": cfg.stream_instants, "backend": "c", "output": "CSV", "wall_s": wall,
                     "peak_rss_mb": rss, "status": status}
    log(f"streaming {cfg.stream_instants} instants to CSV (c): {out['stream']}")
    Path(csv).unlink(missing_ok=True)
    return out


# --- machine ------------------------------------------------------------------------

def machine() -> dict[str, Any]:
    import casadi
    import scipy
    import sympy

    model = ""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    mem = ""
    try:
        mem = Path("/proc/meminfo").read_text().splitlines()[0].split(":", 1)[1].strip()
    except (OSError, IndexError):
        pass
    gcc = subprocess.run(["gcc", "--version"], capture_output=True, text=True).stdout.splitlines()
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, cwd=ROOT)
    return {
        "cpu": model or platform.processor(), "cpu_count": os.cpu_count(), "memory": mem,
        "platform": platform.platform(), "python": platform.python_version(),
        "numpy": np.__version__, "scipy": scipy.__version__, "sympy": sympy.__version__,
        "casadi": casadi.__version__, "gcc": gcc[0] if gcc else "", "symid_commit": commit.stdout.strip(),
        "load_average_start": os.getloadavg(), "blas_threads": 1,
    }


def _fmt(v: Any) -> str:
    return "-" if v is None else f"{v:.3g}" if isinstance(v, float) else str(v)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--smoke", action="store_true", help="tiny sizes and a few instants (for the tests)")
    parser.add_argument("--out", type=Path, default=RESULTS, help="folder for bench.json, bench.md and PNGs")
    parser.add_argument("--worker", help=argparse.SUPPRESS)
    parser.add_argument("--skip-processes", action="store_true", help="leave out the symid solve processes")
    args = parser.parse_args(argv)
    if args.worker:
        print(json.dumps(worker(json.loads(args.worker))))
        return 0
    from benchmarks import report

    cfg = SMOKE if args.smoke else Config()
    args.out.mkdir(parents=True, exist_ok=True)
    start = time.time()

    def log(msg: str) -> None:
        print(f"[{time.time() - start:6.0f} s] {msg}", flush=True)

    with tempfile.TemporaryDirectory(prefix="symid-bench-") as tmp:
        work = Path(tmp)
        info = machine()
        mechs = mechanisms(cfg, work / "mechanisms")
        exact = {m["key"]: exact_torque(m) for m in mechs}
        log(f"{info['cpu']} x {info['cpu_count']}; exact torques ready")
        cells = run_cells(cfg, mechs, exact, work, start + cfg.total_s - cfg.reserve_s, log)
        sweeps = run_sweeps(cfg, mechs, exact, work, log)
        paired = run_paired(cfg, mechs, work, log)
        processes = {} if args.skip_processes else run_processes(cfg, work, log)
    info["load_average_end"] = os.getloadavg()
    info["run_s"] = time.time() - start
    result = {"machine": info, "config": {**cfg.__dict__, "smoke": args.smoke},
              "mechanisms": [{k: v for k, v in m.items() if k != "file"} for m in mechs],
              "cells": cells, "sweeps": sweeps, "paired": paired, "processes": processes}
    (args.out / "bench.json").write_text(json.dumps(result, indent=1, default=float))
    (args.out / "bench.md").write_text(report.markdown(result))
    for path in report.plots(result, args.out):
        log(f"wrote {path}")
    log(f"wrote {args.out / 'bench.json'} and {args.out / 'bench.md'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
