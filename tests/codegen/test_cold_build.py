"""A cold C build samples the elimination plan in a forked child while it
derives (`symid.codegen.forked`), and the `symid` process skips the
interpreter's teardown (`symid.cli.entry.leave`): neither may change what is
generated or lose what the process should do at exit."""

from __future__ import annotations

import os
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest

from symid import api
from symid.codegen import forked
from symid.codegen.model import code_model, options_for
from symid.codegen import c
from symid.model.params import parameter_values
from symid.numeric.evaluator import Needs
from symid.numeric.reference import ReferenceEvaluator
from symid.study.variants import study_mechanism
from symid.symbolic.assemble import assemble

REPO = Path(__file__).resolve().parents[2]


def generated(example: str, tmp: Path, monkeypatch: pytest.MonkeyPatch, fork: bool) -> tuple[str, tuple, int]:
    """The C source of `example`, its sample q0 and how many children forked."""
    monkeypatch.setattr(forked, "ENABLED", fork)
    forks = []
    real = os.fork

    def counted() -> int:
        pid = real()
        if pid:
            forks.append(pid)
        return pid

    monkeypatch.setattr(forked.os, "fork", counted)
    mech = study_mechanism(api.load_mechanism(api.example(example), steps=11))
    model = code_model(mech, options_for(mech), looped=True, meanwhile=lambda sample: None)
    c.write(c.context(model), tmp)
    return (tmp / f"{mech.name}_solver.c").read_text(), model.q0, len(forks)


@pytest.mark.parametrize("example", ["slider_crank", "four_bar"])
def test_the_plan_sampled_in_a_child_generates_the_same_code(example: str, tmp_path: Path,
                                                            monkeypatch: pytest.MonkeyPatch) -> None:
    here, q_here, none = generated(example, tmp_path / "here", monkeypatch, fork=False)
    child, q_child, one = generated(example, tmp_path / "child", monkeypatch, fork=True)
    assert (none, one) == (0, 1), "the child ran only where allowed"
    assert q_child == q_here  # to the last bit: the floats come back pickled
    assert child == here
    mech = api.load_mechanism(api.example(example))
    values = parameter_values(mech.parameters)
    phi = ReferenceEvaluator(assemble(mech), values, Needs(velocity=False)).phi(np.array(q_child), mech.analysis.t0)
    # the assembled configuration satisfies Phi to the Newton tol (1e-12) times the lengths: 1e-10 is met with room
    assert np.max(np.abs(phi)) < 1e-10, "the plan is fixed at the configuration assembled at t0"


def test_a_child_that_fails_leaves_the_value_to_this_process() -> None:
    parent = os.getpid()

    def compute() -> list[float]:
        if os.getpid() != parent:
            raise RuntimeError("only in the child")
        return [1.5, np.pi]

    pending = forked.Pending(compute)
    assert pending.result() == [1.5, np.pi]


def test_an_error_is_raised_here_as_without_a_child() -> None:
    def compute() -> float:
        raise ZeroDivisionError("in both")

    with pytest.raises(ZeroDivisionError, match="in both"):
        forked.Pending(compute).result()


def test_no_child_is_forked_beside_another_thread() -> None:
    stop = threading.Event()
    other = threading.Thread(target=stop.wait, name="not-symid")
    other.start()
    try:
        assert not forked.usable()
        pending = forked.Pending(lambda: os.getpid())
        assert pending.result() == os.getpid(), "computed here"
    finally:
        stop.set()
        other.join()
    assert forked.usable()
    assert forked.Pending(lambda: os.getpid()).result() != os.getpid(), "computed in a child"


# slow: a cold solve in a child of its own; tests/codegen/test_cache_faults.py keeps the unusable caches in the
# quick tier
@pytest.mark.slow
def test_the_process_still_runs_its_exit_handlers_and_flushes(tmp_path: Path) -> None:
    """A cache path that is a file: symid builds in a private temporary cache
    that an exit handler removes; the table and the report are complete."""
    blocked = tmp_path / "cache-is-a-file"
    blocked.write_text("")
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    env = {**os.environ, "PYTHONPATH": str(REPO), "SYMID_CACHE": str(blocked), "TMPDIR": str(tmp)}
    env.pop("CI", None)
    proc = subprocess.run([sys.executable, "-m", "symid", "sweep", str(api.example("slider_crank")),
                           "--grid", "L_rod=0.25:0.35:3", "--steps", "11", "-o", "t.csv", "--json"],
                          cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    assert '"variants": 3' in proc.stdout
    assert proc.stderr.count("private temporary cache") == 1
    assert len((tmp_path / "t.csv").read_text().splitlines()) == 4
    assert not list(tmp.glob("symid-cache-*")), "the exit handler removed the private cache"


def test_an_input_error_keeps_its_exit_status(tmp_path: Path) -> None:
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    proc = subprocess.run([sys.executable, "-m", "symid", "sweep", str(api.example("slider_crank")),
                           "--grid", "L_rod=0.4:0.2:3"], cwd=tmp_path, env=env, capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "L_rod" in proc.stderr


def test_templates_always_included_are_preloaded_before_those_included_for_some_inputs() -> None:
    from symid.codegen.render import _includes

    source = ('{% include "c/a.j2" %}\n{% if x %}{% include "c/b.j2" %}{% else %}{% include "c/c.j2" %}'
              '{% endif %}\n{%- for k in ks %}{% include "c/d.j2" %}{% endfor %}{% include "c/e.j2" %}')
    assert _includes(source) == (["c/a.j2", "c/e.j2"], ["c/b.j2", "c/c.j2", "c/d.j2"])


def test_preloading_stops_once_the_wait_is_over(monkeypatch: pytest.MonkeyPatch) -> None:
    from symid.codegen import render

    loaded: list[str] = []
    env = render._environment()
    real = env.get_template

    def get_template(name: str):  # type: ignore[no-untyped-def]
        loaded.append(name)
        return real(name)

    monkeypatch.setattr(env, "get_template", get_template)
    render.preload(c.TEMPLATES, lambda: len(loaded) == 2)
    assert loaded == ["c/solver.c.j2", "c/solver.h.j2"]


def test_a_child_never_asked_for_is_ended_and_reaped() -> None:
    import time

    pending = forked.Pending(lambda: time.sleep(60))
    pid = pending._pid
    assert pid, "a child ran"
    del pending  # the caller stopped before asking (an error, Ctrl-C)
    with pytest.raises(ChildProcessError):  # killed and already reaped: no zombie left
        os.waitpid(pid, os.WNOHANG)
