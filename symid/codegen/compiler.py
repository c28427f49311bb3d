"""The system C compiler, as the C backend, the FMU export and `symid solve`'s
compiled CSV formatter run it: found from $CC, cc, gcc or clang, its failures
one line naming the compiler and its first error (exit 2)."""

from __future__ import annotations

import os
import shlex
import shutil
import subprocess
from pathlib import Path

from symid.errors import InputError

# -fno-math-errno lets sqrt compile to one instruction; results are unchanged.
# No warning flags: a user's run never depends on what a compiler warns about
# (the tests compile every generated solver with -Wall -Wextra -Werror -pedantic).
CFLAGS = ("-std=c99", "-fno-math-errno", "-fPIC", "-shared")


def _words(cc: str, who: str = "--backend c") -> list[str]:
    """$CC as make reads it: "ccache gcc" is a command and its argument."""
    try:
        return shlex.split(cc)
    except ValueError as exc:  # an unbalanced quote
        raise InputError(f"{who}: the C compiler CC={cc} is not a command line: {exc}") from None


def find(who: str, otherwise: str, purpose: str = "") -> str:
    """The C compiler to use ($CC, cc, gcc or clang), or an input error for
    `who` (the command's words) saying `otherwise` (what else the user can do)."""
    chosen = os.environ.get("CC", "").strip()
    if chosen:  # the user's choice is used or refused, never silently replaced
        words = _words(chosen, who)
        if not words or shutil.which(words[0]) is None:
            raise InputError(f"{who}: the C compiler CC={chosen} was not found")
        return chosen
    for candidate in ("cc", "gcc", "clang"):
        if shutil.which(candidate):
            return candidate
    raise InputError(f"{who}: no C compiler found{purpose} (set CC, or install cc/gcc/clang); {otherwise}")


def _first_error(stderr: str) -> str:
    """The line of a compiler's output that says what went wrong first."""
    lines = [line.strip() for line in stderr.splitlines() if line.strip()]
    return next((line for line in lines if "error" in line.lower()), lines[0] if lines else "")


def _compile(cc: str, args: list[str], artifact: Path, who: str = "--backend c",
             what: str = "the generated solver") -> None:
    """Run the compiler; a failure is an unusable resource (exit 2), one line
    naming the compiler and its first error line."""
    try:
        result = subprocess.run([*_words(cc, who), *args], capture_output=True, text=True, errors="replace")
    except OSError as exc:
        raise InputError(f"{who}: the C compiler {cc} could not be run: {exc.strerror or exc}") from None
    if result.returncode != 0:
        said = _first_error(result.stderr) or f"exit status {result.returncode}, no message"
        raise InputError(f"{who}: the C compiler {cc} failed on {what}: {said}")
    if not artifact.is_file() or artifact.stat().st_size == 0:
        left = f"left {artifact.name} empty" if artifact.is_file() else f"wrote no {artifact.name}"
        raise InputError(f"{who}: the C compiler {cc} reported success but {left}")
