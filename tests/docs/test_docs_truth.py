"""The documentation is true to the code, both ways.

Each constraint, force and driver type, each expression function and motion
law, each backend, each command and option and each limit that exists is
documented, and everything the pages document exists: the types from the
reader's registries, the commands and options from the argparse parser, the
limits from symid/io/limits.py, the pages from docs/ and the README. A
failure names the missing side. The README stays a tutorial (at most 250
lines) whose first commands set everything up, and its first mechanism
solves to the closed form it states.
"""

from __future__ import annotations

import argparse
import math
import re
import os
import shlex
import shutil
from pathlib import Path

import numpy as np
import pytest

from symid import api
from symid.backends import names as backend_names
from symid.cli import main
from symid.cli.entry import build_parser
from symid.model.expr import FUNCTIONS
from symid.model.friction import FAMILIES as FRICTION
from symid.model.motion import LAWS
from symid.symbolic.constraints import TYPES as CONSTRAINTS
from symid.symbolic.forces import TYPES as FORCES

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"
README = ROOT / "README.md"
MANUAL = (DOCS / "mechanism-file.md").read_text(encoding="utf-8")
README_LINES = 250  # issue #27: a tutorial, the reference in docs/


def pages() -> dict[str, str]:
    """Every documentation page a user reads: docs/*.md and the README, by path."""
    found = {str(p.relative_to(ROOT)): p.read_text(encoding="utf-8") for p in sorted(DOCS.glob("*.md"))}
    return {**found, "README.md": README.read_text(encoding="utf-8")}


def top_section(text: str, title: str) -> str:
    match = re.search(rf"^## {re.escape(title)}\n(.*?)(?=^## |\Z)", text, re.M | re.S)
    assert match, f"docs/mechanism-file.md has no section '## {title}'"
    return match.group(1)


def headings(section: str) -> set[str]:
    return set(re.findall(r"^### (\w+)\s*$", section, re.M))


def differ(existing: set[str], documented: set[str], what: str, where: str) -> list[str]:
    """Both sides' misses, as lines naming them."""
    return ([f"{what} '{n}' exists but {where} does not document it" for n in sorted(existing - documented)]
            + [f"{where} documents {what} '{n}', which does not exist" for n in sorted(documented - existing)])


# --- types -------------------------------------------------------------------------------------------------


def test_every_constraint_type_is_documented_and_every_documented_one_exists() -> None:
    documented = headings(top_section(MANUAL, "[[constraint]]"))
    assert not (bad := differ(set(CONSTRAINTS), documented, "constraint type", "docs/mechanism-file.md")), bad


def test_every_force_type_is_documented_and_every_documented_one_exists() -> None:
    documented = headings(top_section(MANUAL, "[[force]]"))
    assert not (bad := differ(set(FORCES), documented, "force type", "docs/mechanism-file.md")), bad


def test_every_driver_has_its_effort_documented_and_every_documented_driver_exists() -> None:
    """The drivers (constraints that prescribe motion) are the rows of the
    effort table of docs/plots.md: what their effort is and its sign."""
    drivers = {n for n, c in CONSTRAINTS.items() if c.is_driver}
    table = (DOCS / "plots.md").read_text(encoding="utf-8").split("| driver | effort |", 1)
    assert len(table) == 2, "docs/plots.md has no table '| driver | effort | ...'"
    documented = set(re.findall(r"^\| `(\w+)` \|", table[1].split("\n\n", 1)[0], re.M))
    assert not (bad := differ(drivers, documented, "driver", "docs/plots.md's effort table")), bad


def test_friction_is_documented_on_exactly_the_types_that_take_it() -> None:
    constraints = top_section(MANUAL, "[[constraint]]")
    documented = {n for n in headings(constraints)
                  if "| `friction` |" in re.split(r"^### ", constraints.split(f"### {n}\n", 1)[1], flags=re.M)[0]}
    assert not (bad := differ(set(FRICTION), documented, "friction on", "docs/mechanism-file.md")), bad


def test_every_type_a_page_names_exists() -> None:
    """`type = "X"` in a page (a file's or a claim's example) names a real type."""
    known = set(CONSTRAINTS) | set(FORCES)
    bad = [f"{path}: type '{t}' does not exist" for path, text in pages().items()
           for t in re.findall(r'^type = "(\w+)"', text, re.M) if t not in known]
    assert not bad, bad


def test_every_expression_function_and_motion_law_is_documented() -> None:
    said = top_section(MANUAL, "Expressions")
    functions = re.search(r"the functions `([a-z0-9 ]+)`", " ".join(said.split()))
    assert functions, "docs/mechanism-file.md's Expressions list no functions"
    assert not (bad := differ(set(FUNCTIONS), set(functions.group(1).split()), "function",
                              "docs/mechanism-file.md's Expressions")), bad
    motion = (DOCS / "motion.md").read_text(encoding="utf-8")
    laws = set(re.findall(r"^\| `(\w+)\(", top_section(motion, "Contract additions"), re.M))
    assert not (bad := differ(set(LAWS), laws, "motion law", "docs/motion.md")), bad


def test_every_backend_is_documented_and_every_documented_one_exists() -> None:
    text = (DOCS / "backends.md").read_text(encoding="utf-8")
    documented = set(re.findall(r"^\| `(\w+)`", text, re.M))
    assert not (bad := differ(set(backend_names()), documented, "backend", "docs/backends.md")), bad


# --- commands and options ----------------------------------------------------------------------------------


def subcommands() -> dict[str, argparse.ArgumentParser]:
    parser = build_parser()
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(action.choices)


def options(parser: argparse.ArgumentParser) -> set[str]:
    return {o for a in parser._actions for o in a.option_strings} - {"-h", "--help"}


def synopsis() -> dict[str, set[str]]:
    """docs/command-line.md's synopsis: each command's options (a command may have several lines)."""
    text = top_section((DOCS / "command-line.md").read_text(encoding="utf-8"), "Synopsis")
    said: dict[str, set[str]] = {}
    command = ""
    for line in text.splitlines():
        start = re.match(r"    symid (\S+)", line)
        if start:
            command = start.group(1)
            said.setdefault(command, set())
        elif not line.startswith("     "):
            command = ""
            continue
        if command:
            said[command] |= set(re.findall(r"(?<![\w-])(--?[a-z][a-z0-9-]*)", line.split("#", 1)[0]))
    return said


def test_every_command_and_option_is_in_the_synopsis_and_nothing_else() -> None:
    commands, said = subcommands(), synopsis()
    bad = differ(set(commands), {c for c in said if c.islower() and not c.startswith("-")}, "command",
                 "docs/command-line.md's synopsis")
    for name in sorted(set(commands) & set(said)):
        documented = said[name] - {"--help"}
        existing = options(commands[name])
        undocumented = {a.option_strings[-1] for a in commands[name]._actions
                        if a.option_strings and a.option_strings[-1] != "--help"
                        and not set(a.option_strings) & documented}
        bad += [f"symid {name} {o} exists but docs/command-line.md's synopsis does not document it"
                for o in sorted(undocumented)]
        bad += [f"docs/command-line.md's synopsis documents symid {name} {o}, which does not exist"
                for o in sorted(documented - existing)]
    top = options(build_parser())
    bad += [f"docs/command-line.md's synopsis documents symid {o}, which does not exist"
            for o in sorted(c for c in said if c.startswith("-") and c not in top)]
    assert not bad, bad


def commands_in(text: str) -> list[str]:
    """Every `symid COMMAND ...` a page writes as code: inline spans and indented lines."""
    text = re.sub(r"\\\n\s*", " ", text)  # a command continued on the next line
    spans = re.findall(r"`(symid [^`]+)`", text)
    lines = [m.split(" #", 1)[0] for m in re.findall(r"^ {4,}(?:\$ )?(symid .*)$", text, re.M)]
    return spans + lines


def test_every_command_and_option_the_pages_write_exists() -> None:
    commands, top = subcommands(), options(build_parser())
    bad = []
    for path, text in pages().items():
        for written in commands_in(text):
            words = written.split()
            name = words[1]
            if name.startswith("-"):
                bad += [f"{path}: `{written}`: symid has no option {name}"] if name not in top | {"--help"} else []
                continue
            if name.isupper() or name.endswith(":"):
                continue  # the synopsis' placeholder (COMMAND), a message quoted (`symid sweep: argument ...`)
            if name not in commands:
                bad.append(f"{path}: `{written}`: symid has no command '{name}'")
                continue
            flags = set(re.findall(r"(?<![\w-])(--?[a-z][a-z0-9-]*)(?==|\s|$|\])", written))
            bad += [f"{path}: `{written}`: symid {name} has no option {f}"
                    for f in sorted(flags - options(commands[name]) - {"--help", "-h"})]
    assert not bad, bad


def test_every_path_a_page_names_exists() -> None:
    """A file or folder of the repository named in a page (`symid/...`, `tests/...`,
    `python -m benchmarks.X`) is there: a page outlives a moved file only by a test."""
    bad = []
    for path, text in pages().items():
        for named in set(re.findall(r"\b((?:symid|templates|tests|benchmarks|docs|generated)/[\w./-]*\w)", text)):
            if not (ROOT / named).exists():
                bad.append(f"{path}: names {named}, which does not exist")
        for module in set(re.findall(r"python3? -m (benchmarks(?:\.\w+)+)", text)):
            if not (ROOT / (module.replace(".", "/") + ".py")).exists():
                bad.append(f"{path}: names python -m {module}, which does not exist")
    assert not bad, bad


# --- the README ---------------------------------------------------------------------------------------------


def test_readme_is_a_tutorial_of_at_most_250_lines() -> None:
    lines = README.read_text(encoding="utf-8").count("\n")
    assert lines <= README_LINES, f"README.md has {lines} lines, more than {README_LINES}: move reference to docs/"


def test_readme_starts_with_the_set_up_commands_ci_runs() -> None:
    """The first two commands: install and solve a bundled example; install and run the tests, as .ci/run does."""
    first = re.findall(r"^    (python3 -m pip .*)$", README.read_text(encoding="utf-8"), re.M)[:2]
    assert len(first) == 2 and "symid solve" in first[0] and "$(symid example" in first[0], first
    install, test = first[1].split(" && ")
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8")
    assert re.search(rf"^{re.escape(install)}", re.sub(r" -q\b", "", ci), re.M), "the README's install is not CI's"
    assert re.search(rf"^{re.escape(test)}$", ci, re.M), "the README's test command is not what .ci/run runs"


def first_mechanism() -> tuple[str, str]:
    text = README.read_text(encoding="utf-8")
    section = top_section(text, "A first mechanism")
    toml = re.search(r"```toml\n(.*?)```", section, re.S)
    assert toml, "the README's first mechanism has no TOML block"
    return toml.group(1), section


def test_readme_first_mechanism_solves_to_its_closed_form(tmp_path: Path) -> None:
    """A rod of length L and mass m turned at constant omega about one end:
    the motor holds its weight, T = m g (L/2) cos(omega t). The bound is
    the 1e-12 of a column's peak that every backend is held to."""
    text, _ = first_mechanism()
    (tmp_path / "crank.toml").write_text(text, encoding="utf-8")
    results = api.solve(tmp_path / "crank.toml")
    assert results.error is None
    m, L, g, omega = 2.0, 0.5, 9.81, 2 * math.pi
    torque = m * g * L / 2 * np.cos(omega * results.t)
    assert np.max(np.abs(results["motor.T_j"] - torque)) <= 1e-12 * np.max(np.abs(torque))
    # and the sensitivities the README states at t = 0: dT/dm = g L/2, dT/dL = m g/2
    sens = api.solve(tmp_path / "crank.toml", sensitivity=["m", "L"], sensitivity_of=["motor.T_j"], steps=2)
    assert sens["d(motor.T_j)/d(m)"][0] == pytest.approx(g * L / 2, rel=1e-12)
    assert sens["d(motor.T_j)/d(L)"][0] == pytest.approx(m * g / 2, rel=1e-12)


def test_readme_first_mechanism_transcript_is_what_symid_prints(tmp_path: Path, capsys, monkeypatch) -> None:
    text, section = first_mechanism()
    (tmp_path / "crank.toml").write_text(text, encoding="utf-8")
    monkeypatch.chdir(tmp_path)
    transcript = re.findall(r"^    \$ (symid .*)\n((?:    (?!\$).*\n)*)", section, re.M)
    assert [c for c, _ in transcript] == ["symid check crank.toml", "symid solve crank.toml"]
    for command, shown in transcript:
        assert main(shlex.split(command)[1:]) == 0
        out = capsys.readouterr()
        printed = [line.rstrip() for line in (out.out + out.err).splitlines()]
        assert printed == [line[4:] for line in shown.splitlines()], command


def test_the_limits_page_states_the_limits_the_code_enforces() -> None:
    """docs/command-line.md's "Limits" against symid/io/limits.py, each as the page words it."""
    from symid.backends import footprint
    from symid.io import limits as L

    def power(n: int) -> str:
        return f"10^{round(math.log10(n))}" if n == 10 ** round(math.log10(n)) else f"{n}"
    text = " ".join(top_section((DOCS / "command-line.md").read_text(encoding="utf-8"), "Limits").split())
    stated = {
        "MAX_FILE_BYTES": f"{L.MAX_FILE_BYTES // 2**20} MiB", "MAX_BODIES": f"{L.MAX_BODIES} bodies",
        "MAX_CONSTRAINTS": f"{L.MAX_CONSTRAINTS} constraints", "MAX_FORCES": f"{L.MAX_FORCES} forces",
        "MAX_PARAMETERS": f"{L.MAX_PARAMETERS} parameters", "MAX_STEPS": f"{power(L.MAX_STEPS)} instants",
        "MAX_NAME_LENGTH": f"names of {L.MAX_NAME_LENGTH} characters",
        "MAX_HELD_VALUES": f"2^{round(math.log2(L.MAX_HELD_VALUES))} values",
        "MAX_VARIANTS": f"at most {power(L.MAX_VARIANTS)} variants", "MAX_WORKERS": f"`--workers` 1 to {L.MAX_WORKERS}",
        "MAX_ITERATIONS": f"`--maxiter` 1 to {power(L.MAX_ITERATIONS)}",
        "MAX_BENCH_INSTANTS": f"`bench --instants` 1 to {power(L.MAX_BENCH_INSTANTS)}",
        "MAX_BUDGET_S": "at most a day" if L.MAX_BUDGET_S == 86_400 else f"{L.MAX_BUDGET_S}",
        "MAX_SEED": f"from 0 to {L.MAX_SEED}",
        "footprint.DEFAULT_LIMIT_MB": f"above {footprint.DEFAULT_LIMIT_MB} MiB", "footprint.LIMIT_VARIABLE":
            f"`{footprint.LIMIT_VARIABLE}` sets the limit", "footprint.DENSE_COPIES": f"{footprint.DENSE_COPIES} copies",
    }
    bad = [f"symid/io/limits.py {name}: docs/command-line.md does not say '{said}'"
           for name, said in stated.items() if said not in text]
    assert not bad, bad


def test_readme_leads_to_every_page() -> None:
    """Each page of docs/ is a row of the README's "Where to read on" (symid help lists them too)."""
    table = top_section(README.read_text(encoding="utf-8"), "Where to read on")
    linked = set(re.findall(r"\]\(docs/([\w-]+)\.md\)", table))
    on_disk = {p.stem for p in DOCS.glob("*.md")}
    assert not (bad := differ(on_disk, linked, "page", "the README's 'Where to read on'")), bad


def test_c_export_page_quotes_the_committed_header() -> None:
    """A count docs/c-export.md quotes from the slider-crank's generated header is the header's own."""
    page = " ".join((DOCS / "c-export.md").read_text(encoding="utf-8").split())
    header = (ROOT / "generated" / "slider_crank" / "c" / "slider_crank_solver.h").read_text(encoding="utf-8")
    quoted = re.search(r"`_OPS_INSTANT`.*?\((\d+) for the slider-crank\)", page)
    emitted = re.search(r"#define SLIDER_CRANK_OPS_INSTANT (\d+)", header)
    assert quoted and emitted and quoted.group(1) == emitted.group(1), (quoted, emitted)


def test_every_bundled_example_is_described_and_their_types_are_every_type() -> None:
    """docs/examples.md's table and symid/examples/README.md name each bundled
    example; the README's closing list of the types they use is every type."""
    examples = set(api.examples())
    table = set(re.findall(r"^\| `(\w+)` \|", (DOCS / "examples.md").read_text(encoding="utf-8"), re.M))
    bad = differ(examples, table, "example", "docs/examples.md")
    described = (ROOT / "symid" / "examples" / "README.md").read_text(encoding="utf-8")
    bad += differ(examples, set(re.findall(r"^- `(\w+)\.toml`", described, re.M)), "example", "symid/examples/README.md")
    flat = " ".join(described.split())
    constraints = re.search(r"every constraint type \(([\w, ]+)\)", flat)
    forces = re.search(r"every applied force \(([\w, ]+)\)", flat)
    assert constraints and forces, "symid/examples/README.md no longer lists the types its examples use"
    bad += differ(set(CONSTRAINTS), set(constraints.group(1).replace(",", " ").split()), "constraint type",
                  "symid/examples/README.md's list")
    bad += differ(set(FORCES) | {"gravity"}, set(forces.group(1).replace(",", " ").split()), "force type",
                  "symid/examples/README.md's list")
    mechanisms = [api.load_mechanism(api.example(n)) for n in sorted(examples)]
    used = {e.type for m in mechanisms for e in (*m.constraints, *m.forces)}
    bad += [f"no bundled example uses type '{t}'" for t in sorted((set(CONSTRAINTS) | set(FORCES)) - used)]
    assert not bad, bad


def test_analysis_options_page_states_newtons_numbers() -> None:
    """The numbers docs/analysis-options.md gives for Newton and branch
    tracking are those of symid/numeric/newton.py's RULE and solve.py."""
    from symid.numeric import solve
    from symid.numeric.newton import RULE

    def g(x: float) -> str:
        return f"{x:g}".replace("e-0", "e-")  # 1e-7 as the page writes it
    text = " ".join((DOCS / "analysis-options.md").read_text(encoding="utf-8").split())
    stated = {
        "RULE.floor_ulps": f"floored at `{RULE.floor_ulps:g} eps max(1,",
        "RULE.min_damping": f"down to 1/{round(1 / RULE.min_damping)} of the full step",
        "RULE.max_iterations": f"An iteration limit of {RULE.max_iterations} applies",
        "solve.JUMP_SUBSTEPS": f"in {solve.JUMP_SUBSTEPS} sub-steps",
        "solve.JUMP_FLOOR": f"(and than {g(solve.JUMP_FLOOR)})",
        "solve.JUMP_SAME": f"(by more than {g(solve.JUMP_SAME)})",
        "solve.UNEXPLAINED": f"within {'half' if solve.UNEXPLAINED == 0.5 else solve.UNEXPLAINED} the motion",
    }
    bad = [f"{name}: docs/analysis-options.md does not say '{said}'" for name, said in stated.items() if said not in text]
    c_page = " ".join((DOCS / "c-export.md").read_text(encoding="utf-8").split())
    if f"iteration cap per instant (default {RULE.max_iterations})" not in c_page:
        bad.append(f"RULE.max_iterations: docs/c-export.md does not give MAX_NEWTON's default {RULE.max_iterations}")
    assert not bad, bad


def test_every_help_topic_a_page_or_message_names_exists(capsys) -> None:
    """`symid help X` in a page, the README or symid's own text names a topic symid help has."""
    from symid.tools import manual

    sources = {**pages(), **{str(p.relative_to(ROOT)): p.read_text(encoding="utf-8")
                             for p in sorted((ROOT / "symid").rglob("*.py"))}}
    topics = set(manual.topics())
    bad = [f"{path}: symid help {topic}: no such topic" for path, text in sources.items()
           for topic in set(re.findall(r"symid help ([\w-]+)", " ".join(text.split())))
           if topic not in topics and not topic.isupper()]
    assert not bad, bad


def test_no_page_calls_a_shipped_feature_unbuilt() -> None:
    """What tests/docs/test_manual.py asks of the manual, for every page: sweeps,
    sensitivities and friction were once 'not implemented' in `symid help format`."""
    unbuilt = re.compile(r"not (yet )?implemented|not yet in this version|planned for|in a future version", re.I)
    bad = [f"{path}: '{m.group(0)}'" for path, text in pages().items() for m in unbuilt.finditer(text)]
    assert not bad, bad


@pytest.mark.skipif(not any(shutil.which(c) for c in (os.environ.get("CC") or "cc", "gcc", "clang")),
                    reason="no C compiler: the command runs on the c backend")
def test_optimize_page_and_readme_give_what_the_command_gives(tmp_path: Path, capsys, monkeypatch) -> None:
    """The counterweight of docs/optimize.md (and the README's '61 %'): its
    command, read from the page and run as written, reaches the optimum, RMS
    and counts the page states, to the digits it writes them with."""
    page = (DOCS / "optimize.md").read_text(encoding="utf-8")
    written = [c for c in re.findall(r"^    (symid optimize .*?)\n\n", page, re.M | re.S) if "$(symid example" in c]
    assert written, "docs/optimize.md has no indented symid optimize command of a bundled example"
    argv = shlex.split(written[0].replace("\\\n", " ").replace(
        '"$(symid example slider_crank_counterweight)"', str(api.example("slider_crank_counterweight"))))
    monkeypatch.chdir(tmp_path)
    assert main(argv[1:]) == 0
    out = capsys.readouterr().out
    found = re.search(r"optimum: m_cw = (\S+), beta_cw = (\S+): motor\.effort_rms = (\S+) \(start (\S+)\), "
                      r"(\d+) iterations, (\d+) solves", out)
    assert found, out
    m_cw, beta, rms, start = (float(found.group(k)) for k in range(1, 5))
    flat = " ".join(page.split())
    assert f"**m_cw = {m_cw:.4f} kg at beta_cw = {beta:.4f} rad**" in flat
    assert f"RMS torque {start:.3f} N·m" in flat and f"RMS {rms:.3f} N·m ({100 * (rms / start - 1):.0f} %)" in flat
    assert f"in {found.group(5)} iterations and {found.group(6)} solves" in flat
    assert f"cuts the RMS motor torque by {100 * (1 - rms / start):.0f} %" in " ".join(README.read_text().split())
