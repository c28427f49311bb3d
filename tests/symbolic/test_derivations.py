"""The sympy derivations of `symid.symbolic.derive` against independent truth.

Truth is written here by hand from `shared/reference/planar-inverse-dynamics.md`
(hand blocks of Phi_q, hand gamma and nu, the reactions table, the applied-force
table) or computed numerically (finite differences of Phi along a motion), never
taken from the derivation under test. Only the generic symbols are shared.
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

from symid.symbolic import symbols as s
from symid.symbolic.assemble import assemble
from symid.symbolic.derive import _derive_constraint, derive_constraint, derive_force, reaction
from symid.model.mechanism import Body, Element, Mechanism
from tiers import first_quick

# -- the families ---------------------------------------------------------------

COORD_VARIANTS = [("coordinate_driver", (("coordinate", c),)) for c in s.COORDS]
ALL_VARIANTS = [(n, ()) for n in (
    "revolute", "revolute_revolute", "distance_driver", "parallel", "pin_in_slot", "translational",
    "translational_driver", "relative_angle_driver", "gear", "gear_on_link")] + COORD_VARIANTS


def vid(v: tuple[str, tuple]) -> str:
    return v[0] + "".join(f"-{val}" for _, val in v[1])


# -- hand-written symbolic truth (own A, B, R; not symid.symbolic.symbols') --------------

I2, Z12 = sp.eye(2), sp.zeros(1, 2)
RH = sp.Matrix([[0, -1], [1, 0]])
f, fd, fdd = s.F_SERIES[:3]
K, C, L = s.scalar("K"), s.scalar("C"), s.scalar("L")


def Ah(role):
    phi = s.q(role)[2]
    return sp.Matrix([[sp.cos(phi), -sp.sin(phi)], [sp.sin(phi), sp.cos(phi)]])


def Bh(role):
    phi = s.q(role)[2]
    return sp.Matrix([[-sp.sin(phi), -sp.cos(phi)], [sp.cos(phi), -sp.sin(phi)]])


def rh(role):
    return sp.Matrix(s.q(role)[:2])


def rdot(role):
    return sp.Matrix(s.qd(role)[:2])


phid = lambda role: s.qd(role)[2]  # noqa: E731


si, sj, vi, vj = (s.point(k) for k in ("si", "sj", "vi", "vj"))
d = rh("j") + Ah("j") * sj - rh("i") - Ah("i") * si                       # d_ij
d_dot = rdot("j") + Bh("j") * sj * phid("j") - rdot("i") - Bh("i") * si * phid("i")
a_i, a_j = Ah("i") * vi, Ah("j") * vj
u_i = a_i / sp.sqrt(vi.dot(vi))
centripetal = Ah("j") * sj * phid("j") ** 2 - Ah("i") * si * phid("i") ** 2  # s_j phid_j^2 - s_i phid_i^2


def block(phi_r, phi_phi):
    """A rows x 3 block [Phi_r | Phi_phi]."""
    return sp.Matrix.hstack(sp.Matrix(phi_r), sp.Matrix(phi_phi))


def angle_row(ci, cj, ck=None):
    out = {"i": block(Z12, [ci]), "j": block(Z12, [cj])}
    if ck is not None:
        out["k"] = block(Z12, [ck])
    return out


slot_i = block(-(RH * a_i).T, (Bh("i") * vi).T * RH.T * d - a_i.T * RH.T * Bh("i") * si)
slot_j = block((RH * a_i).T, a_i.T * RH.T * Bh("j") * sj)
rr = {"i": block(-2 * d.T, -2 * d.T * Bh("i") * si), "j": block(2 * d.T, 2 * d.T * Bh("j") * sj)}

HAND_JAC = {
    "revolute": {"i": block(-I2, -Bh("i") * si), "j": block(I2, Bh("j") * sj)},
    "revolute_revolute": rr,
    "distance_driver": rr,
    "parallel": {"i": block(Z12, -a_i.T * a_j), "j": block(Z12, a_i.T * a_j)},
    "pin_in_slot": {"i": slot_i, "j": slot_j},
    "translational": {"i": sp.Matrix.vstack(slot_i, block(Z12, [-1])),
                      "j": sp.Matrix.vstack(slot_j, block(Z12, [1]))},
    "translational_driver": {
        "i": block(-u_i.T, (RH * u_i).T * d - u_i.T * Bh("i") * si),
        "j": block(u_i.T, u_i.T * Bh("j") * sj)},
    "relative_angle_driver": angle_row(-1, 1),
    "gear": angle_row(-K, 1),
    "gear_on_link": angle_row(-K, 1, K - 1),
    "coordinate_driver-x": {"i": sp.Matrix([[1, 0, 0]])},
    "coordinate_driver-y": {"i": sp.Matrix([[0, 1, 0]])},
    "coordinate_driver-phi": {"i": sp.Matrix([[0, 0, 1]])},
}

rr_gamma = -2 * d_dot.dot(d_dot) + 2 * d.dot(centripetal)
HAND_GAMMA_NU = {  # name -> (gamma rows, nu rows)
    "revolute": (list(centripetal), [0, 0]),
    "revolute_revolute": ([rr_gamma], [0]),           # constant L: Ldot = Lddot = 0
    "distance_driver": ([rr_gamma + 2 * fd ** 2 + 2 * f * fdd], [2 * f * fd]),
    "parallel": ([a_i.dot(RH.T * a_j) * (phid("j") - phid("i")) ** 2], [0]),
    "relative_angle_driver": ([fdd], [fd]),
    "gear": ([0], [0]),
    "gear_on_link": ([0], [0]),
    "coordinate_driver-x": ([fdd], [fd]),
    "coordinate_driver-y": ([fdd], [fd]),
    "coordinate_driver-phi": ([fdd], [fd]),
}


def is_zero(m: sp.Matrix) -> bool:
    return sp.simplify(m) == sp.zeros(*m.shape)


def variant_of(key: str):
    return next(v for v in ALL_VARIANTS if vid(v) == key)


# -- numerical helpers ----------------------------------------------------------

def lambdified(expr, syms):
    fn = sp.lambdify(syms, expr, "numpy")
    return lambda vals: np.array(fn(*[vals[x] for x in syms]), dtype=float)


def all_symbols(der) -> list[sp.Symbol]:
    exprs = [der.phi, der.nu, der.gamma, *der.jac.values(), *der.reactions.values()]
    return sorted(set().union(*(e.free_symbols for e in exprs)), key=str)


class Smooth:
    """a + b t + c sin(w t) with its first two derivatives."""

    def __init__(self, rng):
        self.a, self.b, self.c = rng.uniform(-1, 1, 3)
        self.w = rng.uniform(0.5, 3)

    def __call__(self, t, n=0):
        a, b, c, w = self.a, self.b, self.c, self.w
        return [a + b * t + c * np.sin(w * t), b + c * w * np.cos(w * t), -c * w * w * np.sin(w * t)][n]


def central(g, t, h, order):
    """6th-order central difference of the vector function g at t."""
    ks = np.arange(-3, 4)
    w = {1: np.array([-1, 9, -45, 0, 45, -9, 1]) / (60 * h),
         2: np.array([2, -27, 270, -490, 270, -27, 2]) / (180 * h * h)}[order]
    return sum(wk * g(t + k * h) for k, wk in zip(ks, w))


RN = np.array([[0.0, -1.0], [1.0, 0.0]])


def rotn(phi):
    return np.array([[np.cos(phi), -np.sin(phi)], [np.sin(phi), np.cos(phi)]])


# -- 1, 2: hand blocks, hand gamma and nu ---------------------------------------

@pytest.mark.parametrize("variant", ALL_VARIANTS, ids=vid)
def test_phi_q_blocks_equal_hand_blocks(variant):
    der = derive_constraint(*variant)
    hand = HAND_JAC[vid(variant)]
    assert set(der.jac) == set(hand)
    for role, block_ in hand.items():
        assert der.jac[role].shape == block_.shape
        assert is_zero(der.jac[role] - block_), role


@pytest.mark.parametrize("key", sorted(HAND_GAMMA_NU))
def test_gamma_and_nu_equal_hand_expressions(key):
    der = derive_constraint(*variant_of(key))
    gamma, nu = HAND_GAMMA_NU[key]
    assert is_zero(der.gamma - sp.Matrix(gamma))
    assert is_zero(der.nu - sp.Matrix(nu))


# -- 3: gamma and nu against finite differences of Phi along a motion -----------

@pytest.mark.parametrize("seed", [1, 2])
@pytest.mark.parametrize("variant", ALL_VARIANTS, ids=vid)
def test_gamma_and_nu_match_numerical_derivatives_of_phi(variant, seed):
    der = derive_constraint(*variant)
    rng = np.random.default_rng(seed)
    syms = all_symbols(der)
    motion = {qc: Smooth(rng) for role in der.roles for qc in s.q(role)}
    f_of_t = Smooth(rng)
    moving = set(motion) | {v for role in der.roles for v in s.qd(role)} | set(s.F_SERIES)
    consts = {x: rng.uniform(0.5, 1.5) * rng.choice([-1, 1]) for x in syms if x not in moving}
    phi, gamma, nu = (lambdified(e, syms) for e in (der.phi, der.gamma, der.nu))
    jac = {role: lambdified(der.jac[role], syms) for role in der.roles}

    def state(t):
        vals = dict(consts)
        for role in der.roles:
            for qc, qdc in zip(s.q(role), s.qd(role)):
                vals[qc], vals[qdc] = motion[qc](t), motion[qc](t, 1)
        vals.update(zip(s.F_SERIES[:3], (f_of_t(t, n) for n in range(3))))
        return vals

    def phi_at(t):
        return phi(state(t)).ravel()

    for t in (0.1, 0.4, 0.9):
        vals = state(t)
        phi_q_qd = sum(jac[r](vals) @ np.array([motion[qc](t, 1) for qc in s.q(r)]) for r in der.roles)
        phi_q_qdd = sum(jac[r](vals) @ np.array([motion[qc](t, 2) for qc in s.q(r)]) for r in der.roles)
        d1, d2 = central(phi_at, t, 1e-3, 1), central(phi_at, t, 1e-3, 2)
        # central differences with h = 1e-3: truncation O(h^2) ~1e-6 (both)
        np.testing.assert_allclose(d1, phi_q_qd - nu(vals).ravel(), rtol=1e-6, atol=1e-6)
        np.testing.assert_allclose(d2, phi_q_qdd - gamma(vals).ravel(), rtol=1e-6, atol=1e-6)


# -- 4: reactions reduce to the reference's table at consistent configurations -

def set_pose(vals, role, x, y, phi):
    vals.update(zip(s.q(role), (x, y, phi)))


def set_vec(vals, key, v):
    vals.update(zip(s.point(key), v))


def consistent(name, opts, rng):
    """(values of the generic symbols at a consistent configuration, expected(lam))."""
    vals = {}
    for role in ("i", "j", "k"):
        set_pose(vals, role, *rng.uniform(-1, 1, 2), rng.uniform(-np.pi, np.pi))
    for key in ("si", "sj", "vi", "vj"):
        set_vec(vals, key, rng.uniform(-1, 1, 2))
    pos = lambda role: np.array([vals[c] for c in s.q(role)[:2]])  # noqa: E731
    ang = lambda role: vals[s.q(role)[2]]  # noqa: E731
    vec = lambda key: np.array([vals[c] for c in s.point(key)])  # noqa: E731
    p_i = pos("i") + rotn(ang("i")) @ vec("si")
    a = rotn(ang("i")) @ vec("vi")
    zero2 = np.zeros(2)

    def put_pin(target):  # move body j so that its point sj is at `target`
        set_pose(vals, "j", *(target - rotn(ang("j")) @ vec("sj")), ang("j"))

    def couple(**torques):
        return lambda lam: {r: np.array([0, 0, t(lam)]) for r, t in torques.items()}

    if name == "revolute":
        put_pin(p_i)
        return vals, None  # F_on_i = -F_on_j, both torques 0: checked in the test
    if name in ("revolute_revolute", "distance_driver"):
        length = rng.uniform(0.5, 2)
        vals[L if name == "revolute_revolute" else s.F_SERIES[0]] = length
        dd = length * rotn(rng.uniform(-np.pi, np.pi)) @ np.array([1.0, 0.0])
        put_pin(p_i + dd)
        return vals, lambda lam: {"i": np.r_[2 * dd * lam[0], 0], "j": np.r_[-2 * dd * lam[0], 0]}
    if name == "parallel":
        vj_ = vec("vj")
        set_pose(vals, "j", *pos("j"), np.arctan2(a[1], a[0]) - np.arctan2(vj_[1], vj_[0]))
        n = np.linalg.norm(a) * np.linalg.norm(vj_)
        return vals, couple(i=lambda lam: n * lam[0], j=lambda lam: -n * lam[0])
    if name in ("pin_in_slot", "translational"):
        if name == "translational":
            vals[s.scalar("theta0")] = ang("j") - ang("i")
        dd = rng.uniform(0.2, 2) * a  # pin ahead of P_i on the slot line
        put_pin(p_i + dd)
        t_i = np.linalg.norm(a) * np.linalg.norm(dd)

        def slot(lam):
            l2 = lam[1] if name == "translational" else 0.0
            return {"i": np.r_[RN @ a * lam[0], t_i * lam[0] + l2], "j": np.r_[-RN @ a * lam[0], -l2]}
        return vals, slot
    if name == "translational_driver":
        u = a / np.linalg.norm(vec("vi"))
        dd = pos("j") + rotn(ang("j")) @ vec("sj") - p_i
        vals[s.F_SERIES[0]] = u @ dd
        return vals, lambda lam: {"i": np.r_[u * lam[0], -(RN @ u) @ dd * lam[0]],
                                  "j": np.r_[-u * lam[0], 0]}
    if name == "relative_angle_driver":
        vals[C] = rng.uniform(-1, 1)
        vals[s.F_SERIES[0]] = ang("j") - ang("i") - vals[C]
        return vals, couple(i=lambda lam: lam[0], j=lambda lam: -lam[0])
    if name in ("gear", "gear_on_link"):
        k_ = vals[K] = rng.uniform(-3, 3)
        link = ang("k") if name == "gear_on_link" else 0.0
        vals[C] = (ang("j") - link) - k_ * (ang("i") - link)
        torques = dict(i=lambda lam: k_ * lam[0], j=lambda lam: -lam[0])
        if name == "gear_on_link":
            torques["k"] = lambda lam: (1 - k_) * lam[0]
        return vals, couple(**torques)
    if name == "coordinate_driver":
        c = s.COORDS.index(dict(opts)["coordinate"])
        vals[s.F_SERIES[0]] = vals[s.q("i")[c]]
        return vals, lambda lam: {"i": -lam[0] * np.eye(3)[c]}
    raise AssertionError(name)


@pytest.mark.parametrize("variant", ALL_VARIANTS, ids=vid)
def test_reactions_reduce_to_reference_table_at_consistent_configurations(variant):
    der = derive_constraint(*variant)
    syms = all_symbols(der)
    phi = lambdified(der.phi, syms)
    react = {r: lambdified(der.reactions[r], syms) for r in der.roles}
    for seed in range(5):
        rng = np.random.default_rng(100 + seed)
        vals, expected = consistent(*variant, rng)
        vals.setdefault(s.F_SERIES[1], 0.3)
        vals.setdefault(s.F_SERIES[2], -0.2)
        vals.update({v: 0.7 for role in der.roles for v in s.qd(role)})  # unused by reactions
        lam = rng.uniform(-2, 2, len(der.lam))
        vals.update(zip(der.lam, lam))
        np.testing.assert_allclose(phi(vals).ravel(), 0, atol=1e-12)  # the builder is consistent
        got = {r: react[r](vals).ravel() for r in der.roles}
        if expected is None:  # revolute
            # lambdified expressions at the same point: rounding (this block)
            np.testing.assert_allclose(got["i"][:2], -got["j"][:2], atol=1e-12)
            np.testing.assert_allclose([got["i"][2], got["j"][2]], 0, atol=1e-12)
            continue
        want = expected(lam)
        for role in der.roles:
            # lambdified expressions at the same point: rounding
            np.testing.assert_allclose(got[role], want.get(role, np.zeros(3)), atol=1e-12, err_msg=role)


# -- 5: reactions do not depend on the sign convention of a row -----------------

@pytest.mark.parametrize("name", first_quick(["revolute", "rack_and_pinion", "pin_in_slot", "translational", "gear_on_link"]))
def test_reaction_unchanged_when_a_row_and_its_multiplier_change_sign(name):
    der = derive_constraint(name)
    lam = sp.Matrix(der.lam)
    for row in range(len(der.lam)):
        flip = sp.diag(*[-1 if n == row else 1 for n in range(len(der.lam))])
        for role in der.roles:
            key = der.family.points[role]
            flipped = reaction(flip * der.jac[role], flip * lam, key, role)
            assert is_zero(flipped - reaction(der.jac[role], lam, key, role))
            assert is_zero(flipped - der.reactions[role])


# -- 6: applied-force families -------------------------------------------------

def random_values(exprs, rng):
    syms = sorted(set().union(*(e.free_symbols for e in exprs)), key=str)
    return syms, {x: rng.uniform(-1, 1) for x in syms}


def test_spring_damper_loads_follow_the_reference_tension():
    der = derive_force("spring_damper")
    k, c, l0, fa = (s.scalar(n) for n in ("k", "c", "L0", "fa"))
    length = sp.sqrt(d.dot(d))
    tension = k * (length - l0) + c * d.dot(d_dot) / length + fa
    assert is_zero(der.loads["i"] - sp.Matrix([*(tension * d / length), 0]))
    assert is_zero(der.loads["j"] + der.loads["i"])


@pytest.mark.parametrize("name", ["spring_damper", "rotational_spring_damper", "point_force", "torque"])
def test_generalized_force_equals_virtual_power_of_the_loads(name):
    der = derive_force(name)
    rng = np.random.default_rng(7)
    for _ in range(5):
        syms, vals = random_values([*der.generalized.values(), *der.loads.values()], rng)
        for role in der.roles:
            vals.update({x: rng.uniform(-1, 1) for x in (*s.q(role), *s.qd(role))})
        for role in der.roles:
            qd_ = np.array([vals[x] for x in s.qd(role)])
            key = der.family.points[role]
            sp_ = np.zeros(2) if key is None else np.array([vals[x] for x in s.point(key)])
            v_point = qd_[:2] + RN @ rotn(vals[s.q(role)[2]]) @ sp_ * qd_[2]
            load = lambdified(der.loads[role], syms)(vals).ravel()
            q_gen = lambdified(der.generalized[role], syms)(vals).ravel()
            assert q_gen @ qd_ == pytest.approx(load[:2] @ v_point + load[2] * qd_[2], abs=1e-12)


def test_stretched_spring_pulls_the_points_together():
    der = derive_force("spring_damper")
    rng = np.random.default_rng(3)
    for _ in range(5):
        syms, vals = random_values([*der.loads.values()], rng)
        vals.update({s.scalar("c"): 0.0, s.scalar("fa"): 0.0, s.scalar("k"): rng.uniform(1, 10)})
        for role in der.roles:
            vals.update({x: rng.uniform(-2, 2) for x in s.q(role)})
        p = {r: np.array([vals[s.q(r)[0]], vals[s.q(r)[1]]])
             + rotn(vals[s.q(r)[2]]) @ np.array([vals[x] for x in s.point("s" + r)]) for r in "ij"}
        vals[s.scalar("L0")] = 0.5 * np.linalg.norm(p["j"] - p["i"])  # l > L0
        load = {r: lambdified(der.loads[r], syms)(vals).ravel() for r in "ij"}
        assert load["i"][:2] @ (p["j"] - p["i"]) > 0 < load["j"][:2] @ (p["i"] - p["j"])


def test_rotational_spring_damper_gives_plus_torque_on_i_minus_on_j():
    der = derive_force("rotational_spring_damper")
    k, c, theta0, ta = (s.scalar(n) for n in ("k", "c", "theta0", "Ta"))
    torque = k * (s.q("j")[2] - s.q("i")[2] - theta0) + c * (phid("j") - phid("i")) + ta
    assert is_zero(der.generalized["i"] - sp.Matrix([0, 0, torque]))
    assert is_zero(der.generalized["j"] - sp.Matrix([0, 0, -torque]))


# -- 7: derived once per family -------------------------------------------------

def chain(n: int, extra: tuple[Element, ...] = ()) -> Mechanism:
    """n bars pinned end to end, the first to ground."""
    zero, half = sp.Integer(0), sp.Rational(1, 2)
    bodies = tuple(Body(f"b{m}", sp.Integer(1), sp.Integer(1), (zero, zero, zero)) for m in range(n))
    joints = tuple(Element(f"pin{m}", "revolute", {"i": "ground" if m == 0 else f"b{m - 1}", "j": f"b{m}"},
                           {"si": (half if m else zero, zero), "sj": (-half, zero)}) for m in range(n))
    return Mechanism("chain", bodies, joints + extra)


def test_derive_constraint_returns_the_cached_object():
    assert derive_constraint("revolute") is derive_constraint("revolute")
    x = (("coordinate", "x"),)
    assert derive_constraint("coordinate_driver", x) is derive_constraint("coordinate_driver", x)
    assert derive_constraint("coordinate_driver", x) is not derive_constraint("coordinate_driver", (("coordinate", "y"),))


def test_assembly_derives_once_per_family_not_per_instance():
    def drivers(n):
        return tuple(Element(f"drv{m}", "coordinate_driver", {"i": f"b{m}"}, {"f": s.T},
                             {"coordinate": "xy"[m % 2]}) for m in range(n))

    assemble(chain(2, drivers(2)))
    before = _derive_constraint.cache_info().misses
    layout = assemble(chain(40, drivers(40)))
    assert _derive_constraint.cache_info().misses == before
    assert sorted(g.size for g in layout.constraint_groups) == [20, 20, 40]
    pins = next(g for g in layout.constraint_groups if g.derived.family.name == "revolute")
    assert pins.derived is derive_constraint("revolute", ())


def test_default_and_explicit_empty_variant_share_one_derivation():
    assert derive_constraint("revolute") is derive_constraint("revolute", ())
