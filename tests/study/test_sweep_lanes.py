"""The compiled sweep's variants side by side in SIMD lanes (templates/c/lanes*.j2)
give every variant the figures, status, t_end and instants solved of its own
scalar run, bit for bit: one `<name>_sweep` call with K variants (groups of
W lanes, the remainder one by one) against K calls of one variant each (the
scalar path), for both widths the code has (4 lanes in AVX2 where the
processor has it, 2 in SSE2). The groups are checked to have stayed in the lanes, so that
the equality is not the scalar path's against itself."""

from __future__ import annotations

import ctypes
import math
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from symid import api
from symid.backends import c_backend
from symid.codegen.render import render
from symid.codegen.c import lanes as c_lanes
from symid.study import batch_c
from symid.study.variants import base_matrix, study_mechanism
from runshare import key_of, shared_dir
from tiers import first_quick

STEPS = 101  # crosses the scalar sweep's chunk boundaries (1, then 32 instants a call)

# per bundled example, two base parameters: the first's range (5 values), the second's 2 values
GRIDS = {
    "slider_crank": ("L_rod", (0.25, 0.45), "n", [2.0, 12.0]),
    "four_bar": ("L_coupler", (0.29, 0.31), "n", [1.0, 5.0]),
    "quick_return": ("L_link", (0.38, 0.42), "n", [0.5, 2.5]),
    "excavator": ("m_boom", (300.0, 400.0), "F_dig", [1000.0, 3000.0]),
    "planetary": ("m_sun", (0.4, 0.6), "n_in", [1.0, 4.0]),
    "slider_crank_counterweight": ("m_cw", (0.5, 1.5), "n", [0.5, 2.5]),
    "slider_pendulum": ("L_pendulum", (0.4, 0.6), "f_carriage", [0.5, 2.0]),
}

PENDULUM = """
[mechanism]
name = "lane_pendulum"
gravity = [0.0, -9.81]

[parameters]
L = 0.5
m = 1.0
f = 1.0

[analysis]
kind = "inverse_dynamics"
t0 = 0.0
t1 = 1.0
steps = 101

[[body]]
name = "rod"
mass = "m"
inertia = "m*L^2/12"
q0 = ["L/2", 0.0, 0.0]

[[constraint]]
name = "pivot"
type = "revolute"
i = "ground"
j = "rod"
si = [0.0, 0.0]
sj = ["-L/2", 0.0]

[[constraint]]
name = "motor"
type = "coordinate_driver"
body = "rod"
coordinate = "phi"
f = "0.8*sin(2*pi*f*t)"
"""

RAIL = """
[mechanism]
name = "lane_rail"
gravity = [0.0, -9.81]

[parameters]
m = 2.0
a = 0.2
f = 1.0
k = 50.0

[analysis]
kind = "inverse_dynamics"
t0 = 0.0
t1 = 1.0
steps = 101

[[body]]
name = "block"
mass = "m"
inertia = "m*0.01"
q0 = [0.0, 0.0, 0.0]

[[constraint]]
name = "rail"
type = "translational"
i = "ground"
j = "block"
si = [0.0, 0.0]
vi = [1.0, 0.0]
sj = [0.0, 0.0]

[[constraint]]
name = "cable"
type = "distance_driver"
i = "ground"
j = "block"
si = [-1.0, 0.0]
sj = [0.0, 0.0]
f = "1 + a*sin(2*pi*f*t)"

[[force]]
name = "spring"
type = "spring_damper"
i = "ground"
j = "block"
si = [1.0, 0.0]
sj = [0.0, 0.0]
k = "k"
c = 0.0
L0 = 1.0
"""

INLINE = {"lane_pendulum": (PENDULUM, "L", (0.3, 0.7), "f", [0.5, 3.0]),
          "lane_rail": (RAIL, "a", (0.1, 0.3), "f", [0.5, 3.0])}


def _mechanism(name: str, tmp_path: Path) -> Any:
    if name in INLINE:
        path = tmp_path / f"{name}.toml"
        path.write_text(INLINE[name][0])
    else:
        path = api.example(name)
    return study_mechanism(api.load_mechanism(path, steps=STEPS))


def _grid(name: str, mech: Any, k: int) -> np.ndarray:
    """k full base vectors: the product of the two parameters' values (the first fastest), first k."""
    a, (lo, hi), b, bv = GRIDS[name] if name in GRIDS else INLINE[name][1:]
    pairs = np.array([(x, y) for y in bv for x in np.linspace(lo, hi, 5)][:k])
    return base_matrix(mech, (a, b), pairs)


@pytest.fixture(params=["native", "sse2"])
def width(request: pytest.FixtureRequest) -> str:
    """The library as built (4 lanes with AVX2, else 2), or the two-lane code
    forced by <NAME>_LANES_SSE2 (what a processor without AVX2 runs)."""
    if request.param == "sse2" and 2 not in c_lanes.WIDTHS:
        pytest.skip("the code has no two-lane form (c_lanes.WIDTHS)")
    return str(request.param)


class Sweep:
    """One compiled solver's `<name>_sweep` and `<name>_sweep_lanes`, called directly."""

    def __init__(self, mech: Any, width: str = "native", factory: pytest.TempPathFactory | None = None) -> None:
        self.mech = mech
        self.compiled = batch_c._load(mech)
        library = self.compiled.folder / "solver.so"
        if width == "sse2":  # the same source, the two-lane code whatever the processor
            assert factory is not None
            source = self.compiled.folder / f"{mech.name}_solver.c"
            command = [c_backend.compiler(), "-O2", *c_backend.CFLAGS, f"-D{mech.name.upper()}_LANES_SSE2"]

            def build(folder: Path) -> None:
                subprocess.run([*command, str(source), "-o", str(folder / "sse2.so"), "-lm"], check=True)

            # built once per run for every test (any worker) of the same source and flags
            library = shared_dir(factory, key_of("sse2", source, command), build) / "sse2.so"
        lib = ctypes.CDLL(str(library))
        self._sweep = lib[f"{mech.name}_sweep"]
        self._sweep.argtypes = self.compiled.sweep.argtypes
        self._sweep.restype = ctypes.c_int
        self._lanes = lib[f"{mech.name}_sweep_lanes"]
        self._lanes.argtypes = [ctypes.POINTER(ctypes.c_long)]
        self._lanes.restype = ctypes.c_long
        self.width = self.lanes()[0]
        if self.width == 1 and 2 not in c_lanes.WIDTHS:
            pytest.skip("a processor without AVX2, and the code has no two-lane form (c_lanes.WIDTHS)")
        assert self.width > 1, "the code was generated and compiled with lanes"
        assert width != "sse2" or self.width == 2

    def lanes(self) -> tuple[int, int]:
        """(variants a group, groups abandoned so far)."""
        abandoned = ctypes.c_long(-1)
        width = self._lanes(ctypes.byref(abandoned))
        return int(width), int(abandoned.value)

    def __call__(self, p: np.ndarray) -> tuple[np.ndarray, ...]:
        """(figures, status, solved, t_end) of one call with the variants p."""
        meta, a = self.compiled.meta, self.mech.analysis
        k = len(p)
        p = np.ascontiguousarray(p, dtype=float)
        fig = np.full((k, len(meta["sweep_figures"])), -1.0)
        status = np.full(k, -1, dtype=np.intc)
        solved = np.full(k, -1, dtype=np.dtype(ctypes.c_long))
        t_end = np.full(k, -1.0)
        work = np.zeros(meta["sweep_work"])
        iwork = np.zeros(max(1, meta["ng"]), dtype=np.intc)
        h = (a.t1 - a.t0) / (a.steps - 1) if a.steps > 1 else 0.0  # as batch_c.run
        code = self._sweep(k, p.ctypes.data_as(batch_c._D), a.t0, h, a.steps, a.tol,
                           fig.ctypes.data_as(batch_c._D), status.ctypes.data_as(batch_c._I),
                           t_end.ctypes.data_as(batch_c._D), solved.ctypes.data_as(batch_c._L),
                           work.ctypes.data_as(batch_c._D), iwork.ctypes.data_as(batch_c._I))
        assert code == 0
        return fig, status, solved, t_end


def _assert_lanes_are_scalar(sweep: Sweep, p: np.ndarray) -> int:
    """One call with every variant equals one call per variant, bit for bit;
    returns how many groups the call abandoned."""
    before = sweep.lanes()[1]
    together = sweep(p)
    abandoned = sweep.lanes()[1] - before
    alone = [sweep(p[v:v + 1]) for v in range(len(p))]
    for k, what in enumerate(("figures", "status", "solved", "t_end")):
        single = np.concatenate([a[k] for a in alone])
        assert np.array_equal(together[k], single, equal_nan=True), (what, together[k], single)
    return abandoned


@pytest.mark.parametrize("name", first_quick(["quick_return", "lane_pendulum"]  # a bundled grid quick, an inline one slow
                                             + sorted((set(GRIDS) | set(INLINE)) - {"quick_return", "lane_pendulum"})))
def test_a_grid_in_lanes_is_each_variant_alone_bit_for_bit(name: str, width: str, tmp_path: Path,
                                                          tmp_path_factory: pytest.TempPathFactory) -> None:
    mech = _mechanism(name, tmp_path)
    sweep = Sweep(mech, width, tmp_path_factory)
    k = 2 * sweep.width + 1  # two groups and a variant left over
    p = _grid(name, mech, k)
    abandoned = _assert_lanes_are_scalar(sweep, p)
    assert abandoned == 0, "every group stayed in the lanes"
    fig, status, solved, _ = sweep(p)
    assert np.all(status == 0) and np.all(solved == STEPS)
    assert np.all(np.isfinite(fig)) and len(np.unique(fig, axis=0)) == k, "the variants differ"


def test_the_bundled_examples_without_friction_take_the_lanes() -> None:
    from symid.codegen.model import code_model, options_for
    from symid.codegen import c

    for name in GRIDS:
        mech = study_mechanism(api.load_mechanism(api.example(name)))
        assert c.context(code_model(mech, options_for(mech), looped=True), lanes=True).lanes is not None, name
    mech = study_mechanism(api.load_mechanism(api.example("slider_crank_friction")))
    assert c.context(code_model(mech, options_for(mech), looped=True), lanes=True).lanes is None


def test_a_mechanism_past_the_lanes_size_keeps_the_one_by_one_sweep(monkeypatch: pytest.MonkeyPatch) -> None:
    from symid.codegen.model import code_model, options_for
    from symid.codegen import c

    mech = study_mechanism(api.load_mechanism(api.example("slider_crank")))  # 9 coordinates
    model = code_model(mech, options_for(mech), looped=True)
    monkeypatch.setattr(c_lanes, "MAX_NG", 8)
    ctx = c.context(model, lanes=True)
    assert ctx.lanes is None
    text = render("c/solver.c.j2", **ctx.namespace())
    assert "_Lgroup" not in text and "#define SLIDER_CRANK_LANES 1" in text


def _index(mech: Any, name: str) -> int:
    from symid.study.variants import base_names

    return list(base_names(mech.parameters)).index(name)


def test_lanes_whose_sines_refresh_at_different_instants_are_each_alone(width: str, tmp_path: Path,
        tmp_path_factory: pytest.TempPathFactory) -> None:
    """Crank speeds 2 and 12 rev/s side by side: one lane's crank turns past
    trig_near's 1/16 rad every instant (sin and cos from libm each time), the
    other's only every few instants, so the lanes refresh apart."""
    mech = _mechanism("slider_crank", tmp_path)
    sweep = Sweep(mech, width, tmp_path_factory)
    rods = np.linspace(0.25, 0.45, sweep.width + 1)
    p = base_matrix(mech, ("L_rod", "n"), np.array([(r, n) for r in rods for n in (2.0, 12.0)]))
    n = p[:, _index(mech, "n")]
    h = (mech.analysis.t1 - mech.analysis.t0) / (mech.analysis.steps - 1)
    turn = 2 * math.pi * n * h  # the crank's angle step per instant
    assert n.max() / n.min() > 4
    assert turn.max() > 1 / 16 > 2 * turn.min(), "some lanes refresh every instant, others not"
    for g in range(0, len(p) - sweep.width + 1, sweep.width):  # both kinds share every group
        assert np.ptp(turn[g:g + sweep.width]) > 0
    assert _assert_lanes_are_scalar(sweep, p) == 0


def test_a_lane_failing_mid_run_leaves_its_neighbours_their_scalar_figures(width: str, tmp_path: Path,
        tmp_path_factory: pytest.TempPathFactory) -> None:
    """A rod shorter than the crank cannot close the loop a quarter turn on:
    that variant stops mid-run (status not OK, some instants solved), its
    group is abandoned to the scalar path, and every lane, the neighbours
    included, is its own scalar run."""
    mech = _mechanism("slider_crank", tmp_path)
    sweep = Sweep(mech, width, tmp_path_factory)
    rods = np.linspace(0.3, 0.45, 2 * sweep.width + 1)
    rods[1] = 0.07
    p = base_matrix(mech, ("L_rod",), rods[:, None])
    abandoned = _assert_lanes_are_scalar(sweep, p)
    _, status, solved, t_end = sweep(p)
    assert status[1] != 0 and 1 <= solved[1] < STEPS and np.isfinite(t_end[1])
    assert np.all(np.delete(status, 1) == 0) and np.all(np.delete(solved, 1) == STEPS)
    assert abandoned == 1, "the failing lane's group only"


def test_a_scattered_sample_in_lanes_is_each_variant_alone(width: str, tmp_path: Path,
        tmp_path_factory: pytest.TempPathFactory) -> None:
    """A tolerance study's sample (5 % normal scatter on lengths, masses and
    speed, seeded): neighbours whose Newton takes a different number of
    iterations at an instant stay in the lanes, the one that converged
    first waiting with its state, and still give their scalar bits."""
    mech = _mechanism("slider_crank", tmp_path)
    sweep = Sweep(mech, width, tmp_path_factory)
    names = ("L_crank", "L_rod", "m_crank", "m_rod", "m_slider", "n")
    rng = np.random.default_rng(0)
    base = np.array([0.1, 0.3, 0.5, 1.0, 0.8, 5.0]) * (1 + 0.05 * rng.standard_normal((8 * sweep.width, len(names))))
    assert _assert_lanes_are_scalar(sweep, base_matrix(mech, names, base)) == 0


def test_an_exported_solver_has_the_one_by_one_sweep_only(tmp_path: Path) -> None:
    """`symid generate --target c` writes code for a controller or a board:
    no lanes (half its size); the cache's build, which studies run, has them."""
    from symid.backends.c_backend import build
    from symid.codegen.model import options_for
    from symid.symbolic.assemble import assemble

    mech = study_mechanism(api.load_mechanism(api.example("slider_crank")))
    api.generate(api.example("slider_crank"), "c", tmp_path / "out")
    exported = (tmp_path / "out" / "slider_crank_solver.c").read_text()
    assert "_Lgroup" not in exported and "#define SLIDER_CRANK_LANES 1" in exported
    built = next(build(assemble(mech), options_for(mech)).glob("*_solver.c")).read_text()
    assert "_Lgroup" in built
