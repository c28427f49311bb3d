"""Figures of a design study (`symid sweep --plot`, `symid plot SWEEP.csv`).

- a grid of two parameters: a filled contour of each figure over the grid;
- one parameter: each figure against it, a line;
- a sample (or anything else): a histogram of each figure with its P50, P95
  and P99 marked, and a scatter of each varied parameter against the primary
  figure (the first column: the first driver's peak effort).

A figure constant over the variants but for rounding (a spread below FLAT of
its size) is drawn as one level, with a note: contour levels and histogram
bins cannot divide a spread of a few ulps. A force_peak that is 0 at every
variant (a gear's, an angle driver's, a parallel constraint's reaction is a
pure couple) is left out, with a note.

Failed variants are drawn, never dropped: a red cross at their grid point or
parameter value, a red tick under the histogram. Percentiles are of the
variants that ran to the end. Every artist with data has a `gid`
("contour:<figure>", "line:<figure>", "hist:<figure>", "P95:<figure>",
"scatter:<param>", "failed:<figure or param>") for tests and scripts.
"""

from __future__ import annotations

import itertools
from pathlib import Path
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np

from symid.output.plot import _figure, save

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

PERCENTILES = (50, 95, 99)
COLUMNS = 3  # panels per row
FAILED: dict[str, Any] = {"color": "red", "marker": "x", "linestyle": "none", "markersize": 6}
# A figure whose spread over the variants is at most this share of its size is
# constant but for rounding: the backends agree to ~1e-14, so a spread this
# small says nothing about the design, and 12 levels (or 40 bins) across a few
# ulps are not increasing.
FLAT = 1e-12


def _span(values: np.ndarray) -> tuple[float, float, bool]:
    """(lo, hi, flat) of the finite values; flat when hi - lo <= FLAT max(|lo|, |hi|)."""
    good = values[np.isfinite(values)]
    if not good.size:
        return np.nan, np.nan, False
    lo, hi = float(good.min()), float(good.max())
    return lo, hi, hi - lo <= FLAT * max(abs(lo), abs(hi))


def _one_level(lo: float, hi: float) -> tuple[float, float]:
    """A band around a flat figure's values that a float can split (contour levels, histogram range)."""
    pad = max(abs(lo), abs(hi)) * 1e-6 or 1.0
    return lo - pad, hi + pad


def _flat_note(name: str, lo: float, hi: float) -> str:
    return f"{name} is constant over the variants ({lo:.10g}, spread {hi - lo:.2g}): drawn as one level"


def layout_of(params: Sequence[str], values: np.ndarray) -> str:
    """"grid2", "grid1" or "sample": how the variants lie, from their values alone
    (a grid: every combination of each parameter's values, in product order)."""
    if len(params) not in (1, 2) or not len(values):
        return "sample"
    axes = [np.unique(values[:, k]) for k in range(len(params))]
    if np.prod([len(a) for a in axes]) != len(values):
        return "sample"
    product = np.array(list(itertools.product(*axes)), dtype=float)
    if not np.array_equal(product, values):
        return "sample"
    return f"grid{len(params)}"


def _panels(count: int, width: float = 4.2, height: float = 3.3) -> tuple["Figure", list["Axes"]]:
    cols = min(COLUMNS, max(count, 1))
    rows = -(-count // cols)
    fig = _figure(width * cols, height * rows)
    axes = fig.subplots(rows, cols, squeeze=False).ravel()
    for ax in axes[count:]:
        ax.set_visible(False)
    return fig, list(axes[:count])


def grid2_figure(params: Sequence[str], values: np.ndarray, names: Sequence[str], figures: np.ndarray,
                 ok: np.ndarray, title: str, notes: list[str] | None = None) -> "Figure":
    """A filled contour of each figure over a two-parameter grid (failed points
    crossed); a flat figure is one band, its value written on it (and in notes)."""
    x, y = np.unique(values[:, 0]), np.unique(values[:, 1])
    fig, axes = _panels(len(names))
    for k, (ax, name) in enumerate(zip(axes, names)):
        z = figures[:, k].reshape(len(x), len(y)).T  # rows: y, the last (fastest) parameter
        masked = np.ma.masked_invalid(np.where(ok.reshape(len(x), len(y)).T, z, np.nan))
        if masked.count() and len(x) > 1 and len(y) > 1:
            lo, hi, flat = _span(masked.compressed())
            if flat:
                filled = ax.contourf(x, y, masked, levels=list(_one_level(lo, hi)), cmap="viridis")
                ax.text(0.5, 0.5, f"constant\n{lo:.10g}", transform=ax.transAxes, ha="center", va="center",
                        fontsize=9, color="white", gid=f"constant:{name}")
                if notes is not None:
                    notes.append(_flat_note(name, lo, hi))
            else:
                filled = ax.contourf(x, y, masked, levels=np.linspace(lo, hi, 12), cmap="viridis")
                fig.colorbar(filled, ax=ax)
            filled.set_gid(f"contour:{name}")
        bad = ~ok
        if bad.any():
            ax.plot(values[bad, 0], values[bad, 1], gid=f"failed:{name}", label="failed", **FAILED)
            ax.legend(fontsize=8, loc="best")
        ax.set_xlabel(params[0])
        ax.set_ylabel(params[1])
        ax.set_title(name, fontsize=10)
    fig.suptitle(title, fontsize=12)
    return fig


def grid1_figure(params: Sequence[str], values: np.ndarray, names: Sequence[str], figures: np.ndarray,
                 ok: np.ndarray, title: str) -> "Figure":
    """Each figure against the one varied parameter (failed variants crossed at their partial figures)."""
    x = values[:, 0]
    fig, axes = _panels(len(names))
    for k, (ax, name) in enumerate(zip(axes, names)):
        ax.plot(x, np.where(ok, figures[:, k], np.nan), color="C0", lw=1.8, marker=".", gid=f"line:{name}")
        bad = ~ok
        if bad.any():
            ax.plot(x[bad], figures[bad, k], gid=f"failed:{name}", label="failed (partial run)", **FAILED)
            ax.legend(fontsize=8, loc="best")
        ax.set_xlabel(params[0])
        ax.set_title(name, fontsize=10)
        ax.grid(True, alpha=0.3)
    fig.suptitle(title, fontsize=12)
    return fig


def histogram_figure(names: Sequence[str], figures: np.ndarray, ok: np.ndarray, title: str,
                     notes: list[str] | None = None) -> "Figure":
    """A histogram of each figure over the variants that ran to the end,
    P50/P95/P99 marked; a flat figure is one bar (and a line in notes)."""
    fig, axes = _panels(len(names))
    for k, (ax, name) in enumerate(zip(axes, names)):
        good = figures[ok, k]
        good = good[np.isfinite(good)]
        if good.size:
            lo, hi, flat = _span(good)
            if flat and notes is not None:
                notes.append(_flat_note(name, lo, hi))
            ax.hist(good, bins=1 if flat else min(40, max(5, good.size // 5)),
                    range=_one_level(lo, hi) if flat else None, color="C0", alpha=0.8, gid=f"hist:{name}")
            for p, style in zip(PERCENTILES, ("-", "--", ":")):
                value = float(np.percentile(good, p))
                ax.axvline(value, color="k", linestyle=style, lw=1.2, gid=f"P{p}:{name}",
                           label=f"P{p} {value:.4g}")
        bad = figures[~ok, k]
        if (~ok).any():
            ax.plot(bad, np.zeros_like(bad), gid=f"failed:{name}", color="red", marker="|", linestyle="none",
                    markersize=14, label=f"failed: {int(np.count_nonzero(~ok))}")
        ax.legend(fontsize=7, loc="best")
        ax.set_title(name, fontsize=10)
        ax.set_ylabel("variants")
    fig.suptitle(title, fontsize=12)
    return fig


def scatter_figure(params: Sequence[str], values: np.ndarray, primary: str, y: np.ndarray, ok: np.ndarray,
                   title: str) -> "Figure":
    """Each varied parameter against the primary figure (failed variants crossed)."""
    fig, axes = _panels(len(params))
    for k, (ax, name) in enumerate(zip(axes, params)):
        ax.scatter(values[ok, k], y[ok], s=8, alpha=0.6, color="C0", gid=f"scatter:{name}")
        if (~ok).any():
            ax.plot(values[~ok, k], y[~ok], gid=f"failed:{name}", label="failed (partial run)", **FAILED)
            ax.legend(fontsize=8, loc="best")
        ax.set_xlabel(name)
        ax.set_ylabel(primary)
        ax.grid(True, alpha=0.3)
    fig.suptitle(title, fontsize=12)
    return fig


def figures_of(params: Sequence[str], values: np.ndarray, names: Sequence[str], figures: np.ndarray,
               status: Sequence[str] | np.ndarray, stem: str, kind: str = "",
               notes: list[str] | None = None) -> dict[str, "Figure"]:
    """The study's figures by file suffix ("figures", and "scatter" for a sample).

    Args:
        params, values: the varied parameters, shape (K, len(params)).
        names, figures: the figure columns, shape (K, len(names)).
        status: per variant, "ok" or why it failed.
        kind: "grid", "table", "sample" when known; else read from the values.
        notes: where to append a line per figure left out or drawn flat.
    """
    values = np.asarray(values, dtype=float).reshape(len(status), len(params))
    figures = np.asarray(figures, dtype=float).reshape(len(status), len(names))
    ok = np.array([s == "ok" for s in status], dtype=bool)
    failed = int(np.count_nonzero(~ok))
    title = f"{stem}: {len(status)} variants" + (f", {failed} failed" if failed else "")
    shape = layout_of(params, values) if kind != "sample" else "sample"
    keep = [k for k, name in enumerate(names) if not _no_force(name, figures[ok, k])]
    if notes is not None:
        notes.extend(f"{names[k]} is 0 at every variant (the reaction of a gear, an angle driver or a parallel "
                     "constraint is a pure couple): left out" for k in range(len(names)) if k not in keep)
    names, figures = [names[k] for k in keep], figures[:, keep]
    if not names:
        return {}
    if shape == "grid2":
        return {"figures": grid2_figure(params, values, names, figures, ok, title, notes)}
    if shape == "grid1":
        return {"figures": grid1_figure(params, values, names, figures, ok, title)}
    out = {"figures": histogram_figure(names, figures, ok, title, notes)}
    if params:
        out["scatter"] = scatter_figure(params, values, names[0], figures[:, 0], ok, title)
    return out


def _no_force(name: str, ran: np.ndarray) -> bool:
    """A force_peak exactly 0 at every variant that ran: no force by construction
    (the code writes a literal 0 for a reaction with no force rows)."""
    return name.endswith(".force_peak") and ran.size > 0 and not np.any(ran)


def write_all(params: Sequence[str], values: np.ndarray, names: Sequence[str], figures: np.ndarray,
              status: Sequence[str] | np.ndarray, folder: Path, stem: str, kind: str = "",
              notes: list[str] | None = None) -> list[Path]:
    """Write the study's PNGs as `<stem>_figures.png` (and `<stem>_scatter.png`);
    returns the paths, and appends to notes what was left out or drawn flat."""
    from symid.io.files import make_folder

    folder = make_folder(folder)
    written = []
    for suffix, fig in figures_of(params, values, names, figures, status, stem, kind, notes).items():
        written.append(save(fig, Path(folder) / f"{stem}_{suffix}.png"))
    return written
