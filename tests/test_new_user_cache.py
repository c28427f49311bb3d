"""Found trying symid as a new user: a run plan in the cache is checked like
every other cache entry, so a plan edited or damaged into other valid JSON
(a parameter's value changed) never gives other numbers with exit status 0."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from symid import api
from symid import cli
from symid.cli import solve as solve_command

SLIDER_CRANK = api.example("slider_crank")


def solve(folder: Path, capsys: pytest.CaptureFixture[str]) -> tuple[int, str, bytes]:
    out = folder / "out.csv"
    status = cli.main(["solve", str(folder / "m.toml"), "--steps", "21", "--backend", "numpy", "-o", str(out)])
    return status, capsys.readouterr().out, out.read_bytes()


def test_a_plan_altered_into_valid_json_takes_the_normal_path(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("SYMID_CACHE", str(tmp_path / "cache"))
    normal: list[str] = []
    original = solve_command._solve

    def counting(args, key):  # type: ignore[no-untyped-def]
        normal.append(args.file)
        return original(args, key)

    monkeypatch.setattr(solve_command, "_solve", counting)
    (tmp_path / "m.toml").write_text(SLIDER_CRANK.read_text())
    first = solve(tmp_path, capsys)
    (stored,) = sorted((tmp_path / "cache" / "plans").glob("*.json"))
    data = json.loads(stored.read_text())
    data["params"]["m_slider"] *= 3.0  # a damaged digit: still a plan, other physics
    stored.write_text(json.dumps(data))
    assert solve(tmp_path, capsys) == first, "a damaged plan must not change the table"
    assert len(normal) == 2, "the damaged plan is distrusted: the normal path ran"
