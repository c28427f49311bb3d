"""The instructions case's driver (benchmarks.callgrind's CALLS_DRIVER) never
rots: it builds against the committed slider-crank C solver, runs a
trajectory, and its `_instant` call from a guess near the solution lands on
the trajectory's own q (so the instructions it counts are those of a right
solve). No timing assertions."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from benchmarks import callgrind  # noqa: E402

pytestmark = [pytest.mark.slow,  # a benchmark's driver, built and run
              pytest.mark.skipif(shutil.which("gcc") is None, reason="gcc is not installed")]


@pytest.fixture(scope="module")
def driver(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("sc")
    for f in (ROOT / "generated" / "slider_crank" / "c").iterdir():
        shutil.copy(f, folder / f.name)
    grid = callgrind.file_grid(ROOT / "symid" / "examples" / "slider_crank.toml")
    return callgrind.build(folder, "slider_crank", callgrind.default_q0(folder, "slider_crank"), grid)


def test_driver_trajectory_solves_every_instant(driver: Path) -> None:
    status, done, ns = subprocess.run([str(driver), "traj", "201", "2"], capture_output=True,
                                      text=True, check=True).stdout.split()
    assert (status, done) == ("0", "201") and float(ns) > 0.0


def test_driver_instant_from_a_near_guess_lands_on_the_trajectory(driver: Path) -> None:
    status, done, iters, far = subprocess.run([str(driver), "inst", "3"], capture_output=True,
                                              text=True, check=True).stdout.split()
    assert (status, done) == ("0", "3")
    assert 1 <= int(iters) <= 4  # a guess 1e-6 off: a few Newton steps, not a fresh assembly
    # the instant's distance from the trajectory's q: the Newton tol, with room
    assert float(far) < 1e-9
