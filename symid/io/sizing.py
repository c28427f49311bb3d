"""Read the sizing tables (contract: issue #29): `[[drive]]` on a driver and a
revolute's `bearing = { C = ..., p = 3 }`.

Every problem is one `InputError` naming the file and the key, raised through
the reader's `fail`; numbers are the reader's (expressions of the parameters).
"""

from __future__ import annotations

from typing import Any, Callable, Sequence

import sympy as sp

from symid.errors import InputError
from symid.model.mechanism import Element, is_driver
from symid.model.sizing import BEARING_KEYS, DRIVE_KEYS, Bearing, Drive
from symid.text import number as shown

Number = Callable[[Any, str], tuple[sp.Expr, float]]
Fail = Callable[[str, str], InputError]

# the defaults of the optional keys: a direct drive, lossless, without a rotor
DEFAULTS = {"ratio": 1, "efficiency": 1, "rotor_inertia": 0}
REQUIRED = ("driver", "continuous_torque", "peak_torque", "max_speed")


def drives(items: Any, constraints: Sequence[Element], value_of: Number, fail: Fail) -> tuple[Drive, ...]:
    """The `[[drive]]` array, each checked against the file's drivers.

    Args:
        items: the TOML value of `drive` (a list of tables when well formed).
        constraints: the file's constraints (the drivers are looked up there).
        value_of: the reader's number parser: (raw, where) -> (expression, value).
    """
    if not isinstance(items, list) or not all(isinstance(d, dict) for d in items):
        raise fail("[[drive]]", "must be an array of tables ([[drive]] with driver = ...)")
    drivers = [c.name for c in constraints if is_driver(c)]
    out: list[Drive] = []
    for n, data in enumerate(items):
        where = f"[[drive]] #{n + 1}"
        for key in data:
            if key not in DRIVE_KEYS:
                raise fail(f"{where} key '{key}'", f"unknown key (allowed: {', '.join(DRIVE_KEYS)})")
        for key in REQUIRED:
            if key not in data:
                raise fail(where, f"missing key '{key}'")
        driver = data["driver"]
        if driver not in drivers:
            raise fail(f"{where} key 'driver'", f"{driver!r} is not a driver of the file "
                       f"(drivers: {', '.join(drivers) or 'none'})")
        if any(d.driver == driver for d in out):
            raise fail(f"{where} key 'driver'", f"a second drive on '{driver}' (one drive per driver)")
        where = f"drive '{driver}'"
        out.append(_drive(data, driver, where, value_of, fail))
    return tuple(out)


def _drive(data: dict[str, Any], driver: str, where: str, value_of: Number, fail: Fail) -> Drive:
    def get(key: str, low: float, closed: bool, high: float | None = None) -> tuple[sp.Expr, float]:
        at = f"{where} key '{key}'"
        expr, value = value_of(data.get(key, DEFAULTS.get(key)), at)
        if value < low or (value == low and not closed) or (high is not None and value > high):
            span = f"{'[' if closed else '('}{shown(low)}, {shown(high) + ']' if high is not None else 'inf)'}"
            raise fail(at, f"must be in {span} (it is {shown(value)})")
        return expr, value

    raw = data.get("ratio", DEFAULTS["ratio"])
    if isinstance(raw, list):
        if len(raw) != 2:
            raise fail(f"{where} key 'ratio'", f"a range is [lo, hi], not {len(raw)} values")
        (lo, a), (hi, b) = (value_of(r, f"{where} key 'ratio'") for r in raw)
        if not 0 < a < b:
            raise fail(f"{where} key 'ratio'", f"a range [lo, hi] needs 0 < lo < hi (it is [{shown(a)}, {shown(b)}])")
        ratio = (lo, hi)
    else:
        lo, _ = get("ratio", 0.0, False)
        ratio = (lo, lo)
    efficiency, eta = get("efficiency", 0.0, False, 1.0)
    back = get("back_efficiency", 0.0, False, 1.0)[0] if "back_efficiency" in data else efficiency
    inertia, _ = get("rotor_inertia", 0.0, True)
    continuous, s1 = get("continuous_torque", 0.0, False)
    peak, pk = get("peak_torque", 0.0, False)
    if pk < s1:
        raise fail(f"{where} key 'peak_torque'", f"{shown(pk)} is below continuous_torque {shown(s1)}: "
                   "the envelope is not monotone")
    top, w_max = get("max_speed", 0.0, False)
    corner = None
    if "corner_speed" in data:
        corner, w_c = get("corner_speed", 0.0, False)
        if w_c > w_max:
            raise fail(f"{where} key 'corner_speed'", f"{shown(w_c)} is above max_speed {shown(w_max)}: "
                       "the envelope is not monotone (the peak torque falls from corner_speed to 0 at max_speed)")
    curve = None
    if "envelope" in data:
        curve = _envelope(data["envelope"], f"{where} key 'envelope'", "corner_speed" in data, value_of, fail)
    return Drive(driver, ratio, efficiency, back, inertia, continuous, peak, top, corner, curve)  # type: ignore[arg-type]


def _envelope(raw: Any, at: str, corner: bool, value_of: Number, fail: Fail) -> tuple[tuple[sp.Expr, sp.Expr], ...]:
    """`envelope = [[speed, torque], ...]`: at least 2 points, speeds from 0
    increasing, torques positive and not increasing (a monotone envelope)."""
    if corner:
        raise fail(at, "give corner_speed or envelope, not both")
    if not isinstance(raw, list) or len(raw) < 2 or not all(isinstance(p, list) and len(p) == 2 for p in raw):
        raise fail(at, "must be a list of at least 2 [speed, torque] points")
    points = [(value_of(w, at), value_of(T, at)) for w, T in raw]
    speeds, torques = [w[1] for w, _ in points], [T[1] for _, T in points]
    if speeds[0] < 0 or any(b <= a for a, b in zip(speeds, speeds[1:])):
        raise fail(at, f"the speeds must start at 0 or above and increase (they are {', '.join(map(shown, speeds))})")
    if any(T < 0 for T in torques) or any(b > a for a, b in zip(torques, torques[1:])):
        raise fail(at, f"not monotone: the torques must not increase with speed "
                       f"(they are {', '.join(map(shown, torques))})")
    return tuple((w[0], T[0]) for w, T in points)


def bearing(raw: Any, element: str, kind: str, where: str, value_of: Number, fail: Fail) -> Bearing:
    """A revolute's `bearing = { C = ..., p = ... }` (its `bearing` key given).

    Args:
        element: the joint's name; kind: its type (only a revolute has a bearing).
    """
    here = f"{where} key 'bearing'"
    if kind != "revolute":
        raise fail(here, f"a {kind} has no rotation to carry a rolling bearing (bearing is for revolute)")
    if not isinstance(raw, dict):
        raise fail(here, "must be an inline table { C = ..., p = 3 }")
    for key in raw:
        if key not in BEARING_KEYS:
            raise fail(f"{where} key 'bearing.{key}'", f"unknown bearing key (allowed: {', '.join(BEARING_KEYS)})")
    if "C" not in raw:
        raise fail(here, "missing 'C' (the dynamic load rating, N)")
    C, c = value_of(raw["C"], f"{where} key 'bearing.C'")
    if not c > 0:
        raise fail(f"{where} key 'bearing.C'", f"must be positive (it is {shown(c)})")
    p, e = value_of(raw.get("p", 3), f"{where} key 'bearing.p'")
    if not e > 0:
        raise fail(f"{where} key 'bearing.p'", f"must be positive: 3 for balls, 10/3 for rollers (it is {shown(e)})")
    return Bearing(element, C, p)
