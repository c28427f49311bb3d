"""The C solver's trajectory state and work vectors are laid out once, in
`symid.codegen.c.layout`: the header's `<NAME>_STATE_<PART>` macros, the
.c's `<NAME>_VEC_<NAME>` macros and the build's meta.json (which the Python
hand-back reads) all say what it says, and the compiled trajectory keeps its
history where they say it is."""

from __future__ import annotations

import ctypes
import dataclasses
import json
import re
import subprocess
from pathlib import Path

import numpy as np
import pytest

from symid import api
from symid.backends.c_backend import CEvaluator, build
from symid.codegen import c as c_target
from symid.codegen.c.layout import STATE_PARTS, VECTORS, state_layout, vectors
from symid.codegen.model import code_model, options_for
from symid.symbolic.assemble import assemble
from cbuild import STRICT, needs_cc

GENERATED = Path(__file__).resolve().parents[2] / "generated"
DP = ctypes.POINTER(ctypes.c_double)


def macros(text: str, prefix: str) -> dict[str, int]:
    """`#define <prefix>X n` of a C file: X -> n (integers only)."""
    return {m[1]: int(m[2]) for m in re.finditer(rf"^#define {prefix}(\w+) (-?\d+)\b", text, re.M)}


def header_layout(text: str, P: str) -> dict[str, list[int]]:
    """The state's parts as the header's macros give them: name -> [offset, size]."""
    found = macros(text, f"{P}_STATE_")
    return {name.lower(): [found[name], found[f"{name}_SIZE"]] for name in found if not name.endswith("_SIZE")}


@pytest.mark.parametrize("example", sorted(p.parent.name for p in GENERATED.glob("*/c")))
def test_the_committed_headers_state_the_python_layout(example: str) -> None:
    """Each committed solver's header gives the state's parts at the offsets
    and sizes of the Python layout, and they are the header's documented
    contract: q first (the initial guess, state[0..NG-1]), the jump check's
    scales at 6 NG, the screen's row norms at 7 NG, the count (two reals) last; the parts
    tile STATE reals without a gap or an overlap. Its .c numbers the work
    vectors as the layout does."""
    folder = GENERATED / example / "c"
    header = (folder / f"{example}_solver.h").read_text()
    P = example.upper()
    sizes = macros(header, f"{P}_")
    ng, state = sizes["NG"], sizes["STATE"]
    got = header_layout(header, P)
    assert got == state_layout(ng).to_json()
    assert [name for name, _ in STATE_PARTS] + ["count"] == list(got)  # the header's order is the layout's
    assert got["q"] == [0, ng] and got["scale"] == [6 * ng, ng] and got["rscale"] == [7 * ng, ng]
    assert got["count"] == [state - 2, 2]  # the rest and the multiples of 2^24 (layout.COUNT_CARRY)
    ends = [0] + [o + n for o, n in got.values()]
    assert [o for o, _ in got.values()] == ends[:-1] and ends[-1] == state
    vec = macros((folder / f"{example}_solver.c").read_text(), f"{P}_VEC_")
    assert vec == {s.name.upper(): s.offset for s in vectors()}
    assert list(vec.values()) == list(range(len(VECTORS)))  # VEC(work, k): the k-th vector


def _compile(folder: Path, name: str) -> ctypes.CDLL:
    subprocess.run(["cc", *STRICT, "-fPIC", "-shared", str(folder / f"{name}_solver.c"), "-o", str(folder / "s.so"),
                    "-lm"], check=True)
    return ctypes.CDLL(str(folder / "s.so"))


def _solver(tmp_path: Path, kind: str) -> tuple[ctypes.CDLL, str, dict[str, int], dict[str, list[int]], np.ndarray]:
    """The slider-crank's solver generated for `kind`, compiled: (library,
    name, its header's sizes, its header's state layout, its parameters)."""
    mech = api.load_mechanism(api.example("slider_crank"))
    options = options_for(mech)
    if kind == "statics":
        options = dataclasses.replace(options, kind="statics",
                                      outputs=tuple(g for g in options.outputs if g not in ("qdot", "qddot")))
    model = code_model(mech, options)
    c_target.generate(model, tmp_path)
    header = (tmp_path / "slider_crank_solver.h").read_text()
    return (_compile(tmp_path, "slider_crank"), "slider_crank", macros(header, "SLIDER_CRANK_"),
            header_layout(header, "SLIDER_CRANK"), np.array(model.flat.defaults, dtype=float))


def _trajectory(lib: ctypes.CDLL, sizes: dict[str, int], params: np.ndarray, calls: list[int]) -> tuple[np.ndarray,
                                                                                                       np.ndarray]:
    """The trajectory from the default q0 at h = 1 ms in calls of the given
    numbers of instants: (its rows, the state after)."""
    ng = sizes["NG"]
    fn = lib.slider_crank_trajectory
    fn.argtypes = [ctypes.c_double, ctypes.c_double, ctypes.c_long, DP, ctypes.c_double, DP, DP,
                   ctypes.POINTER(ctypes.c_long), DP, ctypes.POINTER(ctypes.c_int)]
    q0 = np.ctypeslib.as_array((ctypes.c_double * ng).in_dll(lib, "slider_crank_default_q0")).copy()
    work, iwork = np.zeros(sizes["WORK"]), np.zeros(ng, dtype=np.intc)
    state = np.zeros(sizes["STATE"])
    state[:ng] = q0  # the header's contract: the guess in state[0..NG-1], the count (last) 0
    rows = np.zeros((sum(calls), sizes["ROW"]))
    solved, done = ctypes.c_long(0), 0
    for n in calls:
        status = fn(0.0, 1e-3, n, params.ctypes.data_as(DP), 1e-10, state.ctypes.data_as(DP),
                    rows[done:].ctypes.data_as(DP), ctypes.byref(solved), work.ctypes.data_as(DP),
                    iwork.ctypes.data_as(ctypes.POINTER(ctypes.c_int)))
        assert status == 0 and solved.value == n
        done += n
    return rows, state


@needs_cc
@pytest.mark.parametrize("kind", ["inverse_dynamics", "statics"])
def test_the_compiled_trajectory_keeps_its_history_where_the_header_says(tmp_path: Path, kind: str) -> None:
    """After 10 instants in calls of 1, 4 and 5 (the history crosses calls),
    the state read at the header's offsets holds the last instant's q, qd,
    qdd (from its row: t, then the groups in contract order), the three
    accelerations before it (statics: the two positions before it) and the
    count 10."""
    lib, _, sizes, at, params = _solver(tmp_path, kind)
    ng = sizes["NG"]
    rows, state = _trajectory(lib, sizes, params, [1, 4, 5])
    part = {name: state[o:o + n] for name, (o, n) in at.items()}
    q = rows[:, 1:1 + ng]
    assert np.array_equal(part["q"], q[-1]) and part["count"][0] == 10.0
    if kind == "statics":
        history = {"m1": q[-2], "m2": q[-3]}
    else:
        qd, qdd = rows[:, 1 + ng:1 + 2 * ng], rows[:, 1 + 2 * ng:1 + 3 * ng]
        history = {"qd": qd[-1], "qdd": qdd[-1], "m1": qdd[-2], "m2": qdd[-3], "m3": qdd[-4]}
    for name, expected in history.items():
        assert np.array_equal(part[name], expected), name


@needs_cc
def test_the_python_hand_back_reads_the_layout_the_build_states() -> None:
    """The build's meta.json, from which CEvaluator takes its views of the
    state, holds the layout the generated header states."""
    mech = api.load_mechanism(api.example("slider_crank"))
    folder = build(assemble(mech), options_for(mech))
    meta = json.loads((folder / "meta.json").read_text())
    header = (GENERATED / "slider_crank" / "c" / "slider_crank_solver.h").read_text()
    assert meta["state_layout"] == header_layout(header, "SLIDER_CRANK")
    assert meta["state"] == macros(header, "SLIDER_CRANK_")["STATE"]


@needs_cc
def test_the_compiled_solver_reads_the_count_and_the_screens_scales_where_the_header_says(tmp_path: Path) -> None:
    """The trajectory takes its instant's index from the count at its
    offset (t = t0 + k h in the row), and the screen reads its row norms at
    theirs: spread by 1e12 there it trips (ILL_CONDITIONED, 6); the same
    numbers in the jump check's scales, the row norms left 0 (unset), it
    does not (OK, 0)."""
    lib, _, sizes, at, params = _solver(tmp_path, "inverse_dynamics")
    ng = sizes["NG"]
    rows, state = _trajectory(lib, sizes, params, [3])
    state[at["count"][0]] = 7.0
    work, iwork, solved, row = np.zeros(sizes["WORK"]), np.zeros(ng, dtype=np.intc), ctypes.c_long(0), \
        np.zeros(sizes["ROW"])
    status = lib.slider_crank_trajectory(0.0, 1e-3, 1, params.ctypes.data_as(DP), 1e-10, state.ctypes.data_as(DP),
                                         row.ctypes.data_as(DP), ctypes.byref(solved), work.ctypes.data_as(DP),
                                         iwork.ctypes.data_as(ctypes.POINTER(ctypes.c_int)))
    assert solved.value == 1 and row[0] == 7 * 1e-3 and state[at["count"][0]] == 8.0, status
    screen = lib.slider_crank_screen_at
    screen.argtypes = [ctypes.c_double, DP, DP, DP, ctypes.POINTER(ctypes.c_int)]
    spread = np.ones(ng)
    spread[0] = 1e12
    (so, sn), (ro, rn) = at["scale"], at["rscale"]
    for scale, rscale, expected in ((np.ones(ng), spread, 6), (spread, np.zeros(ng), 0)):
        state[so:so + sn], state[ro:ro + rn] = scale, rscale
        got = screen(0.0, params.ctypes.data_as(DP), state.ctypes.data_as(DP), work.ctypes.data_as(DP),
                     iwork.ctypes.data_as(ctypes.POINTER(ctypes.c_int)))
        assert got == expected


@needs_cc
def test_the_python_hand_back_sets_the_scales_where_the_header_says() -> None:
    """When symid's run of the compiled loop screens t0 (`_screen_at`), the
    state it hands over holds, at the header's offsets, q(t0) (the first
    row's), the count 1, the jump check's 1 / column scales and the screen's
    row norms of the Python loop's scaling at q(t0)."""
    study = api.prepare(api.example("slider_crank"), backend="c", steps=5)
    ev = study.evaluator
    assert isinstance(ev, CEvaluator)
    header = (GENERATED / "slider_crank" / "c" / "slider_crank_solver.h").read_text()
    at, size = header_layout(header, "SLIDER_CRANK"), macros(header, "SLIDER_CRANK_")["STATE"]
    seen: list[np.ndarray] = []
    real = ev._screen_at

    def spy(t: object, p: object, state: object, *rest: object) -> int:
        seen.append(np.ctypeslib.as_array(state, shape=(size,)).copy())  # type: ignore[arg-type]
        return int(real(t, p, state, *rest))

    ev._screen_at = spy  # type: ignore[method-assign]
    rows = np.vstack(list(ev.blocks(study.analysis, study.q0())))
    assert len(seen) == 1
    state = seen[0]
    part = {name: state[o:o + n] for name, (o, n) in at.items()}
    ng = macros(header, "SLIDER_CRANK_")["NG"]
    scaling = ev.scaling(rows[0, 1:1 + ng], study.analysis.t0)
    assert np.array_equal(part["q"], rows[0, 1:1 + ng]) and part["count"][0] == 1.0
    assert np.array_equal(part["scale"], scaling.inv_col)
    assert np.array_equal(part["rscale"], scaling.row)
