"""The one render function: Jinja2 templates from `templates/`, strict.

Templates are found in the checkout's top-level `templates/` folder, or, in
an installed package, in `symid/_templates` (the same folder, packaged).
Templates hold layout only: every expression arrives already simplified,
CSE'd and printed.
"""

from __future__ import annotations

import re
from functools import cache
from typing import Any, Callable, Sequence

import jinja2

from symid.codegen.sources import template_dir


@cache
def _environment() -> jinja2.Environment:
    return jinja2.Environment(
        loader=jinja2.FileSystemLoader(str(template_dir())),
        undefined=jinja2.StrictUndefined,
        keep_trailing_newline=True,
        trim_blocks=True,
        lstrip_blocks=True,
    )


def render(template: str, **context: Any) -> str:
    """Render `templates/<template>`; `template_name` is passed for the header."""
    return _environment().get_template(template).render(template_name=template, **context)


_INCLUDE = re.compile(r"""{%-?\s*include\s+["']([^"']+)["']""")


def preload(first: Sequence[str], until: Callable[[], bool]) -> None:
    """Compile templates ahead of `render` (Jinja keeps them), `first` and
    then the templates they name in `include`s, in order, until `until()`:
    work to do while waiting for something else (`symid.codegen.forked`)."""
    env = _environment()
    queue, seen = list(first), set(first)
    while queue and not until():
        name = queue.pop(0)
        template = env.get_template(name)
        with open(template.filename, encoding="utf-8") as f:  # type: ignore[arg-type]
            for included in _INCLUDE.findall(f.read()):
                if included not in seen:
                    seen.add(included)
                    queue.append(included)
