"""Shared fixtures: one private cache of generated solvers for the whole run
(under pytest-xdist, shared by the workers), and thread pools sized to the
worker's share of the cores."""

from __future__ import annotations

import os

import pytest


@pytest.fixture(scope="session", autouse=True)
def _private_cache(tmp_path_factory: pytest.TempPathFactory) -> None:
    """Generated and compiled solvers go to a temporary cache, never the user's,
    one for the whole run: under xdist the workers share it (their temporary
    folders are popen-gwN in the run's own), so a solver two workers both need
    is built once, not once each. Sharing is safe: the cache is content-addressed
    and an entry is renamed into place only when complete (symid.codegen.cache),
    so a worker finds it whole or builds it itself, never half-read."""
    if "SYMID_TEST_CACHE" in os.environ:  # reuse between local runs when asked to (shared: content-addressed)
        os.environ["SYMID_CACHE"] = os.environ["SYMID_TEST_CACHE"]
        return
    from runshare import run_folder

    cache = run_folder(tmp_path_factory) / "symid-cache"
    cache.mkdir(mode=0o700, exist_ok=True)
    os.environ["SYMID_CACHE"] = str(cache)


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


# The quick tier (`-m "not slow"`) runs a test parametrized over the bundled
# examples on these only; the others (the excavator's expressions, Andrews'
# 21 coordinates, the planetary gears, ...) are in the slow tier. Together they
# keep a plain slider-crank, a slider in a moving slot and joint friction.
QUICK_EXAMPLES = frozenset({"slider_crank", "quick_return", "slider_crank_friction"})


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Mark `slow` the bundled examples outside QUICK_EXAMPLES of a test that also
    runs on one of them (a test on big examples only keeps its tier)."""
    from symid import api

    bundled = frozenset(api.examples())

    def examples_of(item: pytest.Item) -> set[str]:
        params = getattr(getattr(item, "callspec", None), "params", {})
        return {v for v in params.values() if isinstance(v, str) and v in bundled}

    quick_tests = {(item.path, item.originalname) for item in items  # type: ignore[attr-defined]
                   if examples_of(item) & QUICK_EXAMPLES}
    for item in items:
        used = examples_of(item)
        if used and not used & QUICK_EXAMPLES and (item.path, item.originalname) in quick_tests:  # type: ignore[attr-defined]
            item.add_marker(pytest.mark.slow)
