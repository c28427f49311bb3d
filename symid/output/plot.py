"""Figures of a solved run: driver efforts, joint reactions, the mechanism drawn.

The drawing of one instant (bodies, joints, paths) is `symid.output.scene`.

matplotlib is imported only inside the functions that draw, and only its Agg
canvas is used (no pyplot, no global state): solving never pays for it. The
mechanism file has no units; labels assume SI (m, s, rad, N, N·m).

Every line that carries results has a `gid` ("effort:<driver>",
"force:<constraint>", "path:<body>:<n>", "pin:<constraint>") so that tests and
scripts can find a figure's data again.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Literal

import numpy as np

from symid.backends import Array
from symid.io.files import atomic_path, atomic_write, make_folder
from symid.output import friction_loss
from symid.output.friction_plot import friction_figure
from symid.output.summary import Table, efforts

if TYPE_CHECKING:  # the mechanism's and the scene's modules import sympy: only the figures that draw it need them
    from matplotlib.figure import Figure

    from symid.model.mechanism import Mechanism
    from symid.output.scene import Scene

DPI = 110
PANELS = 4           # instants drawn in the mechanism figure
TIME = "time t [s]"
# statics solves equilibria at the positions f(t) prescribes: t orders them,
# nothing moves in time (every speed and acceleration is zero)
STATICS_TIME = "t [s]: the instant whose f(t) sets the drivers (statics: equilibria, no motion)"


def time_label(mechanism: Mechanism | None) -> str:
    """The time axis label: what t is in this analysis."""
    return STATICS_TIME if mechanism is not None and mechanism.analysis.kind == "statics" else TIME


def _figure(width: float, height: float,
            layout: Literal["constrained", "compressed", "tight"] | None = "constrained") -> "Figure":
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), layout=layout)
    FigureCanvasAgg(fig)
    return fig


def save(fig: "Figure", path: str | Path) -> Path:
    """Write a figure as PNG through `symid.io.files.atomic_write`."""
    path = Path(path)
    with atomic_write(path, binary=True) as out:
        fig.savefig(out, format="png", dpi=DPI)
    return path


# -- time histories ---------------------------------------------------------

def efforts_figure(table: Table, mechanism: Mechanism) -> "Figure":
    """Each driver's effort (motor torque or actuator force) against time, one panel each.

    Raises:
        ValueError: the table has no driver effort (no driver, or no lambda / reaction columns).
    """
    found = efforts(mechanism, table)
    if not found:
        raise ValueError("no driver effort in the table")
    fig = _figure(8.0, 1.0 + 2.1 * len(found))
    axes = fig.subplots(len(found), 1, sharex=True, squeeze=False)[:, 0]
    for ax, e in zip(axes, found):
        ax.axhline(0.0, color="0.6", lw=0.8)
        ax.plot(e.t, e.value, color="C0", lw=1.8, gid=f"effort:{e.name}")
        ax.set_title(f"{e.name} ({e.type}): {e.meaning}", fontsize=10, loc="left")
        ax.set_ylabel(f"{e.quantity} [{e.unit}]")
        ax.grid(True, alpha=0.3)
    axes[-1].set_xlabel(time_label(mechanism))
    fig.suptitle(f"{mechanism.name}: driver efforts", fontsize=12)
    return fig


@dataclass(frozen=True)
class Reaction:
    """|force| and |torque| of one constraint's reaction on body `role`, shape (instants,)."""

    name: str
    role: str
    force: Array
    torque: Array


def reactions(table: Table) -> list[Reaction]:
    """Reaction magnitudes of every constraint in the table, on its body j (i if j has none).

    For a joint the force on i is equal and opposite, so |force| is the joint's
    load; the torque is about the joint's point on that body.
    """
    out = []
    for column in table.columns:
        name, _, rest = column.rpartition(".")
        if rest not in ("Fx_i", "Fx_j") or (rest == "Fx_i" and f"{name}.Fx_j" in table.columns):
            continue
        role = rest[-1]
        fx, fy, tq = (np.asarray(table[f"{name}.{q}_{role}"]) for q in ("Fx", "Fy", "T"))
        out.append(Reaction(name, role, np.hypot(fx, fy), np.abs(tq)))
    return out


def _nonzero(curves: list[Array]) -> list[bool]:
    """Which curves are more than rounding noise next to the largest of them."""
    scale = max((float(np.max(c)) for c in curves if c.size), default=0.0)
    return [c.size > 0 and float(np.max(c)) > 1e-9 * scale and scale > 0 for c in curves]


def reactions_figure(table: Table, mechanism: Mechanism | None = None) -> "Figure":
    """Magnitude of every joint's reaction force (and torque, where one is non-zero) against time.

    Raises:
        ValueError: the table has no reaction columns.
    """
    found = reactions(table)
    if not found:
        raise ValueError("no reaction columns in the table")
    types = {c.name: c.type for c in mechanism.constraints} if mechanism else {}
    t = np.asarray(table["t"])
    panels = [("force", "|F| force [N]", [r.force for r in found]),
              ("torque", "|T| torque [N·m], about the joint point", [r.torque for r in found])]
    panels = [p for p in panels if any(_nonzero(p[2]))]
    fig = _figure(9.0, 1.2 + 2.8 * max(len(panels), 1))
    axes = fig.subplots(max(len(panels), 1), 1, sharex=True, squeeze=False)[:, 0]
    for ax, (what, label, curves) in zip(axes, panels):
        for k, (r, curve, keep) in enumerate(zip(found, curves, _nonzero(curves))):
            if keep:
                kind = f" ({types[r.name]})" if r.name in types else ""
                ax.plot(t, curve, lw=1.5, color=f"C{k % 10}", label=f"{r.name}{kind}", gid=f"{what}:{r.name}")
        ax.set_ylabel(label)
        ax.set_ylim(bottom=0.0)
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False)
    axes[-1].set_xlabel(time_label(mechanism))
    name = mechanism.name if mechanism else "results"
    fig.suptitle(f"{name}: joint reactions (magnitude, on body j)", fontsize=12)
    if types and any(types.get(r.name) in _gears() for r in found):
        fig.supxlabel("Gear rows couple angles only: their reactions are couples, and the tooth "
                      "force's share of the bearing loads is not represented.", fontsize=8, color="0.35")
    return fig


# -- the mechanism's geometry over the run (numbers only) -------------------


# -- drawing ----------------------------------------------------------------


def _instants(sc: Scene, n: int, count: int) -> list[int]:
    """`count` instants spread over the run; a run that ends where it began
    (a full cycle) does not repeat its first configuration."""
    if n <= 1:
        return [0]
    outlines = list(sc.outlines.values())
    cyclic = all(np.allclose(o[0], o[-1], atol=1e-6 * sc.size) for o in outlines)
    spots = np.linspace(0, n - 1, count + 1)[:-1] if cyclic else np.linspace(0, n - 1, count)
    return sorted({int(round(s)) for s in spots})


def _panel_size(sc: Scene, width: float) -> tuple[float, float]:
    x0, x1, y0, y1 = sc.bounds
    return width, float(np.clip(width * (y1 - y0) / (x1 - x0), 1.6, 1.5 * width))


def _gears() -> Any:
    """The gear types (symid.output.scene imports sympy: a table plotted alone never needs it)."""
    from symid.output.scene import GEARS

    return GEARS


def mechanism_figure(table: Table, mechanism: Mechanism, panels: int = PANELS) -> "Figure":
    """The mechanism drawn at a few instants, each with the paths of its moving points."""
    from symid.output.scene import draw, draw_paths, scene

    sc = scene(table, mechanism)
    t = np.asarray(table["t"])
    ks = _instants(sc, len(t), panels)
    cols = 1 if len(ks) == 1 else 2
    rows = -(-len(ks) // cols)
    w, h = _panel_size(sc, 4.6)
    fig = _figure(cols * w + 0.4, rows * h + 0.9)
    axes = fig.subplots(rows, cols, squeeze=False).ravel()
    for n, (ax, k) in enumerate(zip(axes, ks)):
        draw_paths(ax, sc)
        draw(ax, sc, k)
        ax.set_gid(f"instant:{k}")
        ax.set_title(f"t = {t[k]:.4g} s", fontsize=10)
        ax.grid(True, alpha=0.2)
        if n % cols == 0:
            ax.set_ylabel("y [m]")
        if n >= len(ks) - cols:
            ax.set_xlabel("x [m]")
    for ax in axes[len(ks):]:
        ax.set_visible(False)
    fig.suptitle(f"{mechanism.name}: the mechanism at {len(ks)} instants, paths dashed", fontsize=12)
    return fig


def write_gif(table: Table, mechanism: Mechanism, path: str | Path, frames: int = 60, fps: int = 15) -> Path:
    """An animated GIF of the motion (at most `frames` frames), written atomically."""
    from matplotlib.animation import PillowWriter

    from symid.output.scene import draw, draw_paths, scene

    path = Path(path)
    sc = scene(table, mechanism)
    t = np.asarray(table["t"])
    ks = _instants(sc, len(t), min(frames, len(t)))
    w, h = _panel_size(sc, 5.0)
    fig = _figure(w, h + 0.5, layout=None)  # a fixed layout: frames do not jump, nor re-solve it
    ax = fig.add_axes((0.16, 0.12, 0.8, 0.8))
    with atomic_path(path, ".gif") as tmp:
        writer = PillowWriter(fps=fps)
        draw_paths(ax, sc)
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.grid(True, alpha=0.2)
        static = set(ax.get_children())
        with writer.saving(fig, tmp, dpi=90):
            for k in ks:
                # Only the mechanism is redrawn: clearing the axes would rebuild every tick per frame.
                for artist in set(ax.get_children()) - static:
                    artist.remove()
                draw(ax, sc, k)
                ax.set_title(f"{mechanism.name}   t = {t[k]:.3f} s", fontsize=10)
                writer.grab_frame()
    return path


# -- all of them ------------------------------------------------------------

@dataclass
class Written:
    """The files `write_all` wrote and, for the plots it could not make, why."""

    paths: list[Path] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)


def _sizing_figure(table: Table, mechanism: Mechanism) -> "Figure":
    """The sizing picture of a table (ValueError: it lacks a column sizing reads)."""
    from symid.output import sizing
    from symid.errors import InputError
    from symid.output.sizing_plot import sizing_figure

    try:
        return sizing_figure(sizing.size(mechanism, table), mechanism.name)
    except KeyError as exc:
        raise ValueError(f"{exc.args[0]} (sizing reads every output group)") from None
    except InputError as exc:  # the run cannot be sized (a joint that does not turn): said, the rest drawn
        raise ValueError(str(exc)) from None


def write_all(table: Table, mechanism: Mechanism | None, directory: str | Path, stem: str,
              gif: bool = False) -> Written:
    """Write `<stem>_efforts.png`, `<stem>_reactions.png`, `<stem>_mechanism.png`,
    `<stem>_friction.png` (joint friction only), `<stem>_sizing.png` (drives or
    bearings in the file) and `<stem>_motion.gif` (with
    `gif`) in `directory`, each that the table allows."""
    directory = make_folder(directory)
    out = Written()
    if len(table["t"]) == 0:
        out.skipped.append("plots: the table has no instants")
        return out
    need = "needs the mechanism file (--mechanism)"
    jobs: list[tuple[str, Callable[[], Any] | None]] = [
        ("efforts plot", (lambda: efforts_figure(table, mechanism)) if mechanism else None),
        ("reactions plot", lambda: reactions_figure(table, mechanism)),
        ("mechanism plot", (lambda: mechanism_figure(table, mechanism)) if mechanism else None),
    ]
    if friction_loss.columns(table.columns):  # joint friction: the power each joint's takes
        jobs.append(("friction plot", lambda: friction_figure(table, mechanism)))
    if mechanism is not None and mechanism.sizing:  # drives or bearings: symid help sizing
        jobs.append(("sizing plot", lambda: _sizing_figure(table, mechanism)))
    if gif:
        jobs.append(("animation", (lambda: write_gif(table, mechanism, directory / f"{stem}_motion.gif"))
                     if mechanism else None))
    for what, make in jobs:
        if make is None:
            out.skipped.append(f"{what}: {need}")
            continue
        try:
            made = make()
        except ValueError as exc:  # the table lacks what this plot needs
            out.skipped.append(f"{what}: {exc}")
            continue
        if not isinstance(made, Path):
            made = save(made, directory / f"{stem}_{what.split()[0]}.png")
        out.paths.append(made)
    return out
