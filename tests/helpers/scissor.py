"""The scissor lift the conditioning tests share: two crossed arms pinned at
their middles, a foot on a horizontal guide driven along it, a platform on the
arms (a pin and a roller in a slot). Flat (arm angle 0) Phi_q is singular;
near flat it is ill-conditioned, so the tests set the angle close to it."""

from __future__ import annotations


def _value(text: str) -> str:
    """A TOML value: a number as it is, an expression as a string."""
    try:
        float(text)
        return text
    except ValueError:
        return f'"{text}"'


def scissor_lift(name: str, parameters: str, steps: int, angle: str, mirrored: str, drive: str, arm_mass: str = "5.0",
                 top_mass: str = "50.0", more_bodies: str = "", more_constraints: str = "") -> str:
    """The file: `parameters` (the [parameters] lines, L among them), the
    arms' angles in q0 (`angle` and `mirrored`, pi minus it, as expressions), the foot's motion `drive`
    (an expression of t), the masses (a number or a parameter's name), and
    TOML of bodies and constraints to add (after the platform, after the driver)."""
    body = "[[body]]\nname = \"{}\"\nmass = {}\ninertia = \"{}*L^2/12\"\nq0 = [{}]\n"
    return (f"\n[mechanism]\nname = \"{name}\"\ngravity = [0.0, -9.81]\n\n[parameters]\n{parameters.strip()}\n\n"
            f"[analysis]\nt1 = 1.0\nsteps = {steps}\n\n"
            + body.format("arm1", _value(arm_mass), arm_mass, f'"L/2*cos({angle})", "L/2*sin({angle})", "{angle}"')
            + "\n" + body.format("arm2", _value(arm_mass), arm_mass,
                                 f'"L/2*cos({angle})", "L/2*sin({angle})", "{mirrored}"')
            + f'\n[[body]]\nname = "foot"\nmass = 1.0\ninertia = 0.01\nq0 = ["L*cos({angle})", 0.0, 0.0]\n\n'
            + body.format("platform", _value(top_mass), top_mass, f'"L/2", "L*sin({angle})", 0.0')
            + more_bodies
            + """
[[constraint]]
name = "A"
type = "revolute"
i = "ground"
j = "arm1"
si = [0.0, 0.0]
sj = ["-L/2", 0.0]

[[constraint]]
name = "mid"
type = "revolute"
i = "arm1"
j = "arm2"
si = [0.0, 0.0]
sj = [0.0, 0.0]

[[constraint]]
name = "F"
type = "revolute"
i = "arm2"
j = "foot"
si = ["-L/2", 0.0]
sj = [0.0, 0.0]

[[constraint]]
name = "guide"
type = "translational"
i = "ground"
j = "foot"
si = [0.0, 0.0]
vi = [1.0, 0.0]
sj = [0.0, 0.0]

[[constraint]]
name = "top"
type = "revolute"
i = "arm2"
j = "platform"
si = ["L/2", 0.0]
sj = ["-L/2", 0.0]

[[constraint]]
name = "roller"
type = "pin_in_slot"
i = "platform"
j = "arm1"
si = [0.0, 0.0]
vi = [1.0, 0.0]
sj = ["L/2", 0.0]

[[constraint]]
name = "drive"
type = "translational_driver"
i = "ground"
j = "foot"
si = [0.0, 0.0]
vi = [1.0, 0.0]
sj = [0.0, 0.0]
""" + f'f = "{drive}"\n' + more_constraints)
