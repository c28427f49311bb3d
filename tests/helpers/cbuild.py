"""Building the generated C in the tests: the strict flags every build uses,
the embedded build's warnings and Cortex-M4F target, and the mark that skips
a test on a machine without a C compiler."""

from __future__ import annotations

import shutil

import pytest

STRICT = ["-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", "-pedantic"]
# the embedded engineer's build (tests/c/test_c_embedded.py): conversions, promotions, shadowing
WARNINGS = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic", "-Wconversion", "-Wdouble-promotion", "-Wshadow"]
M4F = ["-mcpu=cortex-m4", "-mfpu=fpv4-sp-d16", "-mfloat-abi=hard", "-mthumb"]
needs_cc = pytest.mark.skipif(shutil.which("cc") is None and shutil.which("gcc") is None, reason="no C compiler")
