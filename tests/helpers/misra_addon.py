"""cppcheck's own MISRA addon (the installed cppcheck's misra.py, every rule
its own code) with one search indexed, for the tests' MISRA checks.

Rule 8.2's helper getFollowingRawTokens(rawTokens, token, count) walks every
raw token of the file for each pointer variable to find the ones at the
variable's place (file, line, column): pointer count times token count, on a
generated export 680 x 54,000 comparisons, 40 % of the addon's time. Here the
helper's code object inside MisraChecker.misra_8_2 is swapped for one that
finds the same raw tokens, in the same order, in a table by place built once
per dump, and then takes the same `count` following tokens skipping comments;
the rest of rule 8.2 and every other rule run as installed. Should the
installed addon have no such helper (another cppcheck), the script runs it
unchanged: the same findings, at its own speed.

Two costs of the process, not of the rules, are cut too: the script runs
without Python's cyclic garbage collector (the dump's ~110,000 tokens,
linked both ways, made the collector walk the growing heap again and again:
12 % of the addon's time on an export; nothing is freed before the process
ends either way, and no object of the addon has a finalizer), and the --addon
JSON names the interpreter running the tests (cppcheck otherwise runs
`python3 --version` and the addon through `python3` on PATH, which may be a
shim: pyenv's ran some 40 processes for each of the four calls an export).

As a script, this is the addon cppcheck runs (`addon_option` writes the
--addon JSON naming it), so cppcheck prints the findings in its own format;
tests/c/test_misra.py checks on a small file with every kind of pointer
declaration rule 8.2 reads that both addons report the same."""

from __future__ import annotations

import gc
import json
import shutil
import sys
import types
from pathlib import Path
from typing import Any


def stock_addon() -> Path | None:
    """The installed cppcheck's misra.py (where the distributions put its addons), or None."""
    found = shutil.which("cppcheck")
    if found is None:
        return None
    prefix = Path(found).resolve().parent
    for folder in (prefix / "addons", *sorted(prefix.parent.glob("lib/*/cppcheck/addons")),
                   prefix.parent / "lib" / "cppcheck" / "addons", prefix.parent / "share" / "cppcheck" / "addons"):
        if (folder / "misra.py").is_file():
            return folder / "misra.py"
    return None


def addon_option(folder: Path) -> str:
    """cppcheck's --addon option for this script (its JSON written into folder),
    or the stock `--addon=misra` where the installed addon is not found."""
    if stock_addon() is None:
        return "--addon=misra"
    config = folder / "misra-indexed.json"
    config.write_text(json.dumps({"script": str(Path(__file__).resolve()), "ctu": True, "python": sys.executable}))
    return f"--addon={config}"


_TABLES: dict[int, tuple[list[Any], dict[tuple[Any, Any, Any], list[Any]]]] = {}


def following_raw_tokens(rawTokens: list[Any], token: Any, count: int) -> list[Any]:
    """What misra.py's getFollowingRawTokens returns: for each raw token at
    token's (file, linenr, column), in the list's order, the `count` raw
    tokens after it that are not comments (fewer where the file ends)."""
    held = _TABLES.get(id(rawTokens))
    if held is None or held[0] is not rawTokens:
        table: dict[tuple[Any, Any, Any], list[Any]] = {}
        for raw in rawTokens:
            table.setdefault((raw.file, raw.linenr, raw.column), []).append(raw)
        held = _TABLES[id(rawTokens)] = (rawTokens, table)
    following = []
    for rawToken in held[1].get((token.file, token.linenr, token.column), ()):
        for _ in range(count):
            rawToken = rawToken.next
            while rawToken and (rawToken.str.startswith('/*') or rawToken.str.startswith('//')):
                rawToken = rawToken.next
            if rawToken is None:
                break
            following.append(rawToken)
    return following


def _indexed(misra: types.ModuleType) -> bool:
    """Swap misra_8_2's nested getFollowingRawTokens for a call of
    following_raw_tokens (the nested function is made, as before, each time
    the rule runs, with misra's globals: the name is put there). False when
    the installed addon has no such nested function."""
    rule = getattr(getattr(misra, "MisraChecker", None), "misra_8_2", None)
    if rule is None:
        return False
    consts = rule.__code__.co_consts
    nested = [i for i, c in enumerate(consts) if isinstance(c, types.CodeType) and c.co_name == "getFollowingRawTokens"
              and c.co_varnames[:c.co_argcount] == ("rawTokens", "token", "count") and not c.co_freevars]
    if len(nested) != 1:
        return False
    misra.__dict__["_indexed_following_raw_tokens"] = following_raw_tokens

    def getFollowingRawTokens(rawTokens, token, count):  # type: ignore[no-untyped-def]
        return _indexed_following_raw_tokens(rawTokens, token, count)  # type: ignore[name-defined] # noqa: F821

    swap = getFollowingRawTokens.__code__.replace(co_qualname=consts[nested[0]].co_qualname) \
        if sys.version_info >= (3, 11) else getFollowingRawTokens.__code__
    rule.__code__ = rule.__code__.replace(co_consts=consts[:nested[0]] + (swap,) + consts[nested[0] + 1:])
    return True


def main() -> None:
    gc.disable()  # see the module's docstring: the dump's objects all live until the process ends
    stock = stock_addon()
    assert stock is not None, "the installed cppcheck's misra.py is not found"
    sys.dont_write_bytecode = True  # imported here, run as a script by cppcheck: no __pycache__ beside it
    sys.path.insert(0, str(stock.parent))
    sys.argv[0] = str(stock)
    import misra  # type: ignore[import-not-found]

    _indexed(misra)
    misra.main()
    sys.exit(misra.cppcheckdata.EXIT_CODE)  # as misra.py's own __main__


if __name__ == "__main__":
    main()
