"""The CasADi target and backend against the core implementation: solved
tables, single evaluations, the saved files, CasADi's C code generator."""

from __future__ import annotations

import ctypes
import shutil
import subprocess
import sys
from pathlib import Path

import casadi as ca
import numpy as np
import pytest
import sympy as sp

from symid import api, cli
from symid.codegen.model import code_model
from symid.codegen.targets import casadi_target
from symid.model.expr import FUNCTIONS
from symid.io.reader import load

EXAMPLES = api.examples()
REFERENCE = "reference"  # the core implementation (family kernels, not generated code)
RTOL = 1e-12
STEPS = 40


@pytest.fixture(autouse=True)
def private_cache(tmp_path_factory: pytest.TempPathFactory, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("SYMID_CACHE", str(tmp_path_factory.mktemp("cache")))


def relative_error(reference: np.ndarray, other: np.ndarray) -> float:
    """Worst |difference| per column over max(max|column|, 1e-3 * max over all
    columns): columns that are zero up to roundoff are judged on the table's scale."""
    assert reference.shape == other.shape
    peak = np.max(np.abs(reference), axis=0)
    scale = np.maximum(peak, 1e-3 * peak.max())
    return float(np.max(np.abs(other - reference) / scale))


@pytest.mark.parametrize("name", EXAMPLES)
def test_api_solve_casadi_matches_reference_on_every_example(name: str) -> None:
    path = api.example(name)
    ref = api.solve(path, backend=REFERENCE, steps=STEPS)
    got = api.solve(path, backend="casadi", steps=STEPS)
    assert ref.error is None and got.error is None, (ref.error, got.error)
    assert got.columns == ref.columns
    assert relative_error(ref.data, got.data) <= RTOL


@pytest.mark.parametrize("kind", ["statics", "kinematics"])
def test_statics_and_kinematics_build_only_their_functions_and_match(kind: str) -> None:
    path = api.example("four_bar")
    study = api.prepare(path, "casadi", kind=kind, steps=STEPS)
    built = set(study.evaluator.manifest["functions"])  # type: ignore[attr-defined]
    expected = {"statics": {"phi", "phi_q", "applied", "mass", "reactions"},
                "kinematics": {"phi", "phi_q", "nu", "gamma"}}[kind]
    assert built == expected
    ref = api.solve(path, backend=REFERENCE, kind=kind, steps=STEPS)
    got = study.solve()
    assert got.error is None
    assert relative_error(ref.data, got.data) <= RTOL


def test_parameter_overrides_reach_the_cached_functions() -> None:
    """Parameters are an input `p`: an override needs no regeneration and is honoured."""
    path = api.example("slider_crank")
    api.prepare(path, "casadi")  # fills the cache with the default values
    override = {"L_crank": "0.12", "F_gas": "250"}
    ref = api.prepare(path, REFERENCE, override, steps=STEPS).solve()
    got = api.prepare(path, "casadi", override, steps=STEPS).solve()
    assert relative_error(ref.data, got.data) <= RTOL


def test_cli_solve_backend_casadi_writes_the_reference_table(tmp_path: Path) -> None:
    path = str(api.example("quick_return"))
    out = tmp_path / "qr.csv"
    assert cli.main(["solve", path, "--backend", "casadi", "--steps", str(STEPS), "-o", str(out)]) == 0
    header = out.read_text().splitlines()[0].split(",")
    table = np.loadtxt(out, delimiter=",", skiprows=1)
    ref = api.solve(path, backend=REFERENCE, steps=STEPS)
    assert header == ref.columns
    assert relative_error(ref.data, table) <= RTOL


@pytest.mark.parametrize("name", sorted(FUNCTIONS))
def test_every_whitelisted_function_and_its_derivative_convert_exactly(name: str) -> None:
    """Every function a mechanism file may use (and its derivative, which
    gamma and the driver rates contain) evaluates in CasADi as in sympy."""
    x, y = sp.Symbol("q[0]", real=True), sp.Symbol("q[1]", real=True)
    arity, build = FUNCTIONS[name]
    e = build(x, y) if arity == 2 else build(x)
    q = ca.SX.sym("q", 2)
    convert = casadi_target._ToSX({"q[0]": q[0], "q[1]": q[1]})  # noqa: SLF001
    point = {x: sp.Rational(3, 10), y: sp.Rational(7, 10)}  # inside every domain
    for expr in (e, sp.diff(e, x)):
        f = ca.Function("f", [q], [convert(expr)])
        value = float(f([0.3, 0.7]))
        assert value == pytest.approx(float(expr.xreplace(point).evalf(30)), rel=1e-14, abs=1e-15), expr


def test_unknown_sympy_function_is_refused_by_name() -> None:
    q = ca.SX.sym("q")
    convert = casadi_target._ToSX({"q[0]": q})  # noqa: SLF001
    with pytest.raises(NotImplementedError, match="gamma"):
        convert(sp.gamma(sp.Symbol("q[0]", real=True)))


@pytest.fixture(scope="module")
def slider_crank() -> tuple:
    """The slider-crank's code model and its generated folder."""
    mech = load(api.example("slider_crank"))
    return mech, code_model(mech)


def test_saved_functions_load_back_and_evaluate_as_the_reference(slider_crank: tuple, tmp_path: Path) -> None:
    mech, model = slider_crank
    casadi_target.generate(model, tmp_path)
    study = api.prepare(mech, REFERENCE)
    ev = study.evaluator
    rng = np.random.default_rng(7)
    f = model.flat
    q, qd, lam = rng.normal(size=f.ng), rng.normal(size=f.ng), rng.normal(size=f.nc)
    t, p = 0.037, np.array(f.defaults)
    load_fn = {key: ca.Function.load(str(tmp_path / f"{mech.name}_{key}.casadi"))
               for key in ("phi", "phi_q", "nu", "gamma", "applied", "mass", "reactions")}
    expected = {
        "phi": ev.phi(q, t), "phi_q": ev.phi_q(q, t), "nu": ev.nu(q, t), "gamma": ev.gamma(q, qd, t),
        "applied": ev.applied(q, qd, t), "mass": ev.mass(), "reactions": ev.reactions(q, lam, t),
    }
    args = {"phi": (q, t, p), "phi_q": (q, t, p), "nu": (q, t, p), "gamma": (q, qd, t, p),
            "applied": (q, qd, t, p), "mass": (p,), "reactions": (q, lam, t, p)}
    for key, fn in load_fn.items():
        value = np.array(fn(*args[key]).full()).squeeze()
        ref = np.asarray(expected[key]).squeeze()
        assert value.shape == ref.shape, key
        assert np.max(np.abs(value - ref)) <= RTOL * max(1.0, np.max(np.abs(ref))), key
    pattern = load_fn["phi_q"].sparsity_out(0)
    assert sorted(zip(*pattern.get_triplet())) == sorted((r, c) for r, c, _ in f.jac)


def test_instant_reproduces_the_solved_instants(slider_crank: tuple, tmp_path: Path) -> None:
    """`<name>_instant` (unrolled Newton + QR solves, loaded from its file)
    from a guess 1e-3 off gives the reference's q, rates, multipliers, reactions."""
    mech, model = slider_crank
    casadi_target.generate(model, tmp_path)
    instant = ca.Function.load(str(tmp_path / f"{mech.name}_instant.casadi"))
    p = np.array(model.flat.defaults)
    for k, ref in enumerate(api.prepare(mech, REFERENCE, steps=STEPS).instants()):
        if k % 7:
            continue
        out = instant(q_guess=ref.q + 1e-3, t=ref.t, p=p)
        # the instant's Newton stops at the mechanism's tol, 1e-12 on the residual
        assert float(out["residual"]) <= 1e-12
        for key, value in (("q", ref.q), ("qd", ref.qd), ("qdd", ref.qdd), ("lam", ref.lam),
                           ("reactions", ref.reactions)):
            got = np.array(out[key]).ravel()
            assert np.max(np.abs(got - value)) <= RTOL * np.max(np.abs(value)), (k, key)


# slow: three casadi generations, one in a fresh child; the casadi backend's agreement stays in the quick tier
@pytest.mark.slow
def test_generating_twice_gives_identical_bytes(slider_crank: tuple, tmp_path: Path) -> None:
    """Twice in this process and once in a fresh one (node numbering, hashing)."""
    mech, model = slider_crank
    first, second, third = tmp_path / "a", tmp_path / "b", tmp_path / "c"
    names = [p.name for p in casadi_target.generate(model, first)]
    casadi_target.generate(model, second)
    script = ("import sys; from pathlib import Path; from symid import api; "
              "from symid.codegen.model import code_model; from symid.codegen.targets import casadi_target; "
              "from symid.io.reader import load; "
              "casadi_target.generate(code_model(load(api.example('slider_crank'))), Path(sys.argv[1]))")
    subprocess.run([sys.executable, "-c", script, str(third)], check=True)
    for name in names:
        data = (first / name).read_bytes()
        assert data == (second / name).read_bytes() == (third / name).read_bytes(), name


def test_generated_files_name_symid_the_mechanism_and_do_not_edit(slider_crank: tuple, tmp_path: Path) -> None:
    mech, model = slider_crank
    readme = (tmp_path / "README.txt")
    casadi_target.generate(model, tmp_path)
    casadi_target.casadi_c(model, tmp_path)
    for path in (readme, tmp_path / "manifest.json", tmp_path / f"{mech.name}_casadi.c",
                 tmp_path / f"{mech.name}_casadi.h"):
        head = path.read_text()[:400]
        assert "Generated by symid" in head and f"'{mech.name}'" in head and "Do not edit" in head, path
        assert str(tmp_path) not in path.read_text(), path
    text = readme.read_text()
    assert "template casadi/README.txt.j2" in text
    for name, value in zip(model.flat.params, model.flat.defaults):
        assert f"{name} = {float(value)!r}" in text


@pytest.fixture(scope="module")
def casadi_object(slider_crank: tuple, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """CasADi's C for every function, compiled (warnings allowed: the code is CasADi's)."""
    cc = shutil.which("gcc")
    if cc is None:
        pytest.skip("gcc not found")
    _, model = slider_crank
    folder = tmp_path_factory.mktemp("casadi_c")
    source = [p for p in casadi_target.casadi_c(model, folder) if p.suffix == ".c"][0]
    obj = folder / "casadi.o"
    result = subprocess.run([cc, "-std=c99", "-O2", "-fPIC", "-c", str(source), "-o", str(obj)],
                            capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    return obj


def test_casadi_c_code_generator_output_compiles(casadi_object: Path) -> None:
    assert casadi_object.stat().st_size > 0


def _call_casadi_c(lib: ctypes.CDLL, fn: ca.Function, inputs: list[np.ndarray]) -> list[np.ndarray]:
    """Call one CasADi-generated C function through its fixed convention
    f(arg, res, iw, w, mem), sizing the work arrays with `<name>_work`."""
    longs = [ctypes.c_longlong() for _ in range(4)]
    getattr(lib, f"{fn.name()}_work")(*[ctypes.byref(v) for v in longs])
    n_arg, n_res, n_iw, n_w = (max(v.value, 1) for v in longs)
    dp = ctypes.POINTER(ctypes.c_double)
    ins = [np.ascontiguousarray(np.atleast_1d(x), dtype=float) for x in inputs]
    outs = [np.zeros(fn.sparsity_out(k).nnz()) for k in range(fn.n_out())]
    arg = (dp * max(n_arg, len(ins)))(*[x.ctypes.data_as(dp) for x in ins])
    res = (dp * max(n_res, len(outs)))(*[x.ctypes.data_as(dp) for x in outs])
    iw, w = (ctypes.c_longlong * n_iw)(), (ctypes.c_double * n_w)()
    assert getattr(lib, fn.name())(arg, res, iw, w, 0) == 0
    return outs


def test_casadi_c_code_evaluates_as_the_saved_functions(slider_crank: tuple, casadi_object: Path) -> None:
    _, model = slider_crank
    lib_path = casadi_object.with_suffix(".so")
    subprocess.run([shutil.which("gcc") or "gcc", "-shared", str(casadi_object), "-o", str(lib_path), "-lm"],
                   check=True)
    lib = ctypes.CDLL(str(lib_path))
    fns = casadi_target.functions(model.flat)
    rng = np.random.default_rng(11)
    f = model.flat
    p = np.array(f.defaults)
    q0 = np.array(model.q0)
    cases = {"phi": [rng.normal(size=f.ng), 0.01, p], "phi_q": [rng.normal(size=f.ng), 0.01, p],
             "gamma": [rng.normal(size=f.ng), rng.normal(size=f.ng), 0.01, p], "mass": [p],
             "instant": [q0 + 1e-3, 0.0, p]}
    for key, inputs in cases.items():
        got = _call_casadi_c(lib, fns[key], inputs)
        want = [np.array(ca.DM(v).nonzeros()) for v in fns[key].call([ca.DM(x) for x in inputs])]
        for g, w_ in zip(got, want):
            # one expression graph run by CasADi's VM and by its own C: a few roundings apart
            assert np.max(np.abs(g - w_)) <= 1e-13 * max(1.0, np.max(np.abs(w_))), key
