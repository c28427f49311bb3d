"""Generated solvers: agreement with the reference, strict C, the fallback
and singular paths, code size with fewer outputs, staleness of generated/."""

from __future__ import annotations

import ctypes
import dataclasses
import filecmp
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from cbuild import HOST_O2, STRICT, example_export, needs_cc, object_file, strict_library
from compare import assert_agree
from data_mechanisms import SINGULAR_PENDULUM, TWO_CABLES
from symid import api
from symid.numeric import solve
from symid.cli import main
from symid.codegen import sparse
from symid.codegen.emit import sample_jacobian
from symid.codegen.model import code_model
from symid.codegen.render import render
from symid.codegen import c as c_target
from symid.codegen.c import layout as c_layout
from symid.codegen.c import lu as c_lu
from symid.io.reader import load, loads
from tiers import first_quick

ROOT = Path(__file__).resolve().parents[2]
GENERATED_BACKENDS = ("numpy", "c")
# generated code has no joint friction yet (it refuses it: tests/numeric/test_friction.py)
EXAMPLES = [n for n in api.examples() if not any(c.friction for c in load(api.example(n)).constraints)]


class _Solved(dict):
    """Each example's reference table, solved when a test first asks for it
    (the quick tier asks for its few examples only, not every one)."""

    def __missing__(self, name: str) -> np.ndarray:
        self[name] = api.solve(api.example(name), backend="reference", steps=60).data
        return self[name]


@pytest.fixture(scope="module")
def reference() -> dict[str, np.ndarray]:
    return _Solved()


@pytest.mark.parametrize("backend", GENERATED_BACKENDS)
@pytest.mark.parametrize("example", EXAMPLES)
def test_backend_agrees_with_reference_through_api(example: str, backend: str, reference) -> None:
    if backend == "c":
        needs_cc(lambda: None)
    result = api.solve(api.example(example), backend=backend, steps=60)
    assert result.error is None
    assert_agree(result.data, reference[example])


@needs_cc
@pytest.mark.parametrize("backend", GENERATED_BACKENDS)
def test_backend_agrees_through_command_line(backend: str, tmp_path: Path, reference) -> None:
    out = tmp_path / "four_bar.csv"
    assert main(["solve", str(api.example("four_bar")), "--backend", backend, "--steps", "60", "-o", str(out)]) == 0
    data = np.loadtxt(out, delimiter=",", skiprows=1)
    assert_agree(data, reference["four_bar"])


def test_unknown_backend_lists_the_valid_ones(capsys) -> None:
    assert main(["solve", str(api.example("four_bar")), "--backend", "fortran"]) == 2
    err = capsys.readouterr().err
    assert "unknown backend 'fortran'" in err and "numpy" in err and "c" in err


@needs_cc
@pytest.mark.parametrize("example", EXAMPLES)
def test_generated_c_compiles_with_strict_flags(example: str, tmp_path_factory) -> None:
    """`symid generate`'s text (the run's shared export) compiled to an object
    with no warning: the run's shared host build, whose flags hold STRICT's
    (and the embedded build's warnings besides), the rows driver's object."""
    assert set(STRICT) <= set(HOST_O2)
    assert object_file(tmp_path_factory, HOST_O2, example_export(tmp_path_factory, example).source("double")).is_file()


@needs_cc
def test_emitted_makefile_builds_a_c_program_alone(tmp_path: Path) -> None:
    api.generate(api.example("slider_crank"), "c", tmp_path)
    subprocess.run(["make", "-C", str(tmp_path)], check=True, capture_output=True)
    exe = tmp_path / "main"
    subprocess.run(["cc", *STRICT, f"-I{tmp_path}", str(ROOT / "docs/c_example/main.c"),
                    str(tmp_path / "libslider_crank_solver.a"), "-lm", "-o", str(exe)], check=True)
    printed = np.loadtxt(subprocess.run([str(exe)], check=True, capture_output=True, text=True).stdout.splitlines())
    expected = api.solve(api.example("slider_crank"), backend="reference", steps=11)
    assert np.array_equal(printed[:, 0], expected.t)
    torque = expected["motor.T_j"]
    # the static library's run and the reference solve the same equations to tol 1e-12: rounding of the peak
    assert np.max(np.abs(printed[:, 1] - torque)) <= 1e-12 * np.max(np.abs(torque))


def _compile(folder: Path, name: str) -> ctypes.CDLL:
    subprocess.run(["cc", *STRICT, "-fPIC", "-shared", str(folder / f"{name}_solver.c"), "-o",
                    str(folder / "s.so"), "-lm"], check=True)
    return ctypes.CDLL(str(folder / "s.so"))


def _instant(lib: ctypes.CDLL, name: str, ctx: c_target.CContext, t: float, q: np.ndarray, p: np.ndarray):
    """Call <name>_instant; returns (status, info, q, lam)."""
    dp = ctypes.POINTER(ctypes.c_double)
    ip = ctypes.POINTER(ctypes.c_int)
    f = getattr(lib, f"{name}_instant")
    f.argtypes = [ctypes.c_double, dp, ctypes.c_double, dp, dp, dp, dp, dp, ip, dp, ip]
    size = max(ctx.ng, ctx.nc, ctx.nr, 1)
    q = q.astype(float).copy()
    qd, qdd, lam, reac = (np.zeros(size) for _ in range(4))
    info, work, iwork = np.zeros(2, np.intc), np.zeros(ctx.work), np.zeros(ctx.ng, np.intc)
    ptr = lambda a: a.ctypes.data_as(dp)  # noqa: E731
    status = f(t, ptr(p), 1e-12, ptr(q), ptr(qd), ptr(qdd), ptr(lam), ptr(reac), info.ctypes.data_as(ip),
               ptr(work), iwork.ctypes.data_as(ip))
    return status, info, q, lam[: ctx.nc]


# slow: builds the two cables with a dense limit of its own; tests/codegen/test_scale.py keeps the sparse
# fallback in the quick tier
@pytest.mark.slow
@needs_cc
@pytest.mark.parametrize("fallback", first_quick(["sparse", "dense"]))
def test_fixed_pivot_too_small_falls_back_and_stays_exact(fallback: str, tmp_path: Path,
                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    """Two cables: where a planned pivot fails at run time the solver
    refactors with pivoting (dense up to DENSE_LIMIT coordinates, sparse
    past it: the limit set to 0 here) and its multipliers are the
    reference's."""
    if fallback == "sparse":
        monkeypatch.setattr(c_layout, "DENSE_LIMIT", 0)
        monkeypatch.setenv("SYMID_CACHE", str(tmp_path / "cache"))
    mech = loads(TWO_CABLES, "two_cables.toml")
    model = code_model(mech)
    ctx = c_target.context(model)
    c_target.generate(model, tmp_path)
    source = (tmp_path / "two_cables_solver.c").read_text()
    assert ("fb_factor" in source) == (fallback == "sparse") and ("dense_factor" in source) == (fallback == "dense")
    lib = _compile(tmp_path, "two_cables")
    reference = api.solve(mech, backend="reference")
    p = np.array(model.flat.defaults)
    fallbacks = 0
    for row in reference.data:
        status, info, q, lam = _instant(lib, "two_cables", ctx, row[0], row[1:4] + 1e-3, p)
        assert status == 0
        fallbacks += info[1]
        # the fallback's multipliers against the reference's, both to tol 1e-12: rounding of the peak
        assert np.max(np.abs(lam - row[10:13])) <= 1e-12 * np.max(np.abs(reference.data[:, 10:13]))
        pattern = [(r, c) for r, c, _ in model.flat.jac]
        jac = sample_jacobian(model.flat, row[1:4], row[0], p)
        fixed = sparse.factor(model.plan, np.array([jac[r, c] for r, c in pattern]))
        assert bool(info[1]) == (fixed is None)  # C and the plan's reference executor agree
    assert fallbacks >= 1
    # the whole trajectory through the backend matches as well
    result = api.solve(mech, backend="c")
    assert_agree(result.data, reference.data)


@needs_cc
def test_singular_configuration_returns_singular_status(tmp_path: Path) -> None:
    mech = loads(SINGULAR_PENDULUM, "stretched.toml")
    model = code_model(mech)
    c_target.generate(model, tmp_path)
    lib = _compile(tmp_path, "stretched_pendulum")
    status, _, _, _ = _instant(lib, "stretched_pendulum", c_target.context(model), 0.0,
                               np.array([1.0, 0.0, 0.0]), np.zeros(0))
    assert status == 2  # STRETCHED_PENDULUM_SINGULAR


def _trajectory(lib: ctypes.CDLL, name: str, ctx: c_target.CContext, q0: np.ndarray, p: np.ndarray, h: float,
                n: int) -> np.ndarray:
    """Call <name>_trajectory from t = 0 for n instants; the rows."""
    dp = ctypes.POINTER(ctypes.c_double)
    f = getattr(lib, f"{name}_trajectory")
    f.argtypes = [ctypes.c_double, ctypes.c_double, ctypes.c_long, dp, ctypes.c_double, dp, dp,
                  ctypes.POINTER(ctypes.c_long), dp, ctypes.POINTER(ctypes.c_int)]
    state, rows = np.zeros(ctx.state), np.zeros((n, ctx.row_width))
    state[: ctx.ng] = q0
    work, iwork, solved = np.zeros(ctx.work), np.zeros(ctx.ng, np.intc), ctypes.c_long(0)
    ptr = lambda a: a.ctypes.data_as(dp)  # noqa: E731
    status = f(0.0, h, n, ptr(p), 1e-12, ptr(state), ptr(rows), ctypes.byref(solved), ptr(work),
               iwork.ctypes.data_as(ctypes.POINTER(ctypes.c_int)))
    assert status == 0 and solved.value == n
    return rows


@needs_cc
@pytest.mark.parametrize("example", EXAMPLES)
def test_folded_constants_give_the_factorization_bitwise(example: str, tmp_path: Path, tmp_path_factory) -> None:
    """The known entries of Phi_q are folded into the generated LU (no
    division by a known pivot, no test the constants decide): every row of a
    trajectory is bitwise the one of the solver that reads them at run time.
    The folded solver is the example's export (the run's shared one, compiled
    strictly once per run: cbuild.strict_library), the other written here."""
    model = code_model(load(api.example(example)))
    contexts = {fold: c_target.context(model, fold) for fold in (True, False)}
    c_target.write(contexts[False], tmp_path / "False")
    sources = {True: example_export(tmp_path_factory, example).source("double"),
               False: tmp_path / "False" / f"{model.name}_solver.c"}
    # the export is this model's folded text (the harness below reads this context's sizes)
    assert sources[True].read_text() == render("c/solver.c.j2", **contexts[True].namespace())
    rows = {}
    for fold in (True, False):
        lib = ctypes.CDLL(str(strict_library(tmp_path_factory, sources[fold], tmp_path / f"lib{fold}")))
        rows[fold] = _trajectory(lib, model.name, contexts[fold], np.array(model.q0),
                                 np.array(model.flat.defaults), 1e-3, 200)
    assert np.array_equal(rows[True], rows[False])
    folded, full = (sources[f].read_text() for f in (True, False))
    assert folded.count("1.0 / piv") < full.count("1.0 / piv")


# what each branch of the folded LU printer writes (tests below check each is exercised)
_FOLDED_FORMS = {
    "known multiplier, computed pivot": r"lu\[\d+\] = -?[\d.e-]+ \* piv;",
    "computed multiplier, known pivot": r"lu\[\d+\] \*= -?[\d.e-]+;",
    "computed multiplier, known pivot -1": r"lu\[\d+\] = -lu\[\d+\];",
    "known target, computed product": r"lu\[\d+\] = -?[\d.e-]+ [-+] ",
    "computed target, known product": r"lu\[\d+\] [-+]= -?[\d.e-]+;",
    "known pivot, computed column": r"if \(!\([\d.e-]+ >=",
    "known +-1 in an update": r"lu\[\d+\] [-+]= lu\[\d+\];",
}


def _lu_case(rng: np.random.Generator, n: int) -> tuple[list[tuple[int, int]], np.ndarray, np.ndarray]:
    """A random nonsingular sparse n x n pattern, its values, and which are numbers."""
    pattern = sorted({(k, k) for k in range(n)} | {(int(r), int(c)) for r, c in rng.integers(0, n, (3 * n, 2))})
    values = rng.normal(size=len(pattern)) + np.array([3.0 * (r == c) for r, c in pattern])
    known = rng.random(len(pattern)) < 0.6
    values[known] = rng.choice([1.0, -1.0, 0.5, -2.5, 3.0, 0.25, 2.0], size=int(known.sum()))
    return pattern, values, known


def _run_lus(tmp_path: Path, cases: list[tuple[sparse.Plan, list[float | None], str]]) -> list[tuple[str, str]]:
    """Render templates/c/sparse_lu.j2 for each case's plan (prefix t0, t1, ...)
    into one lu.c, build tests/c/lu_harness.c with it (one compile: each case's
    functions are its own, in the same floating-point operations as in a file
    alone), run case k on its inputs; (output, factor lines) per case."""
    from symid.codegen.render import render

    parts, lines = [], []
    for k, (plan, values, _) in enumerate(cases):
        p, P = f"t{k}", f"T{k}"
        chunks = c_lu.lu_chunks(plan, values, P)
        lu = c_lu.LU(size=plan.size, tables=None, runs=None, **chunks)
        parts.append(f"typedef double {p}_real;\n#define {P}_N {plan.n}\n#define {P}_THRESHOLD 0.1\n"
                     f"#define {P}_MAX(a, b) ((a) > (b) ? (a) : (b))\n#define {P}_RESTRICT restrict\n"
                     + render("c/sparse_lu.j2", p=p, P=P, ng=plan.n, multipliers=True, singular=plan.singular,
                              f="", lu=lu))
        lines.append("\n".join(line for ch in chunks["factor_chunks"] for line in ch["lines"]))
    table = ", ".join
    k_all = range(len(cases))
    parts.append(f"#define T_CASES {len(cases)}\n"
                 f"#define T_LU_SIZE {max(plan.size for plan, _, _ in cases)}\n"
                 f"#define T_N {max(plan.n for plan, _, _ in cases)}\n"
                 f"static const int t_n[] = {{{table(str(plan.n) for plan, _, _ in cases)}}};\n"
                 f"static const int t_nnz[] = {{{table(str(len(values)) for _, values, _ in cases)}}};\n"
                 f"static int (*const t_factor[])(double *) = {{{table(f't{k}_sparse_factor' for k in k_all)}}};\n"
                 "static void (*const t_solve[])(const double *, const double *, double *, double *) = "
                 f"{{{table(f't{k}_sparse_solve' for k in k_all)}}};\n"
                 "static void (*const t_solve_t[])(const double *, const double *, double *) = "
                 f"{{{table(f't{k}_sparse_solve_t' for k in k_all)}}};\n")
    (tmp_path / "lu.c").write_text("\n".join(parts))
    exe = tmp_path / "lu"
    subprocess.run(["cc", *STRICT, f"-I{tmp_path}", str(ROOT / "tests/c/lu_harness.c"), "-o", str(exe), "-lm"],
                   check=True)
    return [(subprocess.run([str(exe), str(k)], input=inputs, check=True, capture_output=True, text=True).stdout,
             lines[k]) for k, (_, _, inputs) in enumerate(cases)]


@pytest.mark.slow  # many random matrices through two compiled LUs (38 s under load)
@needs_cc
def test_folded_lu_factors_and_solves_random_matrices_bitwise_like_the_full_one(tmp_path: Path) -> None:
    """30 random sparse matrices, 60% of their entries numbers: the folded
    LU's solutions (A x = b, A^T z = b) are bitwise those of the LU that reads
    every value at run time, and solve the system; every printer branch runs."""
    rng = np.random.default_rng(7)
    seen = dict.fromkeys(_FOLDED_FORMS, 0)
    systems, cases = [], []
    for _ in range(30):
        n = int(rng.integers(4, 14))
        pattern, values, known = _lu_case(rng, n)
        a = np.zeros((n, n))
        for (r, c), v in zip(pattern, values):
            a[r, c] = v
        plan = sparse.plan(pattern, a)
        b = rng.normal(size=n)
        inputs = " ".join(repr(float(v)) for v in [*values, *b])
        systems.append((n, a, b))
        cases += [(plan, [float(v) if k else None for v, k in zip(values, known)], inputs),
                  (plan, [None] * len(values), inputs)]
    runs = _run_lus(tmp_path, cases)  # folded, full, folded, full, ...
    for (n, a, b), (folded, code), (full, _) in zip(systems, runs[0::2], runs[1::2]):
        assert folded == full
        for form, pattern_re in _FOLDED_FORMS.items():
            seen[form] += len(re.findall(pattern_re, code))
        if folded.strip() != "fallback":
            got = np.array(folded.split(), float)
            # a residual: a backward-stable solve leaves a few n eps |A| |x|; 1e-9 of it leaves ample room
            assert np.allclose(a @ got[:n], b, rtol=0, atol=1e-9 * np.abs(a).max() * np.abs(got[:n]).max())
            assert np.allclose(a.T @ got[n:], b, rtol=0, atol=1e-9 * np.abs(a).max() * np.abs(got[n:]).max())
    assert all(seen.values()), seen


@needs_cc
def test_known_pivot_that_fails_its_test_falls_back_like_the_full_lu(tmp_path: Path) -> None:
    """A plan chosen by structure alone (its sample is zero) whose first pivot
    is a known 0.01 under a known 1 in its column: the folded code returns
    the fallback without a test at run time, as the full code does with one."""
    pattern = [(0, 0), (0, 1), (1, 0), (1, 1)]
    plan = sparse.plan(pattern, np.zeros((2, 2)))
    assert (plan.steps[0].row, plan.steps[0].col) == (0, 0)
    inputs = "0.01 1.0 1.0 1.0 1.0 2.0"
    (folded, code), (full, _) = _run_lus(tmp_path, [(plan, [0.01, None, 1.0, None], inputs),
                                                    (plan, [None] * 4, inputs)])
    assert "known values fail" in code
    assert folded.strip() == "fallback" == full.strip()


@needs_cc
def test_rotated_sines_and_cosines_are_within_two_roundings_of_exact(tmp_path: Path) -> None:
    """Along a trajectory the C solver rotates sin and cos from the angles it
    last called libm at; tests/c/trig_accuracy.c checks them against long
    double sinl/cosl over 200000 random moves of angles up to 1e3 rad."""
    api.generate(api.example("slider_crank"), "c", tmp_path)
    exe = tmp_path / "trig_accuracy"
    subprocess.run(["cc", *STRICT, f"-I{tmp_path}", str(ROOT / "tests/c/trig_accuracy.c"), "-o", str(exe), "-lm"],
                   check=True)
    wrong, far, rotated, stepped = subprocess.run([str(exe)], check=True, capture_output=True,
                                                  text=True).stdout.split()
    assert int(wrong) == 0  # no base, or moved past the radius: libm's values exactly
    assert int(far) > 10000  # both paths ran
    # in units of 2^-53, absolute: libm's own error plus one rounding, plus one for a first-order step
    assert float(rotated) <= 1.25
    assert float(stepped) <= 2.0


@pytest.mark.parametrize("example", EXAMPLES)
def test_c_trajectory_on_a_fine_grid_agrees_with_numpy(example: str) -> None:
    """2001 instants: steps well inside the rotation radius, so nearly every
    sine and cosine of the C trajectory is rotated, none called from libm
    as the NumPy module's are."""
    rotated = api.solve(api.example(example), backend="c", steps=2001).data
    assert_agree(rotated, api.solve(api.example(example), backend="numpy", steps=2001).data, rel=1e-13)


@pytest.mark.parametrize("backend", ("reference", "numpy", "c"))
def test_singular_configuration_exits_3_naming_the_constraints(backend: str, tmp_path: Path, capsys) -> None:
    if backend == "c":
        needs_cc(lambda: None)
    path = tmp_path / "stretched.toml"
    path.write_text(SINGULAR_PENDULUM)
    out = tmp_path / "out.csv"
    assert main(["solve", str(path), "--backend", backend, "-o", str(out)]) == 3
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "singular" in err and "t = 0" in err
    assert "pivot" in err and "push" in err
    assert out.read_text().count("\n") == 1  # the header only: nothing was solved


def _sizes(mech_text: str, target: str, tmp_path: Path, **analysis: object) -> int:
    mech = loads(mech_text, "m.toml", analysis=analysis)
    folder = tmp_path / f"{target}-{abs(hash(repr(analysis)))}"
    paths = api.generate(mech, target, folder)
    return sum(p.stat().st_size for p in paths if p.suffix in (".c", ".py"))


@pytest.mark.parametrize("target", ("c", "numpy"))
def test_fewer_outputs_give_smaller_code(target: str, tmp_path: Path) -> None:
    text = api.example("slider_crank").read_text()
    everything = _sizes(text, target, tmp_path)
    motor_only = _sizes(text, target, tmp_path, reactions=["motor"])
    positions = _sizes(text, target, tmp_path, outputs=["q", "qdot"], kind="kinematics")
    assert positions < motor_only < everything


@pytest.mark.parametrize("target", ("c", "numpy"))
def test_statics_code_has_no_velocity_terms(target: str, tmp_path: Path) -> None:
    mech = loads(api.example("four_bar").read_text(), "four_bar.toml", analysis={"kind": "statics"})
    paths = api.generate(mech, target, tmp_path)
    code = "".join(p.read_text() for p in paths if p.suffix in (".c", ".py", ".h"))
    assert "qd[" not in code and "gamma" not in code and "_nu(" not in code and "def nu" not in code
    # the damper of the four-bar is in the dynamic code, with velocity terms
    dynamic = api.generate(api.example("four_bar"), target, tmp_path / "dyn")
    assert "qd[" in "".join(p.read_text() for p in dynamic if p.suffix in (".c", ".py"))


def test_generating_twice_gives_identical_bytes(tmp_path: Path) -> None:
    for folder in (tmp_path / "a", tmp_path / "b"):
        api.generate(api.example("quick_return"), "c", folder)
        api.generate(api.example("quick_return"), "numpy", folder)
    match, mismatch, errors = filecmp.cmpfiles(tmp_path / "a", tmp_path / "b",
                                               [p.name for p in (tmp_path / "a").iterdir()], shallow=False)
    assert not mismatch and not errors and len(match) == 5  # the 4 files and the folder's manifest


def test_every_generated_file_names_symid_template_mechanism_and_do_not_edit(tmp_path: Path) -> None:
    for target in ("c", "numpy"):
        for path in api.generate(api.example("planetary"), target, tmp_path / target):
            head = "\n".join(path.read_text().splitlines()[:3])
            assert "symid" in head and "do not edit" in head.lower() and "planetary" in head
            assert ".j2" in head and str(ROOT) not in path.read_text()


@pytest.mark.slow  # generates every bundled example on every target (sympy): CI checks it on every commit
def test_generated_folder_is_current(tmp_path: Path) -> None:
    """generated/ holds every example's output; `symid generate --examples` rewrites it."""
    committed = ROOT / "generated"
    targets = tuple(sorted({p.name for p in committed.glob("*/*") if p.is_dir()}))
    assert {"c", "numpy"} <= set(targets)
    api.generate_examples(tmp_path, targets)
    fresh = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*") if p.is_file())
    kept = sorted(p.relative_to(committed) for p in committed.rglob("*") if p.is_file())
    assert fresh == kept, "generated/ has missing or extra files: run `symid generate --examples`"
    stale = [str(rel) for rel in fresh if (tmp_path / rel).read_bytes() != (committed / rel).read_bytes()]
    assert not stale, f"stale generated files (run `symid generate --examples`): {stale}"


def test_written_q0_is_free_of_the_last_bits_of_libm() -> None:
    """default_q0 is written the same whatever noise of a few eps Newton leaves
    (another libm or BLAS wrote 2.3e-33 where this machine wrote -1.6e-33), the
    file's round numbers stay round, and the committed headers are written so."""
    from symid.codegen.model import settled

    exact = np.array([0.0, 0.0, 0.0, 0.25, 0.0, 0.0, 0.4, -0.05, np.pi / 2, 0.09486832980505137, 0.3, 0.9479697413828938])
    angle = np.arange(exact.size) % 3 == 2
    scale = np.where(angle, 1.0, 0.4)
    rng = np.random.default_rng(27)
    written = settled(exact)
    assert written[:8] == (0.0, 0.0, 0.0, 0.25, 0.0, 0.0, 0.4, -0.05) and str(written[0]) == "0.0"
    assert np.all(np.abs(np.array(written) - exact) <= 1e-13 * scale)  # far below any assembly tolerance
    for _ in range(50):  # a few eps of the scale, either sign, in every value (and 1e-33 about a zero)
        noisy = exact + rng.integers(-4, 5, exact.size) * np.finfo(float).eps * scale
        noisy[exact == 0] = rng.choice([-1.6e-33, 2.3e-33, 8.2e-18, 0.0], (exact == 0).sum())
        assert settled(noisy) == written
    for header in (ROOT / "generated").glob("*/c/*_solver.c"):
        found = re.search(r"_default_q0\[[^\]]*\] = \{([^}]*)\}", header.read_text())
        assert found, header
        values = np.array([float(v) for v in found.group(1).split(",")])
        assert settled(values) == tuple(values), header


@needs_cc
def test_second_run_compiles_nothing(monkeypatch: pytest.MonkeyPatch) -> None:
    api.prepare(api.example("slider_pendulum"), backend="c")

    def refuse(*args: object, **kwargs: object) -> None:
        raise AssertionError("compiled again")

    monkeypatch.setattr(subprocess, "run", refuse)
    monkeypatch.setattr("symid.codegen.model.code_model", refuse)
    assert api.prepare(api.example("slider_pendulum"), backend="c").solve().error is None


def test_missing_compiler_names_the_other_backends(monkeypatch: pytest.MonkeyPatch, tmp_path: Path, capsys) -> None:
    monkeypatch.setenv("SYMID_CACHE", str(tmp_path))
    monkeypatch.delenv("CC", raising=False)
    monkeypatch.setattr(shutil, "which", lambda name: None)
    assert main(["solve", str(api.example("slider_crank")), "--backend", "c", "-o", str(tmp_path / "x.csv")]) == 2
    err = capsys.readouterr().err
    assert "no C compiler" in err and "numpy" in err and "reference" in err


@pytest.mark.parametrize("seed", range(20))
def test_sparse_plan_solves_like_dense_lu(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 15))
    a = rng.normal(size=(n, n)) * (rng.random((n, n)) < 0.3) + np.diag(rng.normal(size=n) + 3)
    pattern = [(r, c) for r in range(n) for c in range(n) if a[r, c] != 0]
    plan = sparse.plan(pattern, a)
    lu = sparse.factor(plan, np.array([a[r, c] for r, c in pattern]))
    assert lu is not None
    b = rng.normal(size=n)
    # a residual of unit-scale entries: a backward-stable solve leaves ~1e-15; 1e-10 leaves ample room
    assert np.allclose(a @ sparse.solve(plan, lu, b), b, rtol=0, atol=1e-10)
    assert np.allclose(a.T @ sparse.solve_transposed(plan, lu, b), b, rtol=0, atol=1e-10)


def test_generated_numpy_module_needs_only_numpy(tmp_path: Path) -> None:
    """The module runs in a fresh interpreter where sympy, scipy and symid cannot be imported."""
    api.generate(api.example("slider_crank"), "numpy", tmp_path)
    script = (
        "import sys\n"
        "for name in ('sympy', 'scipy', 'symid', 'casadi'): sys.modules[name] = None\n"
        f"sys.path.insert(0, {str(tmp_path)!r})\n"
        "import slider_crank_solver as s\n"
        "rows = s.trajectory(0.0, 0.2, 11, s.DEFAULT_PARAMS, [0.05, 0, 0, 0.25, 0, 0, 0.4, 0, 0])\n"
        "print(repr(float(rows[-1, -1])))\n"
    )
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True).stdout
    expected = api.solve(api.example("slider_crank"), backend="reference", steps=11)["motor.T_j"][-1]
    # the generated module and the reference solve the same equations to tol 1e-12: rounding of the torque
    assert abs(float(out) - expected) <= 1e-12 * abs(expected)


@needs_cc
@pytest.mark.parametrize("kind", ("kinematics", "statics", "inverse_dynamics"))
def test_generated_c_of_every_kind_compiles_with_strict_flags(kind: str, tmp_path: Path) -> None:
    mech = loads(api.example("four_bar").read_text(), "four_bar.toml", analysis={"kind": kind})
    api.generate(mech, "c", tmp_path)
    result = subprocess.run(["cc", *STRICT, "-c", str(tmp_path / "four_bar_solver.c"), "-o", str(tmp_path / "x.o")],
                            capture_output=True, text=True)
    assert result.returncode == 0, result.stderr


@pytest.mark.parametrize("backend", GENERATED_BACKENDS)
@pytest.mark.parametrize("kind", ("kinematics", "statics"))
def test_generated_backends_agree_with_reference_for_every_kind(kind: str, backend: str) -> None:
    if backend == "c":
        needs_cc(lambda: None)
    expected = api.solve(api.example("four_bar"), backend="reference", kind=kind, steps=30)
    got = api.solve(api.example("four_bar"), backend=backend, kind=kind, steps=30)
    assert got.error is None and got.columns == expected.columns
    assert_agree(got.data, expected.data)


# -- the numpy backend: the module's loop, the Python loop where needed -----------

@pytest.fixture
def python_instants(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """The indices of the instants the Python loop solves (Stepper.instant), in call order."""
    calls: list[int] = []
    original = solve.Stepper.instant

    def spy(self: solve.Stepper, n: int, *args: object) -> solve.Instant:
        calls.append(n)
        return original(self, n, *args)  # type: ignore[arg-type]

    monkeypatch.setattr(solve.Stepper, "instant", spy)
    return calls


@pytest.mark.parametrize("example", EXAMPLES)
def test_numpy_runs_the_module_loop_when_no_stability_option_is_asked(example: str, python_instants) -> None:
    study = api.prepare(api.example(example), "numpy", steps=60)
    assert study.evaluator.own_loop(study.analysis)
    results = study.solve()
    assert results.error is None and results.data.shape[0] == 60 and results.warnings == []
    assert python_instants == [0]  # t0 only: assembly from q0, and the run's scaling


@pytest.mark.parametrize("option", [{"outputs": ["q", "lambda", "cond"]}, {"cond_warn": 1e4},
                                    {"redundant": "min_norm"}, {"assembly_jump": "warn"}], ids=lambda o: next(iter(o)))
def test_numpy_runs_the_python_loop_for_the_stability_options(option: dict, python_instants) -> None:
    study = api.prepare(api.example("slider_crank"), "numpy", steps=20, **option)
    assert not study.evaluator.own_loop(study.analysis)
    results = study.solve()
    assert results.error is None and python_instants == list(range(20))
    assert_agree(results.data, api.solve(api.example("slider_crank"), "reference", steps=20, **option).data)


def test_numpy_module_loop_hands_a_newton_failure_to_the_python_loop(python_instants) -> None:
    """Rod (0.05) shorter than the crank: past 30 degrees (t = 1/60 s) no
    position exists; the module fails there, and the Python loop reports it."""
    text = re.sub(r"L_rod = 0\.3\b", "L_rod = 0.05", api.example("slider_crank").read_text())
    results = api.solve(loads(text, "short_rod.toml"), "numpy")
    error = results.error
    assert error is not None and error.time == pytest.approx(0.017) and error.solved == 17
    assert "Newton did not converge: diverging" in str(error) and "crank_pin" in str(error)
    assert results.data.shape[0] == 17 and python_instants == [0, 17]


def test_numpy_module_loop_hands_a_suspected_jump_to_the_python_loop(python_instants) -> None:
    """Three instants over a four-bar's crank revolution: the branch check
    fires, and the Python loop finds the jump to the crossed assembly."""
    results = api.solve(api.example("four_bar"), "numpy", steps=3)
    error = results.error
    assert error is not None and "assembly mode jump" in str(error) and error.time == 0.25
    assert results.data.shape[0] == error.solved == 1 and python_instants[-1] == 1


def test_numpy_module_loop_hands_the_dense_fallback_instants_to_the_python_loop(python_instants) -> None:
    mech = loads(TWO_CABLES, "two_cables.toml")
    got = api.solve(mech, backend="numpy")
    handed = list(python_instants)
    assert got.error is None and handed[0] == 0 and len(handed) > 1  # some fixed pivot fails on the way
    assert_agree(got.data, api.solve(mech, backend="reference").data)


def test_numpy_module_loop_warns_and_fails_near_a_toggle_like_the_python_loop(python_instants) -> None:
    """Rod = crank (1 + 1e-12): at 90 degrees (t = 0.05 s) cond is 3.9e6,
    above the default cond_warn, and the rates solved there do not continue
    the motion (just past it the solution would jump branch). The module
    hands t = 0.05 to the Python loop, which warns and stops there."""
    text = re.sub(r"L_rod = 0\.3\b", "L_rod = 0.1000000000001", api.example("slider_crank").read_text())
    mech = loads(text, "near_toggle.toml")
    got = api.solve(mech, "numpy")
    assert python_instants == [0, 50]
    assert got.error is not None and got.error.time == 0.05 and "singular position" in str(got.error)
    expected = api.solve(mech, "reference")
    assert got.warnings == expected.warnings and "ill-conditioned" in got.warnings[0]
    assert str(got.error) == str(expected.error) and got.error.time == expected.error.time  # type: ignore[union-attr]
    # the two loops' Newton iterates differ within tol; near the toggle that
    # shows up to cond eps in positions and cond^2 eps in the rest
    assert_agree(got.data[:, :10], expected.data[:, :10], rel=3.9e6 * 1e-15)
    assert_agree(got.data, expected.data, rel=3.9e6**2 * 1e-15)


def test_a_cse_list_held_for_reuse_is_never_another_lists() -> None:
    """emit.cse keeps what it CSE'd by the expressions: a list that Python
    calls equal but sympy does not (1 and 1.0, 2*x and 2.0*x) gets its own
    CSE and prints its own literals; a list given again prints what a fresh
    CSE of it printed, and a held result is the same object."""
    import sympy as sp

    from symid.codegen import emit

    x = sp.Symbol("x", real=True)
    text = lambda exprs: emit.block(exprs, sp.ccode)  # noqa: E731
    shared = sp.sin(x) * sp.cos(x)
    first = text([1, shared + 1, shared * 2])
    assert first.outputs[0][1] == "1" and first.outputs[2][1] == "2*e0"
    assert text([1.0, shared + 1, shared * 2]).outputs[0][1] == "1.0"  # the lists: == in Python, not in sympy
    again = text([1, shared + 1.0, shared * sp.Float(2.0)])
    assert again.outputs[1][1] == "e0 + 1.0" and again.outputs[2][1] == "2.0*e0", again
    assert text([1, shared + 1, shared * 2]) == first
    assert emit.cse([shared + 1, shared * 2], "e") is emit.cse([shared + 1, shared * 2], "e")
