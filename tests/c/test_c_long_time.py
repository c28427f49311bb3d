"""Time that does not run out (#30, point 2): single-precision C at t = 1e6 s
through the split-time instant (`_instant_at(whole, frac)`) and through
`_trajectory` from t0 = 1e6, within docs/c-export.md's 1e-5 of each column's
peak of double; the trajectory's count exact past 2^24 instants (two reals:
the rest and the multiples of 2^24); double's `_instant_at` is its
`_instant` at whole + frac, bit for bit."""

from __future__ import annotations

import ctypes
import subprocess
from pathlib import Path

import numpy as np
import pytest

from symid import api
from symid.codegen import c as c_target
from symid.codegen.c.layout import COUNT_CARRY
from symid.codegen.model import code_model
from symid.io.reader import load
from cbuild import needs_cc
from longrun import GROUP_FLOOR, LONG_BOUND, _driver, _rows, _turned

pytestmark = pytest.mark.slow  # two to four C builds per test

NAME = "slider_crank"  # its crank turns at n = 5 rev/s: the phase is 2 pi frac(5 t)
WHOLE = 1_000_000  # t = 1e6 s: a float's ulp there is 1/16 s, 62 ticks of 1 ms
REAL = {"double": ctypes.c_double, "single": ctypes.c_float}


def _lib(folder: Path, precision: str):  # type: ignore[no-untyped-def]
    model = code_model(load(api.example(NAME)))
    c_target.generate(model, folder, precision=precision)
    lib = folder / f"lib{NAME}.so"
    subprocess.run(["cc", "-std=c99", "-O1", "-fPIC", "-shared", str(folder / f"{NAME}_solver.c"), "-lm", "-o",
                    str(lib)], check=True)
    return ctypes.CDLL(str(lib)), model, c_target.context(model, precision=precision)


def _bundled(model) -> tuple[np.ndarray, float, float]:  # type: ignore[no-untyped-def]
    """The bundled run in double through the C rows driver, its h and period."""
    a = load(api.example(NAME)).analysis
    h = (a.t1 - a.t0) / (a.steps - 1)
    return a, h, (a.steps - 1) * h


def _scale(ctx, one: np.ndarray, angles: list[int]) -> np.ndarray:  # type: ignore[no-untyped-def]
    """Per column its peak over the bundled run (angles at most pi, their
    reduced range; a column below GROUP_FLOOR of its group's peak, zero but
    for rounding, against that), as test_c_single_long_run measures."""
    peak = np.max(np.abs(one), axis=0)
    peak[angles] = np.minimum(peak[angles], np.pi)
    groups = np.array([0] + [g + 1 for g, (_, _, size, _) in enumerate(ctx.row_parts) for _ in range(size)])
    return np.maximum(peak, GROUP_FLOOR * np.array([np.max(peak[groups == g]) for g in groups]))


def _error(single: np.ndarray, double: np.ndarray, scale: np.ndarray, angles: list[int]) -> np.ndarray:
    diff = single - double
    diff[..., angles] -= 2 * np.pi * np.round(diff[..., angles] / (2 * np.pi))  # angles modulo 2 pi
    return np.max(np.abs(np.atleast_2d(diff)), axis=0) / scale


def _instant(lib, ctx, precision: str, args: tuple,  # type: ignore[no-untyped-def]
             q0: np.ndarray, entry: str = "instant", n: float | None = None) -> tuple[int, np.ndarray]:
    """One call of `entry` (instant or instant_at, its time arguments in
    args): status and the row (t = 0, q, qd, qdd, lam, reactions)."""
    real = REAL[precision]
    ng, nc, nr = ctx.ng, ctx.nc, len(code_model(load(api.example(NAME))).flat.reactions)
    q, qd, qdd = (real * ng)(*q0), (real * ng)(), (real * ng)()
    lam, reac = (real * nc)(), (real * max(nr, 1))()
    work, iwork, info = (real * ctx.work)(), (ctypes.c_int * ng)(), (ctypes.c_int * 2)()
    fn = getattr(lib, f"{NAME}_{entry}")
    fn.restype = ctypes.c_int
    p = (real * ctx.np_)(*(real * ctx.np_).in_dll(lib, f"{NAME}_default_params")[:])
    if n is not None:
        p[7] = n  # the crank's speed, rev/s
    status = fn(*args, p, real(1e-12), q, qd, qdd, lam, reac, info, work, iwork)
    return status, np.concatenate([[0.0], q[:], qd[:], qdd[:], lam[:], reac[:nr]])


@needs_cc
def test_single_instant_at_t_1e6_within_1e5_of_each_columns_peak_of_double(tmp_path: Path) -> None:
    """_instant_at(1000000, frac) in single against double's _instant at
    1e6 + frac (exact in double) over a period's fractions, every output
    column within 1e-5 of its peak (angles modulo 2 pi); single's _instant at
    the float nearest 1e6 + frac cannot (its t is off by up to 1/32 s)."""
    exe, model = _driver(tmp_path / "rows", NAME, "double")
    a, h, period = _bundled(model)
    one = _rows(exe, a.t0, h, a.steps, model.q0)
    ng = len(model.q0)
    turns = _turned(model, one[0, 1:1 + ng], one[-1, 1:1 + ng])
    libs = {p: _lib(tmp_path / p, p) for p in ("double", "single")}
    ctx = libs["single"][2]
    angles = [1 + j for j in range(ng) if j % 3 == 2]
    scale = _scale(ctx, one, angles)
    width = 1 + 3 * ng + ctx.nc + len(model.flat.reactions)
    assert width == one.shape[1]  # the instant's outputs are the row's columns
    worst, naive = np.zeros(width), np.zeros(width)
    # fractions across the period at 1e6 s and past 2^24 s (whole seconds past
    # a float's count, 2^24 + 33222784: the whole split in two); any whole is
    # a whole number of the crank's periods
    for whole, k in [(WHOLE, k) for k in range(0, 185, 13)] + [(3 * COUNT_CARRY + 12345, k) for k in (0, 70, 140)]:
        frac = 0.0123 + k * h
        # the bundled run's q nearest frac: single's guess as a float caller
        # keeps it (angles reduced: a float has no digits left for an angle of
        # 1e7 turns), double's with the whole turns it needs
        guess = one[round(frac / h), 1:1 + ng]
        turned = guess + 2 * np.pi * turns * round(whole / period)
        sd, double = _instant(libs["double"][0], libs["double"][2], "double", (ctypes.c_double(whole + frac),), turned)
        ss, single = _instant(libs["single"][0], ctx, "single", (ctypes.c_long(whole), ctypes.c_float(frac)), guess,
                              "instant_at")
        assert sd == 0 and ss == 0, (whole, frac, sd, ss)
        worst = np.maximum(worst, _error(single, double, scale, angles))
        sn, flat = _instant(libs["single"][0], ctx, "single", (ctypes.c_float(whole + frac),), guess)
        if sn == 0 and whole == WHOLE:
            naive = np.maximum(naive, _error(flat, double, scale, angles))
    # n = 5.3 and 0.1 rev/s: whole seconds are not whole turns, and at 0.1
    # (below 1/2, its float has more than 24 bits of fraction) neither are
    # whole multiples of 2^24 s: both parts of whole reach the phase (the
    # guess from the bundled run at the same crank angle; the peaks of
    # n = 5 scaled by (n / 5)^2 past q where that is larger)
    for n, whole, frac in ((5.3, WHOLE + 7, 0.0123), (5.3, 3 * COUNT_CARRY + 12345, 0.0823),
                           (0.1, 3 * COUNT_CARRY + 12345, 0.0823), (0.1, WHOLE + 3, 0.5)):
        n = float(np.float32(n))
        turns_t = n * (whole + frac)
        guess = one[round((turns_t % 1) / 5 / h) % (a.steps - 1), 1:1 + ng]
        turned = guess + 2 * np.pi * turns * np.floor(turns_t)
        sd, double = _instant(libs["double"][0], libs["double"][2], "double", (ctypes.c_double(whole + frac),), turned,
                              n=n)
        ss, single = _instant(libs["single"][0], ctx, "single", (ctypes.c_long(whole), ctypes.c_float(frac)), guess,
                              "instant_at", n=n)
        assert sd == 0 and ss == 0, (whole, frac, sd, ss)
        scaled = scale * np.where(np.arange(width) > ng, max(1.0, (n / 5) ** 2), 1)
        worst = np.maximum(worst, _error(single, double, scaled, angles))
    col = int(np.argmax(worst))
    print(f"instant_at: worst {worst[col]:.2e} of peak ({model.row_columns[col]}); float t: {naive.max():.2e}")
    assert worst[col] <= LONG_BOUND, (col, worst[col])
    assert worst.max() > 1e-9  # single is single
    assert naive.max() > 100 * LONG_BOUND  # the float time alone is not enough: the split is what holds


@needs_cc
def test_single_trajectory_from_t0_1e6_within_1e5_of_each_columns_peak_of_double(tmp_path: Path) -> None:
    """_trajectory from t0 = 1e6 s (a whole number of periods) in single
    against double, 40 instants of the bundled h, per column within 1e-5 of
    its peak; single's t is the float nearest double's."""
    exes = {p: _driver(tmp_path / p, NAME, p) for p in ("double", "single")}
    model = exes["double"][1]
    a, h, period = _bundled(model)
    one = _rows(exes["double"][0], a.t0, h, a.steps, model.q0)
    ng = len(model.q0)
    turns = _turned(model, one[0, 1:1 + ng], one[-1, 1:1 + ng])
    t0 = float(WHOLE)
    h = float(np.float32(h))  # the h single is given, so that both solve the same instants
    turned = np.array(model.q0) + 2 * np.pi * turns * round(t0 / period)  # double needs the whole turns
    double = _rows(exes["double"][0], t0, h, 40, turned)
    single = _rows(exes["single"][0], t0, h, 40, model.q0)  # a float caller's guess: angles reduced
    angles = [1 + j for j in range(ng) if j % 3 == 2]
    ctx = c_target.context(model)
    error = _error(single, double, _scale(ctx, one, angles), angles)
    worst = int(np.argmax(error[1:])) + 1
    print(f"trajectory from 1e6: worst {error[worst]:.2e} of peak ({model.row_columns[worst]})")
    assert error[worst] <= LONG_BOUND, (model.row_columns[worst], error[worst])
    assert np.array_equal(single[:, 0], double[:, 0].astype(np.float32).astype(float))


def _trajectory(lib, ctx, precision: str, t0: float, h: float, n: int,  # type: ignore[no-untyped-def]
                state: np.ndarray) -> tuple[int, np.ndarray]:
    real = REAL[precision]
    fn = getattr(lib, f"{NAME}_trajectory")
    fn.restype = ctypes.c_int
    s = (real * ctx.state)(*state)
    rows = (real * (n * ctx.row_width))()
    work, iwork, solved = (real * ctx.work)(), (ctypes.c_int * ctx.ng)(), ctypes.c_long(0)
    p = (real * ctx.np_).in_dll(lib, f"{NAME}_default_params")
    status = fn(real(t0), real(h), ctypes.c_long(n), p, real(1e-12), s, rows, ctypes.byref(solved), work, iwork)
    assert solved.value == n, (precision, status, solved.value)
    state[:] = s[:]
    return status, np.array(rows[:]).reshape(n, ctx.row_width)


@needs_cc
def test_trajectory_count_past_2_to_24_advances_t_every_instant_as_double_does(tmp_path: Path) -> None:
    """The state's count set to 2^24 - 2 and 5 instants solved: in single
    each t is the float nearest t0 + k h with k = 2^24 - 2 .. 2^24 + 2 (t0 =
    -2^24 h, so t = -2h .. 2h: a float holds each exactly), t advances every
    instant and equals double's, and the count comes back as 2^24 + 3 split
    into its rest (3) and its multiples of 2^24 (one)."""
    h = 2.0 ** -10  # a float holds it exactly; 2^24 h = 16384 s, 81920 periods of the crank
    t0 = -COUNT_CARRY * h
    k0 = COUNT_CARRY - 2
    rows, states = {}, {}
    for precision in ("double", "single"):
        lib, model, ctx = _lib(tmp_path / precision, precision)
        at = ctx.state_layout
        state = np.zeros(ctx.state)
        state[:ctx.ng] = model.q0  # t0 + k0 h is a whole number of periods less 2h: q0 is a near guess
        state[at.at("count")] = k0
        status, rows[precision] = _trajectory(lib, ctx, precision, t0, h, 5, state)
        assert status == 0, (precision, status)
        states[precision] = state[at.at("count"):at.at("count") + at["count"].size]
    t = rows["single"][:, 0]
    assert np.array_equal(t, (np.arange(k0, k0 + 5) - COUNT_CARRY) * h)  # exact: -2h .. 2h
    assert np.all(np.diff(t) > 0)
    assert np.array_equal(t, rows["double"][:, 0])
    assert list(states["single"]) == [3.0, COUNT_CARRY] and list(states["double"]) == [k0 + 5, 0.0]
    # the rest of the row: single's precision of double's (the crank angle's driver row, phases included)
    assert np.max(np.abs(rows["single"][:, 3] - rows["double"][:, 3])) < 1e-5


@needs_cc
def test_double_instant_at_is_instant_at_whole_plus_frac_bit_for_bit(tmp_path: Path) -> None:
    """In double, _instant_at(w, f) is _instant(w + f): the same bits."""
    lib, model, ctx = _lib(tmp_path, "double")
    for whole, frac in ((0, 0.0123), (3, -0.25), (WHOLE, 0.0421)):
        guess = np.array(model.q0) + np.array([0, 0, 2 * np.pi * 5 * (whole + frac)] + [0] * (ctx.ng - 3))
        a = _instant(lib, ctx, "double", (ctypes.c_long(whole), ctypes.c_double(frac)), guess, "instant_at")
        b = _instant(lib, ctx, "double", (ctypes.c_double(whole + frac),), guess)
        assert a[0] == b[0] == 0 and np.array_equal(a[1], b[1])


PHASE_HARNESS = r"""
#include SOLVER_C
#include <stdio.h>
#include <stdlib.h>
/* argv: nh nl, then t0 kh kl h quadruples: per quadruple phase_at and time */
int main(int argc, char **argv)
{
    const float nh = strtof(argv[1], NULL), nl = strtof(argv[2], NULL);
    int i;
    for (i = 3; i + 3 < argc; i += 4) {
        const float t0 = strtof(argv[i], NULL), kh = strtof(argv[i + 1], NULL), kl = strtof(argv[i + 2], NULL),
                    h = strtof(argv[i + 3], NULL);
        printf("%.9g %.9g\n", slider_crank_phase_at(nh, nl, t0, kh, kl, h), slider_crank_time(t0, kh, kl, h));
    }
    return 0;
}
"""


@needs_cc
def test_phase_at_and_time_against_exact_fractions(tmp_path: Path) -> None:
    """The single build's _phase_at and _time against exact rational
    arithmetic, for a speed a float does not hold (nu = nh + nl, nh = 5.3f,
    nl = 1.2345e-7f, as prepare keeps 1/T_cycle: nu kh h is not whole turns,
    nl t is turns past 2^24 s) at times up to 2^30
    instants of 1 ms and 5e7 s: the phase within 1e-6 rad of 2 pi frac((nh +
    nl) t) (about eight roundings of terms below half a turn, 2e-7 rad each
    at most, and the float result's own), t the float nearest t0 + (kh + kl) h."""
    from fractions import Fraction

    model = code_model(load(api.example(NAME)))
    c_target.generate(model, tmp_path, precision="single")
    src = tmp_path / "harness.c"
    src.write_text(PHASE_HARNESS)
    exe = tmp_path / "harness"
    subprocess.run(["cc", "-std=c99", "-O1", f'-DSOLVER_C="{tmp_path / f"{NAME}_solver.c"}"',
                    str(src), "-lm", "-o", str(exe)], check=True)
    f32 = lambda x: float(np.float32(x))  # noqa: E731
    cases = [(f32(1e6), 0.0, 0.0, f32(1e-3)), (0.0, 0.0, 12345.0, f32(1e-3)),
             (f32(1e6), float(COUNT_CARRY), 3.0, f32(1e-3)),
             (f32(-3.7), float(63 * COUNT_CARRY), 16777215.0, f32(1e-3)),
             (f32(0.0823), float(2 * COUNT_CARRY), 16777215.0, 1.0), (f32(0.7), float(3 * COUNT_CARRY), 12345.0, 1.0),
             (f32(-0.2), float(-5 * COUNT_CARRY), -777.0, 1.0)]
    nh, nl = f32(5.3), f32(1.2345e-7)
    out = subprocess.run([str(exe), repr(nh), repr(nl), *(repr(v) for c in cases for v in c)], check=True,
                         capture_output=True, text=True).stdout.splitlines()
    assert len(out) == len(cases)
    nu = Fraction(nh) + Fraction(nl)
    worst = 0.0
    for (t0, kh, kl, h), line in zip(cases, out):
        phase, t = (float(v) for v in line.split())
        exact_t = Fraction(t0) + (Fraction(kh) + Fraction(kl)) * Fraction(h)
        assert f32(t) == f32(float(exact_t)), (t0, kh, kl, h, t, float(exact_t))  # %.9g names a float
        turns = nu * exact_t
        want = float(2 * np.pi * float(turns - round(turns)))
        err = abs((phase - want + np.pi) % (2 * np.pi) - np.pi)
        worst = max(worst, err)
        assert err <= 1e-6, (t0, kh, kl, h, phase, want)
    print(f"phase_at: worst {worst:.2e} rad")


@needs_cc
def test_single_instant_at_fails_as_instant_does_and_leaves_q(tmp_path: Path) -> None:
    """_instant_at's failures are _instant's: a NaN fraction and a whole past
    2^47 seconds (where its high part is no longer exact) are BAD_ARGUMENT,
    (5), and a rod too short to reach (no solution) fails with q as it was passed."""
    lib, model, ctx = _lib(tmp_path, "single")
    real = ctypes.c_float
    fn = getattr(lib, f"{NAME}_instant_at")
    fn.restype = ctypes.c_int
    ok = (real * ctx.np_).in_dll(lib, f"{NAME}_default_params")
    short = (real * ctx.np_)(*ok[:])
    short[1] = 0.05  # L_rod below L_crank (0.1): the rod cannot follow the crank round
    for whole, frac, p, want in ((WHOLE, float("nan"), ok, 5), (1 << 47, 0.1, ok, 5), (WHOLE, 0.05, short, None)):
        q0 = np.array(model.q0, dtype=np.float32) + np.float32(0.01)
        q, work, iwork = (real * ctx.ng)(*q0), (real * ctx.work)(), (ctypes.c_int * ctx.ng)()
        status = fn(ctypes.c_long(whole), real(frac), p, real(1e-6), q, None, None, None, None, None, work, iwork)
        assert status != 0 and (want is None or status == want), (whole, frac, status)
        assert np.array_equal(np.array(q[:], dtype=np.float32), q0)  # q restored
