"""The derivatives of the sizing figures (`symid.output.sizing`) with respect
to base parameters, from one run's per-instant sensitivities, each
differentiated exactly as it is computed:

- a drive's motor torque tau = J n a + k T / n (k = 1/eta or eta_b, the side
  of each instant, piecewise constant) through the effort T, the driver's
  acceleration a and the drive's J, n, eta, eta_b; the best ratio of a range,
  n^4 = gamma / alpha, moves with them: dn = n/4 (dgamma/gamma - dalpha/alpha)
  inside the range, the bound's derivative on a bound (inside, it changes the
  RMS by nothing to first order, the peak and speed by dtau/dn dn);
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

The drive's own values (ratio or the bound of its range the best ratio sits
on, efficiencies, rotor inertia, ratings) and a bearing's C and p may be
expressions of the parameters: the derivatives go through them. NaN where a
figure has no derivative: the envelope's margin when its points depend on a
parameter differentiated, a bearing whose joint does not turn or carries no load.
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
    shape (instants,) and (instants, params), through the load and the drive's
    own values (ratio, efficiencies, rotor inertia: expressions of parameters)."""

    def __init__(self, drive: Drive, c: Element, d: _Driver, mechanism: Mechanism, names: Sequence[str],
                 values: Mapping[sp.Symbol, float]) -> None:
        from symid.output.sizing.motor import Load

        def by(e: object) -> Array:
            return _by(e, mechanism, names, values)

        self.motor: Motor = motor_of(drive, values)
        f = c.values["f"]
        a = time_function(f, values, d.t, 2)
        definitions = tuple((n, e) for n, e in mechanism.parameters.items() if is_derived(e))
        da = time_functions(_by_parameters(f, definitions, tuple(names))[len(names):], values, d.t, 1)  # d(f'')/dP
        if c.type == "distance_driver":
            s = np.sign(time_function(f, values, d.t))
            a, da = s * a, s[:, None] * da
        load = Load(d.t, d.e, d.v, a)
        motor = self.motor
        lo, hi = motor.ratio
        n = lo if lo == hi else best_ratio(load, motor)
        _, through = split(load, motor)  # the load through the gearbox, its side per instant
        motoring = d.e * d.v >= 0  # as `split`: the side does not move with a parameter
        k = np.where(motoring, 1 / motor.efficiency, motor.back_efficiency)
        dk = np.where(motoring[:, None], -by(drive.efficiency) / motor.efficiency ** 2, by(drive.back_efficiency))
        dthrough = dk * d.e[:, None] + k[:, None] * d.de
        J, dJ = motor.rotor_inertia, by(drive.rotor_inertia)
        if lo < n < hi:  # the best ratio inside its range moves with the load: n^4 = gamma / alpha
            alpha, _, gamma = rms_terms(load, motor)
            w = weights(d.t)
            dalpha = 2 * J * np.sum(w * a * a) * dJ + 2 * J * J * (w * a) @ da
            dgamma = 2 * (w * through) @ dthrough
            dn = n / 4 * (dgamma / gamma - dalpha / alpha)
        else:  # a fixed ratio, or the best on a bound of its range
            dn = by(drive.ratio[0] if n == lo else drive.ratio[1])
        self.t, self.n = d.t, n
        self.tau = J * n * a + through / n
        self.dtau = (np.outer(n * a, dJ) + np.outer(J * a - through / n ** 2, dn) + J * n * da + dthrough / n)
        self.w = n * d.v
        self.dw = n * d.dv + np.outer(d.v, dn)

    def rms_gradient(self) -> Array:
        return _rms_gradient(self.t, self.tau, self.dtau)

    def peak_gradient(self) -> Array:
        j = int(np.argmax(np.abs(self.tau)))
        return np.sign(self.tau[j]) * self.dtau[j]


def _available_by_ratings(m: Motor, speed: float) -> tuple[float, float, float]:
    """d available / d(peak_torque, max_speed, corner_speed) at motor speed `speed`
    (the corner model; with envelope points, the peak's cap only)."""
    w = abs(float(speed))
    if w > m.max_speed:
        return 0.0, 0.0, 0.0
    if m.envelope is not None:
        ws, ts = np.array(m.envelope).T
        capped = w <= ws[-1] and np.interp(w, ws, ts) >= m.peak_torque
        return float(capped), 0.0, 0.0
    corner = m.max_speed if m.corner_speed is None else m.corner_speed
    if w <= corner or corner >= m.max_speed:
        return 1.0, 0.0, 0.0
    span = m.max_speed - corner
    return (m.max_speed - w) / span, m.peak_torque * (w - corner) / span ** 2, \
        m.peak_torque * (m.max_speed - w) / span ** 2


def margin_gradients(drive: Drive, side: MotorSide, mechanism: Mechanism, names: Sequence[str],
                     values: Mapping[sp.Symbol, float]) -> Array:
    """d/dP of `Verdict.margins`, shape (4, len(names)): each check's margin
    through its figure at the figure's own instant (the worst operating point's
    for the envelope, through the curve's slope there) and through the ratings
    (the envelope's NaN when its points depend on a parameter differentiated)."""
    def by(e: object) -> Array:
        return _by(e, mechanism, names, values)

    m = side.motor
    cont, peak, top = m.continuous_torque, m.peak_torque, m.max_speed
    dcont, dpeak, dtop = by(drive.continuous_torque), by(drive.peak_torque), by(drive.max_speed)
    dcorner = np.zeros(len(names)) if drive.corner_speed is None else by(drive.corner_speed)
    rms = float(np.sqrt(np.sum(weights(side.t) * side.tau ** 2)))
    out = np.empty((len(MARGINS), len(names)))
    out[0] = -side.rms_gradient() / cont + rms * dcont / cont ** 2
    j = int(np.argmax(np.abs(side.tau)))
    out[1] = -side.peak_gradient() / peak + abs(side.tau[j]) * dpeak / peak ** 2
    j = int(np.argmax(np.abs(side.w)))
    out[2] = -np.sign(side.w[j]) * side.dw[j] / top + abs(side.w[j]) * dtop / top ** 2
    inside = m.available(side.w) - np.abs(side.tau)
    k = int(np.argmin(inside))
    by_peak, by_top, by_corner = _available_by_ratings(m, side.w[k])
    davailable = m.slope(side.w[k]) * np.sign(side.w[k]) * side.dw[k] + by_peak * dpeak + by_top * dtop \
        + by_corner * dcorner
    out[3] = (davailable - np.sign(side.tau[k]) * side.dtau[k]) / peak - inside[k] * dpeak / peak ** 2
    curve = () if drive.envelope is None else tuple(x for point in drive.envelope for x in point)
    if _depends(curve, mechanism, names):
        out[3] = np.nan  # the curve's points moving are not differentiated
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
