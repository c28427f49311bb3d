"""Shared fixtures: one private cache of generated solvers for the whole run
(under pytest-xdist, one per worker), and thread pools sized to the worker's
share of the cores."""

from __future__ import annotations

import os

import pytest


@pytest.fixture(scope="session", autouse=True)
def _private_cache(tmp_path_factory: pytest.TempPathFactory) -> None:
    """Generated and compiled solvers go to a temporary cache, never the user's.
    Under xdist each worker has its own (tmp_path_factory is per worker): a
    solver two workers both need is built twice, never half-read."""
    if "SYMID_TEST_CACHE" in os.environ:  # reuse between local runs when asked to (shared: content-addressed)
        os.environ["SYMID_CACHE"] = os.environ["SYMID_TEST_CACHE"]
    else:
        os.environ["SYMID_CACHE"] = str(tmp_path_factory.mktemp("symid-cache"))


@pytest.fixture(scope="session", autouse=True)
def _cores_shared_by_workers() -> None:
    """The CSV formatter's and the C sweep's thread pools default to
    os.cpu_count(): under `pytest -n N` every worker would start that many
    threads on the same cores. The product is right to take every core; the
    tests cap the count each worker sees at its share (a test that wants two
    threads asks for them: workers=2)."""
    workers = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1") or 1)
    if workers <= 1:
        return
    share = max(1, (os.cpu_count() or 1) // workers)
    os.cpu_count = lambda: share  # type: ignore[assignment]  # the worker's own process only
