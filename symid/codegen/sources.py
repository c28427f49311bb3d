"""Where symid's templates are, and one hash of its own code and templates.

Plain standard library: both the solver cache (`symid.codegen.cache`) and
the run-plan cache (`symid.tools.plan`) key on `code_version`, and the latter must
answer before sympy or jinja2 is imported.
"""

from __future__ import annotations

import hashlib
from functools import cache
from importlib import resources
from pathlib import Path


def template_dir() -> Path:
    """Where the templates are: the checkout's `templates/` or the packaged copy."""
    checkout = Path(__file__).resolve().parents[2] / "templates"
    if checkout.is_dir():
        return checkout
    return Path(str(resources.files("symid") / "_templates"))


@cache
def code_version() -> str:
    """Hash of symid's sources and templates: any change invalidates the caches."""
    h = hashlib.sha256()
    for root in (Path(__file__).parents[1], template_dir()):
        for path in sorted(root.rglob("*")):
            if path.suffix in (".py", ".j2") and path.is_file():
                h.update(path.relative_to(root).as_posix().encode())
                h.update(path.read_bytes())
    return h.hexdigest()
