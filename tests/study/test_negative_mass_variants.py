"""Found trying symid as a new user: `symid solve --set m=-2` is refused (a
negative mass, exit 2), but a sweep over the same values solved every variant
and wrote status `ok` with exit 0. A sweep now refuses such a variant as the
file would, naming it; an optimizer that visits one stops (exit 3)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from symid import cli
from symid.io.reader import load
from symid.study.inertials import first_negative

PENDULUM = """
[mechanism]
name = "pend"
gravity = [0.0, -9.81]

[parameters]
m = 2.0
L = 0.8
I_rod = "m*L^2/12 - 0.05"   # derived: negative for L < 0.548 at m = 2

[analysis]
t1 = 0.5
steps = 11

[[body]]
name = "rod"
mass = "m"
inertia = "I_rod"
q0 = [0.0, -0.4, "-pi/2"]

[[constraint]]
name = "pivot"
type = "revolute"
i = "ground"
j = "rod"
si = [0.0, 0.0]
sj = ["-L/2", 0.0]

[[constraint]]
name = "motor"
type = "relative_angle_driver"
i = "ground"
j = "rod"
f = "-pi/2 + sin(t)"
"""


@pytest.fixture
def pendulum(tmp_path: Path) -> Path:
    path = tmp_path / "pend.toml"
    path.write_text(PENDULUM)
    return path


def test_first_negative_finds_a_mass_and_an_inertia_through_a_derived_parameter(pendulum):
    mech = load(pendulum)
    assert first_negative(mech, ["m"], np.array([[1.0], [2.0]])) is None
    assert first_negative(mech, ["m"], np.array([[1.0], [-0.5], [2.0]])) == (1, "body 'rod' key 'mass' is -0.5")
    k, what = first_negative(mech, ["L"], np.array([[0.8], [0.6], [0.5]])) or (None, "")
    assert k == 2 and what.startswith("body 'rod' key 'inertia' is -0.00833")


@pytest.mark.parametrize("how", [["--grid", "m=-2:2:5"], ["--sample", "40", "--normal", "m=0.1,1", "--seed", "1"]])
def test_a_sweep_with_a_negative_mass_is_refused_naming_the_variant(pendulum, tmp_path, capsys, how):
    out = tmp_path / "study.csv"
    status = cli.main(["sweep", str(pendulum), *how, "--backend", "numpy", "--workers", "1", "-o", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2 and len(err) == 1
    assert "body 'rod' key 'm" in err[0] or "body 'rod' key 'inertia'" in err[0]  # the first bad variant's
    assert "variant" in err[0] and "must not be negative" in err[0]
    assert not out.exists()


def test_a_sweep_of_valid_masses_still_runs(pendulum, tmp_path, capsys):
    out = tmp_path / "study.csv"
    assert cli.main(["sweep", str(pendulum), "--grid", "m=1:2:2", "--backend", "numpy", "--workers", "1",
                     "-o", str(out)]) == 0
    assert out.read_text().count(",ok,") == 2


def test_an_optimizer_visiting_a_negative_mass_stops_with_exit_3(pendulum, tmp_path, capsys):
    out = tmp_path / "opt.toml"
    status = cli.main(["optimize", str(pendulum), "--minimize", "motor.effort_rms", "--vary", "m=-3:3",
                       "--backend", "numpy", "-o", str(out)])
    err = capsys.readouterr().err
    assert status == 3, err
    assert "body 'rod' key 'mass'" in err and "Traceback" not in err
    assert not out.exists()


def test_api_sweep_refuses_a_negative_mass_too(pendulum):
    from symid import api
    from symid.errors import InputError

    with pytest.raises(InputError, match="variant 1 .*key 'mass'"):
        api.sweep(pendulum, {"m": [1.0, -1.0]}, backend="numpy", workers=1)
