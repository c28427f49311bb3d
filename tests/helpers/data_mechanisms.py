"""Small mechanisms written for particular tests (texts of mechanism files)."""

from symid import api

# A load held by two cables from (-1, 2) and (1, 3), driven so that it moves
# along y = 0 from x = 0.5 to x = -1.5. At t0 the plan pivots the x column on
# the left cable's row; where the load passes x = -1 that cable is vertical,
# its x entry vanishes, while Phi_q stays regular (the fallback case).
TWO_CABLES = """
[mechanism]
name = "two_cables"
gravity = [0.0, -9.81]

[analysis]
t1 = 1.0
steps = 25

[[body]]
name = "load"
mass = 2.0
inertia = 0.1
q0 = [0.5, 0.0, 0.0]

[[constraint]]
name = "cable_left"
type = "distance_driver"
i = "ground"
j = "load"
si = [-1.0, 2.0]
sj = [0.0, 0.0]
f = "sqrt((0.5 - 2*t + 1)^2 + 4)"

[[constraint]]
name = "cable_right"
type = "distance_driver"
i = "ground"
j = "load"
si = [1.0, 3.0]
sj = [0.0, 0.0]
f = "sqrt((0.5 - 2*t - 1)^2 + 9)"

[[constraint]]
name = "no_spin"
type = "coordinate_driver"
body = "load"
coordinate = "phi"
f = 0
"""

# A pendulum pinned at the origin whose centre is driven along x, starting
# at x = 1, the fully stretched (singular) configuration: the revolute's x
# row and the driver's row are equal there.
SINGULAR_PENDULUM = """
[mechanism]
name = "stretched_pendulum"

[analysis]
t1 = 0.5
steps = 11

[[body]]
name = "rod"
mass = 1.0
inertia = 0.1
q0 = [1.0, 0.0, 0.0]

[[constraint]]
name = "pivot"
type = "revolute"
i = "ground"
j = "rod"
si = [0.0, 0.0]
sj = [-1.0, 0.0]

[[constraint]]
name = "push"
type = "coordinate_driver"
body = "rod"
coordinate = "x"
f = "1 - t^2"
"""


def quick_return_with_friction() -> str:
    """The bundled quick-return with friction in its pins, its slot (between
    two moving bodies) and its ram guide."""
    text = api.example("quick_return").read_text(encoding="utf-8")
    text = text.replace('sj = ["r_crank", 0.0]\n', 'sj = ["r_crank", 0.0]\nfriction = { mu = 0.15, viscous = 2.0, arm = 0.05, v_smooth = 1e-3 }\n')
    for name in ("crank_bearing", "lever_pivot"):
        head = f'name = "{name}"\ntype = "revolute"\n'
        text = text.replace(head, head + 'friction = { mu = 0.1, radius = 0.02, viscous = 0.01 }\n')
    head = 'name = "ram_guide"\ntype = "translational"\n'
    text = text.replace(head, head + "friction = { mu = 0.1, viscous = 5.0 }\n")
    assert text.count("friction = ") == 4
    return text
