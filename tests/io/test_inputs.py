"""Bad mechanism files and bad command lines: the input-error contract.

Every wrong input must end `symid solve` with exit status 2 and exactly one
line on stderr naming the file and the key (no traceback), and must write no
results file. Each case edits a copy of the slider-crank text below (kept
here, not read from the bundled example, so that tuning the example cannot
change what these tests exercise).

See /work/shared/reference/mechanism-file.md ("contract v1").
"""

from __future__ import annotations

import os
import re
import resource
import subprocess
import sys
import time
from pathlib import Path

import pytest

from bad_inputs import BASE, DIRECTORY, MISSING, assert_one_line_input_error, solve_bad
from symid.cli import main

REPO = Path(__file__).resolve().parents[2]

MOTOR = """\
[[constraint]]
name = "motor"
type = "relative_angle_driver"
i = "ground"
j = "crank"
f = "omega*t"
"""

GUIDE = """\
[[constraint]]
name = "cylinder_guide"
type = "translational"
i = "ground"
j = "slider"
si = [0.0, 0.0]
vi = [1.0, 0.0]
sj = [0.0, 0.0]
theta0 = 0.0
"""

MAIN_BEARING_POINTS = 'si = [0.0, 0.0]\nsj = ["-L_crank/2", 0.0]'

CONSTRAINT_TYPES = ("revolute", "revolute_revolute", "parallel", "pin_in_slot", "translational",
                    "relative_angle_driver", "gear", "gear_on_link", "coordinate_driver",
                    "distance_driver", "translational_driver")


def edit(*pairs: str, text: str = BASE) -> str:
    """Replace each `old` by `new` (pairs old1, new1, old2, new2, ...); each
    `old` must occur exactly once, so a case cannot silently edit nothing."""
    assert len(pairs) % 2 == 0
    for old, new in zip(pairs[::2], pairs[1::2]):
        assert text.count(old) == 1, f"{old!r} occurs {text.count(old)} times in the base text"
        text = text.replace(old, new)
    return text


def motor_as(replacement: str) -> str:
    """The base with the motor's table replaced."""
    return edit(MOTOR, replacement)


def gear_motor(keys: str) -> str:
    """The motor replaced by a (1-row) gear between ground and the crank."""
    return motor_as(f'[[constraint]]\nname = "motor"\ntype = "gear"\ni = "ground"\nj = "crank"\n{keys}\n')


def coordinate_motor(coordinate: str) -> str:
    return motor_as(f'[[constraint]]\nname = "motor"\ntype = "coordinate_driver"\nbody = "crank"\n'
                    f'coordinate = {coordinate}\nf = "omega*t"\n')


def without_bodies() -> str:
    return re.sub(r"\[\[body\]\]\n(?:.+\n)+\n", "", BASE)


def with_parameters(lines: str) -> str:
    return edit("[parameters]\n", "[parameters]\n" + lines)


def quoted(expression: str) -> str:
    """A TOML basic string holding `expression`."""
    return '"' + expression.replace("\\", "\\\\").replace('"', '\\"') + '"'


LATIN1 = BASE.encode("latin-1") + b"# caf\xe9\n"
INJECTION = "__import__('os').system('touch PWNED')"

# (id, file content, extra arguments, regex the stderr line must match
#  [, reason: a known bug, the case is a strict xfail])
CASES = [
    # -- the file itself ---------------------------------------------------
    ("nonexistent_file", MISSING, [], r"bad\.toml: cannot read"),
    ("path_is_a_folder", DIRECTORY, [], r"bad\.toml: cannot read"),
    ("not_utf8_latin1", LATIN1, [], r"bad\.toml: not UTF-8"),
    ("not_utf8_binary", b"\xff\xfe\x00\x81[mechanism]\n", [], r"bad\.toml: not UTF-8"),
    ("not_utf8_utf16", BASE.encode("utf-16"), [], r"bad\.toml: not UTF-8"),
    ("empty_file", "", [], r"bad\.toml: top level: missing key 'mechanism'"),
    ("toml_syntax_unterminated_string", edit('name = "slider_crank"', 'name = "slider_crank'), [],
     r"bad\.toml: TOML syntax error: .*line 2"),
    ("toml_syntax_duplicate_key", edit('name = "slider_crank"', 'name = "slider_crank"\nname = "x"'), [],
     r"bad\.toml: TOML syntax error"),
    ("toml_syntax_unclosed_array", edit("gravity = [0.0, -9.81]", "gravity = [0.0, -9.81"), [],
     r"bad\.toml: TOML syntax error"),
    # -- top level and [mechanism] -----------------------------------------
    ("unknown_top_level_key", BASE + "\n[solver]\nmaxit = 3\n", [],
     r"bad\.toml: top level key 'solver': unknown key"),
    ("missing_mechanism_table", edit('[mechanism]\nname = "slider_crank"\ngravity = [0.0, -9.81]\n', ""), [],
     r"bad\.toml: top level: missing key 'mechanism'"),
    ("mechanism_not_a_table",
     'mechanism = "slider_crank"\n' + edit('[mechanism]\nname = "slider_crank"\ngravity = [0.0, -9.81]\n', ""),
     [], r"bad\.toml: \[mechanism\]: must be a table"),
    ("missing_mechanism_name", edit('name = "slider_crank"\n', ""), [],
     r"bad\.toml: \[mechanism\]: missing key 'name'"),
    ("mechanism_name_with_space", edit('"slider_crank"', '"slider crank"'), [],
     r"bad\.toml: \[mechanism\] key 'name': 'slider crank' is not a name"),
    ("mechanism_name_with_dash", edit('"slider_crank"', '"slider-crank"'), [],
     r"bad\.toml: \[mechanism\] key 'name': 'slider-crank' is not a name"),
    ("mechanism_name_leading_digit", edit('"slider_crank"', '"2stroke"'), [],
     r"bad\.toml: \[mechanism\] key 'name': '2stroke' is not a name"),
    ("mechanism_name_not_a_string", edit('"slider_crank"', "5"), [],
     r"bad\.toml: \[mechanism\] key 'name': 5 is not a name"),
    ("mechanism_name_code_injection", edit('"slider_crank"', '"x; import os"'), [],
     r"bad\.toml: \[mechanism\] key 'name': .* is not a name"),
    ("mechanism_unknown_key", edit("gravity = [0.0, -9.81]", "gravity = [0.0, -9.81]\nspeed = 3"), [],
     r"bad\.toml: \[mechanism\] key 'speed': unknown key"),
    ("gravity_wrong_length", edit("gravity = [0.0, -9.81]", "gravity = [-9.81]"), [],
     r"bad\.toml: \[mechanism\] key 'gravity': has 1 value, 2 expected"),
    # -- bodies ------------------------------------------------------------
    ("no_bodies", without_bodies(), [], r"bad\.toml: top level: no \[\[body\]\]"),
    ("body_unknown_key", edit('mass = "m_crank"', 'mass = "m_crank"\ncolour = "red"'), [],
     r"bad\.toml: body 'crank' key 'colour': unknown key"),
    ("body_missing_name", edit('name = "crank"\n', ""), [],
     r"bad\.toml: \[\[body\]\] #1: missing key 'name'"),
    ("body_missing_mass", edit('mass = "m_crank"\n', ""), [],
     r"bad\.toml: body 'crank': missing key 'mass'"),
    ("body_missing_inertia", edit('inertia = "m_rod*L_rod^2/12"\n', ""), [],
     r"bad\.toml: body 'connecting_rod': missing key 'inertia'"),
    ("body_missing_q0", edit('q0 = ["L_crank + L_rod", 0.0, 0.0]\n', ""), [],
     r"bad\.toml: body 'slider': missing key 'q0'"),
    ("body_q0_too_short", edit('q0 = ["L_crank/2", 0.0, 0.0]', 'q0 = ["L_crank/2", 0.0]'), [],
     r"bad\.toml: body 'crank' key 'q0': has 2 values, 3 expected"),
    ("body_q0_too_long", edit('q0 = ["L_crank/2", 0.0, 0.0]', 'q0 = ["L_crank/2", 0.0, 0.0, 0.0]'), [],
     r"bad\.toml: body 'crank' key 'q0': has 4 values, 3 expected"),
    ("body_q0_a_string", edit('q0 = ["L_crank/2", 0.0, 0.0]', 'q0 = "0.05, 0, 0"'), [],
     r"bad\.toml: body 'crank' key 'q0': must be a list of 3 .*string"),
    ("body_q0_unknown_name", edit('q0 = ["L_crank/2", 0.0, 0.0]', 'q0 = ["L_crank/2", 0.0, "phi0"]'), [],
     r"bad\.toml: body 'crank' key 'q0': unknown name 'phi0'"),
    ("negative_mass", edit('mass = "m_crank"', "mass = -1.0"), [],
     r"bad\.toml: body 'crank' key 'mass': must not be negative"),
    ("negative_mass_from_parameter", edit("m_crank = 0.5", "m_crank = -0.5"), [],
     r"bad\.toml: body 'crank' key 'mass': must not be negative"),
    ("negative_inertia", edit('inertia = "m_rod*L_rod^2/12"', 'inertia = "-m_rod*L_rod^2/12"'), [],
     r"bad\.toml: body 'connecting_rod' key 'inertia': must not be negative"),
    ("mass_1e999_is_toml_inf", edit('mass = "m_crank"', "mass = 1e999"), [],
     r"bad\.toml: body 'crank' key 'mass': .*not finite"),
    ("mass_toml_inf", edit('mass = "m_crank"', "mass = inf"), [],
     r"bad\.toml: body 'crank' key 'mass': .*not finite"),
    ("mass_toml_nan", edit('mass = "m_crank"', "mass = nan"), [],
     r"bad\.toml: body 'crank' key 'mass': .*not finite"),
    ("mass_expression_inf", edit('mass = "m_crank"', 'mass = "inf"'), [],
     r"bad\.toml: body 'crank' key 'mass': unknown name 'inf'"),
    ("mass_expression_1e999", edit('mass = "m_crank"', 'mass = "1e999"'), [],
     r"bad\.toml: body 'crank' key 'mass': .*too large for a double"),
    ("mass_overflowing_parameter", edit("m_crank = 0.5", 'm_crank = "exp(1000)"'), [],
     r"bad\.toml: \[parameters\] key 'm_crank': .*not finite"),
    ("mass_boolean", edit('mass = "m_crank"', "mass = true"), [],
     r"bad\.toml: body 'crank' key 'mass': .*boolean"),
    ("mass_a_list", edit('mass = "m_crank"', "mass = [1.0]"), [],
     r"bad\.toml: body 'crank' key 'mass': must be a number or an expression"),
    ("duplicate_body_names", edit('name = "slider"\n', 'name = "crank"\n'), [],
     r"bad\.toml: body 'crank' key 'name': duplicate"),
    ("body_named_ground", edit('name = "slider"\n', 'name = "ground"\n'), [],
     r"bad\.toml: body 'ground' key 'name': duplicate or reserved"),
    # -- constraints and forces --------------------------------------------
    ("unknown_constraint_type", edit('type = "relative_angle_driver"', 'type = "rotary_driver"'), [],
     r"bad\.toml: constraint 'motor' key 'type': unknown constraint type 'rotary_driver' \(valid: "
     + "".join(rf"(?=.*\b{t}\b)" for t in CONSTRAINT_TYPES)),
    ("unknown_force_type", edit('type = "point_force"', 'type = "pressure"'), [],
     r"bad\.toml: force 'gas_load' key 'type': unknown force type 'pressure' \(valid: .*point_force"),
    ("constraint_missing_type", edit('type = "relative_angle_driver"\n', ""), [],
     r"bad\.toml: constraint 'motor': missing key 'type'"),
    ("constraint_missing_name", edit('name = "motor"\n', ""), [],
     r"bad\.toml: \[\[constraint\]\] #5: missing key 'name'"),
    ("constraint_unknown_key", edit(MAIN_BEARING_POINTS, MAIN_BEARING_POINTS + "\naxis = [1.0, 0.0]"), [],
     r"bad\.toml: constraint 'main_bearing' key 'axis': unknown key"),
    ("constraint_unknown_body", edit('j = "connecting_rod"', 'j = "conrod"'), [],
     r"bad\.toml: constraint 'crank_pin' key 'j': unknown body 'conrod'"),
    ("constraint_body_not_a_string", edit('j = "connecting_rod"', "j = 2"), [],
     r"bad\.toml: constraint 'crank_pin' key 'j': unknown body 2"),
    ("constraint_body_is_a_force", edit('j = "connecting_rod"', 'j = "gas_load"'), [],
     r"bad\.toml: constraint 'crank_pin' key 'j': unknown body 'gas_load'"),
    ("force_unknown_body", edit('body = "slider"', 'body = "piston"'), [],
     r"bad\.toml: force 'gas_load' key 'body': unknown body 'piston'"),
    ("duplicate_body_constraint_names", edit('name = "motor"', 'name = "crank"'), [],
     r"bad\.toml: constraint 'crank' key 'name': duplicate name"),
    ("duplicate_constraint_force_names", edit('name = "gas_load"', 'name = "motor"'), [],
     r"bad\.toml: force 'motor' key 'name': duplicate name"),
    ("duplicate_constraint_names", edit('name = "crank_pin"', 'name = "main_bearing"'), [],
     r"bad\.toml: constraint 'main_bearing' key 'name': duplicate name"),
    ("duplicate_body_force_names", edit('name = "gas_load"', 'name = "slider"'), [],
     r"bad\.toml: force 'slider' key 'name': duplicate name"),
    ("constraint_connects_body_to_itself", edit('j = "connecting_rod"', 'j = "crank"'), [],
     r"bad\.toml: constraint 'crank_pin': connects a body to itself"),
    ("constraint_ground_to_ground", edit('j = "crank"\nsi = [0.0, 0.0]', 'j = "ground"\nsi = [0.0, 0.0]'), [],
     r"bad\.toml: constraint 'main_bearing': (connects a body to itself|acts on ground only)"),
    ("driver_without_f", edit('f = "omega*t"\n', ""), [],
     r"bad\.toml: constraint 'motor': missing key 'f'"),
    ("too_few_rows_no_driver", edit(MOTOR, ""), [],
     r"bad\.toml: \[\[constraint\]\]: 8 constraint rows for 9 coordinates: 1 missing"),
    ("too_few_rows_no_guide", edit(GUIDE, ""), [],
     r"bad\.toml: \[\[constraint\]\]: 7 constraint rows for 9 coordinates: 2 missing"),
    ("too_many_rows_two_drivers", edit(MOTOR, MOTOR + "\n" + MOTOR.replace('"motor"', '"motor2"')), [],
     r"bad\.toml: \[\[constraint\]\]: 10 constraint rows for 9 coordinates: 1 extra"),
    ("too_many_rows_extra_revolute",
     edit(MOTOR, MOTOR + '\n[[constraint]]\nname = "stop"\ntype = "revolute"\ni = "ground"\n'
          'j = "slider"\nsi = [0.4, 0.0]\nsj = [0.0, 0.0]\n'),
     [], r"bad\.toml: \[\[constraint\]\]: 11 constraint rows for 9 coordinates: 2 extra"),
    ("point_too_short", edit(MAIN_BEARING_POINTS, 'si = [0.0]\nsj = ["-L_crank/2", 0.0]'), [],
     r"bad\.toml: constraint 'main_bearing' key 'si': has 1 value, 2 expected"),
    ("point_too_long", edit(MAIN_BEARING_POINTS, 'si = [0.0, 0.0, 0.0]\nsj = ["-L_crank/2", 0.0]'), [],
     r"bad\.toml: constraint 'main_bearing' key 'si': has 3 values, 2 expected"),
    ("point_a_string", edit(MAIN_BEARING_POINTS, 'si = "0, 0"\nsj = ["-L_crank/2", 0.0]'), [],
     r"bad\.toml: constraint 'main_bearing' key 'si': must be a list of 2 .*string"),
    ("point_a_number", edit(MAIN_BEARING_POINTS, 'si = 0.0\nsj = ["-L_crank/2", 0.0]'), [],
     r"bad\.toml: constraint 'main_bearing' key 'si': must be a list of 2"),
    ("point_of_lists", edit(MAIN_BEARING_POINTS, 'si = [[0.0], [0.0]]\nsj = ["-L_crank/2", 0.0]'), [],
     r"bad\.toml: constraint 'main_bearing' key 'si': must be a number or an expression"),
    ("force_components_wrong_length", edit('F = ["-F_gas*sin(omega*t)", "0"]', 'F = ["-F_gas*sin(omega*t)"]'),
     [], r"bad\.toml: force 'gas_load' key 'F': has 1 value, 2 expected"),
    ("gear_with_K_and_radii", gear_motor("K = 1.0\nradius_i = 1.0\nradius_j = 2.0"), [],
     r"bad\.toml: constraint 'motor'.*either 'K' or 'radius_i' and 'radius_j', not both"),
    ("gear_without_K_or_radii", gear_motor(""), [],
     r"bad\.toml: constraint 'motor'.*missing key 'radius_i' \(or give 'K'\)"),
    ("gear_radius_j_missing", gear_motor("radius_i = 1.0"), [],
     r"bad\.toml: constraint 'motor'.*missing key 'radius_j'"),
    ("gear_internal_not_boolean", gear_motor('radius_i = 1.0\nradius_j = 2.0\ninternal = "yes"'), [],
     r"bad\.toml: constraint 'motor' key 'internal': must be true or false"),
    ("coordinate_driver_coordinate_z", coordinate_motor('"z"'), [],
     r"bad\.toml: constraint 'motor' key 'coordinate': must be one of 'x', 'y', 'phi', not 'z'"),
    ("coordinate_driver_coordinate_number", coordinate_motor("2"), [],
     r"bad\.toml: constraint 'motor' key 'coordinate': must be one of"),
    # -- expressions -------------------------------------------------------
    ("expression_trailing_operator", edit('f = "omega*t"', 'f = "omega*t +"'), [],
     r"bad\.toml: constraint 'motor' key 'f': expression ends too early"),
    ("expression_unclosed_parenthesis", edit('f = "omega*t"', 'f = "omega*(t"'), [],
     r"bad\.toml: constraint 'motor' key 'f': expected '\)'"),
    ("expression_malformed_number", edit("F_gas = 100.0", 'F_gas = "1.0.0"'), [],
     r"bad\.toml: \[parameters\] key 'F_gas': malformed number"),
    ("expression_empty", edit("F_gas = 100.0", 'F_gas = ""'), [],
     r"bad\.toml: \[parameters\] key 'F_gas': empty expression"),
    ("expression_unknown_name", edit('f = "omega*t"', 'f = "omega*time"'), [],
     r"bad\.toml: constraint 'motor' key 'f': unknown name 'time'"),
    ("expression_t_outside_time_function", edit('mass = "m_crank"', 'mass = "m_crank + t"'), [],
     r"bad\.toml: body 'crank' key 'mass': unknown name 't'"),
    ("expression_unknown_function", edit('f = "omega*t"', 'f = "omega*sec(t)"'), [],
     r"bad\.toml: constraint 'motor' key 'f': unknown function 'sec'"),
    ("expression_wrong_arity", edit('f = "omega*t"', 'f = "atan2(t)"'), [],
     r"bad\.toml: constraint 'motor' key 'f': atan2\(\) .*takes 2 arguments, got 1"),
    ("expression_function_not_called", edit('f = "omega*t"', 'f = "sin"'), [],
     r"bad\.toml: constraint 'motor' key 'f': function 'sin' .*must be called"),
    ("expression_division_by_zero", edit("F_gas = 100.0", 'F_gas = "1/0"'), [],
     r"bad\.toml: \[parameters\] key 'F_gas': division by zero"),
    ("expression_division_by_zero_parameter", edit("F_gas = 100.0", 'F_gas = "1/(n - 5)"'), [],
     r"bad\.toml: \[parameters\] key 'F_gas': .*not finite"),
    ("expression_not_real", edit("F_gas = 100.0", 'F_gas = "sqrt(-1)"'), [],
     r"bad\.toml: \[parameters\] key 'F_gas': .*not a real number"),
    ("expression_boolean", edit("F_gas = 100.0", "F_gas = false"), [],
     r"bad\.toml: \[parameters\] key 'F_gas': .*boolean"),
    ("expression_attribute_access", edit('f = "omega*t"', 'f = "omega.real*t"'), [],
     r"bad\.toml: constraint 'motor' key 'f': unexpected character '\.'"),
    ("expression_indexing", edit('f = "omega*t"', 'f = "omega[0]*t"'), [],
     r"bad\.toml: constraint 'motor' key 'f': unexpected character '\['"),
    ("expression_string_literal", edit('f = "omega*t"', "f = \"'omega'\""), [],
     r"bad\.toml: constraint 'motor' key 'f': unexpected character"),
    ("expression_sympy_name", edit('f = "omega*t"', 'f = "Symbol(t)"'), [],
     r"bad\.toml: constraint 'motor' key 'f': unknown function 'Symbol'"),
    # -- parameters --------------------------------------------------------
    ("parameter_cycle_of_two", edit("L_crank = 0.1", 'L_crank = "L_rod/3"', "L_rod = 0.3", 'L_rod = "3*L_crank"'),
     [], r"bad\.toml: \[parameters\]: parameters defined in a cycle: L_crank -> L_rod -> L_crank"),
    ("parameter_cycle_of_three",
     edit("a_slider = 0.06", 'a_slider = "b_slider"', "b_slider = 0.04", 'b_slider = "m_slider"',
          "m_slider = 0.8", 'm_slider = "a_slider"'),
     [], r"bad\.toml: \[parameters\]: parameters defined in a cycle: .*a_slider.*b_slider.*m_slider"),
    ("parameter_defined_by_itself", edit("n = 5", 'n = "n + 1"'), [],
     r"bad\.toml: \[parameters\]: parameters defined in a cycle: n -> n"),
    ("parameter_named_t", with_parameters("t = 1.0\n"), [],
     r"bad\.toml: \[parameters\] key 't': is reserved"),
    ("parameter_named_pi", with_parameters("pi = 3.0\n"), [],
     r"bad\.toml: \[parameters\] key 'pi': is reserved"),
    ("parameter_named_sin", with_parameters("sin = 3.0\n"), [],
     r"bad\.toml: \[parameters\] key 'sin': is reserved"),
    ("parameter_named_ground", with_parameters("ground = 3.0\n"), [],
     r"bad\.toml: \[parameters\] key 'ground': is reserved"),
    ("parameter_name_underscore", with_parameters("_secret = 3.0\n"), [],
     r"bad\.toml: \[parameters\] key '_secret': is reserved or not a valid name"),
    ("parameter_name_with_space", with_parameters('"top speed" = 3.0\n'), [],
     r"bad\.toml: \[parameters\] key 'top speed': is reserved or not a valid name"),
    ("parameter_a_table", with_parameters("[parameters.sub]\nx = 1\n"), [],
     r"bad\.toml: \[parameters\] key 'sub': must be a number or an expression"),
    # -- the command line's --set ------------------------------------------
    ("set_unknown_parameter", BASE, ["--set", "speed=3"],
     r"bad\.toml: --set speed: no such parameter"),
    ("set_bad_expression", BASE, ["--set", "omega=2*pi*rpm"],
     r"bad\.toml: --set omega: unknown name 'rpm'"),
    ("set_derived_parameter_names_its_definition", BASE, ["--set", "omega=3"],
     r"bad\.toml: --set omega: 'omega' is a derived parameter \(omega = \"2\*pi\*n\" in \[parameters\]\); "
     r"set the base parameters it is computed from \(n\)"),
    ("set_empty_value", BASE, ["--set", "omega="],
     r"bad\.toml: --set omega: empty expression"),
    ("set_negative_mass_parameter", BASE, ["--set", "m_rod=-1"],
     r"bad\.toml: body 'connecting_rod' key 'mass': must not be negative"),
    ("set_without_equals", BASE, ["--set", "omega"], r"bad\.toml: .*--set omega"),
    ("set_without_equals_is_input_error", BASE, ["--set", "omega"], r"--set omega: expected NAME=VALUE"),
    ("set_without_name", BASE, ["--set", "=3"], r"--set =3: expected NAME=VALUE"),
    # -- [analysis] and its command-line overrides ---------------------------
    ("analysis_unknown_key", edit("steps = 201", 'steps = 201\nmethod = "newton"'), [],
     r"bad\.toml: \[analysis\] key 'method': unknown key"),
    ("analysis_kind_unknown", edit('kind = "inverse_dynamics"', 'kind = "dynamics"'), [],
     r"bad\.toml: \[analysis\] key 'kind': unknown kind 'dynamics' \(valid: "
     r"(?=.*inverse_dynamics)(?=.*kinematics)(?=.*statics)"),
    ("analysis_kind_a_number", edit('kind = "inverse_dynamics"', "kind = 1"), [],
     r"bad\.toml: \[analysis\] key 'kind': unknown kind 1"),
    ("steps_zero", edit("steps = 201", "steps = 0"), [],
     r"bad\.toml: \[analysis\] key 'steps': must be a whole number >= 1"),
    ("steps_negative", edit("steps = 201", "steps = -5"), [],
     r"bad\.toml: \[analysis\] key 'steps': must be a whole number >= 1"),
    ("steps_fractional", edit("steps = 201", "steps = 1.5"), [],
     r"bad\.toml: \[analysis\] key 'steps': must be a whole number"),
    ("steps_a_string", edit("steps = 201", 'steps = "10"'), [],
     r"bad\.toml: \[analysis\] key 'steps': must be a whole number"),
    ("steps_boolean", edit("steps = 201", "steps = true"), [],
     r"bad\.toml: \[analysis\] key 'steps': must be a whole number"),
    ("steps_zero_on_command_line", BASE, ["--steps", "0"],
     r"argument --steps: must be a whole number from 1 to"),  # the option, not the file's key
    ("t1_before_t0", edit("t0 = 0.0", "t0 = 0.3"), [],
     r"bad\.toml: \[analysis\] key 't1': must be greater than t0"),
    ("t1_equal_to_t0", edit("t0 = 0.0", "t0 = 0.2"), [],
     r"bad\.toml: \[analysis\] key 't1': must be greater than t0"),
    ("t1_before_t0_on_command_line", BASE, ["--t1", "-1"],
     r"bad\.toml: --t1: must be greater than t0"),  # the option, not the file's key
    ("t0_a_string", edit("t0 = 0.0", 't0 = "0"'), [],
     r"bad\.toml: \[analysis\] key 't0': must be a finite number"),
    ("t1_infinite", edit("t1 = 0.2", "t1 = inf"), [],
     r"bad\.toml: \[analysis\] key 't1': must be a finite number"),
    ("t0_nan_on_command_line", BASE, ["--t0", "nan"],
     r"argument --t0: must be a finite number"),  # the option, not the file's key
    ("tol_negative", edit("steps = 201", "steps = 201\ntol = -1e-9"), [],
     r"bad\.toml: \[analysis\] key 'tol': must be positive"),
    ("tol_zero", edit("steps = 201", "steps = 201\ntol = 0.0"), [],
     r"bad\.toml: \[analysis\] key 'tol': must be positive"),
    ("tol_nan", edit("steps = 201", "steps = 201\ntol = nan"), [],
     r"bad\.toml: \[analysis\] key 'tol': must be a finite number"),
    ("tol_negative_on_command_line", BASE, ["--tol", "-1"],
     r"argument --tol: must be a finite number > 0"),  # the option, not the file's key
    ("outputs_unknown_group", edit("steps = 201", 'steps = 201\noutputs = ["q", "forces"]'), [],
     r"bad\.toml: \[analysis\] key 'outputs': unknown output 'forces'"),
    ("outputs_not_a_list", edit("steps = 201", 'steps = 201\noutputs = "q"'), [],
     r"bad\.toml: \[analysis\] key 'outputs': must be a list"),
    ("outputs_group_twice", edit("steps = 201", 'steps = 201\noutputs = ["q", "q"]'), [],
     r"bad\.toml: \[analysis\] key 'outputs': names a group twice"),
    ("outputs_lambda_in_kinematics",
     edit('kind = "inverse_dynamics"', 'kind = "kinematics"\noutputs = ["q", "lambda"]'), [],
     r"bad\.toml: \[analysis\] key 'outputs': 'lambda' is not an output of kinematics"),
    ("reactions_unknown_constraint", edit("steps = 201", 'steps = 201\nreactions = ["piston"]'), [],
     r"bad\.toml: \[analysis\] key 'reactions': unknown constraint 'piston'"),
    ("reactions_naming_a_body", edit("steps = 201", 'steps = 201\nreactions = ["crank"]'), [],
     r"bad\.toml: \[analysis\] key 'reactions': unknown constraint 'crank'"),
    ("reactions_naming_a_force", edit("steps = 201", 'steps = 201\nreactions = ["gas_load"]'), [],
     r"bad\.toml: \[analysis\] key 'reactions': unknown constraint 'gas_load'"),
    ("reactions_not_a_list", edit("steps = 201", 'steps = 201\nreactions = "motor"'), [],
     r"bad\.toml: \[analysis\] key 'reactions': must be a list"),
    # a direction of length 0 (was exit 3, "Phi_q is singular", or "Phi not finite" where a row divides by it)
    ("direction_zero_vector", edit("vi = [1.0, 0.0]", "vi = [0.0, 0.0]"), [],
     r"bad\.toml: constraint 'cylinder_guide' key 'vi': is the zero vector \[0\.0, 0\.0\]"),
    ("direction_zero_by_its_parameters", edit("vi = [1.0, 0.0]", 'vi = ["L_crank - 0.1", "0*L_rod"]'), [],
     r"bad\.toml: constraint 'cylinder_guide' key 'vi': is the zero vector"),
    ("direction_zero_by_set", edit("vi = [1.0, 0.0]", 'vi = ["L_crank", 0.0]'), ["--set", "L_crank=0"],
     r"bad\.toml: constraint 'cylinder_guide' key 'vi': is the zero vector"),
    # -- hostile expressions -------------------------------------------------
    ("injection_in_driver", edit('f = "omega*t"', f"f = {quoted(INJECTION)}"), [],
     r"bad\.toml: constraint 'motor' key 'f': "),
    ("injection_in_parameter", edit("F_gas = 100.0", f"F_gas = {quoted(INJECTION)}"), [],
     r"bad\.toml: \[parameters\] key 'F_gas': "),
    ("injection_dunder_class", edit('f = "omega*t"', 'f = "().__class__"'), [],
     r"bad\.toml: constraint 'motor' key 'f': "),
    ("injection_in_set", BASE, ["--set", f"omega={INJECTION}"],
     r"bad\.toml: --set omega: "),
]


def _params(cases):
    """pytest params from (id, content, extra, pattern[, xfail reason]) tuples."""
    out = []
    for case_id, content, extra, pattern, *reason in cases:
        marks = [pytest.mark.xfail(strict=True, reason=reason[0])] if reason else []
        out.append(pytest.param(content, extra, pattern, id=case_id, marks=marks))
    return out


@pytest.mark.parametrize("content, extra, pattern", _params(CASES))
def test_bad_input_is_one_line_exit_2(tmp_path, capsys, content, extra, pattern):
    status, err, path, out = solve_bad(tmp_path, capsys, content, extra)
    assert_one_line_input_error(status, err, path, out, pattern)
    if pattern.startswith(r"bad\.toml"):
        assert str(path) in err, f"the message must name the file {path}: {err!r}"


def test_there_are_at_least_thirty_distinct_cases():
    ids = [c[0] for c in CASES]
    assert len(set(ids)) == len(ids)
    assert len(ids) >= 30


@pytest.mark.parametrize("args", [["check"], ["solve"]], ids=["check", "solve"])
def test_check_also_refuses_bad_input(tmp_path, capsys, args):
    path = tmp_path / "bad.toml"
    path.write_text(edit('mass = "m_crank"', "mass = -1.0"), encoding="utf-8")
    status = main([*args, str(path)] + (["-o", str(tmp_path / "out.csv")] if args == ["solve"] else []))
    err = capsys.readouterr().err
    assert status == 2
    assert err.count("\n") == 1
    assert re.search(r"bad\.toml: body 'crank' key 'mass': must not be negative", err)


# -- values at the edge that are valid ----------------------------------------

@pytest.mark.parametrize("key, old, new", [
    ("mass", 'mass = "m_slider"', "mass = 0.0"),
    ("inertia", 'inertia = "m_slider*(a_slider^2 + b_slider^2)/12"', "inertia = 0"),
], ids=["zero_mass", "zero_inertia"])
def test_zero_mass_or_inertia_is_accepted(tmp_path, capsys, key, old, new):
    path = tmp_path / "zero.toml"
    path.write_text(edit(old, new), encoding="utf-8")
    out = tmp_path / "out.csv"
    status = main(["solve", str(path), "-o", str(out), "--steps", "11"])
    err = capsys.readouterr().err
    assert status == 0, err
    assert err == ""
    lines = out.read_text().splitlines()
    assert len(lines) == 12


def test_parameter_defined_by_later_parameter_is_not_a_cycle(tmp_path, capsys):
    path = tmp_path / "ok.toml"
    path.write_text(edit("L_crank = 0.1", 'L_crank = "L_rod/3"'), encoding="utf-8")
    out = tmp_path / "out.csv"
    assert main(["solve", str(path), "-o", str(out), "--steps", "3"]) == 0, capsys.readouterr().err
    assert out.exists()


# -- injection: an expression is parsed, never run ---------------------------

@pytest.mark.parametrize("where, text, extra", [
    ("driver_f", edit('f = "omega*t"', f"f = {quoted(INJECTION)}"), []),
    ("parameter", edit("F_gas = 100.0", f"F_gas = {quoted(INJECTION)}"), []),
    ("mass", edit('mass = "m_crank"', f"mass = {quoted(INJECTION)}"), []),
    ("set", BASE, ["--set", f"omega={INJECTION}"]),
    ("dunder_class", edit('f = "omega*t"', 'f = "().__class__.__base__.__subclasses__()"'), []),
    ("eval_call", edit('f = "omega*t"', "f = \"eval('1')\""), []),
    ("import_call", edit("F_gas = 100.0", 'F_gas = "__import__(1)"'), []),
], ids=lambda v: v if isinstance(v, str) and len(v) < 20 else None)
def test_code_in_an_expression_is_refused_and_not_run(tmp_path, capsys, monkeypatch, where, text, extra):
    monkeypatch.chdir(tmp_path)
    status, err, path, out = solve_bad(tmp_path, capsys, text, extra)
    assert status == 2, err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert "bad.toml" in err
    assert not (tmp_path / "PWNED").exists()
    assert not out.exists()


# -- robustness: hostile sizes end promptly -----------------------------------

def _big_comment() -> str:
    return BASE + "# " + "x" * (20 * 1024 * 1024) + "\n"


def _many_parameters() -> str:
    lines = "".join(f"p{k} = {k}.25\n" for k in range(1_300_000))  # ~20 MB
    return with_parameters(lines)


ROBUSTNESS = [
    ("power_tower_10_10_10", edit("F_gas = 100.0", 'F_gas = "10^10^10"'),
     r"bad\.toml: \[parameters\] key 'F_gas': "),
    ("power_tower_in_driver", edit('f = "omega*t"', 'f = "omega*t*9^9^9^9"'),
     r"bad\.toml: constraint 'motor' key 'f': "),
    ("huge_power_of_rational", edit("F_gas = 100.0", 'F_gas = "(1 + 1e-300)^(10^300)"'),
     r"bad\.toml: \[parameters\] key 'F_gas': "),
    ("nested_parentheses_5000", edit("F_gas = 100.0", 'F_gas = "' + "(" * 5000 + "1" + ")" * 5000 + '"'),
     r"bad\.toml: \[parameters\] key 'F_gas': "),
    ("nested_parentheses_4000", edit("F_gas = 100.0", 'F_gas = "' + "(" * 4000 + "1" + ")" * 4000 + '"'),
     r"bad\.toml: \[parameters\] key 'F_gas': .*nested"),
    ("nested_calls_2000", edit("F_gas = 100.0", 'F_gas = "' + "sin(" * 2000 + "1" + ")" * 2000 + '"'),
     r"bad\.toml: \[parameters\] key 'F_gas': "),
    ("unary_minus_5000", edit("F_gas = 100.0", 'F_gas = "' + "-" * 5000 + '1"'),
     r"bad\.toml: \[parameters\] key 'F_gas': "),
    ("power_chain_3000", edit("F_gas = 100.0", 'F_gas = "' + "2^" * 3000 + '1"'),
     r"bad\.toml: \[parameters\] key 'F_gas': "),
    ("long_sum_of_6000_names", edit("F_gas = 100.0", 'F_gas = "' + "+".join(["n"] * 6000) + '"'),
     r"bad\.toml: \[parameters\] key 'F_gas': "),
    ("toml_arrays_nested_5000", edit("F_gas = 100.0", "F_gas = " + "[" * 5000 + "1" + "]" * 5000),
     r"bad\.toml: "),
    ("toml_tables_nested_5000", edit("F_gas = 100.0", "F_gas = " + "{a = " * 5000 + "1" + "}" * 5000),
     r"bad\.toml: "),
    ("file_of_20MB_comment", _big_comment, r"bad\.toml: .*bytes"),
    ("file_of_20MB_parameters", _many_parameters, r"bad\.toml: .*bytes"),
]


@pytest.mark.parametrize("content, pattern", [pytest.param(*c[1:], id=c[0]) for c in ROBUSTNESS])
def test_hostile_input_ends_promptly_with_exit_2(tmp_path, capsys, content, pattern):
    if callable(content):
        content = content()
    start = time.process_time()  # CPU time: the work done, which load does not stretch
    status, err, path, out = solve_bad(tmp_path, capsys, content, [])
    elapsed = time.process_time() - start
    assert elapsed < 5.0, f"took {elapsed:.1f} s of CPU"
    assert_one_line_input_error(status, err, path, out, pattern)


def _run_with_deadline(tmp_path: Path, text: str, deadline: float) -> tuple[int, str, float]:
    """`python -m symid solve` in a child process (an in-process hang could not be
    interrupted): its CPU time must stay under `deadline` seconds; HANG_GUARD
    seconds of wall clock end it (a loaded machine stretches the wall clock,
    not the CPU time)."""
    path = tmp_path / "bad.toml"
    path.write_text(text, encoding="utf-8")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")])}
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    try:
        proc = subprocess.run([sys.executable, "-m", "symid", "solve", str(path), "-o", str(tmp_path / "o.csv")],
                              cwd=tmp_path, env=env, capture_output=True, text=True, timeout=HANG_GUARD)
    except subprocess.TimeoutExpired:
        pytest.fail(f"symid solve still running after {HANG_GUARD} s")
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    assert cpu < deadline, f"symid solve took {cpu:.1f} s of CPU"
    return proc.returncode, proc.stderr, cpu


# Interpreter start and imports take about a second; the budget is 5 s of work.
CHILD_DEADLINE = 10.0
HANG_GUARD = 600.0


def test_exp_tower_parameter_ends_promptly(tmp_path):
    status, err, elapsed = _run_with_deadline(
        tmp_path, edit("F_gas = 100.0", 'F_gas = "exp(exp(exp(100)))"'), CHILD_DEADLINE)
    assert status == 2, err
    assert re.search(r"bad\.toml: \[parameters\] key 'F_gas': .*not finite", err)


@pytest.mark.slow  # a child symid over 10000 parameters (14 s under load)
def test_ten_thousand_parameters_are_read_promptly(tmp_path):
    text = with_parameters("".join(f"p{k} = {k}.25\n" for k in range(10_000)))
    text = edit('mass = "m_crank"\n', "", text=text)  # an error found after the parameters
    status, err, elapsed = _run_with_deadline(tmp_path, text, CHILD_DEADLINE)
    assert status == 2, err
    assert re.search(r"bad\.toml: body 'crank': missing key 'mass'", err)


# -- messages that name the wrong key -----------------------------------------

def test_gear_zero_radius_names_the_radius_key(tmp_path, capsys):
    status, err, path, out = solve_bad(tmp_path, capsys, gear_motor("radius_i = 1.0\nradius_j = 0.0"), [])
    assert_one_line_input_error(status, err, path, out, r"bad\.toml: constraint 'motor' key 'radius_j'")


def test_gear_zero_radius_is_an_input_error(tmp_path, capsys):
    status, err, path, out = solve_bad(tmp_path, capsys, gear_motor("radius_i = 1.0\nradius_j = 0.0"), [])
    assert_one_line_input_error(status, err, path, out, r"bad\.toml: constraint 'motor'")


# -- an input error leaves what was there ---------------------------------------

def test_input_error_leaves_an_existing_output_untouched(tmp_path, capsys):
    out = tmp_path / "out.csv"
    out.write_text("previous results\n")
    path = tmp_path / "bad.toml"
    path.write_text(edit("steps = 201", "steps = 0"), encoding="utf-8")
    assert main(["solve", str(path), "-o", str(out)]) == 2
    assert capsys.readouterr().err.count("\n") == 1
    assert out.read_text() == "previous results\n"
