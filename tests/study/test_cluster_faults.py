"""`symid sweep --scheduler` under the faults a machine has (issue 32, point 3):
every address checked before work starts (scheme, host, port, certificates,
Dask's handshake within HANDSHAKE_TIMEOUT), each fault one line with exit 2;
a study that loses its only worker or its scheduler mid-way ends with exit 3,
the variants finished before it written and named. The cluster is real: a
scheduler and a worker as processes on 127.0.0.1 (`test_sweep_cluster.Cluster`),
killed mid-study; the listeners are real sockets. No time is asserted: the
waits are made short (monkeypatched) only so the suite is quick.
"""

from __future__ import annotations

import csv
import socket
import threading
from pathlib import Path
from typing import Iterator

import pytest

from symid import api
from symid.cli import main
from symid.study import cluster as cluster_module

distributed = pytest.importorskip("distributed")

from cluster import Cluster, free_port  # noqa: E402  (after the skip: it imports distributed)

pytestmark = pytest.mark.slow  # starts Dask schedulers and workers, and listeners that never answer

CRANK = str(api.example("slider_crank"))
SWEEP = ["sweep", CRANK, "--steps", "3", "--grid", "n=4:6:3"]


def one_line(err: str) -> str:
    assert "Traceback" not in err, err
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1, f"stderr is not one line: {err!r}"
    return lines[0]


class Listener:
    """A TCP listener on 127.0.0.1 that accepts and then stays silent, or
    answers every connection with `junk`; it stops by itself when closed."""

    def __init__(self, junk: bytes | None = None) -> None:
        self.sock = socket.socket()
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen(8)
        self.sock.settimeout(0.2)
        self.port = self.sock.getsockname()[1]
        self.junk, self.held, self.stop = junk, [], threading.Event()
        self.thread = threading.Thread(target=self.serve, daemon=True)
        self.thread.start()

    def serve(self) -> None:
        while not self.stop.is_set():
            try:
                conn, _ = self.sock.accept()
            except OSError:  # the accept's timeout: look at stop again
                continue
            self.held.append(conn)
            if self.junk is not None:
                try:
                    conn.sendall(self.junk)
                except OSError:
                    pass

    def close(self) -> None:
        self.stop.set()
        self.thread.join(timeout=10)
        for conn in self.held:
            conn.close()
        self.sock.close()


@pytest.fixture
def quick(monkeypatch) -> None:
    monkeypatch.setattr(cluster_module, "HANDSHAKE_TIMEOUT", 2.0)
    monkeypatch.setattr(cluster_module, "NO_WORKER_TIMEOUT", 3.0)


def refused_port() -> int:
    return free_port()  # bound and released: nobody listens there


@pytest.mark.parametrize("address, said", [
    ("127.0.0.1", "127.0.0.1: no port (use tcp://HOST:PORT"),
    ("tcp://127.0.0.1", "tcp://127.0.0.1: no port"),
    ("tcp://:8786", "tcp://:8786: no host"),
    ("http://127.0.0.1:8786", "http://127.0.0.1:8786: the scheme http:// is not a Dask scheduler's "
                              "(use tcp:// or tls://HOST:PORT)"),
    ("inproc://127.0.0.1/1/2", "the scheme inproc:// is not a Dask scheduler's"),
    ("tcp://127.0.0.1:99999", "port '99999' is not a number from 1 to 65535"),
    ("tcp://127.0.0.1:x", "port 'x' is not a number from 1 to 65535"),
    ("tls://127.0.0.1:8786", "tls://127.0.0.1:8786: tls:// needs certificates: "
                             "DASK_DISTRIBUTED__COMM__TLS__CA_FILE, DASK_DISTRIBUTED__COMM__TLS__CLIENT__CERT not set"),
], ids=["no_scheme_no_port", "no_port", "no_host", "http", "inproc", "port_range", "port_word", "tls_no_certs"])
def test_a_malformed_address_is_one_line_and_exit_2_before_any_connection(tmp_path, capsys, quick, address, said):
    out = tmp_path / "o.csv"
    assert main([*SWEEP, "--scheduler", address, "-o", str(out)]) == 2
    line = one_line(capsys.readouterr().err)
    assert line.startswith(f"symid: --scheduler {address}: ") and said in line, line
    assert not out.exists()


def test_a_port_nobody_listens_on_is_exit_2(tmp_path, capsys, quick):
    port = refused_port()
    assert main([*SWEEP, "--scheduler", f"tcp://127.0.0.1:{port}", "-o", str(tmp_path / "o.csv")]) == 2
    assert one_line(capsys.readouterr().err) == (f"symid: --scheduler tcp://127.0.0.1:{port}: no scheduler reached "
                                                 f"(Connection refused)")


@pytest.mark.parametrize("junk, said", [
    (None, "no answer to Dask's handshake in 2 s (is a Dask scheduler listening there?)"),
    (b"HTTP/1.1 200 OK\r\nContent-Length: 5\r\n\r\nhello" * 40, "it answered, but not in Dask's protocol"),
    (b"\x00" * 4096, "it answered, but not in Dask's protocol"),
], ids=["accepts_never_answers", "http_server", "zeros"])
def test_a_listener_that_is_not_a_scheduler_is_exit_2_within_the_handshake_time(tmp_path, capsys, quick, junk,
                                                                                    said):
    listener = Listener(junk)
    try:
        address = f"tcp://127.0.0.1:{listener.port}"
        assert main([*SWEEP, "--scheduler", address, "-o", str(tmp_path / "o.csv")]) == 2
    finally:
        listener.close()
    line = one_line(capsys.readouterr().err)
    assert line.startswith(f"symid: --scheduler {address}: {said}"), line
    assert not (tmp_path / "o.csv").exists()


# -- lost mid-study ---------------------------------------------------------------------

# 48 variants of 200,001 instants on one single-threaded worker: several tasks
# of seconds each, so that when the first is back the others are still to run
LONG = ["sweep", CRANK, "--steps", "200001", "--grid", "L_rod=0.25:0.35:8", "--grid", "n=4:6:6"]
VARIANTS = 48


@pytest.fixture
def lonely(tmp_path) -> Iterator[Cluster]:
    c = Cluster(tmp_path)
    try:
        c.add_worker("only")
        c.client(1).close()
        yield c
    finally:
        c.stop()


def after_first_chunk(monkeypatch, then) -> None:  # type: ignore[no-untyped-def]
    """Call `then` once symid holds the first finished chunk (its figures
    gathered from the worker), as the next ones still run."""
    gathered = cluster_module._gathered

    def watched(client, futures):  # type: ignore[no-untyped-def]
        for k, item in enumerate(gathered(client, futures)):
            yield item
            if k == 0:
                then()

    monkeypatch.setattr(cluster_module, "_gathered", watched)


def kept(out: Path) -> list[dict[str, str]]:
    with out.open(newline="") as f:
        return list(csv.DictReader(f))


def check_lost(status: int, err: str, out: Path, c: Cluster, why: str) -> None:
    assert status == 3, err
    rows = kept(out)
    assert 0 < len(rows) < VARIANTS  # the first chunk at least, not all
    variants = [int(r["variant"]) for r in rows]
    assert variants == sorted(set(variants))  # in variant order, none twice
    assert all(r["status"] == "ok" for r in rows)
    line = one_line(err)
    assert line.startswith(f"symid: --scheduler {c.address}: {why}; "), line
    assert line.endswith(f"tasks unfinished; {out} holds the {len(rows)} variants finished before it"), line


def test_a_study_whose_only_worker_dies_ends_with_exit_3_keeping_the_finished(lonely, tmp_path, capsys, quick,
                                                                                  monkeypatch):
    worker = lonely.workers["only"]
    after_first_chunk(monkeypatch, lambda: (worker.kill(), worker.wait(timeout=30)))
    out = tmp_path / "part.csv"
    status = main([*LONG, "--scheduler", lonely.address, "-o", str(out)])
    check_lost(status, capsys.readouterr().err, out, lonely, "no live worker for 3 s")


def test_a_study_whose_scheduler_dies_ends_with_exit_3_keeping_the_finished(lonely, tmp_path, capsys, quick,
                                                                                  monkeypatch):
    scheduler = lonely.processes[0]
    after_first_chunk(monkeypatch, lambda: (scheduler.kill(), scheduler.wait(timeout=30)))
    out = tmp_path / "part.csv"
    status = main([*LONG, "--scheduler", lonely.address, "-o", str(out)])
    check_lost(status, capsys.readouterr().err, out, lonely,
               "the scheduler went away mid-study (its tasks cancelled)")
