"""Fault injection: every machine fault and hostile input ends in one line and a
documented exit status, with no temporary file left and no row lost.

The faults come from outside symid (docs/command-line.md, `symid help command-line`): a full disk
(/dev/full), a file-size limit (RLIMIT_FSIZE), odd output paths (a directory,
a device, a FIFO, a name too long), signals, a closed stdout pipe, endless
inputs (/dev/zero), sizes that would exhaust memory, overflowing numbers.
The Python API refuses keywords it does not know; the API snippet of the
README and of docs/python-api.md runs.
"""

from __future__ import annotations

import os
import re
import resource
import signal
import stat
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from symid import api
from symid.cli import main
from symid.io.limits import MAX_BODIES, MAX_FILE_BYTES, MAX_NAME_LENGTH, MAX_STEPS
from symid.output.results import MAX_TABLE_VALUES
from shell import default_signals
from tiers import first_quick

REPO = Path(__file__).resolve().parents[2]
SLIDER_CRANK = REPO / "symid" / "examples" / "slider_crank.toml"
STEPS = 50  # rows written before a fault, where rows are compared
TIMEOUT = 300


def child_env() -> dict[str, str]:
    # no .pyc written: under a file-size limit that write would be the one to fail
    return {**os.environ, "PYTHONDONTWRITEBYTECODE": "1",
            "PYTHONPATH": os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")]))}


def symid(args: list[str], cwd: Path, **kwargs) -> subprocess.CompletedProcess:
    """`python -m symid ARGS` in a child process (text output captured unless given)."""
    kwargs.setdefault("capture_output", True)
    return subprocess.run([sys.executable, "-m", "symid", *args], cwd=cwd, env=child_env(), text=True,
                          timeout=TIMEOUT, **kwargs)


def one_line(err: str) -> str:
    """The only non-empty line of stderr; no traceback."""
    assert "Traceback" not in err and "Exception ignored" not in err, err
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1, f"stderr is not one line: {err!r}"
    return lines[0]


def no_temporaries(folder: Path) -> None:
    left = [p.name for p in folder.iterdir() if p.name.endswith(".tmp")]
    assert not left, f"temporary files left in {folder}: {left}"


def run_main(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    """`symid ARGS` in this process (faults of the output and inputs behave alike here)."""
    status = main(args)
    return status, one_line(capsys.readouterr().err)


def solve_to(output: str, capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    return run_main(["solve", str(SLIDER_CRANK), "--steps", str(STEPS), "-o", output], capsys)


@pytest.fixture(scope="module")
def warm(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The slider-crank's table, its NumPy solver built once: the faults below hit the output, not the cache."""
    path = tmp_path_factory.mktemp("warm") / "warm.csv"
    assert main(["solve", str(SLIDER_CRANK), "--steps", str(STEPS), "-o", str(path)]) == 0
    return path


# -- the output ---------------------------------------------------------------------

def test_full_disk_is_one_line_exit_2(warm, tmp_path, capsys):
    status, line = solve_to("/dev/full", capsys)
    assert status == 2
    assert line == f"symid: /dev/full: cannot write: {os.strerror(28)}"  # ENOSPC
    assert stat.S_ISCHR(os.stat("/dev/full").st_mode)


def test_file_size_limit_is_one_line_exit_2_and_leaves_no_file(warm, tmp_path):
    def limit() -> None:  # SIGXFSZ keeps its default (kill): symid itself must ignore it
        resource.setrlimit(resource.RLIMIT_FSIZE, (4096, 4096))

    proc = symid(["solve", str(SLIDER_CRANK), "--steps", str(STEPS), "-o", "out.csv"], tmp_path,
                 preexec_fn=limit)
    assert proc.returncode == 2, proc.stderr
    assert one_line(proc.stderr) == f"symid: out.csv: cannot write: {os.strerror(27)}"  # EFBIG
    assert list(tmp_path.iterdir()) == []  # neither the table nor its temporary file


@pytest.mark.parametrize("name", ["out.csv", "out.npz"])
def test_output_naming_a_directory_is_one_line_exit_2(warm, tmp_path, capsys, name):
    (tmp_path / name).mkdir()
    status, line = solve_to(str(tmp_path / name), capsys)
    assert status == 2
    assert line == f"symid: {tmp_path / name}: cannot write: is a directory"
    assert (tmp_path / name).is_dir() and list((tmp_path / name).iterdir()) == []
    no_temporaries(tmp_path)


@pytest.mark.parametrize("name, reason", [
    ("missing/out.csv", os.strerror(2)),  # ENOENT
    ("x" * 300 + ".csv", os.strerror(36)),  # ENAMETOOLONG
])
def test_unwritable_output_path_is_one_line_exit_2(warm, tmp_path, capsys, name, reason):
    status, line = solve_to(str(tmp_path / name), capsys)
    assert status == 2
    assert reason in line, line
    assert list(tmp_path.iterdir()) == []


@pytest.mark.skipif(os.geteuid() != 0, reason="as root, the rename over /dev/null was the fault")
def test_dev_null_is_written_into_never_replaced(warm, tmp_path, capsys):
    assert main(["solve", str(SLIDER_CRANK), "--steps", str(STEPS), "-o", "/dev/null"]) == 0
    assert stat.S_ISCHR(os.stat("/dev/null").st_mode)
    assert not [p for p in Path("/dev").iterdir() if p.name.startswith(".null.")]


def test_fifo_with_a_reader_receives_the_whole_table(warm, tmp_path):
    fifo = tmp_path / "pipe.csv"
    os.mkfifo(fifo)
    received: list[str] = []
    reader = threading.Thread(target=lambda: received.append(fifo.read_text()))
    reader.start()
    status = main(["solve", str(SLIDER_CRANK), "--steps", str(STEPS), "-o", str(fifo)])
    reader.join(TIMEOUT)
    assert status == 0
    assert stat.S_ISFIFO(os.stat(fifo).st_mode)
    assert received == [warm.read_text()]  # every row, as a regular file gets them
    no_temporaries(tmp_path)


# -- signals --------------------------------------------------------------------------

@pytest.mark.parametrize("signum", first_quick([signal.SIGTERM, signal.SIGHUP, signal.SIGINT]))  # one handler
def test_signal_mid_run_removes_the_temporary_file(tmp_path, signum):
    # the reference backend builds nothing and takes ~1 ms per instant: far longer than the wait
    proc = subprocess.Popen([sys.executable, "-m", "symid", "solve", str(SLIDER_CRANK), "--backend", "reference",
                             "--steps", "1000000", "-o", "out.csv"], cwd=tmp_path, env=child_env(), text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, preexec_fn=default_signals)
    try:
        deadline = time.monotonic() + TIMEOUT
        while not [p for p in tmp_path.iterdir() if p.name.endswith(".tmp")]:
            assert proc.poll() is None and time.monotonic() < deadline, "no temporary file appeared"
            time.sleep(0.05)
        time.sleep(0.3)  # mid-run: rows are being written
        proc.send_signal(signum)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 128 + signum
    line = one_line(err)
    said = "interrupted" if signum == signal.SIGINT else f"terminated by {signal.Signals(signum).name}"
    assert line == f"symid: {said}; out.csv not written"
    assert list(tmp_path.iterdir()) == []


# -- a closed stdout pipe ------------------------------------------------------------

CLAIM = REPO / "symid" / "claims" / "revolute.toml"


COMMANDS = [
    ["solve", str(SLIDER_CRANK), "--steps", str(STEPS), "-o", "out.csv"],
    ["example"],
    ["verify", str(CLAIM)],
    ["derive", "revolute"],
    ["check", str(SLIDER_CRANK)],
    ["bench", str(SLIDER_CRANK), "--backend", "reference", "--instants", "4", "--budget", "5"],
]


# the quick tier: a table's writer and a one-line printer; the others print through the same guarded stream
@pytest.mark.parametrize("command", first_quick([(c,) for c in COMMANDS], keep=2, ids=[c[0] for c in COMMANDS]))
def test_closed_stdout_pipe_ends_quietly(warm, tmp_path, command):
    read_end, write_end = os.pipe()
    os.close(read_end)  # the reader has gone (`| head -1` after its line): every write is EPIPE
    try:
        proc = subprocess.run([sys.executable, "-m", "symid", *command], cwd=tmp_path, env=child_env(),
                              stdout=write_end, stderr=subprocess.PIPE, text=True, timeout=TIMEOUT)
    finally:
        os.close(write_end)
    assert proc.returncode == 128 + signal.SIGPIPE
    assert proc.stderr == ""
    if command[0] == "solve":  # the table was complete before the summary found the pipe closed
        assert (tmp_path / "out.csv").read_text() == warm.read_text()
    no_temporaries(tmp_path)


# -- inputs that would read or allocate without end ----------------------------------

def test_endless_mechanism_file_is_read_only_up_to_the_limit(tmp_path, capsys):
    status, line = run_main(["solve", "/dev/zero", "-o", str(tmp_path / "out.csv")], capsys)
    assert status == 2
    assert line == f"symid: /dev/zero: file is longer than the {MAX_FILE_BYTES} bytes allowed"
    assert list(tmp_path.iterdir()) == []


def test_endless_motion_table_is_read_only_up_to_the_limit(tmp_path, capsys):
    text = SLIDER_CRANK.read_text().replace('f = "omega*t"', 'f = { table = "/dev/zero", column = "angle" }')
    (tmp_path / "m.toml").write_text(text)
    status, line = run_main(["solve", str(tmp_path / "m.toml"), "-o", str(tmp_path / "out.csv")], capsys)
    assert status == 2
    assert "constraint 'motor' key 'f'" in line and "/dev/zero" in line and str(MAX_FILE_BYTES) in line, line


@pytest.mark.slow  # reads and lays out a file of 9000 bodies
def test_nine_thousand_bodies_on_numpy_are_refused_up_front(tmp_path, capsys, monkeypatch):
    """9000 driven pendulums on numpy: its setup of 80 kB per coordinate (2.2 GiB),
    refused by the memory estimate before anything is derived or cached."""
    monkeypatch.delenv("SYMID_MEMORY_LIMIT", raising=False)
    monkeypatch.setenv("SYMID_CACHE", str(tmp_path / "cache"))
    (tmp_path / "big.toml").write_text('[mechanism]\nname = "big"\n' + "".join(
        f'[[body]]\nname = "b{k}"\nmass = 1\ninertia = 1\nq0 = [{k}, 0, 0]\n'
        f'[[constraint]]\nname = "p{k}"\ntype = "revolute"\ni = "ground"\nj = "b{k}"\nsi = [{k}, 0]\nsj = [0, 0]\n'
        f'[[constraint]]\nname = "d{k}"\ntype = "relative_angle_driver"\ni = "ground"\nj = "b{k}"\nf = "t"\n'
        for k in range(9000)))
    start = time.process_time()  # CPU time: refused up front, whatever the machine's load
    status, line = run_main(["solve", str(tmp_path / "big.toml"), "-o", str(tmp_path / "out.csv")], capsys)
    assert status == 2 and time.process_time() - start < 30
    assert "big.toml: memory: a run of 9000 bodies (ng 27000) needs about" in line, line
    assert "more than the 2048 MiB allowed (SYMID_MEMORY_LIMIT sets it)" in line, line
    assert not (tmp_path / "out.csv").exists()


def test_bodies_past_what_the_reader_holds_are_refused_by_count(tmp_path, capsys):
    """Past MAX_BODIES the count itself is the problem: the reader's objects come before any estimate."""
    n = MAX_BODIES + 1
    bodies = "".join(f'[[body]]\nname = "b{k}"\nmass = 1\ninertia = 1\n' for k in range(n))
    (tmp_path / "big.toml").write_text(f'[mechanism]\nname = "big"\n{bodies}')
    status, line = run_main(["solve", str(tmp_path / "big.toml"), "-o", str(tmp_path / "out.csv")], capsys)
    assert status == 2
    assert line.endswith(f"[[body]]: {n} entries, more than the {MAX_BODIES} allowed"), line


def test_table_held_in_memory_is_refused_up_front(tmp_path, capsys):
    steps = MAX_STEPS  # 10^7 instants x 67 columns: 5 GiB as an .npz, refused before solving
    status, line = run_main(["solve", str(SLIDER_CRANK), "--backend", "reference", "--steps", str(steps),
                             "-o", str(tmp_path / "out.npz")], capsys)
    assert status == 2
    assert f"{steps} instants x 67 columns" in line and str(MAX_TABLE_VALUES) in line, line
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("old, new, key", [
    ('name = "slider_crank"', 'name = "{long}"', "[mechanism] key 'name'"),
    ('name = "crank"', 'name = "{long}"', "[[body]] #1 key 'name'"),
    ("m_crank = 0.5", "{long} = 0.5", "[parameters] key"),
    ('mass = "m_crank"', "mass = 1e400", "body 'crank' key 'mass'"),
    ("L_crank = 0.1", "L_crank = 1e400", "[parameters] key 'L_crank'"),
    ("steps = 201", "steps = 100000000000000000000", "[analysis] key 'steps'"),
], ids=["mechanism-name", "body-name", "parameter-name", "mass-1e400", "parameter-1e400", "steps-1e20"])
def test_long_names_and_overflowing_numbers_are_refused_naming_the_key(tmp_path, capsys, old, new, key):
    long = "a" * 300
    text = SLIDER_CRANK.read_text()
    assert old in text
    (tmp_path / "m.toml").write_text(text.replace(old, new.format(long=long), 1))
    status, line = run_main(["solve", str(tmp_path / "m.toml"), "-o", str(tmp_path / "out.csv")], capsys)
    assert status == 2
    assert key in line and long not in line, line
    if "{long}" in new:
        assert str(MAX_NAME_LENGTH) in line and "300 characters" in line
    assert [p.name for p in tmp_path.iterdir()] == ["m.toml"]


def test_names_up_to_the_limit_are_accepted(tmp_path):
    name = "n" * MAX_NAME_LENGTH
    (tmp_path / "m.toml").write_text(SLIDER_CRANK.read_text().replace('name = "crank"', f'name = "{name}"')
                                     .replace('"crank"', f'"{name}"'))
    mech = api.load_mechanism(tmp_path / "m.toml")
    assert mech.bodies[0].name == name


# -- the Python API ------------------------------------------------------------------

@pytest.mark.parametrize("call", [
    lambda: api.prepare(SLIDER_CRANK, "reference", stepz=3),
    lambda: api.prepare(api.load_mechanism(SLIDER_CRANK), "reference", stepz=3),
    lambda: api.solve(SLIDER_CRANK, "reference", stepz=3),
    lambda: api.load_mechanism(SLIDER_CRANK, stepz=3),
], ids=["prepare-path", "prepare-mechanism", "solve", "load_mechanism"])
def test_unknown_keyword_raises_type_error_naming_it_and_the_accepted(call):
    with pytest.raises(TypeError) as err:
        call()
    message = str(err.value)
    assert "'stepz'" in message and "steps" in message and "t1" in message, message


def api_snippet(page: str) -> str:
    """The first Python block of a page (the README: of its section "From Python")."""
    text = (REPO / page).read_text(encoding="utf-8")
    section = text[text.index("## From Python"):] if page == "README.md" else text
    return re.search(r"```python\n(.*?)```", section, re.S).group(1)  # type: ignore[union-attr]


@pytest.mark.parametrize("page", ["README.md", "docs/python-api.md"])
def test_api_snippet_runs_and_names_real_attributes(page, tmp_path, monkeypatch):
    snippet = api_snippet(page)
    monkeypatch.chdir(tmp_path)
    scope: dict[str, object] = {}
    exec(compile(snippet, page, "exec"), scope)  # noqa: S102 (our own documentation)
    results, torque = scope["results"], scope["torque"]
    assert len(torque) == len(results.t) == 200  # type: ignore[attr-defined]
    assert (tmp_path / "out.csv").read_text().count("\n") == 201
    # every attribute the comments promise exists ("Results: .columns, .data ...")
    promised = re.findall(r"\.([a-z_]+)", snippet.split("# Results:", 1)[1].splitlines()[0])
    assert promised and all(hasattr(results, name) for name in promised), promised
