"""The benchmark harness: one command runs one case.

    python -m benchmarks --list                     # the cases, one line each
    python -m benchmarks CASE [--smoke] [--out DIR] [case options]
    python -m benchmarks CASE --help                # the case's own options

A case (a module of `benchmarks/cases/`) measures and returns a dict of
figures; the harness gives it a scratch folder, runs its cold measurements
in worker processes of their own (a fresh interpreter and cache, peak memory
read by `launch.py`; a smoke run's workers share one cache), writes `<out>/<case>.json` (default
`benchmarks/results/`; with `--smoke`, nothing unless `--out` is given) and
prints the figures. `--smoke` runs tiny sizes: a check that the case runs,
whose figures mean nothing. BLAS is pinned to one thread in every worker
(the generated C is single-threaded), so comparisons are per core.
"""

from __future__ import annotations

import argparse
import importlib
import importlib.metadata
import json
import os
import platform
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from benchmarks.processes import (ROOT, SIGNALS, THREADS, Measured, Signalled, Spawned, env_for, launch,
                                  on_signal, spawn)

RESULTS = Path(__file__).resolve().parent / "results"


class Unavailable(Exception):
    """A case cannot run here (a program it needs is missing): exit status 2."""


@dataclass
class Context:
    """What a case gets from the harness.

    Attributes:
        case: the case's name.
        smoke: tiny sizes (a check that it runs).
        options: the case's own options, parsed.
        work: a scratch folder, removed after the run.
        out: where the JSON and any extra files go (None: nowhere).
    """

    case: str
    smoke: bool
    options: argparse.Namespace
    work: Path
    out: Path | None
    started: float = field(default_factory=time.time)

    def log(self, message: str) -> None:
        """One progress line, with the seconds since the run began."""
        print(f"[{time.time() - self.started:6.0f} s] {message}", flush=True)

    def cache(self, cache: Path | None = None) -> Path:
        """The SYMID_CACHE of a worker: `cache`, or a fresh folder. A smoke run's
        workers all share the run's own (the harness's SYMID_CACHE: the caller's
        when set, else the scratch one): its figures mean nothing, and a solver
        one worker built, another would only build again from the same text."""
        if self.smoke:
            return Path(os.environ["SYMID_CACHE"])
        return cache if cache is not None else Path(tempfile.mkdtemp(prefix="cache-", dir=self.work))

    def env(self, cache: Path | None = None) -> dict[str, str]:
        """The environment of a worker: this checkout first, BLAS on one
        thread, and its own SYMID_CACHE (`cache`)."""
        return env_for(self.cache(cache))

    def isolated(self, call: str, spec: dict[str, Any], cap_s: float, cache: Path | None = None) -> Spawned:
        """`call` ("module:function", the function taking spec) in a worker
        process of its own with an empty cache (or `cache`), killed past cap_s:
        its JSON result, wall time and peak memory."""
        fresh = cache is None and not self.smoke
        env = self.env(cache)
        try:
            return spawn(call, spec, cap_s, env)
        finally:
            if fresh:
                shutil.rmtree(env["SYMID_CACHE"], ignore_errors=True)

    def process(self, cmd: list[str], cap_s: float, env: dict[str, str] | None = None,
                stdout: Any = subprocess.DEVNULL, cwd: Path | None = None) -> Measured:
        """A command as a user runs it (through `launch.py`): wall time, peak
        memory, CPU time and exit status; killed past cap_s."""
        return launch(cmd, cap_s, env if env is not None else self.env(), stdout, subprocess.DEVNULL,
                      cwd if cwd is not None else ROOT)


def _version(module: str) -> str:
    """The installed distribution's version (its metadata: the module's own
    `__version__`, without importing it where the case did not)."""
    try:
        return importlib.metadata.version(module)
    except importlib.metadata.PackageNotFoundError:
        return "not installed"


def machine() -> dict[str, Any]:
    """What the figures were measured on."""
    model, memory = "", ""
    try:
        model = next((line.split(":", 1)[1].strip() for line in Path("/proc/cpuinfo").read_text().splitlines()
                      if line.startswith("model name")), "")
        memory = Path("/proc/meminfo").read_text().splitlines()[0].split(":", 1)[1].strip()
    except (OSError, IndexError):
        pass
    gcc = subprocess.run(["gcc", "--version"], capture_output=True, text=True) if shutil.which("gcc") else None
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, cwd=ROOT)
    return {"cpu": model or platform.processor(), "cpu_count": os.cpu_count(), "memory": memory,
            "platform": platform.platform(), "python": platform.python_version(),
            **{m: _version(m) for m in ("numpy", "scipy", "sympy", "casadi")},
            "gcc": gcc.stdout.splitlines()[0] if gcc and gcc.stdout else "", "symid_commit": commit.stdout.strip(),
            "blas_threads": 1}


def flat(figures: Any, prefix: str = "") -> list[tuple[str, Any]]:
    """(dotted key, value) of every number, string or flag in nested dicts and
    lists (a list's items keyed by their index)."""
    if isinstance(figures, dict):
        return [pair for k, v in figures.items() for pair in flat(v, f"{prefix}{k}.")]
    if isinstance(figures, (list, tuple)):
        return [pair for k, v in enumerate(figures) for pair in flat(v, f"{prefix}{k}.")]
    if isinstance(figures, (int, float, str, bool)) or figures is None:
        return [(prefix[:-1], figures)]
    return []


def _show(value: Any) -> str:
    return f"{value:.4g}" if isinstance(value, float) else str(value)


def worker(payload: str) -> int:
    """The worker's side of `Context.isolated`: call and print the JSON result."""
    request = json.loads(payload)
    module, name = request["call"].split(":")
    tick = time.perf_counter()
    out = getattr(importlib.import_module(module), name)(request["spec"])
    out["worker_s"] = time.perf_counter() - tick
    print(json.dumps(out, default=float))
    return 0


def parser_for(cases: dict[str, Any], name: str | None, help: bool = True) -> argparse.ArgumentParser:
    """The harness's options, and the case's own when `name` is one."""
    parser = argparse.ArgumentParser(prog=f"python -m benchmarks{' ' + name if name in cases else ''}",
                                     description=__doc__.splitlines()[0], add_help=help)
    parser.add_argument("case", nargs="?", help="the case to run (--list: every case)")
    parser.add_argument("--list", action="store_true", help="list the cases and exit")
    parser.add_argument("--smoke", action="store_true", help="tiny sizes: a check that the case runs")
    parser.add_argument("--out", type=Path, help="folder for CASE.json (default benchmarks/results; "
                        "with --smoke, nothing is written unless given)")
    parser.add_argument("--worker", help=argparse.SUPPRESS)
    if name in cases and cases[name].options:
        cases[name].options(parser.add_argument_group(f"options of {name}"))
    return parser


def main(argv: list[str] | None = None) -> int:
    from benchmarks.cases import load_all

    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["--worker"]:
        return worker(argv[1])
    cases = load_all()
    name = parser_for(cases, None, help=False).parse_known_args(argv)[0].case
    args = parser_for(cases, name).parse_args(argv)
    if args.list or not args.case:
        width = max(map(len, cases))
        for case in cases.values():
            print(f"{case.name:{width}s}  {case.summary}")
        return 0
    if args.case not in cases:
        print(f"python -m benchmarks: no case {args.case!r}; the cases: {', '.join(cases)}", file=sys.stderr)
        return 2
    case = cases[args.case]
    missing = [tool for tool in case.tools if shutil.which(tool) is None]
    if missing:
        print(f"python -m benchmarks {case.name}: needs {', '.join(missing)}, not installed", file=sys.stderr)
        return 2
    os.environ.update(THREADS)
    out = args.out if args.out is not None else (None if args.smoke else RESULTS)
    with tempfile.TemporaryDirectory(prefix=f"symid-bench-{case.name}-") as tmp:
        # what a case builds in this process goes to a scratch cache, unless one is set;
        # temporary files of the case and its workers go to the scratch folder, removed with it
        os.environ.setdefault("SYMID_CACHE", str(Path(tmp) / "cache"))
        before = os.environ.get("TMPDIR"), tempfile.tempdir
        os.environ["TMPDIR"] = tempfile.tempdir = tmp
        ctx = Context(case.name, args.smoke, args, Path(tmp), out)
        load_start = list(os.getloadavg())
        try:
            figures = case.run(ctx)
        except Unavailable as exc:
            print(f"python -m benchmarks {case.name}: {exc}", file=sys.stderr)
            return 2
        except (KeyboardInterrupt, Signalled) as exc:  # workers are stopped on the way (processes.launch)
            print(f"python -m benchmarks {case.name}: interrupted; nothing written", file=sys.stderr)
            return 128 + (exc.signum if isinstance(exc, Signalled) else signal.SIGINT)
        except (RuntimeError, OSError, subprocess.CalledProcessError) as exc:  # a run that failed: said, not traced
            detail = f"{exc.cmd[0]} exited {exc.returncode}" if isinstance(exc, subprocess.CalledProcessError) else exc
            print(f"python -m benchmarks {case.name}: failed: {detail}", file=sys.stderr)
            return 3
        finally:
            tempfile.tempdir = before[1]
            if before[0] is None:
                os.environ.pop("TMPDIR", None)
            else:
                os.environ["TMPDIR"] = before[0]
    result = {"case": case.name, "smoke": args.smoke, "machine": machine(), "run_s": time.time() - ctx.started,
              "load_average_start": load_start, "load_average_end": list(os.getloadavg()), "figures": figures}
    for key, value in flat(figures):
        print(f"{key}: {_show(value)}")
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        (out / f"{case.name}.json").write_text(json.dumps(result, indent=1, default=float) + "\n", encoding="utf-8")
        written = case.report(result, out) if case.report else []
        for path in [out / f"{case.name}.json", *written]:
            ctx.log(f"wrote {path}")
    return 0


def entry() -> int:
    """`main`, with stdout closed early (`| head -1`) ending quietly, as symid's own commands do (141),
    and SIGTERM and SIGHUP answered as Ctrl-C is."""
    for signum in SIGNALS:
        signal.signal(signum, on_signal)
    try:
        return main()
    except BrokenPipeError:
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # no second error at exit
        return 141


if __name__ == "__main__":
    raise SystemExit(entry())
