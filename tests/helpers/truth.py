"""Independent truth for the tests: hand formulas evaluated on solver output.

Nothing here uses symid's derivations or backends: loads come from the
reference's formulas written out again, positions and velocities of points
from the body states in a results table. Only the file reader and parameter
evaluation are shared (they are tested on their own).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import sympy as sp

from symid.model.mechanism import T, Mechanism
from symid.model.params import parameter_values, to_float

# The point of each body role where a constraint's reaction acts (None: the
# centre of mass), restated from the reference, independent of the families.
REACTION_POINT = {
    "revolute": {"i": "si", "j": "sj"},
    "revolute_revolute": {"i": "si", "j": "sj"},
    "distance_driver": {"i": "si", "j": "sj"},
    "parallel": {"i": None, "j": None},
    "pin_in_slot": {"i": "si", "j": "sj"},
    "translational": {"i": "si", "j": "sj"},
    "translational_driver": {"i": "si", "j": "sj"},
    "relative_angle_driver": {"i": None, "j": None},
    "coordinate_driver": {"i": None},
    "gear": {"i": None, "j": None},
    "gear_on_link": {"i": None, "j": None, "k": None},
    "rack_and_pinion": {"i": "pitch", "j": "pitch"},  # moves on both bodies: see pitch_point
    "expression": {"i": "si", "j": "sj"},  # the user's rows: where the file says
}


@dataclass
class Load:
    """A force F (n, 2) at global point P (n, 2) and a torque T (n,), on one body."""

    body: str
    point: np.ndarray
    force: np.ndarray
    torque: np.ndarray


class Truth:
    """Hand-formula evaluation of a mechanism over a results table."""

    def __init__(self, mech: Mechanism, results) -> None:  # type: ignore[no-untyped-def]
        self.mech = mech
        self.res = results
        self.values = parameter_values(mech.parameters)
        self.t = results.t
        self.n = len(self.t)

    def num(self, expr: sp.Expr) -> float:
        return to_float(expr, self.values)

    def fn(self, expr: sp.Expr, order: int = 0) -> np.ndarray:
        """An expression of t and parameters (or its d^order/dt^order) over the run."""
        e = sp.diff(sp.sympify(expr), T, order).xreplace({k: sp.Float(v, 17) for k, v in self.values.items()})
        return np.broadcast_to(np.asarray(sp.lambdify(T, e, "numpy")(self.t), dtype=float), (self.n,))

    def of_state(self, expr: sp.Expr) -> np.ndarray:
        """An expression of t, the parameters and the state functions x(B)... as the
        file wrote it (the reader's placeholder `_state_vx_B` is the column `B.vx`)."""
        e = sp.sympify(expr).xreplace({k: sp.Float(v, 17) for k, v in self.values.items()})
        states = sorted((x for x in e.free_symbols if x.name.startswith("_state_")), key=lambda x: x.name)
        columns = []
        for x in states:
            function, _, body = x.name[len("_state_"):].partition("_")
            columns.append(self.res[f"{body}.{function}"])
        fn = sp.lambdify([T, *states], e, "numpy")
        return np.broadcast_to(np.asarray(fn(self.t, *columns), dtype=float), (self.n,))

    def state(self, body: str) -> dict[str, np.ndarray]:
        """r, phi, v, omega, a, alpha of a body (ground: zeros)."""
        if body == "ground":
            z2, z = np.zeros((self.n, 2)), np.zeros(self.n)
            return {"r": z2, "phi": z, "v": z2, "omega": z, "a": z2, "alpha": z}
        r = self.res
        cols = {k: f"{body}.{k}" for k in ("x", "y", "phi", "vx", "vy", "omega", "ax", "ay", "alpha")}
        return {
            "r": np.stack([r[cols["x"]], r[cols["y"]]], 1), "phi": r[cols["phi"]],
            "v": np.stack([r[cols["vx"]], r[cols["vy"]]], 1), "omega": r[cols["omega"]],
            "a": np.stack([r[cols["ax"]], r[cols["ay"]]], 1), "alpha": r[cols["alpha"]],
        }

    def point(self, body: str, s: tuple | None) -> tuple[np.ndarray, np.ndarray]:
        """Global position and velocity of the body point s' (None: centre of mass)."""
        st = self.state(body)
        if s is None:
            return st["r"], st["v"]
        sx, sy = (self.num(v) for v in s)
        c, sn = np.cos(st["phi"]), np.sin(st["phi"])
        arm = np.stack([c * sx - sn * sy, sn * sx + c * sy], 1)
        perp = np.stack([-arm[:, 1], arm[:, 0]], 1)
        return st["r"] + arm, st["v"] + perp * st["omega"][:, None]

    def applied_loads(self) -> list[Load]:
        """Gravity and every force element, from the reference's formulas."""
        g = np.array([self.num(v) for v in self.mech.gravity])
        loads = []
        for b in self.mech.bodies:
            m = self.num(b.mass)
            loads.append(Load(b.name, self.state(b.name)["r"], np.tile(m * g, (self.n, 1)), np.zeros(self.n)))
        for f in self.mech.forces:
            v = f.values
            if f.type == "point_force":
                body = f.bodies["i"]
                p, _ = self.point(body, v["s"])
                written = v.get("written", v["F"])  # as the file has it, state functions and all
                force = np.stack([self.of_state(written[0]), self.of_state(written[1])], 1)
                loads.append(Load(body, p, force, np.zeros(self.n)))
            elif f.type == "torque":
                body = f.bodies["i"]
                torque = self.of_state(v.get("written", (v["T"],))[0])
                loads.append(Load(body, self.state(body)["r"], np.zeros((self.n, 2)), torque))
            elif f.type == "spring_damper":
                bi, bj = f.bodies["i"], f.bodies["j"]
                pi, vi = self.point(bi, v["si"])
                pj, vj = self.point(bj, v["sj"])
                d = pj - pi
                length = np.linalg.norm(d, axis=1)
                u = d / length[:, None]
                rate = np.sum(u * (vj - vi), axis=1)
                tension = self.num(v["k"]) * (length - self.num(v["L0"])) + self.num(v["c"]) * rate + self.fn(v["fa"])
                loads.append(Load(bi, pi, tension[:, None] * u, np.zeros(self.n)))
                loads.append(Load(bj, pj, -tension[:, None] * u, np.zeros(self.n)))
            elif f.type == "rotational_spring_damper":
                bi, bj = f.bodies["i"], f.bodies["j"]
                si, sj = self.state(bi), self.state(bj)
                torque = (self.num(v["k"]) * (sj["phi"] - si["phi"] - self.num(v["theta0"]))
                          + self.num(v["c"]) * (sj["omega"] - si["omega"]) + self.fn(v["Ta"]))
                loads.append(Load(bi, si["r"], np.zeros((self.n, 2)), torque))
                loads.append(Load(bj, sj["r"], np.zeros((self.n, 2)), -torque))
            else:
                raise AssertionError(f"truth has no formula for {f.type}")
        return [ld for ld in loads if ld.body != "ground"]

    def reaction_loads(self) -> list[Load]:
        """Every constraint's reaction on every body, read from the results table."""
        loads = []
        for c in self.mech.constraints:
            for role, body in c.bodies.items():
                if body == "ground":
                    continue
                key = REACTION_POINT[c.type][role]
                if key == "pitch":
                    p = self.pitch_point(c)
                else:
                    p, _ = self.point(body, c.values[key] if key else None)
                force = np.stack([self.res[f"{c.name}.Fx_{role}"], self.res[f"{c.name}.Fy_{role}"]], 1)
                loads.append(Load(body, p, force, self.res[f"{c.name}.T_{role}"]))
        return loads

    def pitch_point(self, c) -> np.ndarray:  # type: ignore[no-untyped-def]
        """A rack and pinion's pitch point, global (n, 2): r R^T u from the pinion's
        axis, u the rack's unit direction; the side where a positive turn of the
        pinion moves its teeth along +u."""
        vx, vy = (self.num(v) for v in c.values["vj"])
        phi = self.state(c.bodies["j"])["phi"]
        ux = (np.cos(phi) * vx - np.sin(phi) * vy) / np.hypot(vx, vy)
        uy = (np.sin(phi) * vx + np.cos(phi) * vy) / np.hypot(vx, vy)
        return self.state(c.bodies["i"])["r"] + self.num(c.values["r"]) * np.stack([uy, -ux], 1)

    def kinetic_power(self) -> np.ndarray:
        """d/dt of the kinetic energy: sum of m v.a + J omega alpha."""
        out = np.zeros(self.n)
        for b in self.mech.bodies:
            st = self.state(b.name)
            out += self.num(b.mass) * np.sum(st["v"] * st["a"], 1) + self.num(b.inertia) * st["omega"] * st["alpha"]
        return out

    def load_power(self, loads: list[Load]) -> np.ndarray:
        """Power of loads: F . v_P + T omega of the body they act on."""
        out = np.zeros(self.n)
        for ld in loads:
            st = self.state(ld.body)
            arm = ld.point - st["r"]
            v_p = st["v"] + np.stack([-arm[:, 1], arm[:, 0]], 1) * st["omega"][:, None]
            out += np.sum(ld.force * v_p, 1) + ld.torque * st["omega"]
        return out

    def driver_phi_t(self, name: str) -> np.ndarray:
        """dPhi/dt (explicit) of a driver, from the reference's Phi by hand."""
        c = next(c for c in self.mech.constraints if c.name == name)
        f, fd = self.fn(c.values["f"]), self.fn(c.values["f"], 1)
        if c.type == "distance_driver":
            return -2 * f * fd
        if c.type in ("relative_angle_driver", "coordinate_driver", "translational_driver", "expression"):
            return -fd
        raise AssertionError(f"{c.type} is not a driver")


def newton_euler_residual(truth: Truth) -> dict[str, tuple[float, float]]:
    """Per body: (max force residual, max moment residual), each relative to
    the largest load magnitude on that body."""
    loads = truth.applied_loads() + truth.reaction_loads()
    out = {}
    for b in truth.mech.bodies:
        st = truth.state(b.name)
        m, j = truth.num(b.mass), truth.num(b.inertia)
        force = -m * st["a"]
        moment = -j * st["alpha"]
        scale = np.max(np.abs(force)) + np.max(np.abs(moment)) + 1e-300
        for ld in loads:
            if ld.body != b.name:
                continue
            arm = ld.point - st["r"]
            force = force + ld.force
            moment = moment + arm[:, 0] * ld.force[:, 1] - arm[:, 1] * ld.force[:, 0] + ld.torque
            scale = max(scale, np.max(np.abs(ld.force)), np.max(np.abs(ld.torque)))
        out[b.name] = (float(np.max(np.abs(force)) / scale), float(np.max(np.abs(moment)) / scale))
    return out
