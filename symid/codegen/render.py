"""The one render function: Jinja2 templates from `templates/`, strict.

Templates are found in the checkout's top-level `templates/` folder, or, in
an installed package, in `symid/_templates` (the same folder, packaged).
Templates hold layout only: every expression arrives already simplified,
CSE'd and printed.
"""

from __future__ import annotations

from functools import cache
from typing import Any

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
