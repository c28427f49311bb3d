"""A Dask cluster on 127.0.0.1 for the tests: a scheduler and workers, each
a process of its own, and a free port."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
DASK = [sys.executable, "-m", "distributed.cli.dask_scheduler"]
WORKER = [sys.executable, "-m", "distributed.cli.dask_worker"]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def environment(pythonpath: str) -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = pythonpath
    env["DASK_DISTRIBUTED__WORKER__DAEMON"] = "False"
    return env


class Cluster:
    """A scheduler and its workers, each a process of its own."""

    def __init__(self, tmp: Path) -> None:
        self.tmp = tmp
        self.port = free_port()
        self.address = f"tcp://127.0.0.1:{self.port}"
        self.processes: list[subprocess.Popen] = []
        self.workers: dict[str, subprocess.Popen] = {}
        self.start(DASK + ["--host", "127.0.0.1", "--port", str(self.port), "--dashboard-address", ":0"],
                   environment(str(REPO)), "scheduler")

    def start(self, command: list[str], env: dict[str, str], name: str) -> subprocess.Popen:
        log = open(self.tmp / f"{name}.log", "wb")
        proc = subprocess.Popen(command, env=env, stdout=log, stderr=subprocess.STDOUT, cwd=self.tmp)
        self.processes.append(proc)
        return proc

    def add_worker(self, name: str, pythonpath: str = str(REPO)) -> subprocess.Popen:
        proc = self.start(WORKER + [self.address, "--nthreads", "1", "--no-nanny", "--name", name,
                                    "--host", "127.0.0.1", "--dashboard-address", ":0"], environment(pythonpath),
                          name)
        self.workers[name] = proc
        return proc

    def client(self, workers: int):  # type: ignore[no-untyped-def]
        import distributed

        client = distributed.Client(self.address, timeout=30, set_as_default=False)
        client.wait_for_workers(workers, timeout=60)
        return client

    def stop(self) -> None:
        for proc in self.processes:
            if proc.poll() is None:
                proc.kill()
            proc.wait(timeout=30)
