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



# a tag of a template's source: a block opening or closing, or an include of a literal name
_TAG = re.compile(r"""{%-?\s*(if|for|endif|endfor|include\s+["']([^"']+)["'])""")


def _includes(source: str) -> tuple[list[str], list[str]]:
    """The templates a template includes by name: outside any if/for block
    (included whenever it renders), then inside one (only for some inputs)."""
    always: list[str] = []
    sometimes: list[str] = []
    depth = 0
    for tag, name in _TAG.findall(source):
        if tag in ("if", "for"):
            depth += 1
        elif tag in ("endif", "endfor"):
            depth -= 1
        elif name:
            (sometimes if depth > 0 else always).append(name)
    return always, sometimes


def preload(names: Sequence[str], until: Callable[[], bool]) -> None:
    """Compile templates ahead of `render` (Jinja keeps them) until `until()`:
    work to do while waiting for something else (`symid.codegen.forked`).
    First `names` and every template they always include, then those they
    include only for some inputs (which may be compiled for nothing)."""
    env = _environment()
    queue, later, seen = list(names), list[str](), set(names)
    while queue or later:
        if until():
            return
        name = queue.pop(0) if queue else later.pop(0)
        template = env.get_template(name)
        with open(str(template.filename), encoding="utf-8") as f:
            always, sometimes = _includes(f.read())
        for found, into in ((always, queue), (sometimes, later)):
            for included in found:
                if included not in seen:
                    seen.add(included)
                    into.append(included)
