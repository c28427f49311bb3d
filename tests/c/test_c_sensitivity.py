"""Parameter sensitivities in the generated C (`--sensitivity`, issue #15):
against central differences of the same compiled solver (independent of
the derivation), warning-free under strict flags in double and single
precision, and opt-in (the cache key and the plain code do not change)."""

from __future__ import annotations

import dataclasses
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from symid import api
from symid.backends.c_backend import CEvaluator
from symid.backends.prepare import needs_of
from symid.codegen import cache
from symid.codegen.model import options_for
from symid.errors import InputError
from symid.output.sensitivity import choose
from symid.symbolic.assemble import assemble
from tiers import first_quick

STRICT = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic", "-Wconversion", "-Wdouble-promotion", "-Wshadow"]

# per example: base parameters (one moves a derived parameter through its definition)
CHOSEN = {
    "slider_crank": ("L_crank", "m_rod", "n"),          # n moves omega = 2 pi n
    "four_bar": ("L_coupler", "n", "k_spring"),
    "planetary": ("r_planet", "m_carrier", "n_in"),     # r_planet moves r_ring
    "quick_return": ("r_crank", "m_ram", "n"),
    "excavator": ("L_stick", "m_bucket", "T_cycle"),    # T_cycle moves w
    "slider_pendulum": ("L_pendulum", "theta_amp", "k_torsion"),
}
STEPS = 11


@dataclasses.dataclass
class Run:
    mech: object
    ev: CEvaluator
    columns: list[str]
    of: tuple[str, ...]
    names: tuple[str, ...]
    q0: np.ndarray
    folder: Path

    def rows(self, ev: CEvaluator | None = None) -> np.ndarray:
        return np.vstack(list((ev or self.ev).blocks(self.mech.analysis, self.q0)))  # type: ignore[attr-defined]


def _prepare(example: str) -> Run:
    """The example's c backend with sensitivities to CHOSEN (default columns
    and some of q, qdot, qddot), as `symid solve --backend c --sensitivity` builds it."""
    names = CHOSEN[example]
    mech = api.load_mechanism(api.example(example))
    # the default columns as api.prepare chooses them (no backend built: the reference's took seconds)
    default = choose(mech, assemble(mech), names, None, needs_of(mech).reactions)
    assert default is not None
    last = mech.bodies[-1].name
    of = default.of + (f"{last}.x", f"{last}.omega", f"{last}.alpha")
    study = api.prepare(api.example(example), backend="c", sensitivity=names, sensitivity_of=of, steps=STEPS)
    ev = study.evaluator
    assert isinstance(ev, CEvaluator) and ev.sensitivity_header == study.sensitivity.header
    return Run(study.mechanism, ev, ev.meta["columns"], of, names, study.q0(), Path(ev.artifact))


# the quick tier: the slider-crank's; quick_return's with the other examples in the slow tier
@pytest.fixture(scope="module", params=[pytest.param(e, marks=pytest.mark.slow) if e == "quick_return" else e
                                        for e in sorted(CHOSEN)])
def run(request: pytest.FixtureRequest) -> Run:
    return _prepare(request.param)


def test_sensitivity_columns_follow_all_others_columns_outer_parameters_inner(run: Run) -> None:
    tail = run.columns[-len(run.of) * len(run.names):]
    assert tail == [f"d({c})/d({n})" for c in run.of for n in run.names]
    assert all(not c.startswith("d(") for c in run.columns[:-len(tail)])


def _central(run: Run, k: int, h: float) -> np.ndarray:
    """(rows(p + h e_k) - rows(p - h e_k)) / 2h of the same compiled solver."""
    params = list(run.ev.meta["params"])
    sides = []
    for sign in (1.0, -1.0):
        other = run.ev.with_params({n: float(v) for n, v in zip(params, run.ev.p)})
        other.p[k] += sign * h
        sides.append(run.rows(other))
    return (sides[0] - sides[1]) / (2 * h)


def test_c_sensitivities_equal_the_python_loops_on_the_reference_backend(run: Run) -> None:
    """The compiled sensitivities against symid.numeric.sensitivity (the
    Python loop's, reference backend): 1e-12 of each column's peak."""
    ref = api.solve(api.example(run.mech.name), backend="reference", sensitivity=run.names,  # type: ignore[attr-defined]
                    sensitivity_of=run.of, steps=STEPS)
    c = api.solve(api.example(run.mech.name), backend="c", sensitivity=run.names,  # type: ignore[attr-defined]
                  sensitivity_of=run.of, steps=STEPS)  # the run's solver, through the API and its cache
    assert ref.error is None and c.error is None and ref.columns == c.columns == run.columns
    rows = c.data
    width = run.ev.meta["sens_width"]
    mine, theirs = rows[:, -width:], ref.data[:, -width:]
    scale = np.maximum(np.abs(theirs).max(axis=0), 1e-3 * np.abs(theirs).max())  # noise columns: the largest
    worst = (np.abs(mine - theirs) / scale).max(axis=0)
    # the C and the reference evaluate the same sensitivity formulas at the same q: rounding of each column's scale
    assert worst.max() <= 1e-12, run.columns[-width + int(worst.argmax())]


@pytest.mark.parametrize("kind, of", [("statics", None), ("kinematics", "slider.x,slider.vx,slider.ax,crank.phi")])
def test_statics_and_kinematics_sensitivities_equal_the_reference_backends(kind: str, of: str | None) -> None:
    """Statics (no rates, no inertia) and kinematics (no multipliers) compile
    only their stages, and agree with the Python loop all the same."""
    kw = {"sensitivity": "L_crank,m_rod,n", "sensitivity_of": of, "steps": STEPS, "kind": kind}
    ref = api.solve(api.example("slider_crank"), backend="reference", **kw)  # type: ignore[arg-type]
    c = api.solve(api.example("slider_crank"), backend="c", **kw)  # type: ignore[arg-type]
    assert ref.error is None and c.error is None and ref.columns == c.columns
    width = sum(col.startswith("d(") for col in c.columns)
    mine, theirs = c.data[:, -width:], ref.data[:, -width:]
    scale = np.maximum(np.abs(theirs).max(axis=0), 1e-3 * np.abs(theirs).max())
    # the C and the reference evaluate the same sensitivity formulas at the same q: rounding of each column's scale
    assert width > 0 and (np.abs(mine - theirs) / scale).max() <= 1e-12


def test_c_sensitivities_match_central_differences_of_the_c_solver(run: Run) -> None:
    """d(COLUMN)/d(NAME) against central differences of the same compiled
    solver (Richardson-extrapolated: error O(h^4)), each to 1e-7 of its
    column's peak: a wrong or missing term (a mass derivative, a chain
    through a derived parameter) shows here whatever the derivation did."""
    rows = run.rows()
    params = list(run.ev.meta["params"])
    for name in run.names:
        k = params.index(name)
        h = 1e-3 * (abs(run.ev.p[k]) or 1.0)
        fd = (4 * _central(run, k, h / 2) - _central(run, k, h)) / 3
        mine = [run.columns.index(f"d({c})/d({name})") for c in run.of]
        largest = np.abs(rows[:, mine]).max()  # a column zero but for rounding is held to the others' scale
        for c, at in zip(run.of, mine):
            col = run.columns.index(c)
            exact = rows[:, at]
            # a column that does not move with the parameter: 1e-7 of the column per unit of relative change
            scale = max(np.abs(exact).max(), np.abs(rows[:, col]).max() / (abs(run.ev.p[k]) or 1.0), 1e-2 * largest)
            # central differences of the compiled solver: truncation and rounding over the step, within 1e-7 of the scale
            assert np.abs(fd[:, col] - exact).max() <= 1e-7 * scale, (c, name, np.abs(fd[:, col] - exact).max(), scale)


def test_instant_sensitivity_entry_point_gives_the_trajectory_row(run: Run) -> None:
    rows = run.rows()
    width = run.ev.meta["sens_width"]
    ng = run.ev.meta["ng"]
    for i in (0, STEPS // 2, STEPS - 1):
        got = run.ev.sensitivity_row(rows[i, 1:1 + ng], float(rows[i, 0]), run.mech.analysis.tol)  # type: ignore[attr-defined]
        # one instant re-solved from its own q to tol 1e-12: the same derivatives to that solve's rounding, 1e-9 with room
        np.testing.assert_allclose(got, rows[i, -width:], rtol=1e-9, atol=1e-9 * np.abs(rows[i, -width:]).max())


@pytest.mark.slow
@pytest.mark.parametrize("cc", ["gcc", "clang"])
def test_sensitivity_solver_compiles_warning_free_with_strict_flags(run: Run, tmp_path: Path, cc: str) -> None:
    if shutil.which(cc) is None:
        pytest.skip(f"{cc} not installed")
    source = run.folder / f"{run.mech.name}_solver.c"  # type: ignore[attr-defined]
    done = subprocess.run([cc, *STRICT, "-c", str(source), "-o", str(tmp_path / "s.o")], capture_output=True, text=True)
    assert done.returncode == 0 and not done.stderr, done.stderr[:2000]


@pytest.mark.slow
def test_single_precision_sensitivity_solver_compiles_strict_and_follows_double(tmp_path: Path) -> None:
    mech = api.load_mechanism(api.example("slider_crank"))
    paths = api.generate(mech, "c", tmp_path, precision="single", sensitivity=("L_crank", "n"))
    source = next(p for p in paths if p.suffix == ".c")
    assert "typedef float slider_crank_real;" in (tmp_path / "slider_crank_solver.h").read_text()
    for cc in ("gcc", "clang"):
        done = subprocess.run([cc, *STRICT, "-c", str(source), "-o", str(tmp_path / f"{cc}.o")],
                              capture_output=True, text=True)
        assert done.returncode == 0 and not done.stderr, done.stderr[:2000]


def test_cache_key_includes_the_sensitivity_set() -> None:
    mech = api.load_mechanism(api.example("slider_crank"))
    plain = options_for(mech)
    keys = {cache.key(mech, o, "c") for o in (
        plain, dataclasses.replace(plain, sensitivity=("L_crank",)),
        dataclasses.replace(plain, sensitivity=("n",)),
        dataclasses.replace(plain, sensitivity=("L_crank",), sensitivity_of=("motor.T_j",)))}
    assert len(keys) == 4


@pytest.mark.parametrize("names, said", first_quick([  # one refusal in the quick tier: each is one line of the same check
    ("omega", "'omega' is a derived parameter (omega = \"2*pi*n\""),
    ("L_crank,nope", "--sensitivity nope: no such parameter"),
    ("n,n", "'n' is named twice"),
], ids=["derived", "unknown", "twice"]))
def test_bad_sensitivity_names_are_one_line_and_exit_2(tmp_path: Path, names: str, said: str) -> None:
    import sys

    done = subprocess.run([sys.executable, "-m", "symid", "generate", str(api.example("slider_crank")), "--target",
                           "c", "--sensitivity", names, "-o", str(tmp_path)], capture_output=True, text=True)
    assert done.returncode == 2 and said in done.stderr and len(done.stderr.strip().splitlines()) == 1, done.stderr


def test_sensitivity_of_other_targets_or_a_missing_column_is_an_input_error(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="--target c only"):
        api.generate(api.example("slider_crank"), "numpy", tmp_path, sensitivity=("n",))
    with pytest.raises(InputError, match="--sensitivity-of motor.nope: no such column"):
        api.generate(api.example("slider_pendulum"), "c", tmp_path, sensitivity=("k_torsion",),
                     sensitivity_of=("motor.nope",))


def test_trajectory_rows_end_with_the_sensitivities_through_ctypes(run: Run) -> None:
    """The rows the c backend streams (CHUNK calls of trajectory) hold finite
    sensitivities at every instant, none left unwritten."""
    rows = run.rows()
    width = run.ev.meta["sens_width"]
    assert rows.shape == (STEPS, len(run.columns)) and np.isfinite(rows[:, -width:]).all()


def test_an_instant_handed_to_the_python_loop_keeps_its_sensitivity_columns(run: Run) -> None:
    """Where the compiled loop hands an instant to the Python loop (a jump
    check, a failure), the c backend completes that row with the compiled
    instant_sensitivity at the Python loop's q: the same columns, the same
    values."""
    ev = run.ev.with_params({n: float(v) for n, v in zip(run.ev.meta["params"], run.ev.p)})
    real, calls = ev._trajectory, []

    def handing_over(*args):  # type: ignore[no-untyped-def]
        calls.append(args)
        if len(calls) == 2:  # the second call (instant 1) stops at once, as UNEXPLAINED does
            args[7]._obj.value = 0  # *solved = 0
            return 4
        return real(*args)

    ev._trajectory = handing_over
    rows, plain = run.rows(ev), run.rows()
    width = run.ev.meta["sens_width"]
    assert len(calls) >= 3 and rows.shape == plain.shape
    # the run handed over between calls is the same arithmetic: rounding of the peak
    np.testing.assert_allclose(rows[:, -width:], plain[:, -width:], rtol=0,
                               atol=1e-12 * np.abs(plain[:, -width:]).max())


DRIVER = """
#include <stdio.h>
#include "{name}_solver.h"
int main(void)
{{
    {name}_real p[{N}_NP > 0 ? {N}_NP : 1], out[{N}_NG], q[{N}_NG], state[{N}_STATE] = {{0}};
    static {name}_real rows[8 * {N}_ROW], work[{N}_WORK];
    static int iwork[{N}_IWORK > 0 ? {N}_IWORK : 1];
    long solved = 0;
    int k, status;
    for (k = 0; k < {N}_NP; ++k) p[k] = {name}_default_params[k];
    for (k = 0; k < {N}_NG; ++k) q[k] = state[k] = {name}_default_q0[k];
    {name}_mass(p, out);
    {name}_phi(q, 0.0{f}, p, out);
    status = {name}_trajectory(0.0{f}, 0.01{f}, 8, p, {tol}, state, rows, &solved, work, iwork);
    printf("%d %ld\\n", status, solved);
    return status != 0 || solved != 8;
}}
"""


@pytest.mark.slow  # an instrumented build and run (~15 s alone under load)
@pytest.mark.parametrize("precision", ["double", "single"])
def test_sensitivity_solver_stays_in_its_buffers_under_the_address_sanitizer(tmp_path: Path, precision: str) -> None:
    """Every public evaluation prepares the parameters into a local vector of
    NPP values: the sensitivities' prepared pieces (after single precision's
    phases) must be counted in it. A merge once left them out: mass() wrote
    past its stack vector and the c backend crashed at random; the numbers
    alone cannot show that, the sanitizer does. Derived parameters (the
    counterweight's centre and inertia) give the prepared pieces."""
    if shutil.which("gcc") is None:
        pytest.skip("gcc not installed")
    mech = api.load_mechanism(api.example("slider_crank_counterweight"))
    api.generate(mech, "c", tmp_path, precision=precision, sensitivity=("m_cw", "beta_cw", "n"))
    name = mech.name  # type: ignore[attr-defined]
    single = precision == "single"
    (tmp_path / "driver.c").write_text(DRIVER.format(name=name, N=name.upper(), f="f" if single else "",
                                                     tol="1e-5f" if single else "1e-12"))
    exe = tmp_path / "driver"
    built = subprocess.run(["gcc", "-std=c99", "-g", "-O1", "-fsanitize=address,undefined", "-fno-omit-frame-pointer",
                            "-fno-sanitize-recover=all", str(tmp_path / f"{name}_solver.c"), str(tmp_path / "driver.c"),
                            "-o", str(exe), "-lm"], capture_output=True, text=True)
    assert built.returncode == 0, built.stderr[:2000]
    done = subprocess.run([str(exe)], capture_output=True, text=True, env={"ASAN_OPTIONS": "detect_leaks=0"})
    assert done.returncode == 0 and "Sanitizer" not in done.stderr, (done.stdout, done.stderr[:3000])
