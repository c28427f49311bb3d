"""Single precision far from t = 0: the rows driver built for one example in
either precision, its rows, the whole turns an angle made, and the bounds
docs/c-export.md states (tests/c/test_c_single_long_run.py, test_c_long_time.py)."""

from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np

from symid import api
from symid.codegen import c as c_target
from symid.codegen.model import code_model
from symid.io.reader import load

DRIVER = Path(__file__).resolve().parents[1] / "c" / "rows_driver.c"
LONG_T0 = 1e4
# docs/c-export.md (long runs in single precision): within 1e-5 of each column's peak at t = 1e4 s
# where the header lists nothing as kept absolute; a column below GROUP_FLOOR
# of its group's peak (zero but for rounding) is measured against that
LONG_BOUND = 1e-5
GROUP_FLOOR = 1e-3
INSTANTS = 40


def _driver(folder: Path, name: str, precision: str) -> tuple[Path, object]:
    model = code_model(load(api.example(name)))
    c_target.generate(model, folder, precision=precision)
    exe = folder / "driver"
    subprocess.run(["cc", "-std=c99", "-O1", f"-I{folder}", f'-DSOLVER_H="{name}_solver.h"', f"-DP={name}",
                    f"-DPU={name.upper()}", str(DRIVER), str(folder / f"{name}_solver.c"), "-lm", "-o", str(exe)],
                   check=True)
    return exe, model


def _rows(exe: Path, t0: float, h: float, n: int, q0) -> np.ndarray:  # type: ignore[no-untyped-def]
    args = [str(exe), "rows", repr(t0), repr(h), str(n), *(repr(float(v)) for v in q0)]
    return np.loadtxt(subprocess.run(args, check=True, capture_output=True, text=True).stdout.splitlines(), ndmin=2)


def _turned(model, start: np.ndarray, end: np.ndarray) -> np.ndarray:  # type: ignore[no-untyped-def]
    """Per coordinate, the whole turns an angle made from start to end (0 elsewhere)."""
    ng = len(model.q0)
    turns = np.round((end - start) / (2 * np.pi))
    # a whole number of turns: 1e-6 rad is far below a turn and above double rounding of the angles
    angle = (np.arange(ng) % 3 == 2) & (np.abs(end - start - 2 * np.pi * turns) < 1e-6)
    return np.where(angle, turns, 0.0)
