"""Found trying symid as a new user on a full disk: `symid generate --target
numpy|casadi|c` left a truncated solver (CasADi's save even wrote empty files
without an error) and said only 'No space left on device'. Each file is now
whole or absent, and the one line names it. The fault here is a file-size
limit (RLIMIT_FSIZE), which fails a write as a full disk does, without root."""

from __future__ import annotations

import os
import resource
import subprocess
import sys
from pathlib import Path

import pytest

from symid import api
from tiers import first_quick

REPO = Path(__file__).resolve().parents[2]
LIMIT = 4096  # bytes: smaller than either target's solver


def generate(out: Path, target: str, cache: Path, limit: int | None) -> subprocess.CompletedProcess[str]:
    def limited() -> None:
        if limit is not None:
            resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    env = {**os.environ, "PYTHONPATH": str(REPO), "SYMID_CACHE": str(cache)}
    return subprocess.run([sys.executable, "-m", "symid", "generate", str(api.example("four_bar")), "--target", target,
                           "-o", str(out)], env=env, capture_output=True, text=True, timeout=600,
                          preexec_fn=limited)


# slow: two `symid generate` children of the c export; tests/io/test_machine_faults.py keeps a full disk in the
# quick tier
@pytest.mark.slow
@pytest.mark.parametrize("target", first_quick(["c", "numpy", "casadi"]))  # one writer of files; c writes the most
def test_generate_on_a_full_disk_leaves_whole_files_and_names_the_file(tmp_path, target):
    whole = generate(tmp_path / "whole", target, tmp_path / "cache", None)
    assert whole.returncode == 0, whole.stderr
    proc = generate(tmp_path / "full", target, tmp_path / "cache", LIMIT)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in proc.stderr
    assert str(tmp_path / "full") in lines[0], "the message names the file that could not be written"
    left = sorted((tmp_path / "full").iterdir()) if (tmp_path / "full").exists() else []
    assert len(left) < len(list((tmp_path / "whole").iterdir())), "some file did not fit"
    for path in left:  # what was written is whole: byte for byte the unlimited run's
        assert path.read_bytes() == (tmp_path / "whole" / path.name).read_bytes(), path.name
