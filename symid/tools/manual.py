"""The user's documentation in the box: `symid help [TOPIC]`.

The pages of the checkout's `docs/` install as `symid/_docs` (like the
templates), so every page the command line names is readable from an
installed package too. `symid help TYPE` adds, for one constraint or force
type, its keys, defaults and columns as symid's registries define them, so
that part can never drift from the code.
"""

from __future__ import annotations

import re
from importlib import resources
from pathlib import Path
from typing import Any

# `symid help format` is the mechanism file's manual; other pages by their stem
ALIASES = {"format": "mechanism-file"}


def doc_dir() -> Path:
    """Where the pages are: the checkout's `docs/` or the packaged copy."""
    checkout = Path(__file__).resolve().parents[2] / "docs"
    if (checkout / "mechanism-file.md").is_file():
        return checkout
    return Path(str(resources.files("symid") / "_docs"))


def pages() -> list[str]:
    """Names of the shipped pages (file stems), sorted."""
    return sorted(p.stem for p in doc_dir().glob("*.md"))


def title(name: str) -> str:
    """A page's first line without its `# `: what `symid help` lists it as."""
    return page(name).split("\n", 1)[0].lstrip("# ").strip()


def page(name: str) -> str:
    """The text of one page, by stem or alias (`format`)."""
    path = doc_dir() / f"{ALIASES.get(name, name)}.md"
    return path.read_text(encoding="utf-8")


def _registries() -> dict[str, tuple[str, Any]]:
    from symid.symbolic.constraints import TYPES as CONSTRAINTS
    from symid.symbolic.forces import TYPES as FORCES

    return {**{n: ("force", f) for n, f in FORCES.items()}, **{n: ("constraint", c) for n, c in CONSTRAINTS.items()}}


def topics() -> list[str]:
    """Everything `symid help` accepts: pages, aliases and type names."""
    return sorted(ALIASES) + pages() + sorted(_registries())


def section(text: str, heading: str) -> str:
    """The Markdown section `### heading` of a page, up to the next heading ("" if none)."""
    match = re.search(rf"^### {re.escape(heading)}\n(.*?)(?=^#{{1,3}} |\Z)", text, re.M | re.S)
    return match.group(1).strip() if match else ""


def _default(key: Any) -> str:
    if key.required:
        return "required"
    if key.default is None:
        return "optional"
    if isinstance(key.default, bool):
        return f"default {str(key.default).lower()}"
    return f"default {key.default}"


def type_help(name: str) -> str:
    """One type's keys with defaults (from the registry), its columns, and its manual section."""
    from symid.model.friction import FAMILIES as FRICTION

    section_name, family = _registries()[name]
    lines = [f"{name} ({section_name} type)", "", "keys (besides name and type):"]
    friction = section_name == "constraint" and name in FRICTION
    width = max([len(k.name) for k in family.keys] + ([len("friction")] if friction else []))
    for key in family.keys:
        kind = {"function": "expression of t", "function2": "two expressions of t",
                "choice": "one of " + ", ".join(f'"{c}"' for c in key.choices),
                "flag": "true or false", "scalar": "number",
                "rows": "list of expressions, one per row"}.get(key.kind, key.kind)
        lines.append(f"  {key.name:<{width}}  {kind}, {_default(key)}")
    if friction:
        lines.append(f"  {'friction':<{width}}  inline table {{ mu, radius, viscous, arm, v_smooth }}, optional "
                     "(symid help format, \"Joint friction\")")
    if section_name == "constraint":
        lam = ["C.lambda"] if family.rows == 1 else [f"C.lambda{k + 1}" for k in range(family.rows)]
        reactions = [f"C.{c}_{role}" for role in family.roles for c in ("Fx", "Fy", "T")]
        rows = f"rows: {family.rows}; multiplier columns: {' '.join(lam)}" if family.shape is None else (
            "rows: one per entry of phi; multiplier columns: C.lambda (one row) or C.lambda1 C.lambda2 ...")
        lines += ["", rows,
                  f"reaction columns: {' '.join(reactions)}  (C: the constraint's name)"]
        if friction:
            lines.append("with friction, after all others: C.friction C.friction_power (not in statics)")
    lines += ["", section(page("format"), name)]
    return "\n".join(lines).rstrip() + "\n"


def text(topic: str | None) -> str:
    """What `symid help TOPIC` prints; no topic: the list of topics.

    Raises:
        LookupError: an unknown topic, with the valid ones.
    """
    if topic is None:
        return ("symid help TOPIC prints one of these:\n"
                "  format             the mechanism file: sections, types, keys, defaults, CSV columns\n"
                + "".join(f"  {p:<18} {title(p)}\n" for p in pages() if p != ALIASES["format"])
                + "  TYPE               one constraint or force type: "
                + ", ".join(sorted(_registries())) + "\n")
    if topic in ALIASES or topic in pages():
        return page(topic)
    if topic in _registries():
        return type_help(topic)
    raise LookupError(f"unknown help topic {topic!r} (topics: {', '.join(topics())})")
