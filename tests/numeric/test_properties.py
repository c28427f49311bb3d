"""Property tests on random mechanisms (hypothesis, derandomized): random
crank-rocker four-bars and random single closed chains of 3 to 5 links.
Every case checks power balance and Newton-Euler on every body against the
independent truth of tests/helpers/truth.py, and the backends against each other.
Random kinds and output and reaction subsets of the smallest mechanisms
(tests/helpers/small_mechanisms.py) check every backend's generated code for each
shape against the reference.

All numbers of a case are parameters, so each structure is generated (and
compiled) once and every example only changes values.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from symid import api, backends
from symid.backends.c_backend import compiler
from symid.errors import InputError
from symid.io.reader import loads
import small_mechanisms
from truth import Truth, newton_euler_residual

SETTINGS = settings(max_examples=10, derandomize=True, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])


def _c_available() -> bool:
    try:
        compiler()
        return True
    except InputError:
        return False


BACKENDS = [b for b in backends.names() if b != "c" or _c_available()]


def _body(name: str, n: int) -> str:
    return (f'\n[[body]]\nname = "{name}"\nmass = "m{n}"\ninertia = "m{n}*L{n}^2/12"\n'
            f'q0 = ["x{n}", "y{n}", "p{n}"]\n')


def _revolute(name: str, i: str, j: str, si: str, sj: str) -> str:
    return (f'\n[[constraint]]\nname = "{name}"\ntype = "revolute"\ni = "{i}"\nj = "{j}"\n'
            f'si = [{si}]\nsj = [{sj}]\n')


def chain_text(links: int, rotate: bool = False) -> str:
    """A closed chain: ground pivot (0, 0), `links` bars, ground pivot (Px, Py);
    links - 2 angle drivers (the first absolute, the others relative), each
    oscillating, or with `rotate` the first turning at w1."""
    names = [f"link{n}" for n in range(1, links + 1)]
    text = f'[mechanism]\nname = "chain{links}{"r" if rotate else ""}"\ngravity = [0.0, -9.81]\n\n[parameters]\n'
    text += "".join(f"{k} = 0.0\n" for n in range(1, links + 1) for k in (f"L{n}", f"m{n}", f"x{n}", f"y{n}",
                                                                          f"p{n}"))
    text += "".join(f"{k} = 0.0\n" for n in range(1, links - 1) for k in (f"f{n}", f"A{n}", f"w{n}"))
    text += "Px = 0.0\nPy = 0.0\nT0 = 0.0\n\n[analysis]\nt1 = 1.0\nsteps = 21\n"
    text += "".join(_body(name, n) for n, name in enumerate(names, start=1))
    text += _revolute("base", "ground", names[0], "0.0, 0.0", '"-L1/2", 0.0')
    for n in range(1, links):
        text += _revolute(f"pin{n}", names[n - 1], names[n], f'"L{n}/2", 0.0', f'"-L{n + 1}/2", 0.0')
    text += _revolute("end", "ground", names[-1], '"Px", "Py"', f'"L{links}/2", 0.0')
    for n in range(1, links - 1):
        i = "ground" if n == 1 else names[n - 2]
        law = f"f{n} + w{n}*t" if rotate else f"f{n} + A{n}*sin(w{n}*t)"
        text += (f'\n[[constraint]]\nname = "motor{n}"\ntype = "relative_angle_driver"\ni = "{i}"\n'
                 f'j = "{names[n - 1]}"\nf = "{law}"\n')
    text += (f'\n[[force]]\nname = "load"\ntype = "torque"\nbody = "{names[1]}"\nT = "T0*cos(3*t)"\n')
    return text


FOUR_BAR = chain_text(3, rotate=True)  # ground, crank, coupler, rocker: the 3-link chain


@st.composite
def crank_rockers(draw) -> dict[str, float]:
    """A Grashof crank-rocker (crank a shortest, next to the ground link d)
    whose transmission angle stays within acos(0.85) of square, assembled open
    at a random crank angle, the crank turning at w1 for one revolution."""
    a = draw(st.floats(0.1, 0.3))
    b, c, d = (draw(st.floats(0.5, 1.0)) for _ in range(3))
    longest = max(b, c, d)
    assume(a + longest <= b + c + d - longest - 0.05)
    for gap in (d - a, d + a):  # crank along, then against, the ground link
        assume(abs((b * b + c * c - gap * gap) / (2 * b * c)) <= 0.85)
    theta = draw(st.floats(-math.pi, math.pi))
    pin = (a * math.cos(theta), a * math.sin(theta))
    dx, dy = d - pin[0], -pin[1]
    e = math.hypot(dx, dy)
    phi3 = math.atan2(dy, dx) + math.acos((b * b + e * e - c * c) / (2 * b * e))
    tip = (pin[0] + b * math.cos(phi3), pin[1] + b * math.sin(phi3))
    phi4 = math.atan2(-tip[1], d - tip[0])  # link 3 runs from the tip to the ground pivot
    values = {"Px": d, "Py": 0.0, "T0": draw(st.floats(-2.0, 2.0)), "f1": theta, "A1": 0.0,
              "w1": draw(st.floats(2.0, 12.0))}
    for n, (length, phi, start) in enumerate([(a, theta, (0.0, 0.0)), (b, phi3, pin), (c, phi4, tip)], start=1):
        values.update({f"L{n}": length, f"m{n}": draw(st.floats(0.1, 5.0)), f"p{n}": phi,
                       f"x{n}": start[0] + length / 2 * math.cos(phi), f"y{n}": start[1] + length / 2 * math.sin(phi)})
    return values


@st.composite
def chains(draw, links: int) -> dict[str, float]:
    """Lengths, masses and an assembled polygon; the undriven last two links
    kept away from collinear so the case stays regular."""
    values: dict[str, float] = {}
    angles = [draw(st.floats(-math.pi, math.pi)) for _ in range(links)]
    turn = draw(st.floats(0.6, 2.5)) * draw(st.sampled_from([-1, 1]))
    angles[-1] = angles[-2] + turn  # |sin| of the last joint's angle >= sin(0.6)
    x = y = 0.0
    for n, phi in enumerate(angles, start=1):
        length = draw(st.floats(0.2, 1.0))
        values.update({f"L{n}": length, f"m{n}": draw(st.floats(0.1, 5.0)), f"p{n}": phi,
                       f"x{n}": x + length / 2 * math.cos(phi), f"y{n}": y + length / 2 * math.sin(phi)})
        x, y = x + length * math.cos(phi), y + length * math.sin(phi)
    values.update({"Px": x, "Py": y, "T0": draw(st.floats(-2.0, 2.0))})
    for n in range(1, links - 1):
        absolute = angles[0] if n == 1 else angles[n - 1] - angles[n - 2]
        values.update({f"f{n}": absolute, f"A{n}": draw(st.floats(-0.15, 0.15)),
                       f"w{n}": draw(st.floats(0.5, 3.0))})
    return values


def _solve(path, backend: str, values: dict[str, float], **analysis: object):
    study = api.prepare(path, backend, {k: repr(v) for k, v in values.items()}, **analysis)
    return study.mechanism, study.solve()


def _check_physics(mech, results) -> None:
    truth = Truth(mech, results)
    for body, (force, moment) in newton_euler_residual(truth).items():
        # random mechanisms are less well conditioned than the examples: 1e-8 N for Newton-Euler
        assert force < 1e-8 and moment < 1e-8, (body, force, moment)
    drive = np.zeros(truth.n)
    for c in mech.constraints:
        if c.type.endswith("driver"):
            drive += results[f"{c.name}.lambda"] * truth.driver_phi_t(c.name)
    expected = truth.kinetic_power() - truth.load_power(truth.applied_loads())
    scale = np.max(np.abs(expected)) + np.max(np.abs(drive)) + 1e-9
    # random mechanisms are less well conditioned than the examples: 1e-7 of the largest power
    assert np.max(np.abs(drive - expected)) <= 1e-7 * scale


def _agree(base, other) -> None:
    assert other.error is None and other.columns == base.columns
    scale = np.maximum(np.abs(base.data).max(axis=0), 1e-3 * np.abs(base.data).max())
    # backends solve the same equations to tol 1e-12; random conditioning costs a few digits
    assert np.max(np.abs(other.data - base.data) / scale) < 1e-9


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("random")
    out = {}
    for links in (4, 5):
        out[links] = folder / f"chain{links}.toml"
        out[links].write_text(chain_text(links), encoding="utf-8")
    out[3] = folder / "four_bar.toml"
    out[3].write_text(FOUR_BAR, encoding="utf-8")
    return out


def test_the_four_bar_file_is_a_four_bar():
    mech = loads(FOUR_BAR)
    assert len(mech.bodies) == 3 and [c.type for c in mech.constraints].count("revolute") == 4


@pytest.mark.slow  # a four-bar derived and solved per drawn example, on every backend
@SETTINGS
@given(values=crank_rockers())
def test_random_four_bars_balance_power_and_forces_on_every_backend(files, values):
    turn = 2 * math.pi / values["w1"]  # one crank revolution
    mech, base = _solve(files[3], "reference", values, t1=turn, steps=41)
    assert base.error is None, base.error
    _check_physics(mech, base)
    for backend in BACKENDS:
        if backend != "reference":
            _agree(base, _solve(files[3], backend, values, t1=turn, steps=41)[1])


@pytest.mark.slow  # 22 s under load; the random four-bars stay in the quick tier
@SETTINGS
@given(links=st.sampled_from([4, 5]), data=st.data())
def test_random_closed_chains_balance_power_and_forces_on_every_backend(files, links, data):
    values = data.draw(chains(links))
    mech, base = _solve(files[links], "reference", values)
    assume(base.error is None)
    _check_physics(mech, base)
    for backend in BACKENDS:
        if backend != "reference":
            _agree(base, _solve(files[links], backend, values)[1])


# -- random output shapes of the smallest mechanisms -----------------------------

KIND_GROUPS = {"inverse_dynamics": ("q", "qdot", "qddot", "lambda", "reactions"),
               "kinematics": ("q", "qdot", "qddot"),
               "statics": ("q", "qdot", "qddot", "lambda", "reactions")}


@st.composite
def output_shapes(draw) -> tuple[str, dict[str, object]]:
    """One small mechanism (each constraint type alone, tests/helpers/small_mechanisms.py)
    with a random kind, a random nonempty set of output groups and, where
    reactions are written, a random nonempty subset of its constraints."""
    name = draw(st.sampled_from(sorted(small_mechanisms.CONSTRAINTS)))
    kind = draw(st.sampled_from(sorted(KIND_GROUPS)))
    outputs = draw(st.lists(st.sampled_from(KIND_GROUPS[kind]), min_size=1, unique=True))
    analysis: dict[str, object] = {"kind": kind, "outputs": tuple(outputs)}
    if "reactions" in outputs:
        names = [c.name for c in loads(small_mechanisms.text(name, small_mechanisms.CONSTRAINTS[name])).constraints]
        analysis["reactions"] = tuple(draw(st.lists(st.sampled_from(names), min_size=1, unique=True)))
    return name, analysis


@pytest.mark.slow  # each of the 8 shapes is generated and compiled anew (C and CasADi); tests/backends/test_small_mechanisms.py keeps the subsets quick
@settings(max_examples=8, derandomize=True, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(shape=output_shapes())
def test_random_output_shapes_of_small_mechanisms_agree_on_every_backend(shape):
    """Each shape is its own generated code (groups left out are not
    compiled): the same header and numbers as the reference on every backend."""
    name, analysis = shape
    mech = loads(small_mechanisms.text(name, small_mechanisms.CONSTRAINTS[name]), f"{name}.toml")
    base = api.solve(mech, backend="reference", **analysis)
    assert base.error is None, base.error
    for backend in BACKENDS:
        if backend != "reference":
            _agree(base, api.solve(mech, backend=backend, **analysis))
