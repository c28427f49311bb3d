"""`symid sweep` on a real Dask cluster on 127.0.0.1: a scheduler and two workers
started as processes (`dask scheduler`, `dask worker --nthreads 1`). The table is
the local one, in variant order; a worker killed mid-sweep costs no variant."""

from __future__ import annotations

from typing import Iterator

import numpy as np
import pytest

from cluster import Cluster
from symid import api
from symid.cli import main
from symid.study import design as vary
from symid.study.run import Sweep

pytestmark = pytest.mark.slow  # starts a Dask scheduler and workers

distributed = pytest.importorskip("distributed")

CRANK = str(api.example("slider_crank"))


@pytest.fixture(scope="module")
def cluster(tmp_path_factory) -> Iterator[Cluster]:
    c = Cluster(tmp_path_factory.mktemp("dask"))
    try:
        c.add_worker("w1")
        c.add_worker("w2")
        yield c
    finally:
        c.stop()


STEPS = 41
KILL_STEPS = 100_001
GRID = ["L_rod=0.25:0.35:4", "n=3:7:6"]


@pytest.fixture(scope="module")
def local() -> tuple:
    mech = api.load_mechanism(CRANK, steps=STEPS)
    v = vary.grid(GRID)
    return mech, v, api.sweep(mech, v, backend="c")


def test_cluster_table_is_the_local_table(cluster, local, tmp_path, capsys):
    mech, v, table = local
    client = cluster.client(2)
    try:
        remote = api.sweep(mech, v, backend="c", client=client)
    finally:
        client.close()
    assert remote.columns == table.columns
    assert np.array_equal(remote.data, table.data, equal_nan=True)
    # and through the command line, to a CSV byte for byte the local one
    table.write(tmp_path / "local.csv")
    args = ["sweep", CRANK, "--steps", str(STEPS), *(a for g in GRID for a in ("--grid", g))]
    assert main([*args, "-o", str(tmp_path / "remote.csv"), "--scheduler", cluster.address]) == 0
    capsys.readouterr()
    assert (tmp_path / "remote.csv").read_bytes() == (tmp_path / "local.csv").read_bytes()


def test_a_worker_killed_mid_sweep_loses_and_duplicates_no_variant(cluster, local):
    # long runs: a chunk of a few variants takes a good part of a second, so
    # that when the first chunk is back the other worker still holds some
    _, v, _ = local
    mech = api.load_mechanism(CRANK, steps=KILL_STEPS)
    table = api.sweep(mech, v, backend="c")
    client = cluster.client(2)
    try:
        sweep = Sweep(mech, v, "c", client=client)
        sweep.setup()
        done = []
        for count in sweep.run():
            done.append(count)
            if len(done) == 1:  # the other worker is mid-chunk or has chunks waiting
                names = {a: w["name"] for a, w in client.scheduler_info()["workers"].items()}
                held = [k for a, keys in client.processing().items() if names.get(a) == "w2" for k in keys]
                victim = cluster.workers.pop("w2")
                victim.kill()
                victim.wait(timeout=30)
        result = sweep.table()
    finally:
        client.close()
    assert held, "w2 held no chunk when killed: the test would not test a retry"
    assert sum(done) == len(v)
    assert result.variant.tolist() == list(range(len(v)))
    assert np.array_equal(result.data, table.data, equal_nan=True)
    cluster.add_worker("w3")  # back to two workers for any test after this one


def test_a_worker_without_symid_is_exit_2_naming_it(cluster, tmp_path, capsys):
    fake = tmp_path / "fake"
    (fake / "symid").mkdir(parents=True)
    (fake / "symid" / "__init__.py").write_text('raise ImportError("this symid is broken")\n')
    broken = cluster.add_worker("broken", pythonpath=str(fake))
    try:
        cluster.client(3).close()
        status = main(["sweep", CRANK, "--steps", "3", "--grid", "n=1:2:2", "-o", str(tmp_path / "o.csv"),
                       "--scheduler", cluster.address])
    finally:
        broken.kill()
        broken.wait(timeout=30)
    err = capsys.readouterr().err
    assert status == 2 and err.count("\n") == 1, err
    assert "worker broken (tcp://127.0.0.1:" in err and "cannot import symid or build the c solver" in err, err
    assert "this symid is broken" in err
    assert not (tmp_path / "o.csv").exists()


def test_the_scheduler_runs_a_sweep_without_importing_symid(cluster, local):
    # it unpickles every task: a task function named by reference would make
    # it import symid and sympy, seconds before the first chunk could start
    def imported() -> list[str]:  # nested: shipped by value, not by this module's name
        import sys

        return sorted(m for m in ("symid", "sympy") if m in sys.modules)

    mech, v, table = local
    client = cluster.client(2)
    try:
        remote = api.sweep(mech, v, backend="c", client=client)
        assert client.run_on_scheduler(imported) == []
    finally:
        client.close()
    assert np.array_equal(remote.data, table.data, equal_nan=True)


@pytest.mark.parametrize("variants, steps, workers, expected", [
    (1000, 1001, 2, 2),       # the grid: one task per worker (each costs a round trip)
    (100_000, 1001, 2, 8),    # the Monte Carlo: four per worker (a lost worker costs a quarter)
    (24, 100_001, 2, 6),      # in between: a whole number per worker
    (3, 11, 5, 5),            # tiny: still one per worker
])
def test_tasks_are_a_whole_number_per_worker_and_few_for_a_short_sweep(variants, steps, workers, expected):
    from symid.study.cluster import tasks

    assert tasks(variants * steps, workers) == expected
