"""The smallest mechanisms of each kind (texts of mechanism files), in one place.

Every constraint type alone with the fewest bodies it needs plus drivers,
every force type on a driven pendulum, linkages without a time term linear
in t, and the analyses and output subsets that leave parts of the generated
code empty: the cases where a generated solver has an unused argument, an
empty kernel or an empty elimination pass (or, in single precision, angles
to wrap but no phase).
Each is assembled at q0 and runs 21 instants over t in [0, 1].
"""

from __future__ import annotations

HEAD = '[mechanism]\nname = "{name}"\ngravity = [0.0, {g}]\n\n[analysis]\nt1 = 1.0\nsteps = 21\n'


def _body(name: str, q0: str, mass: str = "1.5", inertia: str = "0.02") -> str:
    return f'\n[[body]]\nname = "{name}"\nmass = {mass}\ninertia = {inertia}\nq0 = [{q0}]\n'


def _item(table: str, name: str, kind: str, **keys: str) -> str:
    return f'\n[[{table}]]\nname = "{name}"\ntype = "{kind}"\n' + "".join(f"{k} = {v}\n" for k, v in keys.items())


def _constraint(name: str, kind: str, **keys: str) -> str:
    return _item("constraint", name, kind, **keys)


def _force(name: str, kind: str, **keys: str) -> str:
    return _item("force", name, kind, **keys)


def _coordinate(body: str, coordinate: str, f: str) -> str:
    return _constraint(f"drive_{coordinate}", "coordinate_driver", body=f'"{body}"', coordinate=f'"{coordinate}"',
                       f=f'"{f}"')


# a bar of length 1 pinned at its left end to the origin, its angle sin(t)
PENDULUM_PARTS = (_body("bar", "0.5, 0.0, 0.0")
                  + _constraint("pin", "revolute", i='"ground"', j='"bar"', si="[0.0, 0.0]", sj="[-0.5, 0.0]")
                  + _constraint("drive", "relative_angle_driver", i='"ground"', j='"bar"', f='"sin(t)"'))

FORCES = {
    "point_force": _force("push", "point_force", body='"bar"', s="[0.5, 0.0]", F='["2*cos(t)", "-1.5"]'),
    "torque": _force("twist", "torque", body='"bar"', T='"0.7 + sin(3*t)"'),
    "spring_damper": _force("spring", "spring_damper", i='"ground"', j='"bar"', si="[1.0, 1.0]", sj="[0.5, 0.0]",
                            k="40.0", c="0.8", L0="0.9", fa="0.3"),
    "rotational_spring_damper": _force("coil", "rotational_spring_damper", i='"ground"', j='"bar"', k="5.0",
                                       c="0.2", theta0="0.1", Ta="0.05"),
}

CONSTRAINTS = {
    # revolute, relative_angle_driver: the driven pendulum
    "pendulum": PENDULUM_PARTS,
    # a block on a rail along x, pushed along it
    "block_on_rail": (_body("block", "0.0, 0.0, 0.0")
                      + _constraint("rail", "translational", i='"ground"', j='"block"', si="[0.0, 0.0]",
                                    vi="[1.0, 0.0]", sj="[0.0, 0.0]")
                      + _constraint("push", "translational_driver", i='"ground"', j='"block"', si="[0.0, 0.0]",
                                    vi="[1.0, 0.0]", sj="[0.0, 0.0]", f='"0.2 + 0.3*sin(2*t)"')),
    # a bar at distance 1 from the origin, x and phi driven
    "revolute_revolute": (_body("bar", "0.3, 0.95, 0.0")
                          + _constraint("link", "revolute_revolute", i='"ground"', j='"bar"', si="[0.0, 0.0]",
                                        sj="[0.0, 0.0]", length="1.0")
                          + _coordinate("bar", "x", "0.3*cos(t)") + _coordinate("bar", "phi", "0.4*t")),
    # a body kept parallel to ground, moved in x and y
    "parallel": (_body("plate", "0.1, 0.2, 0.0")
                 + _constraint("level", "parallel", i='"ground"', j='"plate"', vi="[1.0, 0.0]", vj="[1.0, 0.0]")
                 + _coordinate("plate", "x", "0.1 + t^2") + _coordinate("plate", "y", "0.2*cos(t)")),
    # a pin on a bar, in a slot along x on ground
    "pin_in_slot": (_body("bar", "0.0, -0.2, 0.0")
                    + _constraint("slot", "pin_in_slot", i='"ground"', j='"bar"', si="[0.0, 0.0]", vi="[1.0, 0.0]",
                                  sj="[0.0, 0.2]")
                    + _coordinate("bar", "x", "0.5*sin(t)") + _coordinate("bar", "phi", "0.3*t")),
    # one body held by three coordinate drivers
    "three_coordinates": (_body("puck", "0.0, 1.0, 0.0") + _coordinate("puck", "x", "sin(t)")
                          + _coordinate("puck", "y", "1 + 0.5*t^2") + _coordinate("puck", "phi", "2*t")),
    # a body at a driven distance from the origin, y and phi driven
    "distance_driver": (_body("bob", "1.0, 0.0, 0.0")
                        + _constraint("cable", "distance_driver", i='"ground"', j='"bob"', si="[0.0, 0.0]",
                                      sj="[0.0, 0.0]", f='"1 + 0.2*t"')
                        + _coordinate("bob", "y", "0.3*sin(t)") + _coordinate("bob", "phi", "0")),
    # two gears on ground bearings, the first driven
    "gears": (_body("pinion", "0.0, 0.0, 0.0", "0.2", "0.0004") + _body("wheel", "0.15, 0.0, 0.0", "0.8", "0.009")
              + _constraint("bearing1", "revolute", i='"ground"', j='"pinion"', si="[0.0, 0.0]", sj="[0.0, 0.0]")
              + _constraint("bearing2", "revolute", i='"ground"', j='"wheel"', si="[0.15, 0.0]", sj="[0.0, 0.0]")
              + _constraint("mesh", "gear", i='"pinion"', j='"wheel"', radius_i="0.05", radius_j="0.1")
              + _constraint("motor", "relative_angle_driver", i='"ground"', j='"pinion"', f='"3*t"')
              + _force("load", "torque", body='"wheel"', T='"-0.5"')),
    # a planet on a driven carrier, rolling inside a fixed ring (ground)
    "gear_on_link": (_body("carrier", "0.0, 0.0, 0.0", "1.0", "0.01")
                     + _body("planet", "0.06, 0.0, 0.0", "0.3", "0.0002")
                     + _constraint("axle", "revolute", i='"ground"', j='"carrier"', si="[0.0, 0.0]",
                                   sj="[0.0, 0.0]")
                     + _constraint("planet_pin", "revolute", i='"carrier"', j='"planet"', si="[0.06, 0.0]",
                                   sj="[0.0, 0.0]")
                     + _constraint("ring", "gear_on_link", i='"planet"', j='"ground"', k='"carrier"',
                                   radius_i="0.03", radius_j="0.09", internal="true")
                     + _constraint("motor", "relative_angle_driver", i='"ground"', j='"carrier"', f='"2*t"')),
    # crank pin in the vertical slot of a yoke sliding along x
    "scotch_yoke": (_body("crank", "0.05, 0.0, 0.0", "0.5", "0.001") + _body("yoke", "0.1, 0.0, 0.0", "2.0", "0.05")
                    + _constraint("crank_pin", "revolute", i='"ground"', j='"crank"', si="[0.0, 0.0]",
                                  sj="[-0.05, 0.0]")
                    + _constraint("guide", "translational", i='"ground"', j='"yoke"', si="[0.0, 0.0]",
                                  vi="[1.0, 0.0]", sj="[0.0, 0.0]")
                    + _constraint("slot", "pin_in_slot", i='"yoke"', j='"crank"', si="[0.0, 0.0]", vi="[0.0, 1.0]",
                                  sj="[0.05, 0.0]")
                    + _constraint("motor", "relative_angle_driver", i='"ground"', j='"crank"', f='"4*t"')),
}


# linkages with no time term linear in t: single precision wraps their angles
# (read only through sin and cos) but has no phase to compute
LINKAGES = {
    # a 2R arm, the second bar's centre moved along a straight line
    "two_r_arm": (_body("upper", "0.268, 0.422, 1.004") + _body("fore", "0.9, 0.5, -0.758")
                  + _constraint("shoulder", "revolute", i='"ground"', j='"upper"', si="[0.0, 0.0]",
                                sj="[-0.5, 0.0]")
                  + _constraint("elbow", "revolute", i='"upper"', j='"fore"', si="[0.5, 0.0]", sj="[-0.5, 0.0]")
                  + _coordinate("fore", "x", "0.9 + 0.2*t") + _coordinate("fore", "y", "0.5 - 0.1*t")),
    # a scissor: two bars pinned at their middles, one pinned to ground, the
    # other's lower end in a slot along x; the crossing's x driven
    "scissor_lift": (_body("arm_a", "0.348, 0.359, 0.8") + _body("arm_b", "0.348, 0.359, 2.342")
                     + _constraint("foot", "revolute", i='"ground"', j='"arm_a"', si="[0.0, 0.0]", sj="[-0.5, 0.0]")
                     + _constraint("cross", "revolute", i='"arm_a"', j='"arm_b"', si="[0.0, 0.0]", sj="[0.0, 0.0]")
                     + _constraint("roller", "pin_in_slot", i='"ground"', j='"arm_b"', si="[0.0, 0.0]",
                                   vi="[1.0, 0.0]", sj="[-0.5, 0.0]")
                     + _coordinate("arm_a", "x", "0.35 - 0.1*t")),
}

# numbers of every magnitude in the generated code: integers past 2^63, a
# rational whose numerator is no double, a subnormal
NUMBERS = (_body("bar", "0.5, 0.0, 0.0", "1e19", '"10^25/3"')
           + PENDULUM_PARTS[PENDULUM_PARTS.index("\n[[constraint]]"):]
           + _force("push", "point_force", body='"bar"', s="[0.5, 0.0]", F='["1e-320*cos(t)", "-2^70"]')
           + _force("twist", "torque", body='"bar"', T='"1e20*sin(t) + 12345678901234567890123"'))


def text(name: str, parts: str, analysis: str = "", gravity: float = -9.81) -> str:
    """A whole mechanism file; `analysis` adds lines to [analysis]."""
    return HEAD.format(name=name, g=gravity) + analysis + parts


def cases() -> dict[str, str]:
    """Every small mechanism, by a name that says what it covers."""
    out = {name: text(name, parts) for name, parts in {**CONSTRAINTS, **LINKAGES}.items()}
    out.update({f"force_{kind}": text(f"force_{kind}", PENDULUM_PARTS + force) for kind, force in FORCES.items()})
    every_force = PENDULUM_PARTS + "".join(FORCES.values())
    out["forces_kinematics"] = text("forces_kinematics", every_force, 'kind = "kinematics"\n')
    out["forces_statics"] = text("forces_statics", every_force, 'kind = "statics"\n')
    out["only_q"] = text("only_q", every_force, 'outputs = ["q"]\n')
    out["one_reaction"] = text("one_reaction", CONSTRAINTS["scotch_yoke"],
                               'outputs = ["reactions"]\nreactions = ["slot"]\n')
    out["statics_q_and_one_reaction"] = text("statics_q_and_one_reaction", CONSTRAINTS["scotch_yoke"],
                                             'kind = "statics"\noutputs = ["q", "reactions"]\nreactions = ["guide"]\n')
    out["kinematics_q_only"] = text("kinematics_q_only", CONSTRAINTS["gears"], 'kind = "kinematics"\noutputs = ["q"]\n')
    out["numbers"] = text("numbers", NUMBERS)
    out["no_loads"] = text("no_loads", CONSTRAINTS["three_coordinates"], gravity=0.0)  # applied forces all 0
    out["lambda_only"] = text("lambda_only", CONSTRAINTS["block_on_rail"], 'outputs = ["lambda"]\n')
    return out
