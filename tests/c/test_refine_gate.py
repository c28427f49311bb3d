"""The generated C's refinement gate (`<name>_mixed` of the body masses, a
function of p alone) is found once per call of trajectory or instant and
kept in the prepared values (`<name>_gate`, PP_MIXED), not scanned at every
instant; statics no longer evaluates the mass kernel at every instant only
to feed it. Counted in the generated code itself, instrumented."""

from __future__ import annotations

import ctypes
import shutil
import subprocess
from pathlib import Path

import pytest

from csolver import INSTRUMENTED_FLAGS, _edit, run_in_cuts
from symid import api
from symid.codegen import c as c_target
from symid.codegen.model import code_model
from symid.io.reader import load

pytestmark = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")


def _counted(kind: str, folder: Path) -> tuple[ctypes.CDLL, object]:
    """The slider-crank's solver of `kind` counting calls of mixed and of the mass kernel."""
    mech = load(api.example("slider_crank"), None, {"kind": kind})
    model = code_model(mech)
    c_target.generate(model, folder)
    p = model.name
    source = folder / f"{p}_solver.c"
    text = source.read_text()
    text = _edit(text, f'#include "{p}_solver.h"\n', f'#include "{p}_solver.h"\nlong test_mixed, test_mass;\n')
    text = _edit(text, f"static int {p}_mixed(const {p}_real *m)\n{{\n",
                 f"static int {p}_mixed(const {p}_real *m)\n{{\n    ++test_mixed;\n")
    text = _edit(text, f"static void {p}_mass_k(const {p}_real * p, {p}_real *out)\n{{\n",
                 f"static void {p}_mass_k(const {p}_real * p, {p}_real *out)\n{{\n    ++test_mass;\n")
    source.write_text(text)
    subprocess.run(["cc", *INSTRUMENTED_FLAGS, str(source), "-o", str(folder / "s.so"), "-lm"], check=True)
    return ctypes.CDLL(str(folder / "s.so")), c_target.context(model)


@pytest.mark.parametrize("kind", ["inverse_dynamics", "statics"])
def test_the_refinement_gate_is_found_once_a_call_not_each_instant(tmp_path: Path, kind: str) -> None:
    lib, ctx = _counted(kind, tmp_path)
    mixed, mass = ctypes.c_long.in_dll(lib, "test_mixed"), ctypes.c_long.in_dll(lib, "test_mass")
    run_in_cuts(lib, ctx, [40, 60])  # 100 instants in two calls
    assert mixed.value == 2  # once a call (it was once an instant: 100)
    # inverse dynamics needs M qddot at each instant (and the gate once a call); statics only the gate
    assert mass.value == (2 + 100 if kind == "inverse_dynamics" else 2)
