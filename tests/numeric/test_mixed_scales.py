"""Multipliers at mixed scales (issue 26, point 2): a boom of 1 t in mm and
tonnes (loads ~1e4 N and a 1e5 N tip load) carrying a part of 2 g (0.2 g)
on a pin, turned by a small actuator mounted on the boom.

The transposed solve for lambda with the LU of Phi_q is backward stable in
the norm of the whole right-hand side: without a refinement step the part's
pin reactions carry ~1e-11 N, 1e-9 of the part's own loads (measured 1.5e-9
to 2.4e-9 on every backend). Every backend, the generated C, the generated
NumPy module and the vectorized sweep refine lambda once where the body
masses span scales; the checks here are Newton-Euler on every body from the
table's reactions (independent of the solver) and a 40-digit solve.
"""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from symid import api
from symid.io.reader import loads
from symid.model.mechanism import Mechanism
from symid.model.params import base_names, parameter_values
from symid.output.results import Results, columns
from symid.study.engine import variant_mechanism
from symid.study.variants import base_matrix, study_mechanism
from symid.symbolic.assemble import assemble
from truth import Truth

needs_cc = pytest.mark.skipif(shutil.which("cc") is None and shutil.which("gcc") is None, reason="no C compiler")

BOOM = """
[mechanism]
name = "boom_part"
gravity = [0.0, -9810.0]       # mm/s^2: lengths in mm, masses in t, forces in N

[parameters]
L_boom = 3000.0
m_boom = 1.0
L_part = 20.0
m_part = {m_part}
F_tip = 1e5

[analysis]
kind = "inverse_dynamics"
t0 = 0.0
t1 = 1.0
steps = 21

[[body]]
name = "boom"
mass = "m_boom"
inertia = "m_boom*L_boom^2/12"
q0 = ["L_boom/2", 0.0, 0.0]

[[body]]
name = "part"
mass = "m_part"
inertia = "m_part*L_part^2/12"
q0 = ["L_boom", "L_part/2", 1.5707963267948966]

[[constraint]]
name = "boom_pivot"
type = "revolute"
i = "ground"
j = "boom"
si = [0.0, 0.0]
sj = ["-L_boom/2", 0.0]

[[constraint]]
name = "boom_motor"
type = "relative_angle_driver"
i = "ground"
j = "boom"
f = "0.5*sin(2*t)"

[[constraint]]
name = "part_pin"
type = "revolute"
i = "boom"
j = "part"
si = ["L_boom/2", 0.0]
sj = ["-L_part/2", 0.0]

[[constraint]]
name = "part_actuator"
type = "distance_driver"
i = "boom"
j = "part"
si = ["L_boom/2 - 100", 60.0]
sj = ["L_part/2", 0.0]
f = "sqrt(100^2 + 40^2) + 5*sin(3*t)"

[[force]]
name = "tip_load"
type = "point_force"
body = "boom"
s = ["L_boom/2", 0.0]
F = ["0", "-F_tip"]
"""

PARTS = (2e-6, 2e-7)  # 2 g and 0.2 g, in t
BACKENDS = ("numpy", "reference", "casadi", pytest.param("c", marks=needs_cc))
# Newton-Euler on a body from double-precision results closes to a few
# roundings of its own largest terms (measured <= 2.4e-15 force, 1.1e-14
# moment on every backend with the refinement; 1.5e-9 to 2.4e-9 without):
# 1e-12 is the bound, with a margin of 100 over rounding.
TOL = 1e-12


def boom(m_part: float) -> Mechanism:
    return loads(BOOM.format(m_part=m_part), "boom_part.toml")


def own_balance(mech: Mechanism, res: Results) -> dict[str, tuple[float, float]]:
    """Per body: the largest force and moment residual of Newton-Euler from
    the table's reactions and the applied loads (hand formulas, `truth`),
    each relative to that body's own loads: the largest of m |a - g| and its
    applied forces for the force; for the moment, the largest of |J alpha|,
    its applied torques and that force times the largest arm of a load about
    its centre of mass. The body's reactions do not set the scale: they are
    what is checked."""
    truth = Truth(mech, res)
    loads = truth.applied_loads() + truth.reaction_loads()
    g = np.array([truth.num(v) for v in mech.gravity])
    out = {}
    for b in mech.bodies:
        st = truth.state(b.name)
        m, j = truth.num(b.mass), truth.num(b.inertia)
        force, moment, arm_max = -m * st["a"], -j * st["alpha"], 0.0
        for ld in loads:
            if ld.body == b.name:
                arm = ld.point - st["r"]
                arm_max = max(arm_max, float(np.max(np.abs(arm))))
                force = force + ld.force
                moment = moment + arm[:, 0] * ld.force[:, 1] - arm[:, 1] * ld.force[:, 0] + ld.torque
        own = float(np.max(np.linalg.norm(m * (st["a"] - g), axis=1)))
        own_moment = float(np.max(np.abs(j * st["alpha"])))
        for ld in truth.applied_loads():  # gravity and the force elements on the body are its own loads too
            if ld.body == b.name:
                own = max(own, float(np.max(np.linalg.norm(ld.force, axis=1))))
                own_moment = max(own_moment, float(np.max(np.abs(ld.torque))))
        own_moment = max(own_moment, own * arm_max)
        out[b.name] = (float(np.max(np.abs(force))) / own, float(np.max(np.abs(moment))) / own_moment)
    return out


def assert_balanced(mech: Mechanism, res: Results) -> None:
    for body, (force, moment) in own_balance(mech, res).items():
        assert force <= TOL and moment <= TOL, (body, force, moment)


@pytest.mark.parametrize("m_part", PARTS)
@pytest.mark.parametrize("backend", BACKENDS)
def test_every_body_balances_its_own_loads_at_mixed_scales(backend: str, m_part: float) -> None:
    mech = boom(m_part)
    res = api.solve(mech, backend=backend)
    assert res.error is None and res.data.shape[0] == 21
    assert_balanced(mech, res)


@pytest.mark.parametrize("backend", ["numpy", pytest.param("c", marks=needs_cc)])
def test_every_variant_of_a_solve_many_balances_its_own_loads(backend: str) -> None:
    """The variants of one study (one generated solver, other parameter
    values): the gate is each variant's own masses, at run time."""
    mech = boom(2e-6)
    study = api.prepare(mech, backend=backend)
    grid = np.array([[2e-6], [2e-7], [1.0]])  # the last one uniform: no refinement needed, and none made
    for row, got in zip(grid, next(study.solve_many(grid, ("m_part",)))):
        assert got.error is None
        assert_balanced(boom(float(row[0])), got)


def test_the_batched_lu_of_the_numpy_sweep_refines_lambda() -> None:
    """The vectorized sweep's LU (symid.study.batch_lu, the module's fixed
    pivot order, K variants at once) at one instant of the 0.2 g part, two
    variants side by side: the part pin's multipliers against a 40-digit
    solve at the same q. (The sweep's loop itself hands this mechanism's
    variants back to the normal path after t0, so its LU is checked here.)"""
    from high_precision import Instant
    from symid.backends.numpy_backend import build, load_module
    from symid.codegen.model import options_for
    from symid.study import batch_numpy

    mech = boom(2e-7)
    layout = assemble(mech)
    module = load_module(build(layout, options_for(mech)))
    res = api.solve(mech, backend="reference")
    k = 12
    t = float(res.t[k])
    coords = [f"{b.name}.{x}" for b in mech.bodies for x in ("x", "y", "phi")]
    q = np.array([[res[c][k]] * 2 for c in coords])  # (NG, K = 2)
    values = parameter_values(mech.parameters)
    by_name = {s.name: v for s, v in values.items()}
    p = np.tile(np.array([by_name[n] for n in module.PARAMS])[:, None], (1, 2))  # a cached module's defaults may be another m_part's
    factors = batch_numpy._factor(module, q, t, p)
    qd = factors.solve(np.asarray(module.nu(q, t, p)))
    qdd = factors.solve(np.asarray(module.gamma(q, qd, t, p)))
    rhs = np.asarray(module.applied(q, qd, t, p)) - np.asarray(module.mass(p)).reshape(layout.ng, -1) * qdd
    lam = factors.refine_t(rhs, factors.solve_t(rhs), np.array([True, True]))
    exact = Instant(mech)
    got = exact.solve(t, [values[s] for s in exact.p], list(q[:, 0]))
    own = 2e-7 * 9810.0
    for r in range(layout.nc):
        if layout.constraint_names_of_rows([r]) == ["part_pin"]:
            err = np.abs(lam[r] - float(got["lam"][r]))
            assert np.all(err <= TOL * own), (r, err / own)


@pytest.mark.parametrize("backend", ["numpy", pytest.param("c", marks=needs_cc)])
def test_the_part_pin_multipliers_agree_with_a_40_digit_solve(backend: str) -> None:
    """The part's pin: its multipliers and its reactions on both bodies at
    three instants, against the same instant solved at 40 digits
    (tests/helpers/high_precision.py, mpmath), within 1e-12 of the part's own load
    m |g| (without the refinement: ~1e-11 N, 1e-9 of it at 2 g)."""
    from high_precision import Instant

    mech = boom(2e-7)
    res = api.solve(mech, backend=backend)
    assert res.error is None
    exact = Instant(mech)
    values = parameter_values(mech.parameters)
    p = [values[s] for s in exact.p]
    own = 2e-7 * 9810.0
    layout = assemble(mech)
    rows = [r for r in range(layout.nc) if layout.constraint_names_of_rows([r]) == ["part_pin"]]
    lam_columns = [c for c in res.columns if ".lambda" in c]
    start = 0  # the pin's reactions in the 40-digit vector: Fx, Fy, T per role, constraints in file order
    for c in mech.constraints:
        if c.name == "part_pin":
            break
        start += 3 * len(c.bodies)
    reaction_columns = [f"part_pin.{f}_{role}" for role in ("i", "j") for f in ("Fx", "Fy", "T")]
    coords = [f"{b.name}.{k}" for b in mech.bodies for k in ("x", "y", "phi")]
    for k in (5, 12, 20):
        got = exact.solve(float(res.t[k]), p, [float(res[c][k]) for c in coords])
        for r in rows:
            err = abs(res[lam_columns[r]][k] - float(got["lam"][r]))
            assert err <= TOL * own, (backend, k, lam_columns[r], err / own)
        for n, col in enumerate(reaction_columns):
            err = abs(res[col][k] - float(got["reactions"][start + n]))
            assert err <= TOL * own * (1.0 if col.startswith("part_pin.F") else 20.0), (backend, k, col, err / own)


# The compiled instants' Newton tolerance: q is the reference's solution
# already; at 1e-12 a squared distance driver's Phi (~1e4 mm^2, rounding
# ~2e-12) may never pass the absolute test, and the instant would not return.
LOOSE = 1e-8


def _compiled_instants(mech: Mechanism, backend: str):  # type: ignore[no-untyped-def]
    """lam at (t, q) by the compiled solver's own instant: the C library's
    `<name>_instant`, or the NumPy module's `instant` and its vectorized
    `outputs` (the loops hand most of this mechanism's instants over to the
    Python loop, so the compiled outputs are called here directly)."""
    import ctypes

    study = api.prepare(mech, backend="c" if backend == "c-dense" else backend)
    ev = study.evaluator
    if backend in ("c", "c-dense"):
        ng, nc = study.layout.ng, study.layout.nc
        instant = ev._instant
        if backend == "c-dense":  # every factorization through the dense fallback (partial pivoting)
            import tempfile
            from pathlib import Path

            from symid.codegen.model import code_model
            from csolver import instrumented

            lib, _, _ = instrumented(code_model(mech), Path(tempfile.mkdtemp(prefix="symid-dense-")))
            ctypes.c_int.in_dll(lib, "test_force_dense").value = 1
            instant = lib[f"{mech.name}_instant"]
            instant.argtypes = ev._instant.argtypes

        def c_lam(t: float, q: list[float]) -> list[np.ndarray]:
            ptr = lambda a: a.ctypes.data_as(ctypes.POINTER(ctypes.c_double))  # noqa: E731
            qq, qd, qdd, lam = np.array(q), np.zeros(ng), np.zeros(ng), np.zeros(nc)
            reac, info = np.zeros(max(1, ev.meta["nr"])), np.zeros(2, dtype=np.intc)
            status = instant(t, ptr(ev.p), LOOSE, ptr(qq), ptr(qd), ptr(qdd), ptr(lam), ptr(reac),
                                 info.ctypes.data_as(ctypes.POINTER(ctypes.c_int)), ptr(ev.work),
                                 ev.iwork.ctypes.data_as(ctypes.POINTER(ctypes.c_int)))
            assert status == 0
            return [lam]
        return c_lam
    module = ev.module
    values = {s.name: v for s, v in parameter_values(mech.parameters).items()}
    p = [values[n] for n in module.PARAMS]

    def numpy_lam(t: float, q: list[float]) -> list[np.ndarray]:
        return [np.array(module.instant(t, p, q, LOOSE)["lam"]), np.asarray(module.outputs(np.array(q), t, p)["lam"])]
    return numpy_lam


@pytest.mark.parametrize("backend", ["numpy", pytest.param("c", marks=needs_cc),
                                     pytest.param("c-dense", marks=needs_cc)])
def test_the_compiled_instants_give_the_part_pin_multipliers_to_rounding(backend: str) -> None:
    """The generated C's instant (its sparse factors, and forced through its
    dense fallback) and the generated NumPy module's instant and vectorized
    outputs, at the 0.2 g part's instants, against a 40-digit solve at the
    same q: each part-pin multiplier within 1e-12 of m |g|. (The dense
    fallback's partial pivoting on the unscaled Phi_q loses most: 1e-6 of
    the part's load without the refinement.)"""
    from high_precision import Instant

    mech = boom(2e-7)
    res = api.solve(mech, backend="reference")
    solve = _compiled_instants(mech, backend)
    exact = Instant(mech)
    values = parameter_values(mech.parameters)
    p = [values[s] for s in exact.p]
    layout = assemble(mech)
    rows = [r for r in range(layout.nc) if layout.constraint_names_of_rows([r]) == ["part_pin"]]
    coords = [f"{b.name}.{x}" for b in mech.bodies for x in ("x", "y", "phi")]
    own = 2e-7 * 9810.0
    for k in range(1, 21, 2):
        q = [float(res[c][k]) for c in coords]
        got = exact.solve(float(res.t[k]), p, q)
        for lam in solve(float(res.t[k]), q):
            for r in rows:
                err = abs(lam[r] - float(got["lam"][r]))
                assert err <= TOL * own, (backend, k, r, err / own)
