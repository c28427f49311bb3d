"""The compiled sweep's figures at forces whose squares overflow a double:
the force peaks (|(Fx, Fy)| kept squared) and the RMS efforts (sums of
squares) are kept in a per-variant power-of-two unit past 2^256
(templates/c/sweep.j2, sweep_big), so a variant of forces near 1e160 or
1e300 has the figures of its NumPy sweep, not inf or NaN."""

from __future__ import annotations

import numpy as np
import pytest

from symid import api

# every load of the slider-crank scales with its masses and F_gas (gravity,
# inertia, the gas load; the motion is imposed): a variant with all of them
# times c has every force figure times c and the same times. Common forces
# (c = 1) next to forces near 1e160 and 1e300 in one group of lanes.
SCALES = np.array([1.0, 1e158, 1.0, 3e297])
BASE = {"m_crank": 0.5, "m_rod": 1.0, "m_slider": 0.8, "F_gas": 100.0}
# then the masses times 1e36 (forces ~1e38 at t0) under a gas load that
# starts at 0 and passes 2^128 = 3.4e38, where the squares' unit changes
# mid-run with the figures so far still in the result, or 1e300 (twice);
# a group of lanes of their own, left mid-run
CROSSING = {"m_crank": 0.5e36, "m_rod": 1e36, "m_slider": 0.8e36}
CROSS_GAS = (1e39, 3e38, 1e300, 2e39)
FORCES = ("motor.effort_peak", "motor.effort_rms", "motor.power_peak", "main_bearing.force_peak",
          "crank_pin.force_peak", "wrist_pin.force_peak", "cylinder_guide.force_peak")


@pytest.fixture(scope="module")
def tables() -> dict[str, object]:
    mech = api.load_mechanism(api.example("slider_crank"), steps=51)
    variants = {name: np.concatenate([value * SCALES, np.full(len(CROSS_GAS), CROSSING[name])
                                      if name in CROSSING else CROSS_GAS]) for name, value in BASE.items()}
    return {backend: api.sweep(mech, variants, backend=backend, workers=1) for backend in ("c", "numpy")}


def test_forces_past_the_squares_range_scale_with_the_loads(tables: dict) -> None:
    c = tables["c"]
    assert list(c["status"]) == ["ok"] * (len(SCALES) + len(CROSS_GAS))
    k = len(SCALES)
    assert np.array_equal(c["motor.effort_t_peak"][:k], np.full(k, c["motor.effort_t_peak"][0]))
    for name in FORCES:
        # c times the common figure: the rounding of the loads' products (1e-15 apart)
        np.testing.assert_allclose(c[name][:k], SCALES * c[name][0], rtol=1e-12, err_msg=name)
        assert np.all(np.isfinite(c[name])), name


def test_forces_past_the_squares_range_are_the_numpy_figures(tables: dict) -> None:
    c, numpy = tables["c"], tables["numpy"]
    for name in (*FORCES, "motor.effort_t_peak", "motor.force_peak"):
        # two solvers' roundings of the same figures (NumPy's RMS in units of its peak, hypot)
        np.testing.assert_allclose(c[name], numpy[name], rtol=1e-12, atol=0.0, err_msg=name)


def test_a_group_of_lanes_with_such_forces_is_each_variant_alone(tables: dict) -> None:
    """One `<name>_sweep` call with every variant (groups of 2 or 4 lanes, the
    huge ones handed to the scalar code) gives the figures of the table,
    whose variants ran one a call (chunks of one: the scalar code), bit for bit."""
    from symid.backends import c_batch
    from symid.study import batch_c
    from symid.study.variants import base_matrix, study_mechanism

    mech = study_mechanism(api.load_mechanism(api.example("slider_crank"), steps=51))
    names = tuple(BASE)
    full = base_matrix(mech, names, np.column_stack([tables["c"][n] for n in names]))
    compiled = batch_c._load(mech)
    batch = c_batch.run(compiled.sweep, compiled.meta, compiled.folder, mech.name, mech.analysis, full, workers=1)
    assert len(c_batch.chunks(len(full), 1)) == len(full)  # the table's run: one variant a call
    c_batch.CHUNKS_PER_WORKER, saved = 1, c_batch.CHUNKS_PER_WORKER
    try:
        together = c_batch.run(compiled.sweep, compiled.meta, compiled.folder, mech.name, mech.analysis, full,
                               workers=1)
    finally:
        c_batch.CHUNKS_PER_WORKER = saved
    assert np.array_equal(together.values, batch.values, equal_nan=True)
    assert np.array_equal(together.values[:, list(batch.names).index("motor.effort_rms")],
                          tables["c"]["motor.effort_rms"])


def test_single_precision_sweep_keeps_forces_past_1e19(tmp_path) -> None:
    """In single precision a square overflows past 1.8e19: the exported
    sweep's figures of loads times 1e22 and 1e30 are those of the common
    loads times that, to float rounding."""
    import ctypes
    import re
    import subprocess

    from symid.backends import c_backend
    from symid.cli import main

    assert main(["generate", str(api.example("slider_crank")), "--target", "c", "--precision", "single",
                 "-o", str(tmp_path)]) == 0
    subprocess.run([c_backend.compiler(), "-O2", "-std=c99", "-shared", "-fPIC", str(tmp_path / "slider_crank_solver.c"),
                    "-o", str(tmp_path / "s.so"), "-lm"], check=True)
    header = (tmp_path / "slider_crank_solver.h").read_text()
    size = {m[0]: int(m[1]) for m in re.findall(r"#define SLIDER_CRANK_(\w+) (\d+)", header)}
    extra = int(re.search(r"SWEEP_WORK \(.*\+ (\d+)\)", header)[1])
    lib = ctypes.CDLL(str(tmp_path / "s.so"))
    f32, ptr = ctypes.c_float, ctypes.POINTER
    default = np.ctypeslib.as_array((f32 * size["NP"]).in_dll(lib, "slider_crank_default_params")).copy()
    scales = np.array([1.0, 1e22, 1e30], dtype=np.float32)
    p = np.tile(default, (3, 1))
    p[:, 2:5] *= scales[:, None]  # m_crank, m_rod, m_slider (the header's order)
    p[:, 8] *= scales  # F_gas
    fig = np.zeros((3, size["SWEEP_FIGURES"]), np.float32)
    status, t_end, solved = np.zeros(3, np.intc), np.zeros(3, np.float32), np.zeros(3, np.dtype(ctypes.c_long))
    work = np.zeros(size["WORK"] + size["STATE"] + 32 * size["ROW"] + extra, np.float32)
    iwork = np.zeros(size["IWORK"], np.intc)
    sweep = lib.slider_crank_sweep
    sweep.argtypes = [ctypes.c_long, ptr(f32), f32, f32, ctypes.c_long, f32, ptr(f32), ptr(ctypes.c_int), ptr(f32),
                      ptr(ctypes.c_long), ptr(f32), ptr(ctypes.c_int)]
    at = lambda a, t: a.ctypes.data_as(ptr(t))  # noqa: E731
    assert sweep(3, at(p, f32), 0.0, 0.2 / 50, 51, 1e-5, at(fig, f32), at(status, ctypes.c_int), at(t_end, f32),
                 at(solved, ctypes.c_long), at(work, f32), at(iwork, ctypes.c_int)) == 0
    assert list(status) == [0, 0, 0] and list(solved) == [51] * 3
    forces = [0, 2, 3, 4, 5, 6, 7]  # effort peak, RMS, power peak, the four joints' force peaks
    # float rounding of the loads' products and of the sums (1e-6 measured)
    np.testing.assert_allclose(fig[1:, forces], scales[1:, None] * fig[0, forces], rtol=1e-5)
