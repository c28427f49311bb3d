"""The sizing picture (`symid size --plot`, and `symid plot` for a file with
drives or bearings): each motor's torque-speed envelope with the run's
operating trajectory and its RMS point, and the bearings' equivalent loads as
bars labelled with their L10 lives.

Lines carry a `gid` ("envelope:<driver>", "trajectory:<driver>",
"rms:<driver>", "bearing:<joint>") so tests and scripts find the data again.
Magnitudes are drawn (|speed|, |torque|): the envelope is symmetric.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from symid.io.files import make_folder
from symid.output.plot import _figure, save

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from symid.output.sizing import Report


def sizing_figure(report: Report, name: str) -> "Figure":
    """One panel per drive, then one of the bearings (when there are any)."""
    panels = len(report.drives) + (1 if report.bearings else 0)
    fig = _figure(6.4, 3.6 * panels)
    axes = fig.subplots(panels, 1, squeeze=False)[:, 0]
    for ax, v in zip(axes, report.drives):
        m = v.motor
        top = max(m.max_speed, float(np.max(np.abs(v.speed))) if len(v.speed) else 0.0) * 1.05
        w = np.linspace(0.0, top, 400)
        ax.plot(w, m.available(w), color="k", lw=1.6, gid=f"envelope:{m.driver}", label="peak envelope")
        ax.axhline(m.continuous_torque, color="0.5", ls="--", lw=1.0, label="continuous")
        ax.plot(np.abs(v.speed), np.abs(v.torque), color="C0", lw=1.2, gid=f"trajectory:{m.driver}",
                label="operating points")
        w_rms = float(np.sqrt(np.mean(v.speed ** 2))) if len(v.speed) else 0.0
        ax.plot([w_rms], [v.motor_rms], "o", color="C3" if v.motor_rms > m.continuous_torque else "C2",
                gid=f"rms:{m.driver}", label="RMS point")
        verdict = "fits" if v.fits else "does not fit"
        ax.set_title(f"{m.driver}: ratio {v.ratio:.4g}, {verdict}", fontsize=10)
        ax.set_xlabel(f"motor speed [{v.rate_unit}]")
        ax.set_ylabel(f"motor {'torque' if v.unit == 'N·m' else 'force'} [{v.unit}]")
        ax.set_xlim(0, top)
        ax.set_ylim(0, max(m.peak_torque, v.motor_peak) * 1.1)
        ax.legend(fontsize=8, loc="upper right")
    if report.bearings:
        ax = axes[-1]
        for k, b in enumerate(report.bearings):
            bar = ax.bar(k, b.P_eq, color="C1", gid=f"bearing:{b.joint}")
            ax.bar_label(bar, [f"L10 {b.L10_h:.3g} h"], fontsize=8)
        ax.set_xticks(range(len(report.bearings)), [b.joint for b in report.bearings])
        ax.set_ylabel("equivalent load P_eq [N]")
        ax.set_title("bearings", fontsize=10)
    fig.suptitle(f"{name}: sizing", fontsize=12)
    return fig


def write(report: Report, name: str, directory: str | Path) -> Path:
    """Write `<name>_sizing.png` in `directory` (atomically); its path."""
    return save(sizing_figure(report, name), make_folder(directory) / f"{name}_sizing.png")
