"""A study's chunks on a Dask distributed cluster.

Each chunk is one task, a pure function of (mechanism, variants, backend): a
worker lost mid-sweep costs the scheduler a rerun of its tasks elsewhere, and
the results are gathered by chunk, so none is lost or counted twice and the
table is in variant order whatever ran where. Each worker process keeps the
mechanism and its solver in a memo keyed by the mechanism's bytes; the solver
itself comes from the worker's cache, keyed by the structure.
"""

from __future__ import annotations

import hashlib
import pickle
from typing import TYPE_CHECKING, Any, Callable, Iterator, Sequence

import numpy as np

from symid.errors import InputError
from symid.model.mechanism import Mechanism
from symid.study.figures import Figures
from symid.study.design import Variants

if TYPE_CHECKING:
    from distributed import Client

CONNECT_TIMEOUT = 10.0  # s to reach a scheduler before giving up (exit 2)
TASKS_PER_WORKER = 4    # chunks per worker at most: a lost worker costs a fraction of the sweep
# at least per task (~0.25 s on one core): each task costs the scheduler's round
# trip, so a short sweep gets one task per worker (the 1000-variant grid: 1.6x
# the threaded local solve with four per worker, 1.1x with one, measured together)
TASK_MIN_INSTANTS = 600_000
TASK_INSTANTS = 20_000_000  # at most per task: ~2 s on the batch engine, a cheap retry
RETRIES = 3             # reruns of a task that raised (a lost worker's tasks are rerun regardless)

_MEMO: dict[tuple[str, str], Mechanism] = {}  # this process's studies: (mechanism digest, backend) -> mechanism


def connect(address: str, timeout: float | None = None) -> Client:
    """A client of the scheduler at `address`.

    Raises:
        InputError: unreachable within `timeout` seconds, naming the address and the wait.
    """
    try:
        from distributed import Client
    except ImportError:
        raise InputError("--scheduler needs dask[distributed] (python3 -m pip install 'symid[sweep]')") from None
    timeout = CONNECT_TIMEOUT if timeout is None else timeout
    try:
        return Client(address, timeout=timeout, set_as_default=False)
    except (OSError, TimeoutError, ValueError) as exc:
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise InputError(f"--scheduler {address}: no scheduler reached in {timeout:g} s ({reason})") from None


def _digest(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def _memo(key: str, data: bytes, backend: str) -> Mechanism:
    """The mechanism of `data`, unpickled and its solver built once per process."""
    found = _MEMO.get((key, backend))
    if found is None:
        from symid.study.run import warm

        found = pickle.loads(data)
        warm(found, backend)
        _MEMO[(key, backend)] = found
    return found


def solve_chunk(key: str, data: bytes, names: Sequence[str], base: np.ndarray, backend: str) -> Figures:
    """One task: the figures of a chunk of variants (pure: the same inputs give the same figures)."""
    from symid.study.run import _engine

    engine, _ = _engine(backend)
    return engine(_memo(key, data, backend), names, base, backend, 1)


def _task() -> Callable[[str, bytes, Sequence[str], np.ndarray, str], Figures]:
    """`solve_chunk` as the function of a task, defined inside a function so
    that Dask ships it by value: the scheduler unpickles each task it is
    given, and a function named by reference makes it import symid, and with
    it sympy (seconds before the first chunk starts)."""
    def task(key: str, data: bytes, names: Sequence[str], base: np.ndarray, backend: str) -> Figures:
        from symid.study.cluster import solve_chunk

        return solve_chunk(key, data, names, base, backend)

    return task


def _probe() -> Callable[[str, bytes, str], str]:
    """The function each worker runs at setup; defined here, inside a function, so
    that Dask ships it by value and a worker without symid reports the ImportError."""
    def probe(key: str, data: bytes, backend: str) -> str:
        from symid.study.cluster import _memo

        _memo(key, data, backend)
        return "ok"

    return probe


def warm_workers(client: Client, mechanism: Mechanism, backend: str) -> None:
    """Import symid and build the solver on every worker, once.

    Raises:
        InputError: no worker, or a worker that cannot (naming it and why).
    """
    data = pickle.dumps(mechanism)
    if not client.scheduler_info().get("workers"):
        try:
            client.wait_for_workers(1, timeout=CONNECT_TIMEOUT)
        except (OSError, TimeoutError):
            raise InputError(f"--scheduler {client.scheduler.address}: no worker joined in "
                             f"{CONNECT_TIMEOUT:g} s") from None
    try:
        answers = client.run(_probe(), _digest(data), data, backend, on_error="return")
    except Exception as exc:  # a worker that cannot even take the function
        raise InputError(f"--scheduler: a worker failed at setup: {type(exc).__name__}: {exc}") from None
    info = client.scheduler_info().get("workers", {})
    for worker, answer in sorted(answers.items()):
        if answer != "ok":
            reason = str(answer).splitlines()[0] if str(answer) else ""
            name = info.get(worker, {}).get("name", worker)
            who = worker if str(name) == worker else f"{name} ({worker})"
            raise InputError(f"--scheduler: worker {who} cannot import symid or build the {backend} solver: "
                             f"{type(answer).__name__}: {reason}")


def tasks(instants: int, workers: int) -> int:
    """How many tasks to cut a sweep of `instants` into: a whole number per
    worker (none idles at the end), few (Dask's overhead is per task) but up
    to TASKS_PER_WORKER each once tasks are long (a lost worker costs little)."""
    each = -(-instants // (TASK_MIN_INSTANTS * workers))
    return workers * max(1, min(TASKS_PER_WORKER, each))


def run_chunks(client: Client, mechanism: Mechanism, variants: Variants, backend: str,
               ) -> Iterator[tuple[int, Figures]]:
    """Submit every chunk and yield (first variant, figures) as each finishes."""
    from distributed import as_completed

    data = pickle.dumps(mechanism)
    key = _digest(data)
    k = len(variants)
    workers = max(1, len(client.scheduler_info().get("workers", {})))
    per = max(1, min(-(-k // tasks(k * mechanism.analysis.steps, workers)),
                     TASK_INSTANTS // max(mechanism.analysis.steps, 1)))
    futures: dict[Any, int] = {}
    task = _task()
    for first in range(0, k, per):
        chunk = variants.values[first:first + per]
        future = client.submit(task, key, data, variants.names, chunk, backend,
                               pure=True, retries=RETRIES,
                               key=f"symid-sweep-{key[:16]}-{first}-{_digest(chunk.tobytes())[:16]}")
        futures[future] = first
    try:
        for future in as_completed(list(futures), loop=client.loop):
            yield futures[future], future.result()
    finally:
        for future in futures:
            future.release()
