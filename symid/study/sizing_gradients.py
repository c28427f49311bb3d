"""The derivatives of the sizing figures (`symid.output.sizing`) with respect
to base parameters, from one run's per-instant sensitivities, each
differentiated exactly as it is computed:

- a drive's motor torque tau = J n a + k T / n (k = 1/eta or eta_b, the side
  of each instant, piecewise constant) through the effort T and the driver's
  acceleration a; the best ratio of a range, n^4 = gamma / alpha, moves with
  them: dn = n/4 (dgamma/gamma - dalpha/alpha) inside the range, 0 on a bound
  (it changes the RMS by nothing to first order, the peak and speed by dtau/dn dn);
- `D.fits` is a verdict (1 or 0) with no derivative, but its four checks as
  margins (`Verdict.margins`: RMS, peak, speed, the worst point against the
  envelope) each have one, which `symid optimize --subject-to D.fits>=1` bounds;
- a bearing's life. With the trapezoidal time weights w_k (summing to 1),
  the relative speed r_k = omega_j - omega_i and the load F_k = |(Fx, Fy)| on j,
  P_eq^p = S / mean|r| and L10 = (C / P_eq)^p 1e6 revolutions at mean|r|, so
  the mean speed cancels from the hours: L10_h = C^p 1e6 2 pi / (3600 S),
  S = sum w_k |r_k| F_k^p, and

      dL10_h / L10_h = p dC / C + ln C dp - dS / S
      dS = sum w_k (sign(r_k) dr_k F_k^p + |r_k| p F_k^(p-1) dF_k + |r_k| F_k^p ln F_k dp)

  with dr_k from the bodies' `d(B.omega)/d(P)` (the velocity sensitivities the
  solve provides) and dF_k = F . dF / F.

NaN where a figure has no derivative: a drive whose ratio, efficiencies or
rotor inertia (for the margins also its ratings) depend on a parameter
differentiated, an envelope of points that do, a bearing whose joint does
not turn or carries no load.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Mapping, Sequence

import numpy as np
import sympy as sp

from symid.backends import Array
from symid.model.mechanism import GROUND, Element, Mechanism, parameter_symbol
from symid.model.params import is_derived
from symid.output.results import Results
from symid.output.sizing.motor import Motor, best_ratio, motor_of, rms_terms, split, weights
from symid.output.summary import time_function, time_functions
from symid.study.gradients import _by_parameters, _rms_gradient, in_base, sensitivity_column

if TYPE_CHECKING:
    from symid.model.sizing import Bearing, Drive
    from symid.study.gradients import _Driver

MARGINS = ("RMS torque", "peak torque", "speed", "envelope")  # `Verdict.margins`, in order


def needed_columns(mechanism: Mechanism, header: Sequence[str]) -> list[str]:
    """The columns a bearing's life is differentiated from: its joint's force on
    j and the angular speeds of its moving bodies."""
    joints = {c.name: c for c in mechanism.constraints}
    out: list[str] = []
    for b in mechanism.sizing.bearings if mechanism.analysis.kind == "inverse_dynamics" else ():
        joint = joints[b.joint]
        out += [f"{b.joint}.Fx_j", f"{b.joint}.Fy_j"]
        out += [f"{joint.bodies[r]}.omega" for r in ("i", "j") if joint.bodies[r] != GROUND]
    return [c for c in dict.fromkeys(out) if c in header]


def _by(expr: object, mechanism: Mechanism, names: Sequence[str], values: Mapping[sp.Symbol, float]) -> Array:
    """d(expr)/dP for P in `names`, through the derived parameters, at `values`, shape (len(names),)."""
    e = in_base(sp.sympify(expr), dict(mechanism.parameters))
    return np.array([float(sp.diff(e, parameter_symbol(p)).xreplace(values)) for p in names], dtype=float)


def _depends(exprs: Sequence[object], mechanism: Mechanism, names: Sequence[str]) -> bool:
    """Whether any of `exprs` depends on a parameter of `names` (through derived ones)."""
    used: set[sp.Basic] = set()
    for e in exprs:
        used |= sp.sympify(in_base(sp.sympify(e), dict(mechanism.parameters))).free_symbols
    return bool(used & {parameter_symbol(p) for p in names})


class MotorSide:
    """A drive's motor torque and speed over the run and their derivatives,
    shape (instants,) and (instants, params); None-valued `tau` when the
    drive's own values depend on a parameter differentiated."""

    def __init__(self, drive: Drive, c: Element, d: _Driver, mechanism: Mechanism, names: Sequence[str],
                 values: Mapping[sp.Symbol, float]) -> None:
        from symid.output.sizing.motor import Load

        self.motor: Motor = motor_of(drive, values)
        self.exact = not _depends((*drive.ratio, drive.efficiency, drive.back_efficiency, drive.rotor_inertia),
                                  mechanism, names)
        f = c.values["f"]
        a = time_function(f, values, d.t, 2)
        definitions = tuple((n, e) for n, e in mechanism.parameters.items() if is_derived(e))
        da = time_functions(_by_parameters(f, definitions, tuple(names))[len(names):], values, d.t, 1)  # d(f'')/dP
        if c.type == "distance_driver":
            s = np.sign(time_function(f, values, d.t))
            a, da = s * a, s[:, None] * da
        load = Load(d.t, d.e, d.v, a)
        motor = self.motor
        n = motor.ratio[0] if motor.ratio[0] == motor.ratio[1] else best_ratio(load, motor)
        _, through = split(load, motor)  # the load through the gearbox, its side per instant
        k = np.where(d.e * d.v >= 0, 1 / motor.efficiency, motor.back_efficiency)  # as `split`
        J = motor.rotor_inertia
        dn = np.zeros(len(names))
        if motor.ratio[0] < n < motor.ratio[1]:  # the best ratio inside its range moves with the load
            alpha, _, gamma = rms_terms(load, motor)
            w = weights(d.t)
            dalpha = 2 * J * J * (w * a) @ da
            dgamma = 2 * (w * through * k) @ d.de
            dn = n / 4 * (dgamma / gamma - dalpha / alpha)
        self.t, self.n = d.t, n
        self.tau = J * n * a + through / n
        self.dtau = J * n * da + k[:, None] * d.de / n + np.outer(J * a - through / n ** 2, dn)
        self.w = n * d.v
        self.dw = n * d.dv + np.outer(d.v, dn)

    def rms_gradient(self) -> Array:
        return _rms_gradient(self.t, self.tau, self.dtau)

    def peak_gradient(self) -> Array:
        j = int(np.argmax(np.abs(self.tau)))
        return np.sign(self.tau[j]) * self.dtau[j]


def margin_gradients(drive: Drive, side: MotorSide, mechanism: Mechanism, names: Sequence[str]) -> Array:
    """d/dP of `Verdict.margins`, shape (4, len(names)): each check's margin
    through its figure at the figure's own instant (the worst operating point's
    for the envelope, through the curve's slope there)."""
    out = np.full((len(MARGINS), len(names)), np.nan)
    ratings = (drive.continuous_torque, drive.peak_torque, drive.max_speed,
               *(() if drive.corner_speed is None else (drive.corner_speed,)))
    curve = () if drive.envelope is None else tuple(x for point in drive.envelope for x in point)
    if not side.exact or _depends((*ratings, *curve), mechanism, names):
        return out
    m = side.motor
    out[0] = -side.rms_gradient() / m.continuous_torque
    out[1] = -side.peak_gradient() / m.peak_torque
    j = int(np.argmax(np.abs(side.w)))
    out[2] = -np.sign(side.w[j]) * side.dw[j] / m.max_speed
    inside = m.available(side.w) - np.abs(side.tau)
    k = int(np.argmin(inside))
    out[3] = (m.slope(side.w[k]) * np.sign(side.w[k]) * side.dw[k] - np.sign(side.tau[k]) * side.dtau[k]) \
        / m.peak_torque
    return out


def life_gradient(bearing: Bearing, joint: Element, mechanism: Mechanism, results: Results, names: Sequence[str],
                  values: Mapping[sp.Symbol, float]) -> Array:
    """d L10_h / dP of one bearing (see the module), shape (len(names),)."""
    from symid.model.params import to_float

    C, p = to_float(bearing.C, values), to_float(bearing.p, values)  # type: ignore[arg-type]
    t = results.t
    w = weights(t)
    fx, fy = results[f"{joint.name}.Fx_j"], results[f"{joint.name}.Fy_j"]

    def sens(column: str) -> Array:
        return np.column_stack([results[sensitivity_column(column, n)] for n in names]).reshape(len(t), -1)

    r = np.zeros(len(t))
    dr = np.zeros((len(t), len(names)))
    for role, sign in (("j", 1.0), ("i", -1.0)):
        body = joint.bodies[role]
        if body != GROUND:
            r = r + sign * results[f"{body}.omega"]
            dr = dr + sign * sens(f"{body}.omega")
    F = np.hypot(fx, fy)
    loaded = F > 0
    safe = np.where(loaded, F, 1.0)
    dF = np.where(loaded[:, None], (fx[:, None] * sens(f"{joint.name}.Fx_j")
                                    + fy[:, None] * sens(f"{joint.name}.Fy_j")) / safe[:, None], 0.0)
    Fp = np.where(loaded, safe ** p, 0.0)
    S = float(np.sum(w * np.abs(r) * Fp))
    if not S > 0 or not np.isfinite(S):
        return np.full(len(names), np.nan)  # no rotation or no load: no finite life to differentiate
    dC, dp = _by(bearing.C, mechanism, names, values), _by(bearing.p, mechanism, names, values)
    dS = (w * np.sign(r) * Fp) @ dr + (w * np.abs(r) * p * np.where(loaded, safe ** (p - 1), 0.0)) @ dF \
        + float(np.sum(w * np.abs(r) * Fp * np.log(safe))) * dp
    hours = C ** p * 1e6 * 2 * np.pi / (3600 * S)
    return np.asarray(hours * (p * dC / C + np.log(C) * dp - dS / S), dtype=float)
