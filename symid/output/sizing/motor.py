"""A drive's motor side: torque and speed per instant through the gearbox,
the verdict against the motor's envelope, and the ratio of least RMS torque.

With the driver's load effort T (`symid.output.summary`: what the actuator
applies to the mechanism), its rate qd and acceleration qdd, a gear of ratio n
(motor turns per driven turn), efficiencies eta (motoring) and eta_b (the load
driving) and a rotor inertia J:

    tau_m = J n qdd + T / (n eta)     when T qd >= 0 (the motor delivers power)
    tau_m = J n qdd + T eta_b / n     when T qd < 0  (the load drives the motor)
    w_m   = n qd

The rotor's own inertia torque J n qdd is that of the reflected inertia
n^2 J seen at the driver (n^2 J qdd there, divided by n). Power through the
gearbox at rest (qd = 0) counts as motoring: the conservative side.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping

import numpy as np

from symid.backends import Array
from symid.model.sizing import Drive
from symid.text import number

# a margin for the comparisons: a motor exactly at its rating fits, rounding of 1e-12 included
REL = 1e-9


@dataclass(frozen=True)
class Load:
    """What the driver demands, shape (instants,) each: its effort T, rate qd, acceleration qdd."""

    t: Array
    torque: Array
    speed: Array
    accel: Array


@dataclass(frozen=True)
class Motor:
    """A drive's numbers at the run's parameter values (SI units, see `Drive`)."""

    driver: str
    ratio: tuple[float, float]
    efficiency: float
    back_efficiency: float
    rotor_inertia: float
    continuous_torque: float
    peak_torque: float
    max_speed: float
    corner_speed: float | None
    envelope: tuple[tuple[float, float], ...] | None = None

    def available(self, speed: Array) -> Array:
        """The peak torque the motor gives at motor speeds `speed` (either sign):
        the peak up to the corner speed, falling linearly to 0 at max_speed, 0
        beyond; with `envelope` points, their linear interpolation (capped by
        the peak, 0 past the last point or max_speed)."""
        w = np.abs(np.asarray(speed, dtype=float))
        if self.envelope is not None:
            ws, ts = np.array(self.envelope).T
            got = np.minimum(np.interp(w, ws, ts, right=0.0), self.peak_torque)
            return np.where(w <= self.max_speed, got, 0.0)
        corner = self.max_speed if self.corner_speed is None else self.corner_speed
        if corner >= self.max_speed:
            return np.where(w <= self.max_speed, self.peak_torque, 0.0)
        falling = self.peak_torque * (self.max_speed - w) / (self.max_speed - corner)
        return np.clip(np.where(w <= corner, self.peak_torque, falling), 0.0, None)

    def slope(self, speed: float) -> float:
        """d available / d|speed| at motor speed `speed` (either sign): 0 where
        the peak caps it or past max_speed; at a kink, the slope of the
        segment below it (the side `available` takes the value of)."""
        w = abs(float(speed))
        if w > self.max_speed:
            return 0.0
        if self.envelope is not None:
            ws, ts = np.array(self.envelope).T
            if w <= ws[0] or w > ws[-1] or np.interp(w, ws, ts) >= self.peak_torque:
                return 0.0
            k = int(np.searchsorted(ws, w, side="left")) - 1  # the segment (ws[k], ws[k + 1]] holding w
            return float((ts[k + 1] - ts[k]) / (ws[k + 1] - ws[k]))
        corner = self.max_speed if self.corner_speed is None else self.corner_speed
        if w <= corner or corner >= self.max_speed:
            return 0.0
        return -self.peak_torque / (self.max_speed - corner)


def motor_of(drive: Drive, values: Mapping[object, float]) -> Motor:
    """The drive's expressions evaluated at the parameter values."""
    from symid.model.params import to_float

    def v(e: object) -> float:
        return to_float(e, values)  # type: ignore[arg-type]

    corner = None if drive.corner_speed is None else v(drive.corner_speed)
    curve = None if drive.envelope is None else tuple((v(w), v(T)) for w, T in drive.envelope)
    return Motor(drive.driver, (v(drive.ratio[0]), v(drive.ratio[1])), v(drive.efficiency),
                 v(drive.back_efficiency), v(drive.rotor_inertia), v(drive.continuous_torque),
                 v(drive.peak_torque), v(drive.max_speed), corner, curve)


def weights(t: Array) -> Array:
    """Trapezoidal weights of the instants, summing to 1 (one instant: weight 1)."""
    t = np.asarray(t, dtype=float)
    if len(t) < 2 or t[-1] == t[0]:
        return np.full(len(t), 1.0 / max(len(t), 1))
    w = np.zeros(len(t))
    dt = np.diff(t)
    w[:-1] += dt / 2
    w[1:] += dt / 2
    return w / (t[-1] - t[0])


def split(load: Load, motor: Motor) -> tuple[Array, Array]:
    """(a, L): the motor torque is J n a + L / n at ratio n; a = qdd, L the
    load through the gearbox's efficiency (T / eta motoring, T eta_b back-driven)."""
    motoring = load.torque * load.speed >= 0
    through = np.where(motoring, load.torque / motor.efficiency, load.torque * motor.back_efficiency)
    return load.accel, through


def torque(load: Load, motor: Motor, n: float) -> Array:
    """Motor torque per instant at ratio n, shape (instants,)."""
    a, through = split(load, motor)
    return motor.rotor_inertia * n * a + through / n


def rms_terms(load: Load, motor: Motor) -> tuple[float, float, float]:
    """(alpha, beta, gamma) with RMS(n)^2 = alpha n^2 + 2 beta + gamma / n^2 (time means, trapezoidal)."""
    a, through = split(load, motor)
    w = weights(load.t)
    J = motor.rotor_inertia
    return float(J * J * np.sum(w * a * a)), float(J * np.sum(w * a * through)), float(np.sum(w * through ** 2))


def rms(load: Load, motor: Motor, n: float) -> float:
    """RMS motor torque at ratio n (the time mean of the square, trapezoidal)."""
    alpha, beta, gamma = rms_terms(load, motor)
    return float(np.sqrt(max(alpha * n * n + 2 * beta + gamma / (n * n), 0.0)))


def rms_derivative(load: Load, motor: Motor, n: float) -> float:
    """d RMS / d n at ratio n, exact: (alpha n - gamma / n^3) / RMS."""
    alpha, _, gamma = rms_terms(load, motor)
    r = rms(load, motor, n)
    return float((alpha * n - gamma / n ** 3) / r) if r > 0 else 0.0


def best_ratio(load: Load, motor: Motor) -> float:
    """The ratio in [lo, hi] of least RMS motor torque.

    RMS^2 = alpha n^2 + 2 beta + gamma / n^2 exactly (the motoring or
    back-driven side of each instant does not depend on n > 0), so its
    derivative vanishes at the one point n^4 = gamma / alpha and the bounded
    minimum is that point clipped to the range: the root of the exact
    derivative, without iterations. A pure inertia load T = J_L qdd (eta = 1)
    gives n = sqrt(J_L / J), the classic inertia match.
    """
    lo, hi = motor.ratio
    alpha, _, gamma = rms_terms(load, motor)
    if alpha <= 0:
        return hi  # no rotor inertia to accelerate: a larger ratio only divides the load
    if gamma <= 0:
        return lo
    return float(np.clip((gamma / alpha) ** 0.25, lo, hi))


@dataclass(frozen=True)
class Verdict:
    """One drive sized over the run (JSON keys: `driver`, `ratio`, `motor_rms`,
    `motor_peak`, `t_peak`, `speed_peak`, `fits`, `why`).

    Attributes:
        motor_peak, t_peak: the largest |motor torque| and its instant.
        speed_peak, t_speed: the largest |motor speed| and its instant.
        thermal_margin: 1 - (RMS / continuous)^2, the share of the motor's
            continuous heat (which goes as torque squared) left; negative: overheats.
        why: what does not fit and when, one phrase each (empty: it fits).
        t, torque, speed: the motor's operating trajectory, shape (instants,).
    """

    motor: Motor
    ratio: float
    motor_rms: float
    motor_peak: float
    t_peak: float
    speed_peak: float
    t_speed: float
    thermal_margin: float
    why: tuple[str, ...]
    t: Array = field(repr=False)
    torque: Array = field(repr=False)
    speed: Array = field(repr=False)
    unit: str = "N·m"
    rate_unit: str = "rad/s"

    @property
    def fits(self) -> bool:
        return not self.why

    def margins(self) -> Array:
        """The verdict's checks as margins, each >= 0 when it passes, shape (4,):
        1 - RMS / continuous, 1 - peak / peak_torque, 1 - speed / max_speed, and
        the worst operating point's min_k (available(w_k) - |tau_k|) / peak_torque.
        (`symid optimize --subject-to D.fits>=1` keeps each >= 0.)"""
        m = self.motor
        inside = (m.available(self.speed) - np.abs(self.torque)) / m.peak_torque
        return np.array([1 - self.motor_rms / m.continuous_torque, 1 - self.motor_peak / m.peak_torque,
                         1 - self.speed_peak / m.max_speed, float(np.min(inside))])

    def json(self) -> dict[str, object]:
        return {"driver": self.motor.driver, "ratio": self.ratio, "motor_rms": self.motor_rms,
                "motor_peak": self.motor_peak, "t_peak": self.t_peak, "speed_peak": self.speed_peak,
                "thermal_margin": self.thermal_margin, "fits": self.fits, "why": list(self.why)}

    def line(self) -> str:
        unit, rate = self.unit, self.rate_unit
        chosen = " (best in the range)" if self.motor.ratio[0] != self.motor.ratio[1] else ""
        head = (f"{self.motor.driver}: ratio {self.ratio:.4g}{chosen}, motor RMS {self.motor_rms:.4g} {unit} "
                f"(continuous {self.motor.continuous_torque:.4g}), peak {self.motor_peak:.4g} {unit} at "
                f"t = {number(self.t_peak)} s (peak {self.motor.peak_torque:.4g}), speed {self.speed_peak:.4g} "
                f"{rate} (max {self.motor.max_speed:.4g}), thermal margin {100 * self.thermal_margin:.3g} %")
        return head + (": fits" if self.fits else ": does not fit: " + "; ".join(self.why))


def verdict(load: Load, motor: Motor, unit: str = "N·m", rate: str = "rad/s") -> Verdict:
    """Size the drive: the ratio (the file's, or the best of its range), then
    RMS against continuous, peak against peak, speed against maximum, every
    operating point against the envelope."""
    n = motor.ratio[0] if motor.ratio[0] == motor.ratio[1] else best_ratio(load, motor)
    tau, w = torque(load, motor, n), n * load.speed
    t = load.t
    r = rms(load, motor, n)
    k, j = int(np.argmax(np.abs(tau))), int(np.argmax(np.abs(w)))
    peak, speed = float(abs(tau[k])), float(abs(w[j]))
    why = []
    if r > motor.continuous_torque * (1 + REL):
        why.append(f"RMS torque {r:.4g} {unit} above continuous {motor.continuous_torque:.4g}")
    if peak > motor.peak_torque * (1 + REL):
        why.append(f"peak torque {peak:.4g} {unit} at t = {number(t[k])} s above peak {motor.peak_torque:.4g}")
    if speed > motor.max_speed * (1 + REL):
        why.append(f"speed {speed:.4g} {rate} at t = {number(t[j])} s above max {motor.max_speed:.4g}")
    outside = np.flatnonzero(np.abs(tau) > motor.available(w) * (1 + REL) + 1e-300)
    if outside.size and peak <= motor.peak_torque * (1 + REL) and speed <= motor.max_speed * (1 + REL):
        m = int(outside[0])  # the peak and the speed said already cover the rest
        why.append(f"outside the envelope at {outside.size} of {len(t)} instants, first at t = {number(t[m])} s "
                   f"({abs(tau[m]):.4g} {unit} at {abs(w[m]):.4g} {rate}, where {motor.available(w[m:m + 1])[0]:.4g} "
                   "is available)")
    margin = 1 - (r / motor.continuous_torque) ** 2
    return Verdict(motor, n, r, peak, float(t[k]), speed, float(t[j]), float(margin), tuple(why), t, tau, w, unit, rate)
