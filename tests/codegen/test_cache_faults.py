"""Fault injection into the cache of generated solvers (`symid.codegen.cache`)
and its run plans: a damaged, incomplete, foreign or unusable cache costs a
rebuild with one warning line, never a crash, a traceback, a wrong number or
code run from a folder someone else can write.

Each case runs `python -m symid solve` on the slider-crank in a fresh
interpreter (a truncated solver.so would kill it with SIGBUS if it were
loaded) against a copy of a cache built once per backend, and compares the
table with the one of the undamaged cache, byte for byte.
"""

from __future__ import annotations

import contextlib
import errno
import hashlib
import io
import json
import marshal
import os
import shutil
import stat
import subprocess
import sys
from pathlib import Path
from typing import Callable, Iterator

import numpy as np
import pytest

from runshare import key_of, run_folder, shared_dir
from symid import api, cli
from symid.codegen import cache

pytestmark = pytest.mark.slow  # every fault on every backend, most in a child process with its own build (194 s under load)

REPO = Path(__file__).resolve().parents[2]
SLIDER_CRANK = api.example("slider_crank")
ARGS = ["solve", str(SLIDER_CRANK), "--steps", "11"]
NOBODY = 65534
HAS_CC = bool(shutil.which(os.environ.get("CC") or "cc") or shutil.which("gcc"))


def on(backend: str, *values: object, root: bool = False) -> object:
    """One parameter set of a case on `backend`, skipped where it cannot run."""
    marks = [pytest.mark.skipif(backend == "c" and not HAS_CC, reason="no C compiler"),
             pytest.mark.skipif(root and os.geteuid() != 0, reason="chown to another user needs root")]
    name = "-".join([backend, *(getattr(v, "__name__", str(v)) for v in values)])
    return pytest.param(backend, *values, marks=marks, id=name)


BACKENDS = [on(b) for b in ("c", "numpy", "casadi")]
CODE_BACKENDS = [on(b) for b in ("c", "numpy")]  # whose entries hold native or Python code


def symid(cache_dir: Path | None, cwd: Path, *args: str, env: dict[str, str] | None = None,
          umask: int | None = None) -> subprocess.CompletedProcess[str]:
    """`python -m symid ARGS` in a fresh interpreter with this checkout first on the path."""
    environ = {**os.environ, "PYTHONPATH": str(REPO), **(env or {})}
    if cache_dir is not None:
        environ["SYMID_CACHE"] = str(cache_dir)
    return subprocess.run([sys.executable, "-m", "symid", *ARGS, *args], cwd=cwd, env=environ, capture_output=True,
                          text=True, timeout=600, preexec_fn=None if umask is None else (lambda: os.umask(umask)))


class Pristine:
    """A cache built once per backend in the run (either xdist worker builds it,
    the other waits: tests/helpers/runshare.py), with its plan, and the table it
    gives. Every child runs in the one folder `root` of the run, the built one
    too: a plan's key holds the current folder, and a case finds the plan
    its cache was built with."""

    def __init__(self, factory: pytest.TempPathFactory) -> None:
        self.factory = factory
        self.root = run_folder(factory) / "cache-faults-cwd"
        self.root.mkdir(exist_ok=True)
        self.built: dict[str, tuple[Path, bytes, str]] = {}

    def get(self, backend: str) -> tuple[Path, bytes]:
        return self.entry(backend)[:2]  # type: ignore[return-value]

    def entry(self, backend: str) -> tuple[Path, bytes, str]:
        """The cache, its table, and the path the cache was built at (its plans name it)."""
        if backend not in self.built:
            def build(folder: Path) -> None:
                # `symid solve` in this process (its derivations are at hand here): the entry, its
                # plan and the table a child writes; the children of the cases load them
                err = io.StringIO()
                with pytest.MonkeyPatch.context() as patch, contextlib.redirect_stderr(err):
                    patch.setenv("SYMID_CACHE", str(folder / "cache"))
                    patch.chdir(self.root)
                    status = cli.main([*ARGS, "--backend", backend, "-o", str(folder / "table.csv")])
                assert (status, err.getvalue()) == (0, ""), err.getvalue()
                (folder / "built-at").write_text(str(folder / "cache"))

            where = shared_dir(self.factory, key_of("test_cache_faults.Pristine", backend, SLIDER_CRANK, ARGS), build)
            self.built[backend] = where / "cache", (where / "table.csv").read_bytes(), (where / "built-at").read_text()
        return self.built[backend]


@pytest.fixture(scope="module")
def pristine(tmp_path_factory: pytest.TempPathFactory) -> Pristine:
    return Pristine(tmp_path_factory)


class Case:
    """A private copy of a backend's pristine cache, its plans pointing at the copy."""

    def __init__(self, pristine: Pristine, backend: str, tmp_path: Path) -> None:
        source, self.expected, built_at = pristine.entry(backend)
        self.backend, self.cwd, self.tmp = backend, pristine.root, tmp_path
        self.cache = tmp_path / "cache"
        shutil.copytree(source, self.cache)
        for path in (self.cache / "plans").glob("*.json"):
            data = json.loads(path.read_text())
            data["artifact"] = data["artifact"].replace(built_at, str(self.cache))
            path.write_text(json.dumps(data))
        (self.entry,) = [p for p in self.cache.iterdir() if p.name.startswith(f"{backend}-")]
        (self.plan,) = (self.cache / "plans").glob("*.json") if backend != "casadi" else (None,)

    def run(self, *, cache_dir: Path | None = None, **kwargs: object) -> tuple[subprocess.CompletedProcess[str], bytes]:
        """Solve again (same folder: the same plan key); returns the process and its table."""
        out = self.tmp / "out.csv"
        out.unlink(missing_ok=True)
        proc = symid(cache_dir or self.cache, self.cwd, "--backend", self.backend, "-o", str(out), **kwargs)
        assert "Traceback" not in proc.stderr, proc.stderr
        return proc, out.read_bytes() if out.exists() else b""


@pytest.fixture
def case(pristine: Pristine, tmp_path: Path, request: pytest.FixtureRequest) -> Case:
    return Case(pristine, request.param, tmp_path)


def one_warning(proc: subprocess.CompletedProcess[str], *words: str) -> str:
    """The run's single stderr line, a warning containing every word."""
    lines = proc.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("symid: warning: "), proc.stderr
    assert all(w in lines[0] for w in words), lines[0]
    return lines[0]


def truncate(path: Path) -> None:
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])


def garbage(path: Path) -> None:
    path.write_bytes(np.random.default_rng(12).bytes(path.stat().st_size))


def edit_sizes(path: Path) -> None:
    """A meta.json / manifest.json that no longer matches its solver (ng one too many)."""
    data = json.loads(path.read_text())
    sizes = data["sizes"] if "sizes" in data else data
    sizes["ng"] += 1
    path.write_text(json.dumps(data))


DAMAGE: list[tuple[str, str, Callable[[Path], None]]] = [
    ("c", "solver.so", truncate),  # SIGBUS if it were mapped
    ("c", "solver.so", garbage),
    ("c", "meta.json", edit_sizes),
    ("numpy", "slider_crank_solver.py", truncate),
    ("numpy", "slider_crank_solver.*.code", garbage),
    ("numpy", "complete", Path.unlink),  # an entry never completed
    ("casadi", "slider_crank_phi.casadi", truncate),
    ("casadi", "manifest.json", edit_sizes),
]


@pytest.mark.parametrize("case, pattern, damage",
                         [on(b, p, d) for b, p, d in DAMAGE], indirect=["case"])
def test_a_damaged_entry_is_rebuilt_with_one_warning(case: Case, pattern: str, damage: Callable[[Path], None]):
    (path,) = case.entry.glob(pattern)
    damage(path)
    proc, table = case.run()
    assert proc.returncode == 0
    one_warning(proc, str(case.entry), "rebuilding")
    assert table == case.expected
    assert cache.verify(case.entry) is None


def foreign(path: Path, how: str) -> None:
    """Make `path` (a folder) writable by others, or another user's."""
    if how == "chmod":
        os.chmod(path, 0o1777)
    else:
        for folder, _, files in os.walk(path):
            for name in [folder, *(os.path.join(folder, f) for f in files)]:
                os.chown(name, NOBODY, NOBODY)


@pytest.mark.parametrize("case, how", [*(on(b, "chmod") for b in ("c", "numpy", "casadi")),
                                       on("numpy", "chown", root=True)], indirect=["case"])
def test_an_entry_others_can_write_is_rebuilt_not_loaded(case: Case, how: str):
    foreign(case.entry, how)
    proc, table = case.run()
    assert proc.returncode == 0
    one_warning(proc, str(case.entry), "another user" if how == "chown" else "mode 1777", "rebuilding")
    assert table == case.expected
    st = case.entry.stat()
    assert (st.st_uid, stat.S_IMODE(st.st_mode)) == (os.geteuid(), 0o700)


def plant(entry: Path, backend: str, marker: Path) -> None:
    """Replace the entry's code by code that creates `marker` when loaded, with a
    manifest that matches it (as another user who can write the folder could)."""
    if backend == "c":
        source = entry / "planted.c"
        source.write_text(f'#include <stdio.h>\n__attribute__((constructor)) static void planted(void)'
                          f' {{ FILE *f = fopen("{marker}", "w"); if (f) fclose(f); }}\n')
        cc = os.environ.get("CC") or "cc"
        subprocess.run([cc, "-shared", "-fPIC", str(source), "-o", str(entry / "solver.so")], check=True)
        source.unlink()
    else:
        code = f"open({str(marker)!r}, 'w').close()\n"
        (py,) = entry.glob("*_solver.py")
        py.write_text(code)
        for path in entry.glob("*.code"):
            path.write_bytes(marshal.dumps(compile(code, str(py), "exec")))
    manifest = json.loads((entry / "complete").read_text())
    for name in manifest["files"]:
        manifest["files"][name] = hashlib.sha256((entry / name).read_bytes()).hexdigest()
    (entry / "complete").write_text(json.dumps(manifest))
    assert cache.verify(entry) is None  # planted well: only the folder's owner or mode betrays it


@pytest.mark.parametrize("case, how", [on("c", "chmod"), on("numpy", "chown", root=True)], indirect=["case"])
def test_code_planted_in_a_shared_cache_never_runs(case: Case, how: str):
    """A cache root others can write (a shared SYMID_CACHE of mode 1777) or
    another user's is not used: one warning, a private temporary cache."""
    marker = case.tmp / "planted-code-ran"
    plant(case.entry, case.backend, marker)
    if how == "chown":
        foreign(case.cache, how)
    else:
        os.chmod(case.cache, 0o1777)
    proc, table = case.run()
    assert proc.returncode == 0
    one_warning(proc, str(case.cache), "another user" if how == "chown" else "mode 1777",
                "private temporary cache")
    assert not marker.exists()
    assert table == case.expected


@pytest.mark.parametrize("case", CODE_BACKENDS, indirect=True)
def test_a_plan_pointing_outside_the_cache_is_ignored(case: Case):
    elsewhere = case.tmp / "elsewhere"
    shutil.copytree(case.entry, elsewhere)
    marker = case.tmp / "planted-code-ran"
    plant(elsewhere, case.backend, marker)
    data = json.loads(case.plan.read_text())
    data["artifact"] = data["artifact"].replace(str(case.entry), str(elsewhere))
    case.plan.write_text(json.dumps(data))
    proc, table = case.run()
    assert (proc.returncode, proc.stderr) == (0, "")
    assert not marker.exists()
    assert table == case.expected
    assert str(case.entry) in json.loads(case.plan.read_text())["artifact"], "the normal path stored it again"


def modes(root: Path) -> Iterator[tuple[Path, int]]:
    yield root, stat.S_IMODE(root.stat().st_mode)
    for path in root.rglob("*"):
        yield path, stat.S_IMODE(path.lstat().st_mode)


@pytest.mark.parametrize("backend", ["numpy"])  # the modes are set in symid.codegen.cache, for every backend
def test_umask_000_still_makes_a_private_cache(tmp_path: Path, pristine: Pristine, backend: str):
    where = tmp_path / "new" / "cache"
    proc = symid(where, pristine.root, "--backend", backend, "-o", str(tmp_path / "out.csv"), umask=0)
    assert (proc.returncode, proc.stderr) == (0, "")
    assert (tmp_path / "out.csv").read_bytes() == pristine.get(backend)[1]
    folders = [(p, m) for p, m in modes(where) if p.is_dir()]
    assert len(folders) >= 3 and all(m == 0o700 for _, m in folders), folders  # root, entry, plans
    assert stat.S_IMODE((tmp_path / "new").stat().st_mode) == 0o700
    assert [p for p, m in modes(where) if m & 0o022] == []


def test_an_empty_symid_cache_means_the_default(tmp_path: Path, pristine: Pristine):
    work = tmp_path / "work"
    work.mkdir()
    env = {"SYMID_CACHE": "", "HOME": str(tmp_path / "home"), "XDG_CACHE_HOME": str(tmp_path / "xdg")}
    proc = symid(None, work, "--backend", "numpy", "-o", str(tmp_path / "out.csv"), env=env)
    assert (proc.returncode, proc.stderr) == (0, "")
    assert list(work.iterdir()) == []
    assert [p.name for p in (tmp_path / "xdg" / "symid").iterdir() if p.name.startswith("numpy-")]
    assert (tmp_path / "out.csv").read_bytes() == pristine.get("numpy")[1]


def test_a_cache_path_that_is_a_file_falls_back_with_one_warning(tmp_path: Path, pristine: Pristine):
    where = tmp_path / "cache"
    where.write_text("not a folder\n")
    proc = symid(where, pristine.root, "--backend", "numpy", "-o", str(tmp_path / "out.csv"))
    assert proc.returncode == 0
    one_warning(proc, str(where), "is not a folder", "private temporary cache")
    assert (tmp_path / "out.csv").read_bytes() == pristine.get("numpy")[1]
    assert where.read_text() == "not a folder\n"


@pytest.mark.skipif(not HAS_CC, reason="no C compiler")
def test_an_empty_solver_from_a_broken_compiler_is_never_cached(tmp_path: Path, pristine: Pristine):
    fake = tmp_path / "fakecc"
    fake.write_text('#!/bin/sh\n# "compiles" to an empty file\nwhile [ $# -gt 0 ]; do\n'
                    '  if [ "$1" = -o ]; then : > "$2"; fi; shift\ndone\n')
    fake.chmod(0o755)
    where = tmp_path / "cache"
    proc = symid(where, pristine.root, "--backend", "c", "-o", str(tmp_path / "out.csv"), env={"CC": str(fake)})
    assert proc.returncode == 2
    assert proc.stderr == f"symid: --backend c: the C compiler {fake} reported success but left solver.so empty\n"
    assert [p.name for p in where.iterdir()] == [], "no entry, complete or not, and no staging folder left"


# In-process: as root, permissions do not stop writes and no read-only or full
# file system is at hand, so the file system's answers are simulated.


@pytest.fixture
def fresh(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> Path:
    """A new cache for an in-process run, and no fallback left from another test."""
    monkeypatch.setattr(cache, "_fallback", {})
    monkeypatch.setenv("SYMID_CACHE", str(tmp_path / "cache"))
    monkeypatch.chdir(tmp_path)
    return tmp_path / "cache"


def test_a_read_only_cache_falls_back_with_one_warning(fresh: Path, monkeypatch, capsys, pristine: Pristine):
    fresh.mkdir(mode=0o700)
    access = os.access
    monkeypatch.setattr(os, "access", lambda p, mode, **kw: False if Path(p) == fresh else access(p, mode, **kw))
    assert cli.main([*ARGS, "-o", "out.csv"]) == 0
    err = capsys.readouterr().err
    assert err == (f"symid: warning: cache {fresh}: is not writable; using a private temporary cache "
                   f"for this run\n")
    assert Path("out.csv").read_bytes() == pristine.get("numpy")[1]
    assert list(fresh.iterdir()) == []


def no_space(monkeypatch: pytest.MonkeyPatch, where: Callable[[Path], bool]) -> None:
    """Writing the generated module fails with ENOSPC in the folders `where` accepts."""
    from symid.codegen.targets import numpy_target

    generate = numpy_target.generate

    def full(model: object, out_dir: Path) -> list[Path]:
        if where(out_dir):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(out_dir))
        return generate(model, out_dir)  # type: ignore[arg-type]

    monkeypatch.setattr(numpy_target, "generate", full)


def test_a_full_cache_falls_back_with_one_warning(fresh: Path, monkeypatch, capsys, pristine: Pristine):
    no_space(monkeypatch, lambda folder: folder.parent == fresh)
    assert cli.main([*ARGS, "-o", "out.csv"]) == 0
    err = capsys.readouterr().err
    assert err == (f"symid: warning: cache {fresh}: cannot be written (No space left on device); "
                   f"using a private temporary cache for this run\n")
    assert Path("out.csv").read_bytes() == pristine.get("numpy")[1]
    assert [p.name for p in fresh.iterdir()] == [], "no staging folder left behind"


def test_no_usable_cache_anywhere_is_exit_2_with_one_line(fresh: Path, monkeypatch, capsys):
    no_space(monkeypatch, lambda folder: True)
    assert cli.main([*ARGS, "-o", "out.csv"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"symid: cache {fresh}: cannot be written (No space left on device), nor the private "
                          f"temporary cache ") and err.endswith(" (No space left on device)\n")
    assert err.count("\n") == 1
