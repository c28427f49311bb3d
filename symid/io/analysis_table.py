"""The `[analysis]` table of a mechanism file, with the command line's overrides."""

from __future__ import annotations

import math
from typing import Any, Callable, Mapping

from symid.errors import InputError
from symid.io.limits import MAX_STEPS
from symid.model.mechanism import EXTRA_OUTPUTS, JUMP_MODES, KIND_OUTPUTS, KINDS, OUTPUT_GROUPS, REDUNDANT_MODES, Analysis
from symid.text import number

Fail = Callable[[str, str], InputError]
ANALYSIS_KEYS = ("kind", "t0", "t1", "steps", "tol", "outputs", "reactions", "cond_warn", "redundant",
                 "assembly_jump")


def read(table: dict[str, Any], overrides: dict[str, Any], fail: Fail,
         unknown: Callable[[Mapping[str, Any], Any, str], None]) -> Analysis:
    """The `[analysis]` table, command-line overrides merged in (`--t1` over `t1`)."""
    where = "[analysis]"
    unknown(table, ANALYSIS_KEYS, where)
    overrides = dict(overrides)
    add_cond = overrides.pop("cond_column", None)  # `symid solve --cond`
    given = {k: v for k, v in overrides.items() if v is not None}
    merged = {**table, **given}

    def key_of(name: str) -> str:
        """Where a value came from: the option that overrode the file's key, or the key."""
        return f"--{name.replace('_', '-')}" if name in given else f"{where} key '{name}'"

    kind = merged.get("kind", "inverse_dynamics")
    if kind not in KINDS:
        raise fail(key_of("kind"), f"unknown kind {kind!r} (valid: {', '.join(KINDS)})")
    t0 = real(merged.get("t0", 0.0), key_of("t0"), fail)
    t1 = real(merged.get("t1", 1.0), key_of("t1"), fail)
    steps = merged.get("steps", 1001)
    if not isinstance(steps, int) or isinstance(steps, bool) or steps < 1:
        raise fail(key_of("steps"), f"must be a whole number >= 1, not {steps!r}")
    if steps > MAX_STEPS:
        raise fail(key_of("steps"), f"{steps} instants, more than the {MAX_STEPS} allowed")
    if steps > 1 and not t1 > t0:
        raise fail(key_of("t1"), f"must be greater than t0 = {number(t0)}")
    if steps > 1 and not (t1 - t0) / (steps - 1) > (ulp := math.ulp(max(abs(t0), abs(t1)))):  # else rows repeat t
        raise fail(key_of("t1"), f"the {steps} instants from t0 = {number(t0)} are not distinct doubles: "
                        f"the step is not above their spacing there, {number(ulp)}")
    tol = real(merged.get("tol", 1e-12), key_of("tol"), fail)
    if not tol > 0:
        raise fail(key_of("tol"), f"must be positive, not {number(tol)}")
    outputs = names(merged.get("outputs"), f"{where} key 'outputs'", OUTPUT_GROUPS + EXTRA_OUTPUTS, fail)
    if add_cond and "cond" not in (outputs or ()):
        outputs = (outputs if outputs is not None else KIND_OUTPUTS[kind]) + ("cond",)
    if outputs is not None:
        allowed = KIND_OUTPUTS[kind] + (("qdot", "qddot") if kind == "statics" else ()) + EXTRA_OUTPUTS
        if bad := [o for o in outputs if o not in allowed]:
            raise fail(f"{where} key 'outputs'", f"{bad[0]!r} is not an output of {kind}")
    reactions = names(merged.get("reactions"), f"{where} key 'reactions'", None, fail)
    cond_warn = merged.get("cond_warn")
    if cond_warn is not None and not real(cond_warn, key_of("cond_warn"), fail) >= 1:
        raise fail(key_of("cond_warn"), f"must be a number >= 1, not {cond_warn!r}")
    modes = {}
    for key, choices in (("redundant", REDUNDANT_MODES), ("assembly_jump", JUMP_MODES)):
        value = merged.get(key, choices[0])
        if value not in choices:
            raise fail(key_of(key), f"must be one of {', '.join(map(repr, choices))}, not {value!r}")
        modes[key] = value
    return Analysis(kind=kind, t0=t0, t1=t1, steps=steps, tol=tol, outputs=outputs,
                    reactions=reactions, cond_warn=None if cond_warn is None else float(cond_warn),
                    **modes)


def real(value: Any, where: str, fail: Fail) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise fail(where, f"must be a finite number, not {value!r}")
    return float(value)


def names(value: Any, where: str, allowed: tuple[str, ...] | None, fail: Fail) -> tuple[str, ...] | None:
    if value is None:
        return None
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        raise fail(where, "must be a list of names")
    if allowed is not None:
        bad = [v for v in value if v not in allowed]
        if bad:
            raise fail(where, f"unknown output {bad[0]!r} (valid: {', '.join(allowed)})")
    if len(set(value)) != len(value):
        raise fail(where, "names a group twice")
    return tuple(value)
