"""What a claim is about, and where its numeric tests are made.

A `TypeSubject` is a constraint family on its generic symbols, a
`MechanismSubject` a whole mechanism file; each picks the derived matrix a
claim's quantity names (`View`) and a configuration consistent with its
constraints, where seeded random test points (`random_points`) are drawn.
"""

from __future__ import annotations

import dataclasses
import random
from pathlib import Path
from typing import Any, Callable, Iterator, Mapping, cast

import sympy as sp

from symid.backends import Array
from symid.errors import InputError
from symid.model.elements import registry_lookup
from symid.model.mechanism import parameter_symbol
from symid.symbolic import symbols as s
from symid.symbolic.constraints import TYPES as CONSTRAINTS
from symid.symbolic.derive import DerivedConstraint, derive_constraint
from symid.tools.show import mechanism_system

POINTS = 24  # random points of a numeric test

# A condition's test points: (free symbols, substitution) -> (point, method) pairs.
Points = Callable[[list[sp.Symbol], Mapping[sp.Symbol, sp.Expr]], Iterator[tuple[dict[sp.Symbol, sp.Expr], str]]]


def random_points(seed: int = 2024) -> Points:
    """Seeded exact points: nonzero multiples of 1/8 in [-2, 2] (positive where assumed)
    for the free symbols; symbols a condition substitutes take their values from it."""
    def points(free: list[sp.Symbol], subs: Mapping[sp.Symbol, sp.Expr]) -> Iterator[tuple[dict, str]]:
        rng = random.Random(seed)
        used = set(free) - set(subs)
        base = sorted(used.union(*(v.free_symbols for k, v in subs.items() if k in free)), key=str)
        for _ in range(POINTS):
            point = {x: sp.Rational(rng.randint(1, 16), 8) * (1 if x.is_positive else rng.choice((-1, 1)))
                     for x in base}
            point.update({k: v.xreplace(point) for k, v in subs.items() if k in free})
            yield point, f"numeric, {POINTS} seeded random points"
    return points


def evaluate(m: sp.Matrix, point: Mapping[sp.Symbol, sp.Expr]) -> sp.Matrix:
    """`m` at `point`, 30 significant digits (complex where a root goes negative)."""
    return m.xreplace(dict(point)).applyfunc(lambda e: complex(sp.N(e, 30)))


@dataclasses.dataclass(frozen=True)
class View:
    """What entries of one subject may name.

    whole: Phi, nu, gamma (and Q_A, M of a mechanism); blocks: body -> its
    columns of Phi_q; reactions: role -> [Fx, Fy, T]; per_body: body -> its
    Q_A (3) and M (3 x 3).
    """

    whole: Mapping[str, sp.Matrix]
    blocks: Mapping[str, sp.Matrix]
    reactions: Mapping[str, sp.Matrix] = dataclasses.field(default_factory=dict)
    per_body: Mapping[str, Mapping[str, sp.Matrix]] = dataclasses.field(default_factory=dict)

    def pick(self, qty: Any, body: Any) -> tuple[str, sp.Matrix, tuple[str, ...] | None]:
        """(label, derived matrix, the block names a named-block value may use)."""
        if qty in ("F_on", "T_on"):
            qty, body = f"{qty}_{body}", None
        label = qty if body is None else f"{qty}, body {body}"
        if isinstance(qty, str) and qty[1:5] == "_on_" and qty[0] in "FT" and qty[5:] in self.reactions:
            if body is not None:
                raise InputError(f"key 'body': {qty} names its body already")
            force = self.reactions[qty[5:]]
            return label, force[:2, :] if qty[0] == "F" else force[2:, :], None
        split = {"Phi_q": self.blocks, "Phi_r": self.blocks, "Phi_phi": self.blocks,
                 **{k: self.per_body for k in ("Q_A", "M") if self.per_body}}
        if qty not in split and qty not in self.whole:
            valid = [*self.whole, *(k for k in split if k not in self.whole),
                     *(f"{c}_on_{r}" for r in self.reactions for c in "FT")]
            raise InputError(f"key 'quantity': unknown quantity {qty!r} (valid: {', '.join(valid)})")
        if body is None:
            if qty == "Phi_q":
                return label, sp.Matrix.hstack(*self.blocks.values()), tuple(self.blocks)
            if qty not in self.whole:
                raise InputError(f"key 'body': {qty} needs one")
            return label, self.whole[qty], None
        if qty not in split:
            raise InputError(f"key 'body': {qty} is not split by body")
        if body not in split[qty]:
            raise InputError(f"key 'body': {body!r} is not one of {', '.join(map(str, split[qty]))}")
        if qty in ("Q_A", "M"):
            return label, self.per_body[body][qty], None
        block = self.blocks[body]
        return label, {"Phi_q": block, "Phi_r": block[:, :2], "Phi_phi": block[:, 2:]}[qty], None


class TypeSubject:
    """One constraint type on the generic symbols of docs/symbols.md."""

    def __init__(self, name: str, options: Mapping[str, str]) -> None:
        try:
            family = registry_lookup(CONSTRAINTS, name, "constraint type")
        except LookupError as exc:
            raise InputError(str(exc)) from None
        for key in family.keys:
            if key.kind == "choice" and options.get(key.name) not in key.choices:
                raise InputError(f"needs options.{key.name} = one of {', '.join(key.choices)} "
                                 f"(in [claim]: options = {{ {key.name} = \"{key.choices[-1]}\" }})")
        self.der = derive_constraint(name, family.variant(dict(options)))
        self.label = name + "".join(f" ({k} = {v})" for k, v in options.items())

    def names(self) -> dict[str, sp.Expr]:
        d = self.der
        roles = [x for r in d.roles for x in (*s.q(r), *s.qd(r))]
        own = {x.name: x for x in (*roles, *d.constants, *d.functions, *d.lam)}
        return {"t": s.T, **_display_names(d), **own}

    def quantity(self, qty: Any, body: Any, constraint: Any) -> tuple[str, sp.Matrix, tuple[str, ...] | None]:
        if constraint is not None:
            raise InputError("key 'constraint': only a mechanism claim names constraints")
        d = self.der
        return View({"Phi": d.phi, "nu": d.nu, "gamma": d.gamma}, d.jac, d.reactions).pick(qty, body)

    def consistent(self) -> tuple[dict[sp.Symbol, sp.Expr], str, Points]:
        subs, text = consistent_configuration(self.der)
        return subs, "consistent: " + text, random_points()


def consistent_configuration(der: DerivedConstraint) -> tuple[dict[sp.Symbol, sp.Expr], str]:
    """A parametrisation of the configurations where Phi = 0 (alpha > 0 is new)."""
    name, alpha = der.family.name, sp.Symbol("alpha", positive=True)
    (xj, yj, phij), phii = s.q("j"), s.q("i")[2]
    f, c = s.F_SERIES[0], s.scalar("C")
    a = s.A("i") * s.vector("vi")

    def pin(target: sp.Matrix) -> dict[sp.Symbol, sp.Expr]:  # move body j until d_ij = target
        d = s.global_point("j", "sj") - s.global_point("i", "si")
        return {xj: xj - d[0] + target[0], yj: yj - d[1] + target[1]}

    d = s.global_point("j", "sj") - s.global_point("i", "si")
    table: dict[str, tuple[dict[sp.Symbol, sp.Expr], str]] = {
        "revolute": (pin(sp.zeros(2, 1)), "P_j = P_i (x_j, y_j eliminated)"),
        "revolute_revolute": ({s.scalar("L"): sp.sqrt(d.dot(d))}, "L = |d_ij|"),
        "distance_driver": ({f: sp.sqrt(d.dot(d))}, "f = |d_ij|"),
        "parallel": (dict(zip(s.vector("vj"), alpha * s.rot(phii - phij) * s.vector("vi"))),
                     "a_j = alpha a_i, alpha > 0 (v'_j eliminated)"),
        "pin_in_slot": (pin(alpha * a), "d_ij = alpha a_i, alpha > 0 (x_j, y_j eliminated)"),
        "translational": ({**pin(alpha * a), s.scalar("theta0"): phij - phii},
                          "d_ij = alpha a_i, alpha > 0, theta0 = phi_j - phi_i"),
    }
    if name in table:
        return table[name]
    unknown = f if f in der.phi.free_symbols else c
    return {unknown: sp.solve(der.phi[0], unknown)[0]}, f"{unknown} solved from Phi = 0"


class MechanismSubject:
    """A whole mechanism: its bodies' coordinates, parameters at their values."""

    def __init__(self, path: Path) -> None:
        from symid.io.reader import load

        self.mech = load(path)
        self.sys = mechanism_system(self.mech)
        self.values: dict[sp.Symbol, sp.Expr] = {}
        for name, expr in self.mech.parameters.items():  # dependency order: exact values
            self.values[parameter_symbol(name)] = expr.xreplace(self.values)
        self.label = f"mechanism {self.mech.name} ({path.name})"

    def names(self) -> dict[str, sp.Expr]:
        out: dict[str, sp.Expr] = {"t": s.T, **{str(k): v for k, v in self.values.items()}}
        for b in self.mech.bodies:
            out.update({n: sp.Symbol(n, real=True) for c in s.COORDS for n in (f"{c}_{b.name}", f"{c}d_{b.name}")})
        return {**out, **{x.name: x for x in (*s.lam(1), *s.lam(2))}}

    def quantity(self, qty: Any, body: Any, constraint: Any) -> tuple[str, sp.Matrix, tuple[str, ...] | None]:
        sy, bodies = self.sys, [b.name for b in self.mech.bodies]
        if constraint is None:
            jac = sy.phi_q()
            whole = {k: sp.Matrix.vstack(*v.values()) for k, v in (("Phi", sy.phi), ("nu", sy.nu), ("gamma", sy.gamma))}
            whole["Q_A"] = sp.Matrix.vstack(*sy.applied.values())
            whole["M"] = sp.diag(*[x for m, j in sy.mass.values() for x in (m, m, j)])
            per_body = {b: {"Q_A": sy.applied[b], "M": sp.diag(sy.mass[b][0], *sy.mass[b])} for b in bodies}
            blocks = {b: jac[:, 3 * n:3 * n + 3] for n, b in enumerate(bodies)}
            label, m, keys = View(whole, blocks, per_body=per_body).pick(qty, body)
        else:
            if constraint not in sy.rows:
                raise InputError(f"key 'constraint': {constraint!r} is not one of {', '.join(sy.rows)}")
            n = sy.rows[constraint][1]
            blocks = {b: sy.blocks[constraint].get(b, sp.zeros(n, 3)) for b in bodies}
            whole = {"Phi": sy.phi[constraint], "nu": sy.nu[constraint], "gamma": sy.gamma[constraint]}
            label, m, keys = View(whole, blocks, sy.reactions[constraint]).pick(qty, body)
            label += f", constraint {constraint}"
        return label, m.xreplace(self.values), keys

    def consistent(self) -> tuple[dict[sp.Symbol, sp.Expr], str, Points]:
        from symid import api

        study = api.prepare(self.mech, "reference", kind="kinematics", steps=5, outputs=("q", "qdot"))
        instants = list(study.instants())
        names = self.names()
        coords = [names[f"{c}_{b.name}"] for b in self.mech.bodies for c in s.COORDS]
        rates = [names[f"{c}d_{b.name}"] for b in self.mech.bodies for c in s.COORDS]

        def points(free: list[sp.Symbol], subs: Mapping[sp.Symbol, sp.Expr]) -> Any:
            rng = random.Random(7)
            for inst in instants:
                point = {s.T: sp.Float(repr(inst.t), 30), **{x: sp.Rational(rng.randint(-16, 16), 8) for x in free}}
                point.update(zip(coords, (sp.Float(repr(float(v)), 30) for v in inst.q)))
                qd = cast(Array, inst.qd)  # set: the study's outputs include qdot
                point.update(zip(rates, (sp.Float(repr(float(v)), 30) for v in qd)))
                yield point, f"numeric, {len(instants)} solved configurations"
        return {}, "consistent: configurations solved from Phi(q, t) = 0", points


def _display_names(d: DerivedConstraint) -> dict[str, sp.Expr]:
    """The hand notation `symid derive TYPE` prints, as claim names (docs/symbols.md):
    s_ix = (A_i s'_i)_x, a_ix = (A_i v'_i)_x, d = (dx, dy) = r_j + s_j - r_i - s_i, its rate (dxd, dyd)."""
    out: dict[str, sp.Expr] = {}
    for key in (k for k in d.family.keys if k.kind in ("point", "vector")):
        role, letter = key.name[1], "s" if key.kind == "point" else "a"
        gx, gy = s.A(role) * s.point(key.name)
        out[f"{letter}_{role}x"], out[f"{letter}_{role}y"] = gx, gy
    if "s_ix" in out and "s_jx" in out and "j" in d.roles:
        (xi, yi, _), (xj, yj, _) = s.q("i"), s.q("j")
        (xdi, ydi, pdi), (xdj, ydj, pdj) = s.qd("i"), s.qd("j")
        out["dx"] = xj + out["s_jx"] - xi - out["s_ix"]
        out["dy"] = yj + out["s_jy"] - yi - out["s_iy"]
        out["dxd"] = xdj - out["s_jy"] * pdj - xdi + out["s_iy"] * pdi
        out["dyd"] = ydj + out["s_jx"] * pdj - ydi - out["s_ix"] * pdi
    return out
