"""How the harness runs a process: in its own process group, through the
small launcher (`launch.py`) that reads the child's own peak memory and CPU
time, killed past its cap; and a worker, a function of a case called in a
fresh interpreter (`python -m benchmarks --worker`), so that its setup is
cold and its peak memory its own.
"""

from __future__ import annotations

import contextlib
import itertools
import json
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterator

ROOT = Path(__file__).resolve().parent.parent
THREADS = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


@dataclass
class Measured:
    """One process run through `launch.py`."""

    wall_s: float
    peak_rss_mb: float | None
    status: int
    cpu_s: float | None
    stopped: bool


@dataclass
class Spawned:
    status: str          # "ok", "failed" or "stopped"
    result: dict[str, Any]
    wall_s: float
    peak_rss_mb: float | None
    note: str = ""


LAUNCH = Path(__file__).with_name("launch.py")
SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)  # what ends a run: `on_signal` answers them
_held: list[int] | None = None  # signals that came while a child was being created


class Signalled(BaseException):
    """SIGTERM or SIGHUP arrived: the run ends as Ctrl-C ends it, with 128 + N."""

    def __init__(self, signum: int) -> None:
        super().__init__(signum)
        self.signum = signum


def on_signal(signum: int, _frame: Any) -> None:
    """The harness's handler of SIGNALS: KeyboardInterrupt or Signalled, at
    once, or as soon as the child being created is known (`_holding`)."""
    if _held is not None:
        _held.append(signum)
        return
    raise KeyboardInterrupt if signum == signal.SIGINT else Signalled(signum)


@contextlib.contextmanager
def _holding() -> Iterator[None]:
    """Hold the signals while a child is created: one raised inside Popen
    (after the fork, before it returns) would leave a child nobody can stop."""
    global _held
    _held = []
    try:
        yield
    finally:
        held, _held = _held, None
        if held:
            on_signal(held[0], None)
_LAUNCHES = itertools.count()  # names the launcher's report: nothing is created before the child runs


def launch(cmd: list[str], cap_s: float, env: dict[str, str], stdout: Any, stderr: Any,
           cwd: Path = ROOT) -> Measured:
    """One command run through `launch.py` in its own process group, the
    group killed (by id) past cap_s, or when the harness is interrupted (its
    own group does not get the terminal's signals)."""
    report = Path(tempfile.gettempdir()) / f"symid-launch-{os.getpid()}-{next(_LAUNCHES)}.json"
    stopped = threading.Event()
    proc: subprocess.Popen[bytes] | None = None

    def stop() -> None:
        stopped.set()
        try:
            if proc is not None:
                os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass

    timer = threading.Timer(cap_s, stop)
    timer.daemon = True  # never what keeps the harness alive
    tick = time.perf_counter()
    try:
        with _holding():
            proc = subprocess.Popen([sys.executable, str(LAUNCH), str(report), *cmd], stdout=stdout, stderr=stderr,
                                    env=env, cwd=cwd, start_new_session=True)
        timer.start()
        proc.wait()
    except BaseException:
        if proc is not None:
            stop()
            proc.wait()
            gone(proc.pid)
        report.unlink(missing_ok=True)
        raise
    finally:
        timer.cancel()
    wall = time.perf_counter() - tick
    try:
        measured = json.loads(report.read_text())
        rss, code, cpu = measured["maxrss_mb"], measured["status"], measured["cpu_s"]
    except (OSError, ValueError, KeyError):
        rss, code, cpu = None, proc.returncode, None
    report.unlink(missing_ok=True)
    return Measured(wall, rss, code, cpu, stopped.is_set())


def gone(group: int, wait_s: float = 10.0) -> None:
    """Wait until a killed process group has no member left: its grandchildren
    (the worker under the launcher) are reaped by init, a moment after the
    launcher itself; an interrupted harness ends after its workers, not before."""
    end = time.monotonic() + wait_s
    while time.monotonic() < end:
        try:
            os.killpg(group, 0)
        except ProcessLookupError:
            return
        time.sleep(0.01)


def spawn(call: str, spec: dict[str, Any], cap_s: float, env: dict[str, str]) -> Spawned:
    """Run `call` ("module:function") on spec in a worker process; its last
    stdout line is the function's JSON result."""
    cmd = [sys.executable, "-m", "benchmarks", "--worker", json.dumps({"call": call, "spec": spec})]
    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err:
        got = launch(cmd, cap_s, env, out, err)
        wall, rss, code = got.wall_s, got.peak_rss_mb, got.status
        if got.stopped:
            return Spawned("stopped", {}, wall, rss, f"stopped after {cap_s:.0f} s")
        out.seek(0)
        err.seek(0)
        lines = out.read().decode(errors="replace").strip().splitlines()
        if code != 0 or not lines:
            tail = err.read().decode(errors="replace").strip().splitlines()
            return Spawned("failed", {}, wall, rss, tail[-1][:300] if tail else f"exit {code}")
        return Spawned("ok", json.loads(lines[-1]), wall, rss)


def env_for(cache: Path) -> dict[str, str]:
    env = {**os.environ, **THREADS, "SYMID_CACHE": str(cache)}
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(ROOT), env.get("PYTHONPATH", "")) if p)
    return env


def timed_process(cmd: list[str], env: dict[str, str], cap_s: float) -> tuple[float, float | None, int]:
    """(wall s, peak RSS MB, exit status) of one process, killed past cap_s."""
    got = launch(cmd, cap_s, env, subprocess.DEVNULL, subprocess.DEVNULL)
    return got.wall_s, got.peak_rss_mb, got.status
