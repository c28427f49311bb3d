"""benchmarks.callgrind's trajectory driver builds and runs for every bundled example,
whatever its name holds: slider_crank_counterweight contains T and H, which
the driver's marks once were, and came out mangled (no instruction count)."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from benchmarks import callgrind  # noqa: E402
from symid import api  # noqa: E402

pytestmark = [pytest.mark.slow,  # a benchmark's driver, built and run
              pytest.mark.skipif(shutil.which("gcc") is None, reason="gcc is not installed")]


@pytest.mark.parametrize("example", ["slider_crank_counterweight", "slider_pendulum"])
def test_driver_solves_the_examples_trajectory(tmp_path: Path, example: str) -> None:
    mech = api.load_mechanism(api.example(example))
    folder = ROOT / "generated" / example / "c"
    driver = tmp_path / "driver.c"
    q0 = api.prepare(mech, "numpy").q0()  # assembled at t0, as `symid solve` starts
    driver.write_text(callgrind.driver_source(mech.name, mech.analysis, q0, 101))
    assert "@" not in driver.read_text()
    subprocess.run(["gcc", "-O1", "-std=c99", "-I", str(folder), str(driver), str(folder / f"{example}_solver.c"),
                    "-o", str(tmp_path / "driver"), "-lm"], check=True)
    out = subprocess.run([str(tmp_path / "driver"), "101"], capture_output=True, text=True, check=True).stdout
    assert out.split() == ["0", "101"]
