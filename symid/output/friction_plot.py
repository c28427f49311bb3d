"""The figure of joint friction (contract v1.1): the power each joint's
friction dissipates against time, from the table's `C.friction_power` columns."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from symid.output import friction_loss

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from symid.model.mechanism import Mechanism
    from symid.output.summary import Table


def friction_figure(table: Table, mechanism: Mechanism | None = None) -> "Figure":
    """Each joint's friction power (<= 0, W) against time, one curve per joint,
    gid "friction:<joint>"; the legend gives each joint's energy over the run.

    Raises:
        ValueError: the table has no friction columns.
    """
    from symid.output.plot import TIME, _figure

    names = friction_loss.columns(table.columns)
    if not names:
        raise ValueError("no friction columns in the table")
    t = np.asarray(table["t"], dtype=float)
    fig = _figure(9.0, 4.0)
    ax = fig.add_subplot()
    for k, column in enumerate(names):
        joint = column[:-len(friction_loss.SUFFIX)]
        power = np.asarray(table[column], dtype=float)
        ax.plot(t, power, lw=1.5, color=f"C{k % 10}", gid=f"friction:{joint}",
                label=f"{joint} ({friction_loss.energy(t, power):.4g} J)")
    ax.set_xlabel(TIME)
    ax.set_ylabel("friction power [W] (dissipated: <= 0)")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False)
    name = mechanism.name if mechanism else "results"
    fig.suptitle(f"{name}: joint friction power", fontsize=12)
    return fig
