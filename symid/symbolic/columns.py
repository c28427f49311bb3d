"""The contract's column names of a results table, from a layout and the analysis.

Plain Python at import (the families are imported when called), so a cached
run (`symid.tools.plan`) names its columns without sympy.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from symid.model.analysis import Analysis
    from symid.symbolic.assemble import Layout

GROUP_SUFFIXES = {"q": ("x", "y", "phi"), "qdot": ("vx", "vy", "omega"), "qddot": ("ax", "ay", "alpha")}


def columns(layout: Layout, analysis: Analysis) -> list[str]:
    """The CSV header: `t`, then each requested group in contract order."""
    from symid.symbolic.assemble import reaction_columns
    from symid.symbolic.constraints import family_of

    mech = layout.mechanism
    out = ["t"]
    for group in analysis.output_groups():
        if group in GROUP_SUFFIXES:
            out += [f"{b.name}.{c}" for b in mech.bodies for c in GROUP_SUFFIXES[group]]
        elif group == "lambda":
            for c in mech.constraints:
                rows = family_of(c).rows
                out += [f"{c.name}.lambda"] if rows == 1 else [f"{c.name}.lambda{k + 1}" for k in range(rows)]
        else:
            out += [col for _, col in reaction_columns(layout, analysis.reactions)]
    out += list(analysis.extra_outputs())  # `cond`: after every contract group
    if "reactions" in analysis.output_groups() and analysis.kind == "inverse_dynamics":
        # joint friction (contract v1.1): after all other columns, in file order
        out += [f"{c.name}.{what}" for c in mech.constraints if c.friction
                for what in ("friction", "friction_power")]
    return out
