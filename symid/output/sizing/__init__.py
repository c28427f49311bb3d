"""Sizing (`symid size`): motors, gear ratios and bearings from a solved run.

Pure post-processing of a results table: the drivers' efforts and the
rates and accelerations of their f(t) (`motor`), the revolutes' reactions and
relative rotation (`bearings`). See docs/sizing.md.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from symid.errors import InputError
from symid.output.sizing.bearings import Life, life
from symid.output.sizing.motor import Load, Motor, Verdict, motor_of, verdict

# what a run must write for sizing: every column group (and every reaction: `for_sizing`)
ANALYSIS = {"outputs": ["q", "qdot", "qddot", "lambda", "reactions"]}


def for_sizing(mechanism: Any) -> Any:
    """The mechanism with every constraint's reactions solved (a bearing's joint
    may be one the file's `[analysis] reactions` leaves out)."""
    import dataclasses

    return dataclasses.replace(mechanism, analysis=dataclasses.replace(mechanism.analysis, reactions=None))


@dataclass(frozen=True)
class Report:
    """Every drive's verdict and every bearing's life, in file order."""

    drives: tuple[Verdict, ...]
    bearings: tuple[Life, ...]

    @property
    def fits(self) -> bool:
        return all(d.fits for d in self.drives)

    def json(self) -> dict[str, Any]:
        return {"drives": [d.json() for d in self.drives], "bearings": [b.json() for b in self.bearings]}

    def lines(self) -> list[str]:
        return [d.line() for d in self.drives] + [b.line() for b in self.bearings]


def load_of(mechanism: Any, table: Any, driver: str, values: Mapping[Any, float]) -> tuple[Load, str, str]:
    """The driver's effort, rate and acceleration over the run, and the units of its effort and rate."""
    from symid.output.summary import effort, time_function

    c = next(c for c in mechanism.constraints if c.name == driver)
    e = effort(c, table, values)
    if e is None:
        raise InputError(f"{mechanism.source}: drive '{driver}': the run has no effort for it")
    f = c.values["f"]
    accel = time_function(f, values, e.t, 2)
    if c.type == "distance_driver":  # the rate of |f|, as the effort's
        accel = np.sign(time_function(f, values, e.t)) * accel
    unit = "N·m" if e.quantity == "torque" else "N"
    return Load(e.t, e.value, e.rate, accel), unit, e.rate_unit


def size(mechanism: Any, table: Any, values: Mapping[Any, float] | None = None) -> Report:
    """Size the mechanism's drives and bearings from a solved run's table
    (one solved with `ANALYSIS`: speeds and every reaction).

    Args:
        values: every parameter's value (default: the mechanism's own).
    """
    from symid.model.params import parameter_values

    if mechanism.analysis.kind != "inverse_dynamics":
        raise InputError(f"{mechanism.source}: [analysis] key 'kind': sizing needs inverse_dynamics "
                         f"(speeds and accelerations), not {mechanism.analysis.kind}")
    values = parameter_values(mechanism.parameters) if values is None else values
    drives = []
    for d in mechanism.sizing.drives:
        load, unit, rate = load_of(mechanism, table, d.driver, values)
        motor: Motor = motor_of(d, values)
        drives.append(verdict(load, motor, unit, rate))
    joints = {c.name: c for c in mechanism.constraints}
    lives = tuple(life(b, joints[b.joint], table, values, mechanism.source) for b in mechanism.sizing.bearings)
    return Report(tuple(drives), lives)


# the study figures (`symid.study.figures`): per drive on driver D, per bearing on joint C
DRIVE_FIGURES = ("motor_rms", "motor_peak", "fits")
BEARING_FIGURES = ("L10_h",)


def figure_names(mechanism: Any) -> tuple[str, ...]:
    """`D.motor_rms D.motor_peak D.fits` per drive, then `C.L10_h` per bearing
    (none unless the run is inverse dynamics)."""
    if mechanism.analysis.kind != "inverse_dynamics":
        return ()
    return tuple([f"{d.driver}.{f}" for d in mechanism.sizing.drives for f in DRIVE_FIGURES]
                 + [f"{b.joint}.{f}" for b in mechanism.sizing.bearings for f in BEARING_FIGURES])


def figures(mechanism: Any, table: Any, values: Mapping[Any, float] | None = None) -> list[float]:
    """The values of `figure_names` for one solved table (`fits` 1 or 0; a
    bearing whose joint does not turn: NaN, its life undefined)."""
    from symid.model.params import parameter_values

    values = parameter_values(mechanism.parameters) if values is None else values
    out: list[float] = []
    for d in mechanism.sizing.drives:
        load, unit, rate = load_of(mechanism, table, d.driver, values)
        v = verdict(load, motor_of(d, values), unit, rate)
        out += [v.motor_rms, v.motor_peak, float(v.fits)]
    joints = {c.name: c for c in mechanism.constraints}
    for b in mechanism.sizing.bearings:
        try:
            out.append(life(b, joints[b.joint], table, values, mechanism.source).L10_h)
        except InputError:
            out.append(float("nan"))
    return out
