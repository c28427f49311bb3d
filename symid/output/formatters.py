"""Where CSV blocks are formatted: a second thread, then other processes once
the table proves long.

NumPy releases the GIL inside its loops, but the formatter's Python between
them holds it: two threads reach about 1.4 cores. A long table (PROCESS_ROWS
rows or more) is therefore formatted by worker processes, forked (nothing
is imported again, and no user script runs twice); a short one never pays
for starting them. Each block's text is a pure function of the block, and
the caller writes the results in submission order, so the bytes are the
same wherever a block ran. A worker that dies (or a pool that cannot start)
costs that block a local formatting, never a wrong or missing row.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
from concurrent.futures import Executor, Future, ProcessPoolExecutor, ThreadPoolExecutor
from typing import Callable

from symid.backends import Array

PROCESS_ROWS = 32768  # rows submitted before worker processes take over
WORKERS = 2


def _ignore_interrupt() -> None:
    """Workers leave Ctrl-C to the main process, which stops them (no second traceback)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


class Formatters:
    """Submit blocks to be formatted by `fn` (a module-level function); `result`
    returns a block's text, formatting it here if its worker was lost."""

    def __init__(self, fn: Callable[[Array], bytes], process_rows: int | None = None) -> None:
        self.fn = fn
        self.process_rows = PROCESS_ROWS if process_rows is None else process_rows
        self.rows = 0
        cpus = os.cpu_count() or 1
        self.threads = ThreadPoolExecutor(max_workers=min(WORKERS, cpus))
        self.processes: Executor | None = None
        self.can_fork = cpus > 1 and "fork" in multiprocessing.get_all_start_methods()

    def submit(self, block: Array) -> Future[bytes]:
        self.rows += len(block)
        if self.processes is None and self.can_fork and self.rows > self.process_rows:
            try:
                self.processes = ProcessPoolExecutor(max_workers=WORKERS, mp_context=multiprocessing.get_context("fork"),
                                                     initializer=_ignore_interrupt)
            except (OSError, ValueError):  # no processes to be had: threads it stays
                self.can_fork = False
        if self.processes is not None:
            try:
                return self.processes.submit(self.fn, block)
            except (OSError, RuntimeError):  # a broken pool refuses work: back to threads
                self.processes, self.can_fork = None, False
        return self.threads.submit(self.fn, block)

    def result(self, future: Future[bytes], block: Array) -> bytes:
        """The block's text; a worker lost on the way (killed, out of memory) costs a local formatting."""
        try:
            return future.result()
        except (OSError, RuntimeError, EOFError):  # BrokenProcessPool is a RuntimeError
            return self.fn(block)

    def close(self) -> None:
        for pool in (self.threads, self.processes):
            if pool is not None:
                pool.shutdown(wait=True, cancel_futures=True)
