"""The reader parses a text met again once (`_Reader.expr`, `_Reader.number`):
the mechanism read is what each key's own text means there (hand-written truth
below), whatever other key wrote the same text in another context."""

from __future__ import annotations

import pytest
import sympy as sp

from symid.errors import InputError
from symid.io.reader import loads
from symid.model.mechanism import T, parameter_symbol

A, R = parameter_symbol("a"), parameter_symbol("r")
FILE = '''
[mechanism]
name = "twice"
gravity = [0.0, -9.81]

[parameters]
a = 2.0
r = 0.5
half = "a/2"

[signals]
lift = "a*t"
turn = "lift / r"

[analysis]
t1 = 1.0
steps = 5

[[body]]
name = "bar"
mass = "a/2"
inertia = 0.02
q0 = ["a/2", 0.0, 0.0]

[[constraint]]
name = "pin"
type = "revolute"
i = "ground"
j = "bar"
si = [0.0, 0.0]
sj = ["-a/2", 0.0]

[[constraint]]
name = "drive"
type = "coordinate_driver"
body = "bar"
coordinate = "phi"
f = "lift / r"
'''


def test_a_text_means_in_each_key_what_it_means_there():
    mech = loads(FILE)
    assert mech.parameters["half"] == A / 2
    bar = mech.bodies[0]
    assert bar.mass == A / 2 and bar.q0[0] == A / 2
    # The signal `turn` was read with `lift` as a placeholder; the driver's same
    # text "lift / r", read after the signals, is lift's expression over r.
    drive = mech.constraints[1]
    f = drive.values["f"]
    assert sp.simplify(f - A * T / R) == 0 and f.free_symbols == {A, T, R}


def test_a_number_is_checked_with_the_values_of_its_own_read():
    # "1/(a-2)" is finite with a = 3 (first read), infinite with a = 2 (second): each read refuses on its own values
    bad = FILE.replace('inertia = 0.02', 'inertia = "1/(a-2)"')
    assert loads(bad, set_values={"a": "3.0"}).bodies[0].inertia == 1 / (A - 2)
    with pytest.raises(InputError, match="inertia"):
        loads(bad)


def test_a_repeated_bad_text_is_refused_at_its_first_key():
    with pytest.raises(InputError, match=r"body 'bar'.*mass"):
        loads(FILE.replace('mass = "a/2"', 'mass = "lift"'))
