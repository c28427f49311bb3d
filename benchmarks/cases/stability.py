"""Numerical stability: near-singular accuracy, units, long runs.

    python -m benchmarks stability [--instants N]

Writes `stability.png` beside the JSON (error against the distance to the
singularity and against cond, every backend). Three parts:

1. stress: the slider-crank with a rod of (1 + 10^-k) crank lengths (k = 1..8)
   at 90 degrees, and a four-bar at 10^-k rad before its toggle (k = 1..15),
   each backend's motor torque against the 40-digit reference of
   tests/helpers/stress.py, next to cond and to the torque's own condition number
   kappa (the error no double-precision method can avoid is about kappa eps);
2. units: every bundled example in metres vs millimetres, and with masses
   times 1e6, after unit conversion (tests/numeric/test_stability.py's converter);
3. long run: the bundled slider-crank for N instants (default 1e6) streamed to
   a CSV, crank angle past 1e4 rad, the motor torque against the 40-digit
   closed form every N/1000 instants (N/100 in a smoke run), and Python's allocated
   blocks sampled.
"""

from __future__ import annotations

import functools
import math
import resource
import sys
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks.cases import register
from benchmarks.processes import ROOT
from benchmarks.run import Context
from symid import api, backends
from symid.output.results import write_csv

EPS = float(np.finfo(float).eps)
KS = {"slider_crank": range(1, 9), "four_bar_toggle": range(1, 16)}
STEPS = 201  # instants of each units run


def _tests() -> None:
    """tests/ on the path: its stress cases (tests/helpers/stress.py, with their 40-digit
    reference) and unit converter (tests/numeric/test_stability.py) are the truth here."""
    for folder in (ROOT / "tests" / "helpers", ROOT / "tests" / "numeric"):
        if str(folder) not in sys.path:
            sys.path.insert(0, str(folder))


def available_backends() -> list[str]:
    out = []
    for name in backends.names():
        if name == "c":
            from symid.backends.c_backend import compiler
            from symid.errors import InputError

            try:
                compiler()
            except InputError:
                continue
        out.append(name)
    return out


# -- 1. stress ---------------------------------------------------------------------

def _once_per_point(kappa: Callable[[str, Mapping[str, float]], float]) -> Callable[[str, Mapping[str, float]], float]:
    """stress.kappa computed once per family and values: it depends on them only, and every
    backend solves the same point (60-digit differences: most of the stress part's time)."""
    known: dict[tuple[str, tuple[tuple[str, float], ...]], float] = {}

    def once(name: str, values: Mapping[str, float]) -> float:
        key = (name, tuple(sorted(values.items())))
        if key not in known:
            known[key] = kappa(name, values)
        return known[key]
    return once


def stress_part(folder: Path, quick: bool) -> list[dict[str, object]]:
    """Every backend on each family's points (smoke, `quick`: the slider-crank family's hardest
    point only: the four-bar's goes through the same steps with another closed form, whose
    40-digit derivation is most of a smoke run's time; tests/numeric/test_stability.py checks it)."""
    _tests()
    import stress

    if not hasattr(stress.kappa, "__wrapped__"):
        stress.kappa = functools.update_wrapper(_once_per_point(stress.kappa), stress.kappa)
    rows = []
    for name, ks in (list(KS.items())[:1] if quick else KS.items()):
        path = folder / f"{name}.toml"
        path.write_text(stress.FAMILIES[name].text, encoding="utf-8")
        for backend in available_backends():
            for k in (list(ks)[-1:] if quick else ks):
                try:
                    case = stress.solve_case(name, k, path, backend)
                except Exception as exc:  # a failed case is a data point, not the end of the run
                    rows.append({"family": name, "k": k, "backend": backend, "error": None, "failure": str(exc)})
                    print(f"stress {name:16s} k={k:2d} {backend:9s} failed: {exc}", flush=True)
                    continue
                rows.append({"family": name, "k": k, "distance": case.distance, "backend": backend,
                             "cond": None if math.isnan(case.cond) else case.cond, "torque": case.torque,
                             "reference": case.reference, "error": case.error, "kappa": case.kappa,
                             "error_over_cond_eps": None if math.isnan(case.cond) else case.error / (case.cond * EPS),
                             "error_over_kappa_eps": case.error / (case.kappa * EPS)})
                print(f"stress {name:16s} k={k:2d} {backend:9s} cond={case.cond:10.3g} "
                      f"err={case.error:9.2e} kappa*eps={case.kappa * EPS:9.2e}", flush=True)
    # the compiled backend reports no cond: give its rows the reference's
    conds = {(r["family"], r["k"]): r["cond"] for r in rows if r["backend"] == "reference"}
    for r in rows:
        if r.get("cond") is None and r.get("error") is not None:
            r["cond_from_reference"] = conds.get((r["family"], r["k"]))
    return rows


# -- 2. units ----------------------------------------------------------------------

def units_part(folder: Path, names: list[str]) -> list[dict[str, object]]:
    _tests()
    from test_stability import _unit_of, in_units  # the tests' converter

    out = []
    for name in names:
        text = api.example(name).read_text(encoding="utf-8")
        base_path = folder / f"{name}_base.toml"
        base_path.write_text(in_units(text, 1.0, 1.0), encoding="utf-8")
        base = api.solve(base_path, "numpy", steps=STEPS)
        for label, u, m in (("mm", 1000.0, 1.0), ("mass_1e6", 1.0, 1e6), ("mm_and_mass_1e6", 1000.0, 1e6)):
            path = folder / f"{name}_{label}.toml"
            path.write_text(in_units(text, u, m), encoding="utf-8")
            other = api.solve(path, "numpy", steps=STEPS)
            worst = 0.0
            kinds: dict[str, list[int]] = {}
            for k, column in enumerate(base.columns[1:], start=1):
                kinds.setdefault(_unit_of(column)[0], []).append(k)
            for kind, cols in kinds.items():
                if kind == "other":
                    continue
                dim = _unit_of(base.columns[cols[0]])[1]
                converted = other.data[:, cols] / (u ** dim[0] * m ** dim[1])
                scale = np.max(np.abs(base.data[:, cols]))
                if scale > 0:  # some examples have no torque columns that move
                    worst = max(worst, float(np.max(np.abs(converted - base.data[:, cols])) / scale))
            out.append({"example": name, "units": label, "max_relative_difference": worst})
            print(f"units {name:16s} {label:16s} {worst:.2e}", flush=True)
    return out


# -- 3. long run -------------------------------------------------------------------

@functools.cache
def _torque_closed_form():
    """The bundled slider-crank's motor torque, sympy -> mpmath (as the tests)."""
    import sympy as sp

    values = {k.name: v for k, v in api.prepare(api.example("slider_crank"), "reference").values.items()}
    t = sp.Symbol("t")
    r, l, w = (sp.Float(values[k], 30) for k in ("L_crank", "L_rod", "omega"))
    m1, m2, m3 = (sp.Float(values[k], 30) for k in ("m_crank", "m_rod", "m_slider"))
    th = w * t
    pin = sp.Matrix([r * sp.cos(th), r * sp.sin(th)])
    slider = sp.Matrix([r * sp.cos(th) + sp.sqrt(l**2 - r**2 * sp.sin(th) ** 2), 0])
    rod = sp.atan2(-r * sp.sin(th), slider[0] - pin[0])
    centres = [(m1, pin / 2), (m2, (pin + slider) / 2), (m3, slider)]
    kinetic = sum(m * (c.diff(t).T * c.diff(t))[0] for m, c in centres) / 2
    kinetic += (m1 * r**2 / 12 * w**2 + m2 * l**2 / 12 * rod.diff(t) ** 2) / 2
    power = sum(-m * 9.81 * c[1].diff(t) for m, c in centres) - values["F_gas"] * sp.sin(th) * slider[0].diff(t)
    return sp.lambdify(t, (kinetic.diff(t) - power) / w, "mpmath")


@functools.cache
def _reference_torque(t: float) -> float:
    """The closed form at t to 40 digits (once per t: every backend samples the same instants)."""
    import mpmath

    with mpmath.workdps(40):
        return float(_torque_closed_form()(mpmath.mpf(t)))


def long_part(folder: Path, instants: int, backend: str, checks: int = 1000, t1: float = 400.0) -> dict[str, object]:
    """The bundled slider-crank streamed to a CSV over [0, t1]: t1 = 400 s is 2000 revolutions at
    5 rev/s, the crank ends at 12566 rad."""
    study = api.prepare(api.example("slider_crank"), backend, t1=t1, steps=instants)
    columns = study.columns()
    k_tau, k_phi = columns.index("motor.T_j"), columns.index("crank.phi")
    every = max(1, instants // checks)  # the torque checked every `every` instants
    samples: list[tuple[float, float, float]] = []
    blocks: list[int] = []
    rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss

    def watched(rows):
        for n, values in enumerate(rows):
            if n % every == 0 or n == instants - 1:
                samples.append((float(values[0]), float(values[k_phi]), float(values[k_tau])))
                blocks.append(sys.getallocatedblocks())
            yield values

    start = time.perf_counter()
    count = write_csv(folder / "long.csv", columns, watched(study.rows()))
    elapsed = time.perf_counter() - start
    size = (folder / "long.csv").stat().st_size
    (folder / "long.csv").unlink()
    reference = np.array([_reference_torque(t) for t, _, _ in samples])
    got = np.array([s[2] for s in samples])
    scale = float(np.max(np.abs(reference)))
    err = np.abs(got - reference) / scale
    phi = np.array([s[1] for s in samples])
    tenth = max(1, len(err) // 10)
    result = {
        "backend": backend, "instants": count, "seconds": elapsed, "us_per_instant": 1e6 * elapsed / count,
        "csv_bytes": size, "final_crank_angle_rad": float(phi[-1]),
        "torque_error_first_tenth": float(np.max(err[:tenth])), "torque_error_last_tenth": float(np.max(err[-tenth:])),
        "torque_error_max": float(np.max(err)), "angle_times_eps": float(phi[-1] * EPS),
        "allocated_blocks_first_sample": blocks[0] if blocks else None,
        "allocated_blocks_max": max(blocks) if blocks else None,
        "allocated_blocks_last_sample": blocks[-1] if blocks else None,
        "max_rss_growth_kB": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - rss0,
        "error_samples": [[s[0], s[1], e] for s, e in zip(samples[::10], err[::10])],
    }
    print(f"long {backend}: {count} instants in {elapsed:.0f} s, crank at {phi[-1]:.0f} rad, "
          f"torque error first/last tenth {result['torque_error_first_tenth']:.2e} / "
          f"{result['torque_error_last_tenth']:.2e}, blocks {result['allocated_blocks_first_sample']} -> "
          f"{result['allocated_blocks_max']}", flush=True)
    return result


# -- the plot ----------------------------------------------------------------------

def plot(stress_rows: list[dict[str, object]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 2, figsize=(12, 9))
    markers = {"reference": "o", "numpy": "s", "casadi": "^", "c": "x"}
    for col, family in enumerate(KS):
        rows = [r for r in stress_rows if r["family"] == family and r.get("error") is not None]
        for backend, marker in markers.items():
            mine = [r for r in rows if r["backend"] == backend]
            if not mine:
                continue
            d = [r["distance"] for r in mine]
            err = [max(r["error"], 1e-18) for r in mine]
            cond = [r.get("cond") or r.get("cond_from_reference") for r in mine]
            axes[0, col].loglog(d, err, marker, label=backend, fillstyle="none")
            axes[1, col].loglog(cond, err, marker, label=backend, fillstyle="none")
        ref = sorted((r for r in rows if r["backend"] == "reference"), key=lambda r: r["distance"])
        if ref:
            d = np.array([r["distance"] for r in ref])
            cond = np.array([r["cond"] for r in ref])
            kappa = np.array([r["kappa"] for r in ref])
            axes[0, col].loglog(d, kappa * EPS, "k--", label="kappa eps (intrinsic)")
            axes[1, col].loglog(cond, cond * EPS, "g:", label="cond eps")
            axes[1, col].loglog(cond, cond**2 * EPS, "r-.", label="cond^2 eps")
            axes[1, col].loglog(cond, kappa * EPS, "k--", label="kappa eps (intrinsic)")
        what = "rod - crank (crank lengths)" if family == "slider_crank" else "crank angle to the toggle (rad)"
        axes[0, col].set(title=f"{family}: motor torque error", xlabel=what, ylabel="relative error")
        axes[1, col].set(title=f"{family}: error against cond", xlabel="cond (equilibrated Phi_q)",
                         ylabel="relative error")
        for ax in axes[:, col]:
            ax.grid(True, which="both", alpha=0.3)
            ax.legend(fontsize=8)
        axes[0, col].invert_xaxis()
    fig.suptitle("symid: motor torque near singular positions against a 40-digit reference")
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def _options(group: Any) -> None:
    group.add_argument("--instants", type=int, default=1_000_000, help="long-run instants")


def _plot(result: dict[str, Any], out: Path) -> list[Path]:
    plot(result["figures"]["stress"], out / "stability.png")
    return [out / "stability.png"]


@register("stability", "accuracy near singular positions against 40-digit references, units, a long run's error "
          "and memory", options=_options, report=_plot)
def stability(ctx: Context) -> dict[str, Any]:
    # smoke: a tenth of the span in 10^3 instants, a step of a fifth of a turn as 10^4 instants over
    # the whole span take (fewer instants over it would step whole turns: a jump)
    instants, t1 = (1000, 40.0) if ctx.smoke else (ctx.options.instants, 400.0)
    report: dict[str, Any] = {"eps": EPS}
    report["stress"] = stress_part(ctx.work, ctx.smoke)
    report["units"] = units_part(ctx.work, ["slider_crank"] if ctx.smoke else api.examples())
    # smoke: 20 samples against the 40-digit closed form show the comparison as 1000 do
    report["long_run"] = [long_part(ctx.work, instants, b, 20 if ctx.smoke else 1000, t1)
                          for b in ("numpy", "c") if b in available_backends()]
    return report
