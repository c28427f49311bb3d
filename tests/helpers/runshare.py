"""What the workers of one test run share: a folder per run (under pytest-xdist
the workers' temporary folders are popen-gwN in it), and entries in it built
once per run by whichever worker asks first (a Cortex-M build, a 40-digit
truth, an export), keyed by the caller on everything the entry depends on.

An entry is built under a lock file, so a second worker asking for it waits
for the first instead of building it again, and is built in a private folder
renamed into place when complete: a worker finds it whole or not at all. An
entry whose build raised is not kept; the next asker builds it again and
sees the same error."""

from __future__ import annotations

import fcntl
import hashlib
import os
import pickle
import shutil
import tempfile
from pathlib import Path
from typing import Any, Callable

import pytest


def run_folder(factory: pytest.TempPathFactory) -> Path:
    """The run's own temporary folder, the same for every worker of the run."""
    run = factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        run = run.parent  # the run's folder, above this worker's popen-gwN
    return run


def key_of(*parts: object) -> str:
    """A short name for an entry from everything it depends on (texts, paths' contents, flags)."""
    digest = hashlib.sha256()
    for part in parts:
        data = part.read_bytes() if isinstance(part, Path) else repr(part).encode()
        digest.update(len(data).to_bytes(8, "little") + data)
    return digest.hexdigest()[:24]


def shared_dir(factory: pytest.TempPathFactory, key: str, build: Callable[[Path], None]) -> Path:
    """The folder of entry `key`: build(folder) fills a fresh folder the first time
    in the run, every later call (any worker) returns it as built."""
    root = run_folder(factory) / "shared"
    root.mkdir(exist_ok=True)
    entry = root / key
    with open(root / f"{key}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes
        if not entry.is_dir():
            work = Path(tempfile.mkdtemp(prefix=f".{key}.", dir=root))
            try:
                build(work)
            except BaseException:
                shutil.rmtree(work, ignore_errors=True)
                raise
            work.rename(entry)
    return entry


def shared_value(factory: pytest.TempPathFactory, key: str, compute: Callable[[], Any]) -> Any:
    """compute()'s value, computed once in the run (any worker) and read back by
    the others (pickled in the run's private folder: the tests' own data)."""
    def build(folder: Path) -> None:
        (folder / "value.pickle").write_bytes(pickle.dumps(compute()))

    return pickle.loads((shared_dir(factory, key, build) / "value.pickle").read_bytes())
