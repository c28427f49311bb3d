"""A mutation run: plausible hand-made bugs, and whether the test suite notices them.

Each mutant replaces one exact piece of text (found exactly once) in one file
of a copy of the repository, never the checkout itself, and runs a chosen
selection of the tests there (`-x`, with a timeout). A mutant is *killed*
when the selection fails (or times out), *survives* when it passes. A
survivor names something no test watches.

    python -m benchmarks mutation                  # every mutant
    python -m benchmarks mutation -k c_ dense      # mutants whose name contains c_ or dense
    python -m benchmarks mutation --smoke          # only check that every mutant applies

CPU heavy: each mutant runs its selection of the tests (`mutation.json`'s
`seconds` per mutant says how long).
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from benchmarks.cases import register
from benchmarks.processes import ROOT as REPO
from benchmarks.run import Context

TIMEOUT = 240  # seconds per mutant; a hang counts as killed (the suite noticed)
IGNORE = shutil.ignore_patterns(".git", "__pycache__", ".pytest_cache", ".mypy_cache", "*.egg-info", "results")

CLI = "tests/cli/test_cli.py"
OUT = "tests/output/test_output_integrity.py"
CSOLVER = "tests/c/test_solver_internals.py"
CODEGEN = "tests/codegen/test_codegen.py"


@dataclass(frozen=True)
class Mutant:
    """One bug: in `file`, the text `old` (exactly once) becomes `new`; `tests`
    are pytest arguments (paths, node ids, -k expressions) that should notice."""

    name: str
    file: str
    old: str
    new: str
    tests: tuple[str, ...]


def k(path: str, expr: str) -> tuple[str, ...]:
    """The tests of `path` whose names match the -k expression."""
    return (path, "-k", expr)


MUTANTS: tuple[Mutant, ...] = (
    # -- output: the CSV and NPZ writers, the summary --------------------------------
    Mutant("csv_written_in_place", "symid/io/files.py",
           'fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=suffix, dir=None if into else path.parent)',
           "fd, tmp = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600), str(path)",
           k(OUT, "in_place or interrupt or target")),
    Mutant("csv_rename_skipped", "symid/io/files.py",
           "        os.replace(tmp, path)\n    except OSError as exc:\n        Path(tmp).unlink",
           "        pass\n    except OSError as exc:\n        Path(tmp).unlink",
           k(CLI, "success_leaves or failure_replaces")),
    Mutant("csv_15_digits", "symid/output/results.py", 'return ",".join(["%.17g"] * width)',
           'return ",".join(["%.15g"] * width)', k(CLI, "17_significant")),
    Mutant("csv_failure_drops_rows", "symid/output/tables.py",
           "            except AnalysisError as exc:  # keep the instants before it: the file is completed\n"
           "                failure = exc\n",
           "            except AnalysisError as exc:  # keep the instants before it: the file is completed\n"
           "                failure = exc\n                out.seek(0)\n                out.truncate(0)\n"
           "                waiting.clear()\n",
           k(CLI, "part_way_exits_3_and_keeps")),
    Mutant("csv_unsolved_group_not_zero", "symid/numeric/solve.py",
           "parts.append(np.zeros(ng) if value is None else value)",
           "parts.append(np.zeros(0) if value is None else value)", k(CLI, "statics_rate_columns")),
    Mutant("npz_written_in_place", "symid/output/npz.py", "    with atomic_write(path, binary=True) as out:",
           "    with open(path, \"wb\") as out:",
           ("tests/output/test_npz.py",)),
    Mutant("summary_cylinder_sign", "symid/output/summary.py", "value, rate = -2 * np.abs(f) * raw, np.sign(f) * fd",
           "value, rate = 2 * np.abs(f) * raw, np.sign(f) * fd", k("tests/numeric/test_summary.py", "cylinder_force")),
    Mutant("summary_rms_not_halved", "symid/output/summary.py", "* np.diff(e.t)) / 2 / span))",
           "* np.diff(e.t)) / span))", k("tests/numeric/test_summary.py", "sine")),
    Mutant("summary_peak_power_unsigned", "symid/output/summary.py", "float(e.power[p]), float(e.t[p]))",
           "float(abs(e.power[p])), float(e.t[p]))", k("tests/numeric/test_summary.py", "brakes")),
    # -- the reference backend's reactions subset -------------------------------------
    Mutant("reference_reactions_of_every_constraint", "symid/numeric/reference.py",
           "order = [c.name for c in mech.constraints if c.name in wanted]",
           "order = [c.name for c in mech.constraints]",
           k(OUT, "subset") + k(CLI, "reactions_motor or subset")),
    # -- the Python solver loop -----------------------------------------------------
    Mutant("python_predictor_half_dropped", "symid/numeric/solve.py",
           "return prev.q + h * prev.qd + 0.5 * h * h * prev.qdd",
           "return prev.q + h * prev.qd + h * h * prev.qdd", k(CSOLVER, "loop and python")),
    Mutant("statics_predictor_quadratic_wrong", "symid/numeric/solve.py",
           "return 3 * history[-1] - 3 * history[-2] + history[-3]",
           "return 3 * history[-1] - 2 * history[-2] + history[-3]", k(CSOLVER, "loop and python")),
    Mutant("lambda_rhs_sign", "symid/numeric/solve.py", "rhs = ev.applied(q, out.qd, t) - self.mass * out.qdd",
           "rhs = ev.applied(q, out.qd, t) + self.mass * out.qdd", ("tests/numeric/test_physics.py", "-k", "closed_form")
           + k(OUT, "part_way_keeps_every and numpy")),
    Mutant("time_grid_off_by_one", "symid/numeric/solve.py", "h = (analysis.t1 - analysis.t0) / (analysis.steps - 1)",
           "h = (analysis.t1 - analysis.t0) / analysis.steps", k(CLI, "one_row_per_step")
           + k(OUT, "part_way_keeps_every and numpy")),
    Mutant("newton_damping_never_halves", "symid/numeric/solve.py", "            alpha *= 0.5\n",
           "            alpha *= 0.999\n", ("tests/numeric/test_stability.py", "-k", "diverg or damp")),
    # -- the compiled (C) backend's loop in Python -----------------------------------
    Mutant("c_failed_chunk_rows_dropped", "symid/backends/c_backend.py",
           "            if solved.value:\n                yield buf[:solved.value].copy()",
           "            if solved.value and status == 0:\n                yield buf[:solved.value].copy()",
           (f"{OUT}::test_failure_part_way_in_a_later_chunk_keeps_the_chunks_rows[c]",)),
    Mutant("c_failure_time_off_by_one", "symid/backends/c_backend.py",
           "out = stepper.instant(k, analysis.t0 + k * h, prev, history, q0)",
           "out = stepper.instant(k, analysis.t0 + (k + 1) * h, prev, history, q0)",
           (f"{OUT}::test_failure_part_way_keeps_every_instant_before_it_equal_to_the_reference[c]",)),
    Mutant("c_chunk_start_time_off_by_one", "symid/backends/c_backend.py",
           "status = self._trajectory(ctypes.c_double(analysis.t0),",
           "status = self._trajectory(ctypes.c_double(analysis.t0 + h),",
           k(CODEGEN, "fine_grid and slider_crank")),
    # -- the C template: predictor, dense fallback, outputs ---------------------------
    Mutant("c_predictor_coefficient", "templates/c/solver.c.j2", "(323.0 / 360.0) * qdd[k]",
           "(324.0 / 360.0) * qdd[k]", k(CSOLVER, "c_predictor or factors_once")),
    Mutant("c_predictor_history_order", "templates/c/solver.c.j2",
           "        memcpy(m3, m2, sizeof(double) * {{ ng }});\n        memcpy(m2, m1, sizeof(double) * {{ ng }});\n"
           "        memcpy(m1, qdd,",
           "        memcpy(m2, m1, sizeof(double) * {{ ng }});\n        memcpy(m3, m2, sizeof(double) * {{ ng }});\n"
           "        memcpy(m1, qdd,", k(CSOLVER, "c_predictor or factors_once")),
    Mutant("c_dense_pivot_smallest", "templates/c/solver.c.j2",
           "if (fabs(a[i * n + k]) > fabs(a[best * n + k])) best = i;",
           "if (fabs(a[i * n + k]) < fabs(a[best * n + k])) best = i;", k(CSOLVER, "dense")),
    Mutant("c_dense_solve_t_index_swapped", "templates/c/solver.c.j2",
           "        for (j = 0; j < i; ++j) x[i] -= a[j * n + i] * x[j];\n        x[i] /= a[i * n + i];",
           "        for (j = 0; j < i; ++j) x[i] -= a[i * n + j] * x[j];\n        x[i] /= a[i * n + i];",
           k(CSOLVER, "dense")),
    Mutant("c_dense_solve_no_permutation", "templates/c/solver.c.j2",
           "        double tmp = x[perm[i]];\n        x[perm[i]] = x[i];\n        x[i] = tmp;\n"
           "        for (j = 0; j < i; ++j) x[i] -= a[i * n + j] * x[j];",
           "        for (j = 0; j < i; ++j) x[i] -= a[i * n + j] * x[j];", k(CSOLVER, "dense")),
    Mutant("c_mass_term_sign", "templates/c/solver.c.j2", "for (k = 0; k < {{ ng }}; ++k) b[k] -= y[k] * qdd[k];",
           "for (k = 0; k < {{ ng }}; ++k) b[k] += y[k] * qdd[k];", k(CODEGEN, "fine_grid and slider_crank")),
    Mutant("c_statics_predictor", "templates/c/solver.c.j2", "3.0 * q[k] - 3.0 * m1[k] + m2[k]",
           "3.0 * q[k] - 2.0 * m1[k] + m2[k]", k(CSOLVER, "c_statics")),
    # -- derivation -------------------------------------------------------------------
    Mutant("reaction_force_sign", "symid/symbolic/derive.py", "    force = -phi_r.T * lam\n", "    force = phi_r.T * lam\n",
           ("tests/symbolic/test_derivations.py", "-k", "reference_table")),
    Mutant("reaction_torque_arm_sign", "symid/symbolic/derive.py", "torque = ((bs.T * phi_r.T - phi_phi.T) * lam)[0]",
           "torque = ((-bs.T * phi_r.T - phi_phi.T) * lam)[0]", ("tests/symbolic/test_derivations.py", "-k", "reference_table")),
    Mutant("gamma_drops_driver_rate", "symid/symbolic/derive.py", "        out += sp.diff(expr, f) * fd\n",
           "        pass\n", ("tests/symbolic/test_derivations.py", "-k", "hand_expressions")),
    Mutant("total_derivative_drops_q_chain", "symid/symbolic/derive.py",
           "out += sp.diff(expr, qc) * qdc + sp.diff(expr, qdc) * qddc", "out += sp.diff(expr, qdc) * qddc",
           ("tests/symbolic/test_derivations.py", "-k", "hand_expressions")),
    Mutant("distance_length_not_squared", "symid/symbolic/constraints/distance.py",
           'phi=lambda o: [(_d().T * _d())[0] - s.scalar("L") ** 2],',
           'phi=lambda o: [(_d().T * _d())[0] - s.scalar("L")],',
           ("tests/tools/test_verify.py", "-k", "verifies and revolute_revolute")),
    Mutant("angle_driver_offset_sign", "symid/symbolic/constraints/angle.py",
           'phi=lambda o: [s.q("j")[2] - s.q("i")[2] - s.scalar("C") - s.F_SERIES[0]],',
           'phi=lambda o: [s.q("j")[2] - s.q("i")[2] + s.scalar("C") - s.F_SERIES[0]],',
           ("tests/symbolic/test_derivations.py", "-k", "relative_angle_driver")),
    Mutant("gear_on_link_carrier_dropped", "symid/symbolic/constraints/gear.py",
           '(s.q("j")[2] - s.q("k")[2]) - _k() * (s.q("i")[2] - s.q("k")[2])',
           '(s.q("j")[2] - s.q("k")[2]) - _k() * s.q("i")[2]', ("tests/symbolic/test_derivations.py", "-k", "gear_on_link")),
    Mutant("slot_angle_offset_sign", "symid/symbolic/constraints/slot.py",
           'phi=lambda o: [_off_line(), s.q("j")[2] - s.q("i")[2] - s.scalar("theta0")],',
           'phi=lambda o: [_off_line(), s.q("j")[2] - s.q("i")[2] + s.scalar("theta0")],',
           ("tests/symbolic/test_derivations.py", "-k", "translational and not driver")),
    # -- code generation --------------------------------------------------------------
    Mutant("flat_gravity_y_dropped", "symid/codegen/flat.py", "applied[3 * b + 1] += m * gy",
           "applied[3 * b + 1] += 0 * gy", k(CODEGEN, "agrees_with_reference_through_api and slider_crank and c")),
    Mutant("sparse_threshold_ignored", "symid/codegen/sparse.py",
           "if not abs(piv) >= THRESHOLD * colmax or piv == 0:", "if piv == 0:",
           k(CODEGEN, "too_small_falls_back or known_pivot")),
    Mutant("numpy_predictor_half_dropped", "templates/numpy/module.py.j2", "hh = 0.5 * h * h", "hh = h * h",
           k(CSOLVER, "loop and numpy")),
    # -- added after the first run: more of the output and loop code ----------------------
    Mutant("csv_header_columns_shifted", "symid/symbolic/columns.py", "    out += list(analysis.extra_outputs())",
           "    out = out[1:] + [\"t\"] + list(analysis.extra_outputs())", k(OUT, "subset and numpy")),
    Mutant("c_state_not_seeded", "symid/backends/c_backend.py", "        state[:ng] = q0\n", "        pass\n",
           k(CODEGEN, "agrees_with_reference_through_api and c]")),
    Mutant("python_history_too_short", "symid/numeric/solve.py", "history = (history + [prev.q])[-3:]",
           "history = (history + [prev.q])[-2:]", k(CSOLVER, "python and statics")),
    Mutant("c_chord_without_refactor", "templates/c/solver.c.j2",
           "current = !chord && step <= {{ P }}_EPS * qmag;", "current = step <= {{ P }}_EPS * qmag || chord;",
           k(CODEGEN, "fine_grid and slider_crank")),
)


def applies(tree: Path, m: Mutant) -> bool:
    """Whether the mutant's old text occurs exactly once in its file (the code
    moves on: a mutant that no longer applies is stale, and reported so)."""
    path = tree / m.file
    return path.is_file() and path.read_text(encoding="utf-8").count(m.old) == 1


def apply(tree: Path, m: Mutant) -> str:
    """Apply the mutant in `tree`; returns the original text (to restore)."""
    path = tree / m.file
    text = path.read_text(encoding="utf-8")
    count = text.count(m.old)
    if count != 1:
        raise SystemExit(f"mutant {m.name}: the old text occurs {count} times in {m.file}")
    path.write_text(text.replace(m.old, m.new), encoding="utf-8")
    return text


def selection(tree: Path, tests: tuple[str, ...]) -> list[str]:
    """The pytest arguments, without the files (and their -k) that this tree lacks."""
    out: list[str] = []
    args = list(tests)
    while args:
        arg = args.pop(0)
        if arg.startswith("tests/") and not (tree / arg.split("::")[0]).exists():
            if args[:1] == ["-k"]:
                del args[:2]
            continue
        out.append(arg)
    return out


def run_tests(tree: Path, args: list[str], cache: Path) -> tuple[str, float, str]:
    """('killed' | 'survived' | 'timeout' | 'no tests', seconds, last output line)."""
    # each path with its own -k: one pytest call per path
    groups: list[list[str]] = []
    for arg in args:
        if arg == "-k" or (groups and groups[-1][-1] == "-k"):
            groups[-1].append(arg)
        elif groups and "-k" not in groups[-1] and "::" in arg and "::" in groups[-1][0]:
            groups[-1].append(arg)  # node ids share one pytest call
        else:
            groups.append([arg])
    env = dict(os.environ, PYTHONPATH=str(tree), SYMID_CACHE=str(cache), PYTHONDONTWRITEBYTECODE="1")
    start = time.monotonic()
    if not groups:
        return "no tests", 0.0, ""
    for group in groups:
        cmd = [sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider", *group]
        try:
            proc = subprocess.run(cmd, cwd=tree, env=env, capture_output=True, text=True,
                                  timeout=max(1.0, TIMEOUT - (time.monotonic() - start)))
        except subprocess.TimeoutExpired:
            return "timeout", time.monotonic() - start, ""
        lines = proc.stdout.strip().splitlines()
        last = lines[-1] if lines else proc.stderr.strip()[-200:]
        if proc.returncode == 5:
            return "no tests", time.monotonic() - start, last
        if proc.returncode != 0:
            return "killed", time.monotonic() - start, last
    return "survived", time.monotonic() - start, last


def _options(group: Any) -> None:
    group.add_argument("-k", nargs="*", default=[], help="only mutants whose name contains one of these")
    group.add_argument("--baseline", action="store_true", help="first run every selection unmutated")


@register("mutation", "plausible hand-made bugs, each against a selection of the tests: which the suite kills, "
          "which survive (--smoke: only that every mutant applies)", options=_options)
def mutation(ctx: Context) -> dict[str, Any]:
    args = ctx.options
    named = [m for m in MUTANTS if not args.k or any(s in m.name for s in args.k)]
    stale = [m.name for m in named if not applies(REPO, m)]
    chosen = [m for m in named if m.name not in stale]
    if stale:
        ctx.log(f"{len(stale)} of {len(named)} mutants no longer apply (stale): {', '.join(stale)}")
    if ctx.smoke:
        return {"mutants": len(named), "apply": len(chosen), "stale": stale}
    with tempfile.TemporaryDirectory(prefix="symid-mutation-") as tmp:
        tree = Path(tmp) / "repo"
        shutil.copytree(REPO, tree, ignore=IGNORE)
        if args.baseline:
            for m in chosen:
                verdict, seconds, last = run_tests(tree, selection(tree, m.tests), Path(tmp) / "cache-base")
                if verdict != "survived":
                    raise RuntimeError(f"baseline of {m.name}: {verdict} ({last})")
        records = []
        for n, m in enumerate(chosen, 1):
            original = apply(tree, m)
            try:
                verdict, seconds, last = run_tests(tree, selection(tree, m.tests), Path(tmp) / f"cache-{n}")
            finally:
                (tree / m.file).write_text(original, encoding="utf-8")
            records.append({"name": m.name, "file": m.file, "tests": list(m.tests), "verdict": verdict,
                            "seconds": round(seconds, 1), "last_line": last})
            ctx.log(f"[{n}/{len(chosen)}] {m.name}: {verdict} ({seconds:.0f} s)")
    killed = sum(r["verdict"] in ("killed", "timeout") for r in records)
    survivors = [r["name"] for r in records if r["verdict"] not in ("killed", "timeout")]
    return {"mutants": len(records), "killed": killed, "score": round(killed / max(1, len(records)), 3),
            "survivors": survivors, "stale": stale, "results": records}
