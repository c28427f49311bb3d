"""The overview's Markdown tables and PNG plots, from its figures (overview.py)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from benchmarks.cases import design_study

# What the issue asks of symid (the lead works on reaching them).
TARGETS = {
    "c_slider_crank_us": 0.5, "c_speedup": 5.0, "c_ladder64_us": 30.0, "ladder64_setup_s": 10.0,
    "ladder256_setup_s": 60.0, "numpy_slider_crank_us": 50.0, "solve_process_s": 1.0, "error": 1e-13,
    "stream_mb": 200.0, "c_ladder64_speedup": 10.0, "growth_slope": 1.15,
}
PYTHON_BASELINES = ("numpy-hand", "sympy-lambdify", "casadi-python")


def _g(v: Any, digits: int = 3) -> str:
    if v is None:
        return "–"
    if isinstance(v, float):
        if v != v:
            return "nan"
        return f"{v:.{digits}g}"
    return str(v)


def _cell(result: dict[str, Any], approach: str, mech: str) -> dict[str, Any] | None:
    return next((c for c in result["cells"] if c["approach"] == approach and c["mechanism"] == mech), None)


def _status(c: dict[str, Any] | None) -> str | None:
    if c is None:
        return "–"
    if c["status"] == "ok":
        return None
    return {"stopped": "stopped", "failed": "failed", "skipped": "skipped"}[c["status"]]


def _matrix(result: dict[str, Any], title: str, value: Any) -> list[str]:
    mechs = result["mechanisms"]
    order = list(dict.fromkeys(c["approach"] for c in result["cells"]))
    head = "| approach | " + " | ".join(f"{m['key']} (ng {m['ng']})" for m in mechs) + " |"
    lines = [f"**{title}**", "", head, "|---" * (len(mechs) + 1) + "|"]
    for a in order:
        row = []
        for m in mechs:
            c = _cell(result, a, m["key"])
            row.append(_status(c) or value(c))
        lines.append(f"| {a} | " + " | ".join(row) + " |")
    return lines + [""]


def _setup(c: dict[str, Any]) -> str:
    parts = [_g(c.get(k), 2) for k in ("derive_s", "generate_s", "compile_s")]
    return f"{_g(c.get('setup_s'))} ({' / '.join(parts)})"


def targets(result: dict[str, Any]) -> list[dict[str, Any]]:
    """Each target with the measured figure and whether it is met."""
    def us(a: str, m: str) -> float | None:
        c = _cell(result, a, m)
        return c.get("us_per_instant") if c and c["status"] == "ok" else None

    def setup(a: str, m: str) -> float | None:
        c = _cell(result, a, m)
        return c.get("setup_s") if c and c["status"] == "ok" else None

    rows = []

    def add(name: str, measured: float | None, limit: float, at_least: bool = False, note: str = "") -> None:
        met = None if measured is None else (measured >= limit if at_least else measured <= limit)
        rows.append({"target": name, "measured": measured, "limit": limit, "met": met, "note": note})

    def paired(m: str) -> tuple[float | None, str]:
        p = result.get("paired", {}).get(m)
        if not p or p.get("status") != "ok":
            return None, ""
        lo, hi = p["ratio_range"]
        return p["ratio"], f"same process, {p['rounds']} alternated rounds, range {lo:.3g}-{hi:.3g}"

    c_sc = us("symid-c", "slider_crank")
    add("slider-crank full instant, generated C (us)", c_sc, TARGETS["c_slider_crank_us"])
    ratio, note = paired("slider_crank")
    add("slider-crank: casadi-c time / symid-c time", ratio, TARGETS["c_speedup"], at_least=True, note=note)
    other = us("casadi-python", "slider_crank")
    add("slider-crank: casadi-python time / symid-c time", other / c_sc if other and c_sc else None,
        TARGETS["c_speedup"], at_least=True)
    c64 = us("symid-c", "ladder_64")
    add("ladder N=64 (ng 387), generated C (us per instant)", c64, TARGETS["c_ladder64_us"])
    ratio, note = paired("ladder_64")
    add("ladder N=64: casadi-c (sparse) time / symid-c time", ratio, TARGETS["c_ladder64_speedup"], at_least=True,
        note=note)
    for what, value in (("time per instant", us), ("setup", setup)):
        points = [(c["ng"], value("symid-c", c["mechanism"])) for c in result["cells"]
                  if c["approach"] == "symid-c" and c["mechanism"].startswith("ladder_") and c["ng"] >= 27]
        points = [(n, v) for n, v in points if v]
        slope = float(np.polyfit(np.log([n for n, _ in points]), np.log([v for _, v in points]), 1)[0]) \
            if len(points) >= 2 else None
        add(f"ladder, generated C: {what} grows as ng^slope (log-log fit, ng >= 27)", slope,
            TARGETS["growth_slope"], note=f"{len(points)} sizes")
    add("ladder N=64 setup, generated C (s)", setup("symid-c", "ladder_64"), TARGETS["ladder64_setup_s"])
    c256 = _cell(result, "symid-c", "ladder_256")
    add("ladder N=256 setup, generated C (s)", setup("symid-c", "ladder_256"), TARGETS["ladder256_setup_s"],
        note=c256.get("note", "") if c256 and c256["status"] != "ok" else "")
    np_sc = us("symid-numpy", "slider_crank")
    add("slider-crank, NumPy backend (us per instant)", np_sc, TARGETS["numpy_slider_crank_us"])
    fastest = min((v for v in (us(b, "slider_crank") for b in PYTHON_BASELINES) if v), default=None)
    add("slider-crank: fastest Python-loop baseline time / NumPy backend time",
        fastest / np_sc if fastest and np_sc else None, 1.0, at_least=True)
    for backend, r in result.get("processes", {}).get("solve_1001", {}).items():
        add(f"`symid solve` slider-crank, 1001 instants, cached, --backend {backend} (s, whole process)",
            r["wall_s"], TARGETS["solve_process_s"])
    errors = [(c["approach"], c["mechanism"], c["error_rel"]) for c in result["cells"]
              if c["kind"] == "symid" and c["status"] == "ok" and c.get("error_rel") is not None]
    if errors:
        worst = max(errors, key=lambda e: e[2])
        add("largest torque error of any symid backend (relative to peak)", worst[2], TARGETS["error"],
            note=f"{worst[0]} on {worst[1]}")
    stream = result.get("processes", {}).get("stream")
    if stream:
        add(f"streaming {stream['instants']:,} instants to CSV, peak memory (MB)", stream["peak_rss_mb"],
            TARGETS["stream_mb"], note=f"{stream['wall_s']:.0f} s")
    return rows


def markdown(result: dict[str, Any]) -> str:
    m = result["machine"]
    cfg = result["config"]
    lines = [
        "# symid benchmark",
        "",
        f"Machine: {m['cpu']}, {m['cpu_count']} cores, {m['memory']}; {m['platform']}; Python {m['python']}, "
        f"NumPy {m['numpy']}, SciPy {m['scipy']}, sympy {m['sympy']}, CasADi {m['casadi']}, {m['gcc']}. "
        f"symid {m['symid_commit']}. BLAS pinned to 1 thread. Load average at start "
        f"{', '.join(f'{x:.1f}' for x in m['load_average_start'])}, at end "
        f"{', '.join(f'{x:.1f}' for x in m['load_average_end'])} (a shared machine: timings carry that noise). "
        f"Whole run {m['run_s'] / 60:.1f} min" + (" (smoke run: sizes and instants are tiny)" if cfg["smoke"] else ""),
        "",
        "Each cell is its own process with an empty cache. A full instant is Newton positions from the "
        "previous instant (tol 1e-12; 2nd-order predictor, except symid-c: Taylor to h^5 and a first correction "
        "on the previous instant's factors), velocities, accelerations, multipliers and every "
        f"joint's reaction. Python loops time up to {cfg['steps']} instants (one period) within "
        f"{cfg['budget_s']:g} s; compiled loops up to {cfg['compiled_instants']} instants (whole periods). A cell "
        f"past {cfg['cap_s']:g} s is stopped and larger sizes of that approach are not tried.",
        "",
    ]
    lines += _matrix(result, "Microseconds per instant (median)", lambda c: _g(c.get("us_per_instant")))
    lines += _matrix(result, "Setup, seconds: total (derive / generate / compile); ends with the first instant",
                     _setup)
    lines += _matrix(result, "Motor torque error, max |tau - exact| / max |exact| over the first period "
                     "(instants compared)",
                     lambda c: f"{_g(c.get('error_rel'), 2)} ({c.get('error_instants')})")
    lines += _matrix(result, "Peak memory of the process, MB (RSS; interpreter and imports included)",
                     lambda c: _g(c.get("peak_rss_mb")))
    notes = [c for c in result["cells"] if c["status"] != "ok" and "not run" not in c.get("note", "")]
    if notes:
        lines += ["**Stopped and failed cells**", ""]
        lines += [f"- {c['approach']} on {c['mechanism']}: {c['status']}: {c.get('note', '')}" for c in notes]
        lines.append("")
    for key, sw in result["sweeps"].items():
        if sw.get("status") != "ok":
            lines += [f"**Sweeps on {key}**: {sw.get('status')} {sw.get('note', '')}", ""]
            continue
        lines += [f"**Predictor order x Newton tolerance on {key} (ng {sw['ng']})**: mean Newton iterations, "
                  "us per instant, torque error", "",
                  "| driver | order | " + " | ".join(f"tol {t:g}" for t in cfg["tolerances"]) + " |",
                  "|---" * (len(cfg["tolerances"]) + 2) + "|"]
        for driver in ("compiled-loop", "python-newton"):
            for order in cfg["orders"]:
                row = []
                for tol in cfg["tolerances"]:
                    p = next((r for r in sw["predictor"] if r["driver"] == driver and r["order"] == order
                              and r["tol"] == tol), None)
                    if p is None or p.get("error"):
                        row.append("failed" if p else "–")
                    else:
                        row.append(f"{_g(p['mean_iterations'], 2)} it, {_g(p['us_per_instant'])} us, "
                                   f"{_g(p['error_rel'], 2)}")
                lines.append(f"| {driver} | {order} | " + " | ".join(row) + " |")
        lines += ["", f"**Newton tolerance through `api.prepare(tol=...)` on {key}**: us per instant, "
                  "torque error, max |Phi|", "",
                  "| backend | " + " | ".join(f"tol {t:g}" for t in cfg["tolerances"]) + " |",
                  "|---" * (len(cfg["tolerances"]) + 1) + "|"]
        for backend in dict.fromkeys(r["backend"] for r in sw["tolerance"]):
            row = []
            for tol in cfg["tolerances"]:
                p = next((r for r in sw["tolerance"] if r["backend"] == backend and r["tol"] == tol), None)
                if p is None:
                    row.append("–")
                elif p.get("failed") or p.get("error"):
                    row.append("failed")
                else:
                    row.append(f"{_g(p['us_per_instant'])} us, {_g(p['error_rel'], 2)}, "
                               f"{_g(p['max_residual'], 2)}")
            lines.append(f"| {backend} | " + " | ".join(row) + " |")
        lines.append("")
    pairs = {k: p for k, p in result.get("paired", {}).items()}
    if pairs:
        lines += ["**symid-c against casadi-c in one process** (each round one whole grid of each, in turn; "
                  "medians)", "", "| mechanism | rounds | symid-c us | casadi-c us | ratio (range) |",
                  "|---|---|---|---|---|"]
        for k, p in pairs.items():
            if p.get("status") != "ok":
                lines.append(f"| {k} | {p.get('status')}: {p.get('note', '')} | | | |")
                continue
            lo, hi = p["ratio_range"]
            lines.append(f"| {k} (ng {p['ng']}) | {p['rounds']} | {_g(p['symid_c_us'])} | {_g(p['casadi_c_us'])} | "
                         f"{_g(p['ratio'])} ({_g(lo)}-{_g(hi)}) |")
        lines.append("")
    lines += design_study.markdown(result.get("study"))
    rows = targets(result) + design_study.targets(result.get("study"))
    if rows:
        lines += ["**Targets**", "", "| target | measured | limit | met |", "|---|---|---|---|"]
        for r in rows:
            met = "–" if r["met"] is None else "yes" if r["met"] else "**no**"
            note = f" ({r['note']})" if r["note"] else ""
            lines.append(f"| {r['target']}{note} | {_g(r['measured'])} | {_g(r['limit'])} | {met} |")
        lines.append("")
    return "\n".join(lines)


def plots(result: dict[str, Any], folder: Path) -> list[Path]:
    """time_vs_ng.png, time_vs_error.png, tolerance_sweep.png."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    written = []
    order = list(dict.fromkeys(c["approach"] for c in result["cells"]))
    colors = {a: plt.get_cmap("tab10")(k % 10) for k, a in enumerate(order)}
    ok = [c for c in result["cells"] if c["status"] == "ok" and c.get("us_per_instant")]

    fig, ax = plt.subplots(figsize=(7.5, 5))
    for a in order:
        pts = sorted((c["ng"], c["us_per_instant"]) for c in ok if c["approach"] == a
                     and c["mechanism"].startswith("ladder"))
        if pts:
            ax.plot(*zip(*pts), "o-", color=colors[a], label=a)
        sc = [c for c in ok if c["approach"] == a and c["mechanism"] == "slider_crank"]
        if sc:
            ax.plot([sc[0]["ng"]], [sc[0]["us_per_instant"]], "*", ms=11, mfc="none", color=colors[a])
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("ng (generalized coordinates); ladder of N four-bars, ng = 6N + 3")
    ax.set_ylabel("microseconds per full instant (median)")
    ax.set_title("Time per instant against size (stars: slider-crank, ng 9)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    written.append(folder / "time_vs_ng.png")
    fig.savefig(written[-1], dpi=120)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(7.5, 5))
    markers = dict(zip([m["key"] for m in result["mechanisms"]], "*ovs^D"))
    floor = 1e-17
    for c in ok:
        if c.get("error_rel") is not None:
            ax.plot(c["us_per_instant"], max(c["error_rel"], floor), markers.get(c["mechanism"], "o"),
                    color=colors[c["approach"]], ms=7)
    for key, sw in result["sweeps"].items():
        pts = sorted((r["us_per_instant"], r["error_rel"], r["tol"]) for r in sw.get("tolerance", [])
                     if r.get("backend") == "c" and r.get("error_rel") is not None and r.get("us_per_instant"))
        if pts:
            ax.plot([p[0] for p in pts], [max(p[1], floor) for p in pts], ":.", color="grey", ms=3)
    for a in order:
        ax.plot([], [], "s", color=colors[a], label=a)
    for key, mk in markers.items():
        ax.plot([], [], mk, color="black", mfc="none", label=key)
    ax.plot([], [], ":.", color="grey", label="symid-c, Newton tol 1e-6..1e-14")
    ax.axhline(TARGETS["error"], color="red", lw=0.8, ls="--")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("microseconds per instant")
    ax.set_ylabel("motor torque error / peak torque")
    ax.set_title("Error against time, every approach and mechanism")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=6, ncol=2)
    fig.tight_layout()
    written.append(folder / "time_vs_error.png")
    fig.savefig(written[-1], dpi=120)
    plt.close(fig)

    sweeps = {k: v for k, v in result["sweeps"].items() if v.get("status") == "ok"}
    if sweeps:
        fig, axes = plt.subplots(len(sweeps), 3, figsize=(12, 3.6 * len(sweeps)), squeeze=False)
        for row, (key, sw) in zip(axes, sweeps.items()):
            for driver, style in (("compiled-loop", "-"), ("python-newton", "--")):
                for order in result["config"]["orders"]:
                    pts = sorted((r["tol"], r["mean_iterations"], r["us_per_instant"], r["error_rel"])
                                 for r in sw["predictor"] if r["driver"] == driver and r["order"] == order
                                 and not r.get("error") and r.get("error_rel") is not None)
                    if not pts:
                        continue
                    tol, its, us, err = (np.array(v, dtype=float) for v in zip(*pts))
                    label = f"{driver}, order {order}"
                    row[0].plot(tol, its, style + "o", ms=3, label=label)
                    row[1].plot(tol, us, style + "o", ms=3, label=label)
                    row[2].plot(tol, np.maximum(err, 1e-17), style + "o", ms=3, label=label)
            for ax, ylabel in zip(row, ("mean Newton iterations", "us per instant", "torque error / peak")):
                ax.set_xscale("log")
                ax.invert_xaxis()
                ax.set_xlabel("Newton tolerance")
                ax.set_ylabel(ylabel)
                ax.set_title(f"{key} (ng {sw['ng']})", fontsize=9)
                ax.grid(True, which="both", alpha=0.3)
            row[1].set_yscale("log")
            row[2].set_yscale("log")
            row[0].legend(fontsize=6)
        fig.tight_layout()
        written.append(folder / "tolerance_sweep.png")
        fig.savefig(written[-1], dpi=110)
        plt.close(fig)
    return written
