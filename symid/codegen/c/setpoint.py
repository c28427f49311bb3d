"""The C target's set-point entry: the drivers' values from the caller, not the compiled laws.

`<name>_setpoint` solves one instant as `<name>_instant` does, but each
driver row reads the caller's desired value, rate and second rate instead of
its motion law f(t), f'(t), f''(t): the feed-forward of a computed-torque
controller. A driver is a constraint whose family has a time function (the
relative angle, coordinate, distance and translational drivers, and an
expression constraint whose row has t, read as g(q) - f(t)); its rows
are derived once per family on the symbols f, fd, fdd (`symid.symbolic.derive`),
so substituting the set-points for them gives its Phi, nu and gamma rows for
every driver type. The rows are computed by small kernels that overwrite the
driver rows of the compiled Phi, nu and gamma (templates/c/setpoint.j2), so
the rest of the solver (Phi_q, which no driver's law enters, the forces, the
reactions) is shared with instant. The other time functions (applied loads,
actuator forces) are still read at the call's t.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, Callable, Sequence

import sympy as sp

from symid.codegen.c.kernels import Chunk, Kernel, Make
from symid.codegen.emit import Block
from symid.codegen.flat import _role_map, parameter_map, vector
from symid.codegen.model import CodeModel
from symid.codegen.c import phase as c_phase
from symid.symbolic.derive import DerivedConstraint
from symid.symbolic.differentiate import Differentiator
from symid.symbolic.rounding import grouped


@dataclass(frozen=True)
class Driver:
    """One driver: its constraint's name and type, and its constraint row."""

    name: str
    type: str
    row: int


@dataclass(frozen=True)
class Rows:
    """The drivers' rows with the set-points for f, fd, fdd (index k: driver k):
    symbols `q_des[k]`, `qd_des[k]`, `qdd_des[k]`; phi, nu, gamma per driver
    (one row each)."""

    drivers: list[Driver]
    phi: list[sp.Expr]
    nu: list[sp.Expr]
    gamma: list[sp.Expr]


def rows(model: CodeModel) -> Rows:
    """The driver rows of a mechanism with set-point symbols for their laws,
    drivers in row order (the file's order of the constraints)."""
    layout, options = model.layout, model.flat.options
    mech = layout.mechanism
    ng, nb = layout.ng, layout.nb
    _, pmap, _ = parameter_map(mech.parameters)
    q = vector("q", ng)
    qd = vector("qd", ng) if options.velocity else None
    found: list[tuple[int, str, str, DerivedConstraint, dict[sp.Symbol, sp.Expr]]] = []
    for group in layout.constraint_groups:
        derived = group.derived
        assert isinstance(derived, DerivedConstraint)
        if not derived.functions:
            continue
        for m in range(group.size):
            sub = _role_map(group, m, nb, q, qd)
            sub.update({c: sp.sympify(v).xreplace(pmap) for c, v in zip(derived.constants, group.constants[m])})
            found.append((int(group.rows[m]), group.names[m], group.family, derived, sub))
    found.sort(key=lambda x: x[0])
    drivers, phi, nu, gamma = [], [], [], []
    for k, (row, name, family, derived, sub) in enumerate(found):
        assert derived.family.rows == 1, "a driver has one row"
        f, fd, fdd = derived.functions
        sub = {**sub, f: sp.Symbol(f"q_des[{k}]", real=True), fd: sp.Symbol(f"qd_des[{k}]", real=True),
               fdd: sp.Symbol(f"qdd_des[{k}]", real=True)}
        drivers.append(Driver(name, family, row))
        phi.append(grouped(derived.phi[0].xreplace(sub)))
        nu.append(grouped(derived.nu[0].xreplace(sub)))
        gamma.append(grouped(derived.gamma[0].xreplace(sub)) if options.velocity else sp.Integer(0))
    return Rows(drivers, phi, nu, gamma)


def _at_rows(fn: Kernel, where: list[int]) -> Kernel:
    """A kernel whose k-th output is written to out[where[k]]: the driver
    rows of a vector of all NC rows."""
    chunks = [Chunk(Block(ch.block.temps, tuple((where[k], e) for k, e in ch.block.outputs)), ch.unused)
              for ch in fn.chunks]
    return dataclasses.replace(fn, chunks=chunks)


@dataclass(frozen=True)
class Setpoint:
    """What templates/c/setpoint.j2 and setpoint.h.j2 read.

    Attributes:
        drivers: the drivers whose rows take set-points, in the order of ND.
        kernels: sp_phi (and sp_nu, sp_gamma) writing the driver rows.
        sens_kernels: the sensitivity stages' driver rows, set-points held.
        wrapped: the drivers whose row single precision reads modulo 2 pi.
    """

    drivers: list[Any]
    nd: int
    kernels: list[Kernel]
    sens_kernels: list[Kernel]
    wrapped: list[str]
    uses_powi: bool


def context(model: CodeModel, red: c_phase.Reduced | None, make: Make,
            trig: dict[sp.Expr, sp.Symbol], printer: Callable[[sp.Expr], str], real: str,
            stages: Sequence[str] = ()) -> Setpoint | None:
    """What templates/c/setpoint.j2 and setpoint.h.j2 need; None for a
    mechanism without drivers.

    Args:
        red: single precision's reductions (c_phase.reduce), None in double:
            a driver row the compiled Phi reads modulo 2 pi is read so here too.
        make: kernels.function (a kernel of chunks, sines and cosines shared).
        stages: the sensitivity stages the solver computes (c_sens), of
            which q, qdot and qddot get set-point kernels.
    """
    r = rows(model)
    if not r.drivers:
        return None
    o = model.flat.options
    phi, wrapped = r.phi, []
    if red is not None:
        angles = set(c_phase._angles(model.flat.ng))
        out = []
        for d, e in zip(r.drivers, phi):
            coefficients = c_phase._periodic(e, angles) if d.row in red.wrapped_rows else None
            out.append(c_phase.Phases().row(e, coefficients) if coefficients else e)
            if coefficients:
                wrapped.append(d.name)
        phi = out
    cv = lambda name: (f"const {real} *", name)  # noqa: E731
    args = [cv("q"), cv("qd"), cv("q_des"), cv("qd_des"), cv("qdd_des"), cv("p")]
    where = [d.row for d in r.drivers]
    kernels = [_at_rows(make("sp_phi", args, phi, trig, printer, real), where)]
    if o.velocity:
        kernels += [_at_rows(make("sp_nu", args, r.nu, trig, printer, real), where),
                    _at_rows(make("sp_gamma", args, r.gamma, trig, printer, real), where)]
    sens = _sensitivity(model, r, make, trig, printer, real, stages) if o.sensitivity else []
    texts = [e for fn in kernels + sens for ch in fn.chunks for _, e in ch.block.temps + ch.block.outputs]
    return Setpoint(r.drivers, len(r.drivers), kernels, sens, wrapped,
                    any(f"{model.flat.name}_powi(" in e for e in texts))


def _sensitivity(model: CodeModel, r: Rows, make: Make, trig: dict[sp.Expr, sp.Symbol],
                 printer: Callable[[sp.Expr], str], real: str, wanted: Sequence[str]) -> list[Kernel]:
    """Kernels writing the driver rows of the sensitivity stages q, qdot and
    qddot (symid.codegen.sensitivity's right-hand sides, index k NG + row for
    parameter k) with the set-points held fixed: with R the driver's row of
    Phi, Phi_q qd - nu or Phi_q qdd - gamma (set-points for its law), the
    stage's right-hand side is -(R_q sq + R_qd sqd + R_p): only what reads
    the parameters besides the law (a point, a constant C) moves it."""
    f = model.flat
    o = f.options
    ng = f.ng
    q, qd, qdd = vector("q", ng), vector("qd", ng), vector("qdd", ng)
    ns = len(o.sensitivity)
    stages: dict[str, list[sp.Expr]] = {"q": [], "qdot": [], "qddot": []}
    where: list[int] = []
    dd = Differentiator().diff  # sympy's own derivatives, shared subtrees differentiated once
    for k, name in enumerate(o.sensitivity):
        pk = sp.Symbol(f"p[{f.params.index(name)}]", real=True)
        sq = vector("sq", ng * (k + 1))[k * ng:]
        sqd = vector("sqd", ng * (k + 1))[k * ng:]
        for d, phi, nu, gamma in zip(r.drivers, r.phi, r.nu, r.gamma):
            e = c_phase._plain(phi)
            grad = [dd(e, x) for x in q]
            where.append(k * ng + d.row)
            stages["q"].append(-dd(e, pk))
            if not o.velocity:
                continue
            rv = sp.Add(*[g * v for g, v in zip(grad, qd) if g != 0]) - c_phase._plain(nu)
            ra = sp.Add(*[g * a for g, a in zip(grad, qdd) if g != 0]) - c_phase._plain(gamma)
            stages["qdot"].append(-(sp.Add(*[dd(rv, x) * s for x, s in zip(q, sq)]) + dd(rv, pk)))
            stages["qddot"].append(-(sp.Add(*[dd(ra, x) * s for x, s in zip(q, sq)])
                                     + sp.Add(*[dd(ra, v) * s for v, s in zip(qd, sqd)]) + dd(ra, pk)))
    assert len(where) == ns * len(r.drivers)
    cv = lambda name: (f"const {real} *", name)  # noqa: E731
    args = [cv("q"), cv("qd"), cv("qdd"), cv("q_des"), cv("qd_des"), cv("qdd_des"), cv("p"), cv("sq"), cv("sqd")]
    return [_at_rows(make(f"sp_s_{st}", args, exprs, trig, printer, real), where)
            for st, exprs in stages.items() if exprs and st in wanted]
