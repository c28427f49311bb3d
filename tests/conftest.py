"""Shared fixtures: one private cache of generated solvers for the whole run."""

from __future__ import annotations

import os

import pytest


@pytest.fixture(scope="session", autouse=True)
def _private_cache(tmp_path_factory: pytest.TempPathFactory) -> None:
    """Generated and compiled solvers go to a temporary cache, never the user's."""
    if "SYMID_TEST_CACHE" in os.environ:  # reuse between local runs when asked to
        os.environ["SYMID_CACHE"] = os.environ["SYMID_TEST_CACHE"]
    else:
        os.environ["SYMID_CACHE"] = str(tmp_path_factory.mktemp("symid-cache"))
