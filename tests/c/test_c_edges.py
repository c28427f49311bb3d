"""The C export's sharp edges (issue 30, point 3): no double in a single
build, fast-math refused, no pointer arithmetic on NULL, the caller's q kept
by a failed instant, the real type, the iteration cap and the tolerance
floor overridable, and a stated worst-case instruction count per call."""

from __future__ import annotations

import re
import shutil
import subprocess
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest

from cbuild import HOST_O2, M4F, WARNINGS, example_export, object_file
from csolver import slider_crank_mode
from symid import api
from symid.codegen.model import code_model
from symid.codegen import c as c_target
from symid.io.reader import load, loads

pytestmark = pytest.mark.slow  # cross-compiles for Cortex-M, runs cppcheck and callgrind on every example

ROOT = Path(__file__).resolve().parents[2]
DRIVER = ROOT / "tests" / "c" / "instant_driver.c"
EXAMPLES = tuple(api.examples())
OK, NOT_CONVERGED = 0, 1
# what a single build must not reference: the EABI's double helpers (__aeabi_dadd,
# __aeabi_f2d ...) and libm's double functions (sin where sinf is meant)
DOUBLE_LIBM = {"sin", "cos", "tan", "exp", "log", "sqrt", "atan2", "atan", "asin", "acos", "tanh", "sinh",
               "cosh", "pow", "fabs", "fmax", "fmin", "floor", "ceil", "fmod", "round", "trunc"}


def _generate(folder: Path, example: str, precision: str, text: str | None = None) -> Path:
    model = code_model(loads(text, f"{example}.toml") if text else load(api.example(example)))
    c_target.generate(model, folder, precision=precision)
    return folder / f"{model.name}_solver.c"


@pytest.fixture(scope="module")
def singles(tmp_path_factory) -> dict[str, Path]:
    """Every example's single export (the run's shared ones: read, never written to)."""
    return {name: example_export(tmp_path_factory, name).source("single") for name in EXAMPLES}


def _exe(source: Path, defines: tuple[str, ...], out: Path | None) -> Path:
    """Where _driver puts its program: in out (else beside the source), named by the defines."""
    return (out or source.parent) / ("drv" + "".join("_" + re.sub(r"\W", "", d) for d in defines))


def _driver(source: Path, *defines: str, cc: str = "cc", out: Path | None = None,
            obj: Path | None = None) -> subprocess.CompletedProcess[str]:
    """instant_driver.c built with the solver at `source` and -D defines (the
    exe in _exe's place); with `obj`, the solver's object compiled without
    defines (the run's shared HOST_O2 one, whose flags hold these) instead
    of the source: the solver reads none of the driver's macros."""
    name = source.name.removesuffix("_solver.c")
    exe = _exe(source, defines, out)
    return subprocess.run([cc, *WARNINGS, "-O2", f"-I{source.parent}", f'-DSOLVER_H="{name}_solver.h"',
                           f"-DP={name}", f"-DPU={name.upper()}", *defines, str(DRIVER), str(obj or source), "-lm",
                           "-o", str(exe)], capture_output=True, text=True)


def _calls(source: Path, *groups: tuple[float, float], q0, defines: tuple[str, ...] = (),  # type: ignore[no-untyped-def]
           out: Path | None = None, share: pytest.TempPathFactory | None = None) -> list[tuple]:
    """Each (t, tol) an instant call, the first from q0, each next from the q
    the one before left: per call (status, iterations, fallback, q); the
    program in out (else beside the source). With `share` and no defines the
    solver is the run's shared HOST_O2 object of the source (object_file)."""
    assert set(WARNINGS) | {"-O2"} <= set(HOST_O2)  # the object is built at least as strictly as the source was
    obj = object_file(share, HOST_O2, source) if share is not None and not defines else None
    built = _driver(source, *defines, out=out, obj=obj)
    assert built.returncode == 0, built.stderr[:3000]
    exe = _exe(source, defines, out)
    args = [repr(groups[0][0]), repr(groups[0][1]), *(repr(float(v)) for v in q0)]
    for t, tol in groups[1:]:
        args += ["--", repr(t), repr(tol)]
    out = subprocess.run([str(exe), *args], check=True, capture_output=True, text=True).stdout.splitlines()
    return [(int(s), int(i), int(d), np.array(q, float)) for s, i, d, *q in (line.split() for line in out)]


# --- no double in a single build ---


def test_single_source_names_no_double_and_builds_with_double_promotion_an_error(singles, tmp_path_factory) -> None:
    """The host gcc with -Wdouble-promotion -Werror (every implicit float to
    double), and no `double` in the code (an explicit cast is not warned).
    The build is the run's shared host object (HOST_O2: WARNINGS, which hold
    -Wdouble-promotion and -Werror, with -Wfloat-conversion at -O2), the one
    the single-precision rows driver links."""
    if shutil.which("gcc") is None or shutil.which("cc") is None:
        pytest.skip("gcc is not installed: the host single-precision build is not checked")
    assert {"-Wdouble-promotion", "-Wfloat-conversion", "-Werror", "-O2"} <= set(HOST_O2)
    for name, source in singles.items():
        code = re.sub(r"/\*.*?\*/", "", source.read_text() + source.with_suffix(".h").read_text(), flags=re.S)
        assert not re.search(r"\bdouble\b", code), name
    with ThreadPoolExecutor(max_workers=2) as pool:  # two at a time: CI has two cores
        objects = list(pool.map(lambda source: object_file(tmp_path_factory, HOST_O2, source), singles.values()))
    assert all(o.is_file() for o in objects)


def test_every_single_build_links_for_a_cortex_m4f_without_double_helpers(singles, tmp_path_factory,
                                                                         tmp_path: Path) -> None:
    """Each example's single export compiled for a Cortex-M4F (single-precision
    FPU: a double would be a call to the EABI's soft-float helpers) and linked
    with newlib into a program calling instant, trajectory and sweep: no
    __aeabi_d* nor double libm referenced by the object, none in the program,
    and no double-precision instruction. The object is the run's shared one
    (the strict M4F build's and the emulated run's: same flags)."""
    for tool in ("arm-none-eabi-gcc", "arm-none-eabi-nm", "arm-none-eabi-objdump"):
        if shutil.which(tool) is None:
            pytest.skip(f"{tool} is not installed (.ci/run installs gcc-arm-none-eabi where apt-get may): "
                        "the single build's double helpers are not checked")
    specs = subprocess.run(["arm-none-eabi-gcc", "-print-file-name=nosys.specs"], capture_output=True,
                           text=True).stdout.strip()
    if not Path(specs).is_file():
        pytest.skip("newlib for arm-none-eabi is not installed (.ci/run installs libnewlib-arm-none-eabi): "
                    "the single build is not linked")

    def one(item: tuple[str, Path]) -> str:
        name, source = item
        main = tmp_path / f"{name}_main.c"
        main.write_text(f'#include "{name}_solver.h"\n'
                        f"static {name}_real work[{name.upper()}_SWEEP_WORK], state[{name.upper()}_STATE], "
                        f"rows[{name.upper()}_ROW], fig[{name.upper()}_SWEEP_FIGURES + 1], t_end[1];\n"
                        f"static {name}_real q[{name.upper()}_NG];\n"
                        f"static int iwork[{name.upper()}_IWORK], status[1];\n"
                        "static long solved[1];\n"
                        "int main(void)\n{\n"
                        f"    int s = {name}_instant(0.1f, {name}_default_params, 1e-5f, q, 0, 0, 0, 0, 0, work, iwork);\n"
                        f"    s += {name}_trajectory(0.0f, 1e-3f, 1, {name}_default_params, 1e-5f, state, rows, 0, "
                        "work, iwork);\n"
                        f"    s += {name}_sweep(1, {name}_default_params, 0.0f, 1e-3f, 2, 1e-5f, fig, status, t_end, "
                        "solved, work, iwork);\n"
                        "    return s;\n}\n")
        elf = tmp_path / f"{name}.elf"
        obj = object_file(tmp_path_factory, ["arm-none-eabi-gcc", *WARNINGS, *M4F, "-O2"], source)
        flags = ["arm-none-eabi-gcc", *WARNINGS, *M4F, "-O2", f"-I{source.parent}"]
        undefined = set(subprocess.run(["arm-none-eabi-nm", "-u", str(obj)], check=True, capture_output=True,
                                       text=True).stdout.split()) - {"U"}
        bad = {s for s in undefined if s.startswith(("__aeabi_d", "__aeabi_f2d", "__aeabi_l2d", "__aeabi_i2d"))
               or s in DOUBLE_LIBM}
        assert not bad, (name, sorted(bad))
        linked = subprocess.run([*flags, str(main), str(obj), "--specs=nosys.specs", "-lm", "-o", str(elf)],
                                capture_output=True, text=True)
        assert linked.returncode == 0, (name, linked.stderr[:2000])
        symbols = subprocess.run(["arm-none-eabi-nm", str(elf)], check=True, capture_output=True, text=True).stdout
        helpers = sorted(set(re.findall(r"\b__aeabi_(?:d\w+|f2d|i2d|ui2d|l2d)\b", symbols)))
        assert not helpers, (name, helpers)
        code = subprocess.run(["arm-none-eabi-objdump", "-d", str(elf)], check=True, capture_output=True,
                              text=True).stdout
        assert not re.search(r"\tv\w+\.f64\b", code), name
        return name

    with ThreadPoolExecutor(max_workers=2) as pool:
        assert sorted(pool.map(one, singles.items())) == sorted(EXAMPLES)


def test_single_nu_in_float_float_keeps_the_phase_of_double(tmp_path: Path) -> None:
    """The excavator's phase nu = 1/T, now float-float instead of double: its
    (hi, lo) pair is 1/T to ~1e-14 (a float alone: 6e-8), checked through the
    function that prints it against the exact quotient."""
    from symid.codegen.c import phase as c_phase
    import sympy as sp

    T = sp.Symbol("p[0]", real=True)
    for nu, p0 in ((1 / T, 3.0), (sp.sqrt(T) / (2 * sp.pi), 7.0), ((T + sp.Rational(1, 3)) * T ** 2, 0.7)):
        lines = c_phase.nu_lines([nu], 1, 1, lambda e: sp.ccode(e))
        src = tmp_path / "nu.c"
        body = "\n    ".join(line.replace("{p}", "x") for line in lines)
        phase = (ROOT / "templates" / "c" / "phase.j2").read_text()
        fns = re.findall(r"(static void \{\{ p \}\}_(?:two_prod|ff_\w+)\(.*?\n\}\n)", phase, re.S)
        code = "\n".join(fns).replace("{{ p }}", "x").replace("{{ lm.sqrt }}", "sqrtf")
        src.write_text("#include <math.h>\n#include <stdio.h>\ntypedef float x_real;\n" + code +
                       "int main(void)\n{\n    const float p[1] = {" + repr(p0) + "f};\n    float pp[3];\n    "
                       + body + "\n    printf(\"%.17g %.17g\\n\", (double)pp[1], (double)pp[2]);\n    return 0;\n}\n")
        exe = tmp_path / "nu"
        subprocess.run(["cc", "-std=c99", "-O2", "-ffp-contract=off", str(src), "-lm", "-o", str(exe)], check=True)
        hi, lo = map(float, subprocess.run([str(exe)], check=True, capture_output=True, text=True).stdout.split())
        exact = sp.N(nu.subs(T, sp.Float(np.float32(p0), 30)), 30)
        # the docstring's ~1e-14 of a float-float pair, with a factor 10 of room
        assert abs(sp.Float(hi, 30) + sp.Float(lo, 30) - exact) <= 1e-13 * abs(exact), (nu, hi, lo, exact)
        assert np.float32(hi) == hi and abs(lo) <= abs(hi) * 2.0 ** -24  # a normalized pair of floats


# --- fast-math refused ---


@pytest.mark.parametrize("precision", ["double", "single"])
def test_fast_math_build_stops_with_an_error_naming_the_nan_guards(tmp_path: Path, tmp_path_factory,
                                                                   precision: str) -> None:
    if shutil.which("gcc") is None:
        pytest.skip("gcc is not installed: the fast-math refusal is not checked")
    source = example_export(tmp_path_factory, "slider_crank").source(precision)  # shared: the object goes to tmp_path
    base = ["gcc", *WARNINGS, "-O2", "-c", str(source), "-o", str(tmp_path / "s.o")]
    # without the flag it builds: the run's shared HOST_O2 object of this source (its flags hold base's)
    assert set(base[1:-4]) <= set(HOST_O2) and object_file(tmp_path_factory, ["gcc", *HOST_O2[1:]], source).is_file()
    for flag in ("-ffast-math", "-ffinite-math-only"):
        built = subprocess.run([*base, flag], capture_output=True, text=True)
        assert built.returncode != 0 and "needs IEEE floating point" in built.stderr, (flag, built.stderr[:500])
        assert "NaN guards" in built.stderr


# --- no pointer arithmetic on NULL ---


def _preprocessed(path: Path, *defines: str) -> str:
    """cppcheck -E of path (its own preprocessor, headers beside it) with -D defines, blanks collapsed."""
    out = subprocess.run(["cppcheck", "-E", *(f"-D{d}" for d in defines), str(path)], capture_output=True, text=True)
    return " ".join(out.stdout.split()) + (" #error" if "#error" in out.stderr else "")


# what the double exports' configurations past the first hold: cppcheck checks a
# source once per combination of the macros its #ifs test, and the double
# exports have 4: the first (none defined, the one checked), <P>_REAL, __GNUC__
# and __FAST_MATH__ / __FINITE_MATH_ONLY__
DOUBLE_CONFIGS = 4


def _other_configs_hold_nothing_new(path: Path) -> None:
    """The configurations cppcheck would check after the first add no code to
    check: __GNUC__'s text is the first's with the cold functions'
    `__attribute__((noinline, cold))`, which cppcheck's tokenizer drops (the
    token lists of both, in a --dump of all configurations, are the same:
    its second analysis reports what the first does); <P>_REAL's is the first's
    with `typedef 1 <p>_real;`, which does not parse (cppcheck drops such a
    configuration unreported when the first parses: a --dump of all holds no
    analysis of it); __FAST_MATH__ stops at the #error (not checked)."""
    name = path.name.removesuffix("_solver.c")
    first = _preprocessed(path)
    cold = " __attribute__ ( ( noinline , cold ) )"
    gnuc = _preprocessed(path, "__GNUC__")
    assert cold in gnuc and gnuc.replace(cold, "") == first, path.name
    typedef = f"typedef double {name}_real ;"
    real = _preprocessed(path, f"{name.upper()}_REAL")
    assert first.count(typedef) == 1 and re.sub(r"#line \d+ \S+ ", "", real) == \
        re.sub(r"#line \d+ \S+ ", "", first.replace(typedef, f"typedef 1 {name}_real ;")), path.name
    assert _preprocessed(path, "__FAST_MATH__").endswith("#error"), path.name


def test_cppcheck_finds_nothing_in_any_generated_solver(singles) -> None:
    """cppcheck --enable=warning on every example's solver in both
    precisions: the sweep formed work + WORK before checking work for NULL.

    Each in its first configuration only (--max-configs=1, half of cppcheck's
    time): the double exports' other configurations add no code to check
    (_other_configs_hold_nothing_new, by cppcheck's preprocessor: milliseconds),
    and the single exports' #ifdef branches are the double ones' text with
    another real type."""
    if shutil.which("cppcheck") is None:
        pytest.skip("cppcheck is not installed (.ci/run installs it where apt-get may): the generated C is not "
                    "checked for pointer arithmetic on NULL")
    files = [ROOT / "generated" / n / "c" / f"{n}_solver.c" for n in EXAMPLES
             if (ROOT / "generated" / n / "c").is_dir()] + list(singles.values())

    singles_ = set(singles.values())
    too_many = re.compile(r"^\S+: information: Too many #ifdef configurations - cppcheck only checks 1 of (\d+) "
                          r"configurations\..*\[toomanyconfigs\]\n(?:\n\^\n)?", re.M)  # its line, its empty excerpt

    def one(path: Path) -> str:
        if path in singles_:
            configs = ["--enable=warning", "--suppress=toomanyconfigs"]
        else:  # information: the count of configurations (the system headers are not followed)
            configs = ["--enable=warning,information", "--suppress=missingIncludeSystem"]
        found = subprocess.run(["cppcheck", *configs, "--max-configs=1", "--quiet", str(path)],
                               capture_output=True, text=True).stderr
        if path not in singles_:
            counted = too_many.search(found)
            assert counted is not None and int(counted.group(1)) == DOUBLE_CONFIGS, (path.name, found[:2000])
            found = too_many.sub("", found, count=1)
            _other_configs_hold_nothing_new(path)
        return found

    with ThreadPoolExecutor(max_workers=2) as pool:
        for path, findings in zip(files, pool.map(one, files)):
            assert not findings.strip(), (path.name, findings[:2000])


# --- a failed instant keeps the caller's q ---


@pytest.mark.parametrize("precision, tol, close", [("double", 1e-12, 1e-12), ("single", 1e-5, 2e-6)])
def test_failed_instant_leaves_the_callers_q_and_the_next_call_solves(tmp_path: Path, precision: str, tol: float,
                                                                     close: float) -> None:
    """A slider-crank whose rod (0.05 m) is shorter than its crank (0.1 m):
    at crank angle pi/2 the rod cannot reach the guide (an unreachable
    position, NOT_CONVERGED); q comes back as passed, and a call at
    t = 0.01 s (angle 0.1 pi, reachable) from it solves to the closed form."""
    text = api.example("slider_crank").read_text().replace("L_rod = 0.3 ", "L_rod = 0.05", 1)
    source = _generate(tmp_path, "slider_crank", precision, text)
    q0 = slider_crank_mode(0.0, 1.0, 0.1, 0.05)
    (s1, it1, _, q1), (s2, _, _, q2) = _calls(source, (0.05, tol), (0.01, tol), q0=q0)
    assert s1 == NOT_CONVERGED and it1 == 50
    assert np.array_equal(q1, q0.astype(np.float32 if precision == "single" else float))
    assert s2 == OK
    truth = slider_crank_mode(2 * np.pi * 5 * 0.01, 1.0, 0.1, 0.05)  # omega = 2 pi n, n = 5
    assert np.max(np.abs(q2 - truth)) <= close  # single: a few ulps of 0.3 rad


# --- overrides: the cap, the floor, the type ---


@pytest.mark.parametrize("precision, tol", [("double", 1e-12), ("single", 1e-5)])
def test_max_newton_and_floor_overrides_take_effect(tmp_path: Path, tmp_path_factory, precision: str,
                                                    tol: float) -> None:
    """From a guess 1e-3 off at t = 0.01 s: the default needs >= 3 Newton
    iterations (single, to 1e-5: 2) and solves to the closed form; MAX_NEWTON=1 makes the same
    call NOT_CONVERGED after one; a tolerance floor of 1e13 ulps (2e-3 in
    double) accepts the first correction (error ~1e-6, quadratic from 1e-3).
    The source is the example's export (the run's shared one, read only)."""
    source = example_export(tmp_path_factory, "slider_crank").source(precision)
    truth = slider_crank_mode(2 * np.pi * 5 * 0.01, 1.0)
    guess = truth + 1e-3
    floor = "1e13" if precision == "double" else "1e4"  # 2.2e-3 and 1.2e-3: above the guess's residual
    (status, iterations, _, q), = _calls(source, (0.01, tol), q0=guess, out=tmp_path, share=tmp_path_factory)
    assert status == OK and iterations >= (3 if precision == "double" else 2)  # single: 1e-5 after two
    assert np.max(np.abs(q - truth)) <= (1e-12 if precision == "double" else 2e-6)
    (status, iterations, _, q), = _calls(source, (0.01, tol), q0=guess, defines=("-DSLIDER_CRANK_MAX_NEWTON=1",),
                                         out=tmp_path)
    assert (status, iterations) == (NOT_CONVERGED, 1)
    assert np.array_equal(q, guess.astype(np.float32 if precision == "single" else float))  # kept, as failed
    (status, iterations, _, q), = _calls(source, (0.01, tol), q0=guess,
                                         defines=(f"-DSLIDER_CRANK_FLOOR_ULPS={floor}",), out=tmp_path)
    error = np.max(np.abs(q - truth))
    # the docstring's first correction, ~1e-6 (quadratic from 1e-3): above a converged error, below the guess's
    assert status == OK and iterations == 1 and 1e-8 < error < 1e-4, (iterations, error)


@pytest.mark.parametrize("precision", ["double", "single"])
def test_real_type_override_takes_a_same_size_typedef_and_refuses_another_size(tmp_path: Path, tmp_path_factory,
                                                                               precision: str) -> None:
    source = example_export(tmp_path_factory, "slider_crank").source(precision)  # shared: the programs go to tmp_path
    real = "double" if precision == "double" else "float"
    (tmp_path / "mine.h").write_text(f"typedef {real} my_real;\n")
    guess = slider_crank_mode(0.3, 1.0) + 1e-3
    tol = 1e-12 if precision == "double" else 1e-5
    plain = _calls(source, (0.01, tol), q0=guess, out=tmp_path, share=tmp_path_factory)
    mine = _calls(source, (0.01, tol), q0=guess, defines=("-include", str(tmp_path / "mine.h"),
                                                          "-DSLIDER_CRANK_REAL=my_real"), out=tmp_path)
    assert plain[0][:3] == mine[0][:3] == (OK, plain[0][1], 0) and np.array_equal(plain[0][3], mine[0][3])
    other = "float" if precision == "double" else "double"
    built = _driver(source, f"-DSLIDER_CRANK_REAL={other}", out=tmp_path)
    assert built.returncode != 0 and f"slider_crank_real_must_have_the_size_of_{real}" in built.stderr
    header = source.with_suffix(".h").read_text()
    assert "#ifdef SLIDER_CRANK_REAL\n" in header
    for macro in ("MAX_NEWTON", "FLOOR_ULPS"):
        assert f"#ifndef SLIDER_CRANK_{macro}\n" in header, macro


# --- the worst case per call, stated and kept ---


@pytest.mark.parametrize("precision", ["double", "single"])
def test_worst_case_instructions_stated_and_a_capped_call_stays_under_them(singles, tmp_path_factory,
                                                                          tmp_path: Path, precision: str) -> None:
    """Every example: the header states WORST_INSTRUCTIONS (fixed + per
    iteration times the cap); a call that cannot meet its tolerance (floor 0,
    tol 1e-30: Newton runs to the cap unless it lands on an exact zero)
    counted by callgrind on the host stays under it."""
    if shutil.which("valgrind") is None:
        pytest.skip("valgrind is not installed: the stated worst case is not measured")
    root = tmp_path
    # single precision's count has the same form (fixed + per iteration x cap):
    # checked on the slider-crank, Andrews' squeezer (the most coordinates) and
    # the excavator (the longest instant); double on every example
    for name in EXAMPLES if precision == "double" else ("slider_crank", "andrews_squeezer", "excavator"):
        export = example_export(tmp_path_factory, name)  # shared: the programs go to tmp_path
        source = export.source(precision)
        header = source.with_suffix(".h").read_text()
        m = re.search(rf"#define {name.upper()}_WORST_INSTRUCTIONS \((\d+)L \+ (\d+)L \* \(long\)"
                      rf"{name.upper()}_MAX_NEWTON\)", header)
        cap = int(re.search(rf"#define {name.upper()}_MAX_NEWTON (\d+)", header).group(1))
        assert m is not None, name
        bound = int(m.group(1)) + cap * int(m.group(2))
        defines = (f"-D{name.upper()}_FLOOR_ULPS=0",)
        built = _driver(source, *defines, out=tmp_path)
        assert built.returncode == 0, built.stderr[:2000]
        exe = _exe(source, defines, tmp_path)
        args = [repr(export.t0 + 0.37 * (export.t1 - export.t0)), "1e-30", *(repr(float(v) + 1e-3) for v in export.q0)]
        run = subprocess.run(["valgrind", "--tool=callgrind", f"--callgrind-out-file={root / (name + '.cg')}",
                              f"--toggle-collect={name}_instant", str(exe), *args],
                             capture_output=True, text=True, check=True)
        refs = int(re.search(r"refs:\s*([\d,]+)", run.stderr).group(1).replace(",", ""))
        assert 0 < refs <= bound, (name, refs, bound, run.stdout.split()[:3])


# --- the header's parameter list is true ---


def test_friction_parameters_are_read_and_the_header_says_so(tmp_path: Path, tmp_path_factory) -> None:
    """The bundled friction example's coefficients, pin radii and viscous
    drags were listed as read by nothing: each set to NaN now makes an
    instant NONFINITE (it is read), and the header lists none as unread."""
    from csolver import NONFINITE, Solver

    if shutil.which("cc") is None:
        pytest.skip("no C compiler")
    solver = Solver(api.example("slider_crank_friction"), tmp_path, share=tmp_path_factory)  # its export's object
    header = (tmp_path / f"{solver.name}_solver.h").read_text()
    assert "read by nothing" not in header.lower()
    for name in ("mu_pin", "mu_guide", "r_main", "r_crank_pin", "r_wrist", "c_main", "c_guide"):
        k = solver.ctx.params.index(name)
        saved = solver.p.copy()
        solver.p[k] = np.nan
        try:
            assert solver.instant()[0] == NONFINITE, name
        finally:
            solver.p = saved
    assert solver.instant()[0] == OK
