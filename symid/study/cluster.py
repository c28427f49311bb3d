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
import socket
import time
from typing import TYPE_CHECKING, Any, Callable, Iterator, Sequence

import numpy as np

from symid.errors import EXIT_ANALYSIS, InputError, SymidError, check_signal
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


SCHEMES = ("tcp", "tls")  # the schemes a scheduler is reached by; an address without one is tcp://
HANDSHAKE_TIMEOUT = 10.0  # s for the address to answer Dask's handshake and say it is a scheduler (exit 2)
NO_WORKER_TIMEOUT = 60.0  # s a study waits with no live worker, or without its scheduler, before it ends (exit 3)
POLL = 0.5              # s between looks at the workers and the scheduler while chunks run
TICK = 0.02             # s between looks at the chunks' futures (a task takes 0.25 s at least)
TLS_KEYS = ("distributed.comm.tls.ca-file", "distributed.comm.tls.client.cert")


class ClusterLost(SymidError):
    """The cluster went away mid-study (its scheduler, or every worker for
    NO_WORKER_TIMEOUT): exit 3, the variants finished before it kept."""

    exit_status = EXIT_ANALYSIS


def check_address(address: str) -> str:
    """The scheduler's address as Dask takes it, checked before any connection.

    Raises:
        InputError: a scheme other than tcp:// or tls://, tls:// without the
            certificates in Dask's configuration, no host, no port or one out of range.
    """
    where = f"--scheduler {address}"
    scheme, sep, rest = address.partition("://")
    if not sep:
        scheme, rest = "tcp", address
    if scheme.lower() not in SCHEMES:
        raise InputError(f"{where}: the scheme {scheme}:// is not a Dask scheduler's "
                         f"(use {' or '.join(s + '://' for s in SCHEMES)}HOST:PORT)")
    host, colon, port = rest.rpartition(":")
    if not colon or "/" in rest or not host.strip("[]"):
        raise InputError(f"{where}: no {'host' if colon else 'port'} (use {scheme}://HOST:PORT, the port "
                         f"the scheduler prints, 8786 by default)")
    if not port.isdigit() or not 0 < int(port) < 65536:
        raise InputError(f"{where}: port {port!r} is not a number from 1 to 65535")
    if scheme.lower() == "tls":
        import dask

        missing = [key for key in TLS_KEYS if not dask.config.get(key, None)]
        if missing:
            names = ", ".join("DASK_" + k.upper().replace(".", "__").replace("-", "_") for k in missing)
            raise InputError(f"{where}: tls:// needs certificates: {names} not set (the CA file and the "
                             f"client's certificate, with its key in DASK_DISTRIBUTED__COMM__TLS__CLIENT__KEY "
                             f"unless in the same file)")
    return f"{scheme.lower()}://{rest}"


def handshake(address: str, timeout: float = HANDSHAKE_TIMEOUT) -> None:
    """Connect to `address` and ask who it is, all within `timeout` seconds.

    A listener that accepts and never answers, one that answers something other
    than Dask's protocol, or a Dask server that is not a scheduler (a worker)
    is refused here, before a client waits on it.

    Raises:
        InputError: naming the address, the wait and what was wrong.
    """
    import asyncio

    from distributed.comm import connect as open_comm
    from distributed.security import Security

    async def ask() -> Any:
        args = Security().get_connection_args("client")
        comm = await open_comm(address, timeout=timeout, **args)
        try:
            await comm.write({"op": "identity", "reply": True})
            return await comm.read()
        finally:
            comm.abort()

    host, _, port = address.partition("://")[2].rpartition(":")
    try:  # refused or unreachable: said at once, not after Dask's retries
        socket.create_connection((host.strip("[]"), int(port)), timeout=timeout).close()
    except OSError as exc:
        reason = exc.strerror or str(exc) or type(exc).__name__
        raise InputError(f"--scheduler {address}: no scheduler reached ({reason})") from None
    try:
        answer = asyncio.run(asyncio.wait_for(ask(), timeout))
    except (asyncio.TimeoutError, TimeoutError, OSError):
        raise InputError(f"--scheduler {address}: no answer to Dask's handshake in {timeout:g} s (is a Dask "
                         f"scheduler listening there?)") from None
    except Exception:  # whatever a junk listener's bytes made of Dask's reader (a MemoryError too)
        raise InputError(f"--scheduler {address}: it answered, but not in Dask's protocol (is a Dask "
                         f"scheduler listening there?)") from None
    kind = answer.get("type") if isinstance(answer, dict) else None
    if kind != "Scheduler":
        raise InputError(f"--scheduler {address}: answered as {kind or 'something'} not a Dask scheduler")


def connect(address: str, timeout: float | None = None) -> Client:
    """A client of the scheduler at `address`, checked first (`check_address`,
    then `handshake` within HANDSHAKE_TIMEOUT).

    Raises:
        InputError: a malformed address, or no scheduler there within `timeout`
            seconds, naming the address and the wait.
    """
    try:
        from distributed import Client
    except ImportError:
        raise InputError("--scheduler needs dask[distributed] (python3 -m pip install 'symid[sweep]')") from None
    address = check_address(address)
    timeout = CONNECT_TIMEOUT if timeout is None else timeout
    handshake(address, min(timeout, HANDSHAKE_TIMEOUT))
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
    """Submit every chunk and yield (first variant, figures) as each finishes.

    Raises:
        ClusterLost: no live worker, or no scheduler, for NO_WORKER_TIMEOUT s.
    """
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
        yield from _gathered(client, futures)
    finally:
        for future in futures:
            future.release()


def _gathered(client: Client, futures: dict[Any, int]) -> Iterator[tuple[int, Figures]]:
    """(first variant, figures) of each future as it finishes; a signal is
    answered within POLL seconds, and a cluster without a live worker or its
    scheduler for NO_WORKER_TIMEOUT seconds ends the study.

    Raises:
        ClusterLost: naming what went away and for how long.
    """
    pending = set(futures)
    alone_since: float | None = None  # when the cluster was first seen unable to run a task
    looked = time.monotonic()
    while pending:
        check_signal()
        finished = [f for f in pending if f.status in ("finished", "error")]
        for future in finished:
            pending.discard(future)
            yield futures[future], future.result()
        if finished:
            alone_since = None
            continue
        time.sleep(TICK)  # a signal interrupts it
        now = time.monotonic()
        if now - looked < POLL:
            continue
        looked = now
        why, final = _unable(client, pending)
        if why is None:
            alone_since = None
            continue
        alone_since = now if alone_since is None else alone_since
        if final or now - alone_since >= NO_WORKER_TIMEOUT:
            raise ClusterLost(f"--scheduler {client.scheduler.address}: {why}; {len(pending)} of "
                              f"{len(futures)} tasks unfinished")


def _unable(client: Client, pending: set[Any]) -> tuple[str | None, bool]:
    """Why the cluster cannot run the pending tasks now (None: it can), and
    whether that is final (the tasks are gone with their scheduler)."""
    if any(f.status == "cancelled" for f in pending):  # lost: a dead worker's result, computed again
        return "the scheduler went away mid-study (its tasks cancelled)", True
    if client.status != "running":
        return f"the scheduler unreachable for {NO_WORKER_TIMEOUT:g} s", False
    if not client.scheduler_info().get("workers"):
        return f"no live worker for {NO_WORKER_TIMEOUT:g} s", False
    return None, False
