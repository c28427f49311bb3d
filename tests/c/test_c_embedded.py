"""The generated C as an embedded engineer builds it: non-finite parameters
reported, the assembly mode an instant converges to, single precision
against double, the header's description of the mechanism, the libm calls,
and strict warning-free builds with gcc, clang and arm-none-eabi-gcc."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from cbuild import (GROUP_FLOOR, M4F, PRECISIONS, WARNINGS, case_export, example_export, host_rows, needs_cc,
                    object_file, single_bound)
from csolver import BAD_ARGUMENT, NONFINITE, OK, Solver, slider_crank_mode
from small_mechanisms import cases
from symid import api
from symid.codegen.model import code_model
from symid.codegen import c as c_target
from symid.io.reader import load
from symid.model.params import base_names
from tiers import first_quick

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = tuple(api.examples())


@pytest.fixture(scope="module")
def solvers(tmp_path_factory) -> dict[str, Solver]:
    if shutil.which("cc") is None:
        pytest.skip("no C compiler")
    return {name: Solver(api.example(name), tmp_path_factory.mktemp(name), share=tmp_path_factory)  # the export's
            for name in ("slider_crank", "four_bar")}


# --- point 1: non-finite parameters, scalars, the assembly mode ---


@needs_cc
@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
@pytest.mark.parametrize("example", ["slider_crank", "four_bar"])
def test_nonfinite_parameter_returns_nonfinite_unless_nothing_reads_it(solvers, example: str, bad: float) -> None:
    """Every parameter (masses, inertias, lengths, loads, speeds) set to NaN
    or +-inf: NONFINITE from instant and from trajectory with info written,
    or, for a parameter the header lists as read by nothing, the nominal
    outputs bitwise."""
    solver = solvers[example]
    header = (solver.folder / f"{solver.name}_solver.h").read_text()
    unread = re.search(r"Read by nothing in this solver.*?list\): ([^.]*)\.", header, re.S)
    unread_names = set(unread.group(1).replace("\n", " ").replace(" ", "").split(",")) if unread else set()
    nominal = solver.instant()[1]
    for k, name in enumerate(solver.ctx.params):
        saved = solver.p.copy()
        solver.p[k] = bad
        try:
            info = np.full(2, -7, np.intc)
            status, out = solver.instant(info=info)
            run_status, solved, _ = solver.trajectory(0.0, 1e-3, 5)
        finally:
            solver.p = saved
        if name in unread_names:
            assert (status, run_status, solved) == (OK, OK, 5), name
            assert all(np.array_equal(out[key], nominal[key]) for key in out), name
        else:
            assert (status, run_status, solved) == (NONFINITE, NONFINITE, 0), (name, status, run_status)
            assert info[0] >= 0 and info[1] in (0, 1), (name, info)


@needs_cc
def test_negative_count_returns_bad_argument_with_zero_solved(solvers) -> None:
    assert solvers["four_bar"].trajectory(0.0, 1e-3, -3)[:2] == (BAD_ARGUMENT, 0)


@needs_cc
def test_instant_solves_from_its_guess_and_the_trajectory_keeps_the_branch(solvers) -> None:
    """As the header documents: `_instant` converges to the assembly mode
    nearest its guess (a stale guess in the other mode gives that mode, OK);
    `_trajectory`, predicting each instant from the last, stays on the mode
    it started in."""
    solver = solvers["slider_crank"]
    t = 0.05
    theta = 2 * np.pi * float(solver.p[solver.ctx.params.index("n")]) * t  # omega = 2 pi n, derived
    other = slider_crank_mode(theta, -1.0)
    status, out = solver.instant(t=t, q=other + 1e-3)
    assert status == OK
    assert np.max(np.abs(out["q"] - other)) <= 1e-12  # the other mode, not an error
    status, out = solver.instant(t=t)
    # Newton converged to tol 1e-12 on the residual: q to rounding of the closed form
    assert status == OK and np.max(np.abs(out["q"] - slider_crank_mode(theta, 1.0))) <= 1e-12
    status, solved, q = solver.trajectory(0.0, 1e-3, 200)
    assert (status, solved) == (OK, 200)
    # Newton converged to tol 1e-12 each instant: q to rounding of the closed form
    assert np.max(np.abs(q - slider_crank_mode(theta * 199 / 50, 1.0))) <= 1e-12
    header = (solver.folder / f"{solver.name}_solver.h").read_text()
    assert "assembly mode" in header


# --- point 3: single precision ---


@needs_cc
@pytest.mark.parametrize("example", first_quick(sorted(EXAMPLES, key=lambda e: e != "slider_crank")))  # the bound is one code
def test_single_precision_rows_within_the_readme_bound_of_double(tmp_path_factory, example: str) -> None:
    export = example_export(tmp_path_factory, example)  # shared with the emulated run's host rows
    runs = {p: host_rows(tmp_path_factory, export, p)[1] for p in PRECISIONS}
    header = (export.folder / "single" / f"{example}_solver.h").read_text()
    assert f"typedef float {example}_real;" in header
    groups_of = [0] + [k + 1 for k, size in enumerate(export.row_sizes) for _ in range(size)]
    friction = runs["double"].shape[1] - len(groups_of)  # C.friction, C.friction_power: a group of their own
    groups = np.array(groups_of + [len(export.row_sizes) + 1] * friction)
    peak = np.max(np.abs(runs["double"]), axis=0)
    scale = np.maximum(peak, GROUP_FLOOR * np.array([np.max(peak[groups == g]) for g in groups]))
    error = np.max(np.abs(runs["single"] - runs["double"]), axis=0) / scale
    bound = single_bound(export.folder / "single", example)  # the header's statement
    worst = int(np.argmax(error))
    assert error[worst] <= bound, (export.row_columns[worst], error[worst])
    assert error.max() > 1e-9  # the single run is single: it differs from double


@needs_cc
def test_cli_generates_single_precision_c_and_refuses_it_for_other_targets(tmp_path: Path) -> None:
    from symid.cli.entry import main

    assert main(["generate", str(api.example("slider_crank")), "--target", "c", "--precision", "single",
                 "-o", str(tmp_path / "c")]) == 0
    source = re.sub(r"/\*.*?\*/", "", (tmp_path / "c" / "slider_crank_solver.c").read_text(), flags=re.S)
    assert "sinf(" in source and "sin(" not in source.replace("sinf(", "")
    assert main(["generate", str(api.example("slider_crank")), "--target", "numpy", "--precision", "single",
                 "-o", str(tmp_path / "n")]) == 2


# --- point 4: the header describes the mechanism ---


@needs_cc
@pytest.mark.parametrize("example", ["slider_crank", "quick_return"])
def test_header_names_columns_parameters_q0_and_time_grid_of_the_file(tmp_path_factory, example: str) -> None:
    """row_names as the CSV header of `symid solve`, param_names as the
    file's [parameters], default_q0 the configuration the reference backend
    assembles at t0, T0/T1/STEPS/TOL the file's [analysis]."""
    mech = load(api.example(example))
    exe = host_rows(tmp_path_factory, example_export(tmp_path_factory, example), "double")[0]
    lines = subprocess.run([str(exe), "describe"], check=True, capture_output=True, text=True).stdout.splitlines()
    truth = api.solve(api.example(example), backend="reference", steps=2)
    assert lines[0].split() == list(truth.columns)
    assert lines[1].split() == list(base_names(mech.parameters))  # the inputs: base parameters only
    # the header's q0 is the assembled configuration written to 17 digits: rounding of the reference's
    assert np.max(np.abs(np.array(lines[2].split(), float) - truth.data[0][1:1 + 3 * len(mech.bodies)])) <= 1e-12
    t0, t1, steps, tol, ops = lines[3].split()
    a = mech.analysis
    assert (float(t0), float(t1), int(steps), float(tol)) == (a.t0, a.t1, a.steps, a.tol)
    assert int(ops) > 10 * len(mech.bodies)


def test_unread_parameters_are_listed_and_the_others_are_not(tmp_path: Path) -> None:
    """A parameter nothing reads is listed; slider_crank's `n`, read through its
    derived `omega = 2*pi*n` (computed inside), is not; units from the file's
    comments and the contract."""
    text = api.example("slider_crank").read_text().replace("[parameters]\n", "[parameters]\nspare = 2.5\n", 1)
    (tmp_path / "spare.toml").write_text(text)
    assert c_target.context(code_model(load(tmp_path / "spare.toml"))).d.unread == ["spare"]
    model = code_model(load(api.example("slider_crank")))
    ctx = c_target.context(model)
    assert ctx.d.unread == []
    assert {c["name"]: c["unit"] for c in ctx.d.columns}["crank.phi"] == "rad"
    assert {c["name"]: c["unit"] for c in ctx.d.columns}["motor.T_j"] == "force*length"
    assert {p["name"]: p["comment"] for p in ctx.d.param_info}["L_crank"] == "crank radius, m"


# --- point 5: lean code ---

ALLOWED = {"sin", "cos", "sqrt", "fabs", "fmax", "fmin", "isfinite", "memcpy", "memset"}


# One example per test (the loop it was): the quick tier checks the quick
# examples (tests/conftest.py), the slow tier the big ones, whose C takes the
# longest to generate.
@pytest.mark.parametrize("name", EXAMPLES)
@pytest.mark.parametrize("precision", ["double", "single"])
def test_generated_c_calls_only_sin_cos_sqrt_and_what_the_file_calls(tmp_path_factory, precision: str,
                                                                     name: str) -> None:
    """No pow (integer powers are products, x^(-1/2) is 1/sqrt), and no libm
    call the mechanism's own expressions do not make; parameter-only pieces
    (the inertias) are computed by prepare, not in the kernels."""
    text = api.example(name).read_text()
    own = set(re.findall(r"\b([a-z][a-z0-9]*)\(", text)) | ({"tanh"} if "friction" in text else set())  # s(v)
    source = example_export(tmp_path_factory, name).source(precision).read_text()
    body = re.sub(r"/\*.*?\*/", "", source, flags=re.S)
    called = set(re.findall(r"\b([a-z][a-z0-9]*)\(", body))
    suffix = "f" if precision == "single" else ""
    libm = {c[:-1] if suffix and c.endswith("f") and c[:-1] in ALLOWED | own else c for c in called}
    assert not libm - ALLOWED - own - {"if", "for", "while", "switch", "return", "sizeof"}, (name, libm)
    assert "pow(" not in body and "powf(" not in body, name
    mass = re.search(rf"static void {name}_mass_k0\(.*?\n}}", body, re.S)
    assert mass is not None and "*" not in mass.group(0).split("{", 1)[1], name


# --- point 6: strict builds ---
# gcc and clang check every solver's front-end warnings (-fsyntax-only: what
# the flags ask is diagnosed there); arm-none-eabi-gcc compiles for real, so
# the optimizers' warnings (-Waggressive-loop-optimizations, uninitialized
# values) run too: every example and small case at -O2 in single and -Os in
# double (each optimizer level and each precision seen once; the emulated run,
# tests/c/test_c_qemu.py, runs these objects of every example).


@pytest.fixture(scope="module")
def sources(tmp_path_factory) -> dict[str, dict[str, list[Path]]]:
    """Every example and every small-mechanism case, generated in both
    precisions (the exports the other C tests share, the cases as `symid
    generate` writes them): {"examples" | "cases": {precision: sources}}."""
    exports = [example_export(tmp_path_factory, name) for name in EXAMPLES]
    return {"examples": {p: [e.source(p) for e in exports] for p in PRECISIONS},
            "cases": {p: [case_export(tmp_path_factory, name, text, p) for name, text in cases().items()]
                      for p in PRECISIONS}}


def _compile_all(compiler: list[str], files: list[Path], cwd: Path) -> None:
    """Each file on its own (two at a time: CI has two cores), no warning."""
    from concurrent.futures import ThreadPoolExecutor

    def one(path: Path) -> subprocess.CompletedProcess[str]:
        return subprocess.run([*compiler, "-c", str(path), "-o", str(cwd / (path.stem + ".o"))],
                              capture_output=True, text=True)

    with ThreadPoolExecutor(max_workers=2) as pool:
        for path, result in zip(files, pool.map(one, files)):
            assert result.returncode == 0 and "warning" not in result.stderr, (path.name, result.stderr[:3000])


@pytest.mark.slow
@pytest.mark.parametrize("precision", ["double", "single"])
@pytest.mark.parametrize("cc", ["gcc", "clang"])
def test_every_solver_compiles_warning_free_with_strict_flags(sources, tmp_path: Path, cc: str,
                                                              precision: str) -> None:
    if shutil.which(cc) is None:
        pytest.skip(f"{cc} is not installed (.ci/run installs it where apt-get may): strict {cc} build not checked")
    files = sources["examples"][precision] + sources["cases"][precision]
    _compile_all([cc, *WARNINGS, "-fsyntax-only"], files, tmp_path)


@pytest.mark.slow
@pytest.mark.parametrize("precision, level", [("single", "-O2"), ("double", "-Os")])
def test_every_solver_compiles_warning_free_for_a_cortex_m4f(sources, tmp_path_factory, precision: str,
                                                             level: str) -> None:
    """The objects are the run's shared ones (cbuild.object_file: no warning):
    the emulated run links them, the double-helper link the single ones."""
    if shutil.which("arm-none-eabi-gcc") is None:
        pytest.skip("arm-none-eabi-gcc is not installed (.ci/run installs gcc-arm-none-eabi where apt-get may): "
                    "the Cortex-M4F build is not checked")
    from concurrent.futures import ThreadPoolExecutor

    files = sources["examples"][precision] + sources["cases"][precision]
    with ThreadPoolExecutor(max_workers=2) as pool:  # two at a time: CI has two cores
        objects = list(pool.map(lambda f: object_file(tmp_path_factory, ["arm-none-eabi-gcc", *WARNINGS, *M4F, level],
                                                      f), files))
    assert all(o.is_file() for o in objects)
