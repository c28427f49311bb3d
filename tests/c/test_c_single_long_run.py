"""Single-precision C far from t = 0 (#19: "time and driver phase kept
small so long runs do not lose precision"): at t = 1e4 s the float results
stay within docs/c-export.md's bound of double precision, angles come back
reduced by whole turns, and the header says what cannot be reduced."""

from __future__ import annotations

import ctypes
import subprocess
from pathlib import Path

import numpy as np
import pytest

from cbuild import needs_cc
from small_mechanisms import cases
from symid import api
from symid.codegen.model import code_model
from symid.codegen import c as c_target
from symid.codegen.c import phase as c_phase
from symid.io.reader import load, loads
from symid.model.mechanism import T

pytestmark = pytest.mark.slow  # C builds dominate: 51 s for the file alone under load

from longrun import DRIVER, GROUP_FLOOR, INSTANTS, LONG_BOUND, LONG_T0, _driver, _rows, _turned  # noqa: F401


@needs_cc
@pytest.mark.parametrize("example", ["slider_crank", "quick_return"])
def test_single_precision_at_t_1e4_within_1e5_of_each_columns_peak_of_double(tmp_path: Path, example: str) -> None:
    """A few dozen instants from t0 = 1e4 s (a whole number of the bundled
    run's periods), single against double per column, angles modulo 2 pi."""
    exes = {p: _driver(tmp_path / p, example, p) for p in ("double", "single")}
    model = exes["double"][1]
    a = load(api.example(example)).analysis
    h = (a.t1 - a.t0) / (a.steps - 1)
    period = (a.steps - 1) * h
    k = round(LONG_T0 / period)
    one = _rows(exes["double"][0], a.t0, h, a.steps, model.q0)
    ng = len(model.q0)
    turns = _turned(model, one[0, 1:1 + ng], one[-1, 1:1 + ng])
    assert turns.any()  # something turns: the run tests the reduction
    guess = np.array(model.q0) + 2 * np.pi * k * turns  # double needs the whole turns; single reduces them
    t0 = a.t0 + k * period
    double = _rows(exes["double"][0], t0, h, INSTANTS, guess)
    single = _rows(exes["single"][0], t0, h, INSTANTS, guess)
    diff = single - double
    angles = [1 + j for j in range(ng) if j % 3 == 2]
    diff[:, angles] -= 2 * np.pi * np.round(diff[:, angles] / (2 * np.pi))
    assert np.all(np.abs(single[:, angles]) <= 4 * np.pi + 1e-5)  # carried reduced, as the header says
    # peaks over the bundled run (angles: at most pi, their reduced range)
    peak = np.max(np.abs(one), axis=0)
    peak[angles] = np.minimum(peak[angles], np.pi)
    ctx = c_target.context(model)
    groups = np.array([0] + [g + 1 for g, (_, _, size, _) in enumerate(ctx.row_parts) for _ in range(size)])
    scale = np.maximum(peak, GROUP_FLOOR * np.array([np.max(peak[groups == g]) for g in groups]))
    error = np.max(np.abs(diff), axis=0) / scale
    worst = int(np.argmax(error[1:])) + 1
    assert error[worst] <= LONG_BOUND, (model.row_columns[worst], error[worst])
    assert error[1:].max() > 1e-9  # single is single


def _instant_lib(folder: Path, name: str, precision: str) -> tuple[ctypes.CDLL, object]:
    model = code_model(load(api.example(name)))
    c_target.generate(model, folder, precision=precision)
    lib = folder / f"lib{name}.so"
    subprocess.run(["cc", "-std=c99", "-O1", "-fPIC", "-shared", str(folder / f"{name}_solver.c"), "-lm", "-o",
                    str(lib)], check=True)
    return ctypes.CDLL(str(lib)), model


@needs_cc
def test_single_precision_instant_at_t_1e4_gives_the_crank_angle_reduced_and_the_torque_of_double(
        tmp_path: Path) -> None:
    """slider_crank_instant at a float t past 1e4 s, from a guess turned
    50000 times: the crank angle is 2 pi frac(n t) (the driver, in closed
    form, at that float t) within 2e-6 rad and in [-pi, pi]; the motor torque
    is double's at the same t within 1e-5 of its value's scale."""
    name, n = "slider_crank", 5.0
    out = {}
    t = float(np.float32(LONG_T0 + 0.0123))
    for precision, ctype in (("double", ctypes.c_double), ("single", ctypes.c_float)):
        lib, model = _instant_lib(tmp_path / precision, name, precision)
        ctx = c_target.context(model, precision=precision)
        ng, nc = ctx.ng, ctx.nc
        q0 = np.array(model.q0, dtype=float)
        q0[2] = 2 * np.pi * n * t + 0.3  # near the solution, whole turns included
        q = (ctype * ng)(*q0)
        lam = (ctype * nc)()
        work, iwork = (ctype * ctx.work)(), (ctypes.c_int * ng)()
        info = (ctypes.c_int * 2)()
        fn = getattr(lib, f"{name}_instant")
        fn.restype = ctypes.c_int
        p = (ctype * ctx.np_).in_dll(lib, f"{name}_default_params")
        status = fn(ctype(t), p, ctype(1e-12), q, None, None, lam, None, info, work, iwork)
        assert status == 0, (precision, status)
        out[precision] = (np.array(q[:]), np.array(lam[:]))
    crank = 2 * np.pi * (n * t - round(n * t))
    q32, lam32 = out["single"]
    assert abs(q32[2]) <= np.pi + 1e-6 and abs(q32[2] - crank) <= 2e-6
    torque = out["double"][1][-1]  # the motor's multiplier: the driver is the last row
    scale = max(np.max(np.abs(out["double"][1])), 1.0)
    # single against double: float's 6e-8 times the condition of the multipliers, bound 1e-5 of the peak
    assert abs(lam32[-1] - torque) <= 1e-5 * scale, (lam32[-1], torque)


def test_reduction_wraps_angle_rows_and_keeps_gear_ratios_and_nonperiodic_time() -> None:
    """The rewrite itself: a driven crank's row is compared modulo 2 pi on its
    phase and sin(omega t) reads the same phase; a gear train's rows (angles
    times a ratio) and a driver on angles a spring reads are left as they
    are (a whole turn there is another load), and a pulse in t is listed as kept."""
    crank = code_model(load(api.example("slider_crank"))).flat
    red = c_phase.reduce(crank.ng, crank.phi, [crank.applied], crank.params)
    assert len(red.nu) == 1 and red.angles == [2, 5, 8] and not red.kept
    assert all(not e.has(T) for g in red.groups for e in g)
    assert isinstance(red.groups[0][-1], c_phase.Wrap)
    gears = code_model(load(api.example("planetary"))).flat
    red = c_phase.reduce(gears.ng, gears.phi, [], gears.params)
    assert red.angles == [] and any("q[11]" in k for k in red.kept)
    swing = code_model(load(api.example("slider_pendulum"))).flat  # a torsion spring reads its angles
    red = c_phase.reduce(swing.ng, swing.phi, [swing.applied], swing.params)
    assert red.wrapped_rows == [] and red.angles == [] and len(red.nu) == 2
    dig = code_model(load(api.example("excavator"))).flat
    red = c_phase.reduce(dig.ng, dig.phi, [dig.applied], dig.params)
    assert any(k.startswith("t in exp(") for k in red.kept)


FE_HARNESS = """#define _GNU_SOURCE
#include <fenv.h>
#include <stdio.h>

#include "{p}_solver.h"

/* A single-precision trajectory and an instant far from t = 0, the guess's
   angles turned many times, with invalid, division-by-zero and overflow
   trapping (SIGFPE on any); at the end no flag but inexact and underflow. */
int main(void)
{{
    static {p}_real work[{P}_WORK], rows[{n} * {P}_ROW], state[{P}_STATE];
    static int iwork[{P}_IWORK];
    {p}_real q[{P}_NG] = {{ {q0} }};
    long solved = 0;
    int k, status;
    for (k = 0; k < {P}_NG; ++k) state[k] = q[k];
    feclearexcept(FE_ALL_EXCEPT);
    feenableexcept(FE_INVALID | FE_DIVBYZERO | FE_OVERFLOW);
    status = {p}_trajectory({t0}f, {h}f, {n}, {p}_default_params, 1e-6f, state, rows, &solved, work, iwork);
    if (status != {P}_OK || solved != {n}) return 10 + status;
    status = {p}_instant({t0}f + 0.37f, {p}_default_params, 1e-6f, q, NULL, NULL, NULL, NULL, NULL, work, iwork);
    if (status != {P}_OK) return 20 + status;
    if (fetestexcept(FE_ALL_EXCEPT & ~(FE_INEXACT | FE_UNDERFLOW))) return 40;
    return 0;
}}
"""


@needs_cc
@pytest.mark.parametrize("example", ["slider_crank", "excavator"])
def test_single_precision_run_at_t_1e4_raises_no_floating_point_exception(tmp_path: Path, example: str) -> None:
    """The phases' float-to-long conversions and the wraps raise nothing but
    inexact (the excavator's pulse underflows there, as exp does)."""
    model = code_model(load(api.example(example)))
    c_target.generate(model, tmp_path, precision="single")
    a = load(api.example(example)).analysis
    q0 = np.array(model.q0, dtype=float)
    q0[2::3] += 2 * np.pi * 5e4  # turned many times: reduced on entry
    name = model.flat.name
    (tmp_path / "fe.c").write_text(FE_HARNESS.format(
        p=name, P=name.upper(), n=INSTANTS, q0=", ".join(f"{float(v)!r}f" for v in q0), t0=repr(LONG_T0),
        h=repr((a.t1 - a.t0) / (a.steps - 1))))
    exe = tmp_path / "fe"
    subprocess.run(["cc", "-std=c99", "-O1", "-Wall", "-Wextra", "-Werror", f"-I{tmp_path}", str(tmp_path / "fe.c"),
                    str(tmp_path / f"{name}_solver.c"), "-lm", "-o", str(exe)], check=True)
    run = subprocess.run([str(exe)], capture_output=True, text=True)
    assert run.returncode == 0, f"exit {run.returncode} (negative: killed by that signal; 40: a flag raised)"


@needs_cc
@pytest.mark.parametrize("case", ["scotch_yoke", "statics_q_and_one_reaction"])
def test_single_precision_crank_turning_many_times_matches_double_through_its_reductions(
        tmp_path: Path, case: str) -> None:
    """A crank driven by 4 t (no pi in it: nu = 2/pi in double) for 80 rad:
    its angle is reduced by whole turns a few times, across which dynamics
    predicts from accelerations and statics extrapolates the reduced
    positions; every column stays within 1e-5 of its peak of double."""
    model = code_model(loads(cases()[case]))
    name = model.flat.name
    runs = {}
    for precision in ("double", "single"):
        folder = tmp_path / precision
        c_target.generate(model, folder, precision=precision)
        exe = folder / "driver"
        subprocess.run(["cc", "-std=c99", "-O1", f"-I{folder}", f'-DSOLVER_H="{name}_solver.h"', f"-DP={name}",
                        f"-DPU={name.upper()}", str(DRIVER), str(folder / f"{name}_solver.c"), "-lm", "-o", str(exe)],
                       check=True)
        runs[precision] = _rows(exe, 0.0, 0.05, 401, model.q0)
    crank = 1 + 2  # the crank's phi column
    assert np.max(np.abs(runs["double"][:, crank])) > 60.0 and np.max(np.abs(runs["single"][:, crank])) < 4 * np.pi + 1e-5
    diff = runs["single"] - runs["double"]
    angles = [1 + j for j in range(len(model.q0)) if j % 3 == 2]
    diff[:, angles] -= 2 * np.pi * np.round(diff[:, angles] / (2 * np.pi))
    peak = np.max(np.abs(runs["double"]), axis=0)
    peak[angles] = np.minimum(peak[angles], np.pi)
    scale = np.maximum(peak, GROUP_FLOOR * peak[1:].max())
    error = np.max(np.abs(diff), axis=0) / scale
    assert error.max() <= LONG_BOUND, (model.row_columns[int(np.argmax(error))], error.max())
