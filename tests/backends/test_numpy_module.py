"""The generated NumPy module compiled a top-level definition at a time
(`symid.backends.numpy_backend.compile_module`): the same bytecode as the
module compiled whole, so the same results to the bit, for a fraction of the
compiler's memory (the ladder of 1024 four-bars: 1.36 GiB -> 527 MiB)."""

from __future__ import annotations

import tracemalloc
import types
from pathlib import Path

import pytest

from symid import api
from symid.backends.numpy_backend import build, compile_module, load_module
from symid.codegen.model import options_for
from symid.symbolic.assemble import assemble


@pytest.fixture(scope="module")
def module_path() -> Path:
    mech = api.load_mechanism(api.example("slider_crank"))
    return build(assemble(mech), options_for(mech))


def functions(codes: tuple[types.CodeType, ...]) -> dict[str, types.CodeType]:
    """The code objects of the top-level definitions, by name."""
    return {c.co_name: c for code in codes for c in code.co_consts if isinstance(c, types.CodeType)}


def test_each_definition_compiles_to_the_bytecode_of_the_whole_module(module_path: Path) -> None:
    """Code objects compare their bytecode, constants, names, first line and
    line table: equal code runs the same operations on the same values."""
    source = module_path.read_bytes()
    whole = functions((compile(source, str(module_path), "exec", dont_inherit=True),))
    pieces = compile_module(source, str(module_path))
    assert len(pieces) > 20  # the header, then one piece per definition
    assert functions(pieces).keys() == whole.keys() and len(whole) > 20
    different = [name for name, code in functions(pieces).items() if code != whole[name]]
    assert not different, different
    loaded = load_module(module_path)  # from the cache entry's marshalled pieces
    assert all(getattr(loaded, name).__code__ == code for name, code in whole.items()
               if isinstance(getattr(loaded, name), types.FunctionType))
    assert loaded.__doc__ and loaded.__doc__.startswith("Inverse-dynamics solver of the mechanism 'slider_crank'")


def test_compiling_a_definition_at_a_time_holds_a_fraction_of_the_whole(module_path: Path) -> None:
    """Python's own allocations (tracemalloc) at the peak of each compilation:
    the compiler's tree and tables are those of the largest definition, a
    tenth of this module (0.10 measured)."""
    source = module_path.read_bytes()
    peaks = []
    for compiled in (lambda: compile(source, "m", "exec", dont_inherit=True), lambda: compile_module(source, "m")):
        tracemalloc.start()
        try:
            compiled()
            peaks.append(tracemalloc.get_traced_memory()[1])
        finally:
            tracemalloc.stop()
    whole, pieces = peaks
    assert pieces <= whole / 3, (pieces, whole)


def test_a_source_that_does_not_split_at_its_definitions_is_compiled_whole() -> None:
    """A `def ` at column 0 inside a string: the piece before it does not
    compile alone, so the module is compiled in one piece, as it reads."""
    source = b'import math\nTEXT = """\ndef not_a_function():\n"""\n\n\ndef f():\n    return math.pi, TEXT\n'
    (code,) = compile_module(source, "m")
    namespace: dict[str, object] = {}
    exec(code, namespace)  # noqa: S102 (the test's own source)
    assert namespace["f"]() == (3.141592653589793, "\ndef not_a_function():\n")  # type: ignore[operator]


def test_line_numbers_are_the_files(module_path: Path) -> None:
    """An error inside a generated function names its line in the file."""
    lines = module_path.read_text().splitlines()
    for name, code in functions(compile_module(module_path.read_bytes(), "m")).items():
        assert lines[code.co_firstlineno - 1].startswith((f"def {name}(", f"class {name}")), name
