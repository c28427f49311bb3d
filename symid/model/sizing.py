"""What a file says about sizing: drivetrains on drivers (`[[drive]]`) and
bearings on revolutes (`bearing = {...}`), as plain data.

Values are expressions of the parameters, as everywhere in the model: a
study that varies a parameter varies the motor or the bearing it defines.
Sizing itself is post-processing of a solved run (`symid.output.sizing`).
"""

from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

# the [[drive]] keys, in the order the docs list them
DRIVE_KEYS = ("driver", "ratio", "efficiency", "back_efficiency", "rotor_inertia", "continuous_torque",
              "peak_torque", "max_speed", "corner_speed", "envelope")
BEARING_KEYS = ("C", "p")


@dataclass(frozen=True)
class Drive:
    """A motor and gearbox on one driver.

    Attributes:
        driver: the driver constraint's name.
        ratio: (lo, hi) expressions; lo == hi for a fixed ratio (motor turns per driven turn).
        efficiency, back_efficiency: motoring and back-driving efficiencies, in (0, 1].
        rotor_inertia: kg m^2 (kg for a linear motor).
        continuous_torque, peak_torque: N m (N); max_speed: rad/s (m/s) at the motor.
        corner_speed: where the peak torque starts falling linearly to 0 at
            max_speed; None: the peak holds up to max_speed.
        envelope: instead of corner_speed, the torque-speed curve as points
            ((speed, torque), ...), speeds increasing, torques not increasing.
    """

    driver: str
    ratio: tuple[sp.Expr, sp.Expr]
    efficiency: sp.Expr
    back_efficiency: sp.Expr
    rotor_inertia: sp.Expr
    continuous_torque: sp.Expr
    peak_torque: sp.Expr
    max_speed: sp.Expr
    corner_speed: sp.Expr | None = None
    envelope: tuple[tuple[sp.Expr, sp.Expr], ...] | None = None

    @property
    def chooses_ratio(self) -> bool:
        """Whether the file gives a range to choose the ratio from."""
        return self.ratio[0] != self.ratio[1]


@dataclass(frozen=True)
class Bearing:
    """A rolling bearing on a revolute: dynamic rating C [N] and life exponent p (3 balls, 10/3 rollers)."""

    joint: str
    C: sp.Expr
    p: sp.Expr


@dataclass(frozen=True)
class Sizing:
    """The file's drives (file order) and bearings (constraint order)."""

    drives: tuple[Drive, ...] = ()
    bearings: tuple[Bearing, ...] = ()

    def __bool__(self) -> bool:
        return bool(self.drives or self.bearings)


NONE = Sizing()
