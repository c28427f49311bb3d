"""The smallest mechanisms (tests/helpers/small_mechanisms.py) on every backend: each
constraint type alone, each force type, each analysis kind, output and
reaction subsets, numbers of every magnitude. Each is solved on numpy, C and
CasADi and compared with the reference backend, and its generated C is
compiled with the strict flags; a compiler that fails is one line, exit 2.
"""

from __future__ import annotations

import shutil
import stat
import subprocess
from fractions import Fraction
from functools import cache
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

from cbuild import STRICT, case_export, needs_cc
from small_mechanisms import cases
from tiers import diagonal, first_quick
from symid import api
from symid.api import Results
from symid.cli import main
from symid.io.reader import loads
from symid.model.mechanism import Mechanism

CASES = cases()
BACKENDS = ("numpy", "c", "casadi")


@cache
def mechanism(name: str) -> Mechanism:
    return loads(CASES[name], f"{name}.toml")


@cache
def reference(name: str) -> Results:
    return api.solve(mechanism(name), backend="reference")


GROUPS = {"x": "q", "y": "q", "phi": "q", "vx": "qdot", "vy": "qdot", "omega": "qdot", "ax": "qddot",
          "ay": "qddot", "alpha": "qddot"}


def assert_same_table(got: Results, expected: Results, rel: float = 1e-12) -> None:
    """Same header; every column within rel of that column's peak. A column
    that is zero up to rounding (a joint without load, a constant speed's
    acceleration) is measured against 1e-3 of the largest peak of its output
    group instead: its values are the rounding of that group's terms."""
    assert got.error is None, got.error
    assert got.columns == expected.columns
    assert got.data.shape == expected.data.shape
    peak = np.max(np.abs(expected.data), axis=0)
    groups = [GROUPS.get(c.rsplit(".", 1)[-1], "lambda" if ".lambda" in c else "reactions") for c in expected.columns]
    for k, column in enumerate(expected.columns[1:], start=1):
        group = max(peak[j] for j, g in enumerate(groups) if g == groups[k] and j > 0)
        scale = max(peak[k], 1e-3 * group, np.finfo(float).tiny)
        worst = np.max(np.abs(got.data[:, k] - expected.data[:, k])) / scale
        assert worst <= rel, (column, worst)
    assert np.array_equal(got.data[:, 0], expected.data[:, 0])


@pytest.mark.parametrize("name, backend", diagonal(list(CASES), BACKENDS))
def test_small_mechanism_agrees_with_reference(name: str, backend: str) -> None:
    if backend == "c" and shutil.which("cc") is None and shutil.which("gcc") is None:
        pytest.skip("no C compiler")
    expected = reference(name)
    assert expected.error is None and len(expected.t) == 21
    assert_same_table(api.solve(mechanism(name), backend=backend), expected)


@needs_cc
@pytest.mark.parametrize("name", first_quick(list(CASES)))  # strict flags over every case: slow tier
def test_generated_c_of_small_mechanism_compiles_with_strict_flags(name: str, tmp_path: Path,
                                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    """The source the C backend builds for a study (the sweep's SIMD lanes,
    no set-points), compiled by the backend itself with a CC holding the
    strict flags, as a user's CC (`CC="cc -Werror ..."`) would: its own
    compile is the strict check, one compile where the backend's build and
    a second strict one were two. A private cache, so it compiles here."""
    from symid.symbolic.assemble import assemble
    from symid.backends.c_backend import build
    from symid.codegen.model import options_for
    from symid.errors import InputError

    monkeypatch.setenv("CC", " ".join([shutil.which("cc") or str(shutil.which("gcc")), *STRICT]))
    monkeypatch.setenv("SYMID_CACHE", str(tmp_path / "cache"))
    try:
        folder = build(assemble(mechanism(name)), options_for(mechanism(name)))
    except InputError as exc:  # the compiler's first error: a warning made one by -Werror
        pytest.fail(str(exc))
    assert (folder / "solver.so").stat().st_size > 0 and (folder / f"{name}_solver.c").is_file()


@pytest.mark.slow  # every small mechanism compiled and linked (33 s each under load)
@needs_cc
@pytest.mark.parametrize("precision", ("double", "single"))
def test_every_small_mechanism_compiles_and_links_in_both_precisions(precision: str, tmp_path_factory,
                                                                    tmp_path: Path) -> None:
    """`symid generate --precision P` of every shape, built as a user builds
    it: strict flags, linked into a shared library that may leave no symbol
    undefined (a helper called but only defined for another shape, as
    `<name>_frac` was for linkages with wraps but no phase, is a link error;
    -fsyntax-only alone would see it only as an implicit declaration). The
    generated sources are the run's shared ones (cbuild.case_export, which
    runs that command; the Cortex-M4F and strict builds read them too)."""
    failed = {}
    for name in CASES:
        source = case_export(tmp_path_factory, name, CASES[name], precision)
        result = subprocess.run(["cc", *STRICT, "-fPIC", "-shared", "-Wl,--no-undefined", str(source), "-lm",
                                 "-o", str(tmp_path / f"lib{name}.so")], capture_output=True, text=True)
        if result.returncode != 0:
            failed[name] = result.stderr[:600]
    assert not failed, failed


def test_family_has_linkages_that_wrap_angles_without_a_phase() -> None:
    """The shape the link test above needs: in single precision, angles to
    wrap and no term linear in t (else `_frac` is defined for the phases)."""
    from symid.codegen.model import code_model
    from symid.codegen import c as c_target

    for name in ("two_r_arm", "scissor_lift"):
        ctx = c_target.context(code_model(mechanism(name)), True, "single")
        assert ctx.phase.wraps and not ctx.phase.phases, name


@needs_cc
@pytest.mark.parametrize("name", first_quick(["pendulum", "only_q", "kinematics_q_only", "statics_q_and_one_reaction",
                                              "lambda_only", "numbers"], keep=2))  # the quick tier: every output and one
def test_casadi_c_of_small_mechanism_compiles(name: str, tmp_path: Path) -> None:
    """CasADi's own C for the shapes that leave groups out. Its fixed calling
    convention f(arg, res, iw, w, mem) leaves parameters unused: the only
    warning allowed."""
    from symid.codegen.model import code_model
    from symid.codegen.targets import casadi_target

    source = [p for p in casadi_target.casadi_c(code_model(mechanism(name)), tmp_path) if p.suffix == ".c"][0]
    result = subprocess.run(["cc", *STRICT, "-Wno-unused-parameter", "-fPIC", "-c", str(source), "-o",
                             str(tmp_path / "x.o")], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr


def test_subsets_give_the_columns_asked_for() -> None:
    """The subset cases really are subsets: the comparison above is of the
    header the contract gives them."""
    assert reference("only_q").columns == ["t", "bar.x", "bar.y", "bar.phi"]
    assert reference("one_reaction").columns == ["t"] + [f"slot.{f}_{s}" for s in "ij" for f in ("Fx", "Fy", "T")]
    statics = reference("statics_q_and_one_reaction").columns
    assert statics[:7] == ["t", "crank.x", "crank.y", "crank.phi", "yoke.x", "yoke.y", "yoke.phi"]
    assert statics[7:] == [f"guide.{f}_{s}" for s in "ij" for f in ("Fx", "Fy", "T")]
    assert reference("kinematics_q_only").columns == ["t"] + [f"{b}.{c}" for b in ("pinion", "wheel")
                                                              for c in ("x", "y", "phi")]


@pytest.mark.slow  # a cold c build and a bench run; the small mechanisms' agreement on c stays in the quick tier
@needs_cc
def test_driven_pendulum_solves_on_c_from_the_command_line(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                           capsys: pytest.CaptureFixture[str]) -> None:
    """The case first reported: `symid solve --backend c` on a pendulum (a
    fresh cache, so the solver is compiled), then `symid bench`."""
    monkeypatch.setenv("SYMID_CACHE", str(tmp_path / "cache"))
    path = tmp_path / "pendulum.toml"
    path.write_text(CASES["pendulum"])
    out = tmp_path / "pendulum.csv"
    assert main(["solve", str(path), "--backend", "c", "-o", str(out)]) == 0
    data = np.loadtxt(out, delimiter=",", skiprows=1)
    # both solve the same equations to tol 1e-12: rounding of the run's largest value
    assert np.max(np.abs(data - reference("pendulum").data)) <= 1e-12 * np.max(np.abs(data))
    assert main(["bench", str(path), "--budget", "1"]) == 0
    assert "Traceback" not in capsys.readouterr().err


@needs_cc
def test_emitted_makefile_builds_a_small_mechanism(tmp_path: Path) -> None:
    api.generate(mechanism("three_coordinates"), "c", tmp_path)
    subprocess.run(["make", "-C", str(tmp_path)], check=True, capture_output=True)
    assert (tmp_path / "libthree_coordinates_solver.so").stat().st_size > 0


def _fake_compiler(folder: Path, script: str) -> str:
    path = folder / "fakecc"
    path.write_text("#!/bin/sh\n" + script)
    path.chmod(path.stat().st_mode | stat.S_IXUSR)
    return str(path)


COMPILERS = {
    # CC value (or a script), what the one line must say
    "false": ("false", "the C compiler false failed on the generated solver: exit status 1"),
    "missing": ("/nonexistent/cc", "the C compiler CC=/nonexistent/cc was not found"),
    "errors": ("echo 'x.c:3:1: warning: w' >&2; echo 'x.c:7:2: error: no way' >&2; echo 'x.c:9:1: error: b' >&2;"
               " exit 1", "failed on the generated solver: x.c:7:2: error: no way"),
    "no_output": ("exit 0", "reported success but wrote no solver.so"),
    "unbalanced": ("'cc", "the C compiler CC='cc is not a command line: No closing quotation"),
}


@pytest.mark.skipif(shutil.which("sh") is None, reason="no shell")
@pytest.mark.parametrize("command", ("solve", "bench"))
@pytest.mark.parametrize("case", COMPILERS)
def test_failing_compiler_is_one_line_and_exit_2(case: str, command: str, tmp_path: Path,
                                                  monkeypatch: pytest.MonkeyPatch,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    cc, says = COMPILERS[case]
    if case in ("errors", "no_output"):
        cc = _fake_compiler(tmp_path, cc)
    monkeypatch.setenv("CC", cc)
    monkeypatch.setenv("SYMID_CACHE", str(tmp_path / "cache"))
    path = tmp_path / "pendulum.toml"
    path.write_text(CASES["pendulum"])
    out = tmp_path / "pendulum.csv"
    argv = ["solve", str(path), "--backend", "c", "-o", str(out)] if command == "solve" else ["bench", str(path)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("symid: --backend c: ") and says in err, err
    assert not out.exists()
    # nothing half-built is left to be loaded by the next run
    assert not [p for p in (tmp_path / "cache").glob("*") if (p / "complete").exists()]


def test_runtime_compile_does_not_turn_warnings_into_errors() -> None:
    """A user's run never depends on what a compiler warns about: the flags
    of the runtime build have no -Werror (the strict tests above keep it)."""
    from symid.backends.c_backend import CFLAGS

    assert not [f for f in CFLAGS if f.startswith("-Werror")]
    makefile = (Path(__file__).resolve().parents[2] / "templates/c/Makefile.j2").read_text()
    assert "-Werror" not in makefile


NUMBERS = [sp.Integer(10**18), sp.Integer(981 * 10**16), sp.Integer(-2**70), sp.Integer(2**53 + 1),
           sp.Rational(10**25, 3), sp.Rational(1, 10**320), sp.Rational(5, 10**324), sp.Rational(-7, 10**330),
           sp.Rational(17976931348623157 * 10**292), sp.Float("1e308"), sp.Float("1e-320"), sp.Rational(3, 7),
           sp.Integer(12345678901234567890123)]


@needs_cc
def test_numbers_of_every_magnitude_print_as_c_doubles_of_their_value(tmp_path: Path) -> None:
    """Each literal, compiled strictly and printed back by C, is the double
    nearest the exact number (0 below the subnormals, +-inf past the top)."""
    from symid.codegen.c import ccode

    lines = "".join(f'    printf("%.17g\\n", (double)({ccode(x)}));\n' for x in NUMBERS)
    (tmp_path / "n.c").write_text(f"#include <math.h>\n#include <stdio.h>\nint main(void)\n{{\n{lines}    return 0;\n}}\n")
    subprocess.run(["cc", *STRICT, str(tmp_path / "n.c"), "-o", str(tmp_path / "n"), "-lm"], check=True)
    printed = subprocess.run([str(tmp_path / "n")], capture_output=True, text=True, check=True).stdout.split()
    assert [float(v) for v in printed] == [float(Fraction(int(x.p), int(x.q))) if x.is_Rational else float(x)
                                           for x in NUMBERS]


@needs_cc
def test_compiler_with_arguments_is_run_as_make_would(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("CC", f"{shutil.which('cc') or shutil.which('gcc')} -O0")
    monkeypatch.setenv("SYMID_CACHE", str(tmp_path / "cache"))
    assert_same_table(api.solve(mechanism("pendulum"), backend="c"), reference("pendulum"))
