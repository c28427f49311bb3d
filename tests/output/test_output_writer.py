"""Every output of every command goes through the one atomic writer, tried the
way a machine fails: the format follows the suffix or is refused; a real full
device (/dev/full) behind a link, a real FIFO with a reader, a real full disk
(a tiny tmpfs, as root) and a real file-size limit (RLIMIT_FSIZE) end in one
line and exit 2 with nothing half-written; `symid generate` writes its folder
as a whole and never replaces a file it did not write without `--force`; and
no command leaves a file in the current folder that nobody asked for.
(Issue 32, point 1.)"""

from __future__ import annotations

import errno
import json
import os
import resource
import shutil
import signal
import stat
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from symid import api
from symid.cli import main
from symid.io.folder import MANIFEST
from tiers import first_quick

REPO = Path(__file__).resolve().parents[2]
CRANK = str(api.example("slider_crank"))
FOUR_BAR = str(api.example("four_bar"))
STEPS = "21"
TIMEOUT = 600
SOLVE = ["solve", CRANK, "--steps", STEPS]
SWEEP = ["sweep", CRANK, "--grid", "L_rod=0.25:0.4:3", "--steps", STEPS, "--backend", "numpy"]
OPTIMIZE = ["optimize", CRANK, "--minimize", "motor.effort_rms", "--vary", "L_rod=0.25:0.4", "--steps", STEPS,
            "--backend", "numpy"]


def one_line(err: str) -> str:
    """The only non-empty line of stderr; no traceback."""
    assert "Traceback" not in err, err
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1, f"stderr is not one line: {err!r}"
    return lines[0]


def run(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    """`symid ARGS` in this process: (exit status, stderr)."""
    status = main(args)
    return status, capsys.readouterr().err


def symid(args: list[str], cwd: Path, limit: int | None = None,
          python: bool = False) -> subprocess.CompletedProcess[str]:
    """`python -m symid ARGS` (`python ARGS` if `python`) in a child, under a file-size limit of
    `limit` bytes if given (SIGXFSZ ignored before symid starts, as a shell's `ulimit -f` with
    `trap '' XFSZ` would)."""
    def limited() -> None:
        if limit is not None:
            signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
            resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    env = {**os.environ, "PYTHONDONTWRITEBYTECODE": "1",
           "PYTHONPATH": os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")]))}
    return subprocess.run([sys.executable, *([] if python else ["-m", "symid"]), *args], cwd=cwd, env=env,
                          capture_output=True,
                          text=True, timeout=TIMEOUT, preexec_fn=limited)


MARK = "symid-test-command"


def symids(commands: list[list[str]], cwd: Path, limit: int | None = None) -> list[tuple[int, str, list[str]]]:
    """Each `symid ARGS` of `commands` in turn in one child interpreter (the
    limit and SIGXFSZ as `symid`'s), as `python -m symid` runs one (cli.main;
    at the end leave(), the exit handlers): per command its exit status, its
    stderr and the current folder's names after it. The imports and the
    derivations the commands share happen once."""
    driver = ("import json, os, sys\n"
              "from symid.cli.entry import leave, main\n"
              "for command in json.loads(sys.argv[1]):\n"
              f"    print({MARK!r}, file=sys.stderr, flush=True)\n"
              "    status = main(command)\n"
              "    sys.stderr.flush()\n"
              f"    print({MARK!r}, json.dumps([status, sorted(os.listdir())]), flush=True)\n"
              "leave(0)\n")
    proc = symid(["-c", driver, json.dumps(commands)], cwd, limit, python=True)
    assert proc.returncode == 0, proc.stderr
    reports = [json.loads(line.split(" ", 1)[1]) for line in proc.stdout.splitlines() if line.startswith(MARK + " ")]
    errs = proc.stderr.split(MARK + "\n")
    assert len(reports) == len(commands) and errs[0] == "" and len(errs) == len(commands) + 1, proc.stderr
    return [(status, err, left) for (status, left), err in zip(reports, errs[1:])]


def contents(folder: Path) -> dict[str, bytes]:
    """Every entry of a folder, hidden ones included, with its bytes (a link: its target's name)."""
    return {p.name: (os.readlink(p).encode() if p.is_symlink() else p.read_bytes() if p.is_file() else b"<dir>")
            for p in sorted(folder.iterdir())}


# -- the format follows the suffix, or the output is refused -------------------------------

@pytest.mark.parametrize("command, name, accepted", [
    (SWEEP, "out.npz", ".csv or .parquet"),  # wrote CSV text into out.npz, exit 0
    (SWEEP, "out.txt", ".csv or .parquet"),
    (SOLVE, "out.txt", ".csv, .npz or .parquet"),
    (SOLVE, "out", ".csv, .npz or .parquet"),
    (OPTIMIZE, "best.csv", ".toml"),
])
def test_an_output_suffix_the_command_does_not_write_is_refused_naming_it(tmp_path, capsys, command, name, accepted):
    out = tmp_path / name
    status, err = run([*command, "-o", str(out)], capsys)
    assert status == 2
    line = one_line(err)
    given = f"suffix {out.suffix!r}" if out.suffix else "no suffix"
    assert line.startswith(f"symid: {out}: {given}: ") and accepted in line, line
    assert list(tmp_path.iterdir()) == []


def test_a_device_without_a_suffix_gets_the_commands_default_format(capsys):
    status, _ = run([*SOLVE, "-o", "/dev/null"], capsys)
    assert status == 0
    assert stat.S_ISCHR(os.stat("/dev/null").st_mode)


# -- devices, FIFOs and links: written into, never replaced --------------------------------

@pytest.mark.parametrize("command", [SWEEP, SOLVE], ids=["sweep", "solve"])
@pytest.mark.parametrize("suffix", [".parquet", ".csv"])
def test_an_output_linked_to_a_full_device_is_exit_2_and_the_link_kept(tmp_path, capsys, command, suffix):
    link = tmp_path / f"out{suffix}"
    link.symlink_to("/dev/full")  # a real device whose every write fails with ENOSPC
    status, err = run([*command, "-o", str(link)], capsys)
    assert status == 2
    assert one_line(err) == f"symid: {link}: cannot write: {os.strerror(errno.ENOSPC)}"
    assert link.is_symlink() and os.readlink(link) == "/dev/full", "the link was replaced by a regular file"
    assert [p.name for p in tmp_path.iterdir()] == [link.name]  # no temporary file either


def release(fifo: Path) -> None:
    """End a reader still waiting on `fifo` for a writer (one that never came: the run wrote
    elsewhere): open it for writing and close it, which adds no bytes to what it reads."""
    try:
        os.close(os.open(fifo, os.O_WRONLY | os.O_NONBLOCK))
    except OSError as exc:  # ENXIO: no reader left, it has read the whole table
        assert exc.errno == errno.ENXIO, exc


@pytest.mark.parametrize("command", [SWEEP, SOLVE], ids=["sweep", "solve"])
def test_a_parquet_output_that_is_a_fifo_gets_the_table_and_stays_a_fifo(tmp_path, capsys, command):
    pq = pytest.importorskip("pyarrow.parquet")
    regular = tmp_path / "regular.parquet"
    assert run([*command, "-o", str(regular)], capsys)[0] == 0
    fifo = tmp_path / "pipe.parquet"
    os.mkfifo(fifo)
    (tmp_path / "keep").mkdir()
    os.link(fifo, tmp_path / "keep" / "fifo")  # the FIFO itself, reachable even if symid replaced its name
    received: list[bytes] = []
    reader = threading.Thread(target=lambda: received.append(fifo.read_bytes()))
    reader.start()
    status, err = run([*command, "-o", str(fifo)], capsys)
    release(tmp_path / "keep" / "fifo")
    reader.join(TIMEOUT)
    assert status == 0, err
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode), "the FIFO was replaced"
    assert len(received) == 1 and received[0][:4] == b"PAR1" and received[0][-4:] == b"PAR1"
    got = tmp_path / "got.parquet"
    got.write_bytes(received[0])
    assert pq.read_table(got).equals(pq.read_table(regular)), "the reader got another table than a file gets"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["got.parquet", "keep", "pipe.parquet", "regular.parquet"]


@pytest.mark.parametrize("command, suffix", [(SOLVE, ".csv"), (SWEEP, ".parquet")], ids=["solve", "sweep"])
def test_a_link_to_a_regular_file_is_kept_and_its_target_replaced(tmp_path, capsys, command, suffix):
    (tmp_path / "data").mkdir()
    target = tmp_path / "data" / f"table{suffix}"
    target.write_bytes(b"old")
    link = tmp_path / f"out{suffix}"
    link.symlink_to(target)
    assert run([*command, "-o", str(link)], capsys)[0] == 0
    assert link.is_symlink() and Path(os.readlink(link)) == target
    assert target.read_bytes() != b"old" and target.stat().st_size > 100
    assert [p.name for p in (tmp_path / "data").iterdir()] == [target.name]  # no temporary left


# -- a full disk, a file-size limit: exit 2, the old file as it was -------------------------

TABLES = [(SWEEP, ".parquet"), (SWEEP, ".csv"), (SOLVE, ".npz"), (SOLVE, ".parquet")]
TABLE_IDS = ["sweep-parquet", "sweep-csv", "solve-npz", "solve-parquet"]


@pytest.mark.parametrize("command, suffix", first_quick(TABLES, keep=2, ids=TABLE_IDS))
def test_a_table_over_a_file_size_limit_is_exit_2_and_the_old_one_kept(tmp_path, capsys, command, suffix):
    (tmp_path / "warm").mkdir()  # the solver built first: the limit must hit the table, not the cache
    assert run([*command, "-o", str(tmp_path / "warm" / f"out{suffix}")], capsys)[0] == 0
    shutil.rmtree(tmp_path / "warm")
    old = tmp_path / f"out{suffix}"
    old.write_bytes(b"the previous table")
    proc = symid([*command, "-o", old.name], tmp_path, limit=512)  # smaller than any of these tables
    assert proc.returncode == 2, proc.stderr
    assert one_line(proc.stderr) == f"symid: {old.name}: cannot write: {os.strerror(errno.EFBIG)}"
    assert contents(tmp_path) == {old.name: b"the previous table"}  # and no temporary file


@pytest.mark.parametrize("command, suffix", TABLES, ids=TABLE_IDS)
def test_a_table_onto_a_full_disk_is_exit_2_and_the_old_one_kept(tiny_disk, capsys, command, suffix):
    old = tiny_disk / f"out{suffix}"
    old.write_bytes(b"the previous table")
    free = os.statvfs(tiny_disk).f_bavail * os.statvfs(tiny_disk).f_frsize
    (tiny_disk / "filler").write_bytes(b"\0" * free)  # nothing left
    status, err = run([*command, "-o", str(old)], capsys)
    assert status == 2
    assert one_line(err) == f"symid: {old}: cannot write: {os.strerror(errno.ENOSPC)}"
    assert sorted(contents(tiny_disk)) == ["filler", old.name] and old.read_bytes() == b"the previous table"


# -- generate: a folder written as a whole, files it did not write kept --------------------

def test_generate_refuses_to_replace_a_makefile_it_did_not_write_unless_forced(tmp_path, capsys):
    out = tmp_path / "sc"
    out.mkdir()
    mine = b"all:\n\techo my own build\n"
    (out / "Makefile").write_bytes(mine)
    status, err = run(["generate", FOUR_BAR, "--target", "c", "-o", str(out)], capsys)
    assert status == 2
    assert one_line(err) == (f"symid: {out / 'Makefile'}: a file symid did not generate; nothing written "
                             "(give --force to replace it)")
    assert contents(out) == {"Makefile": mine}, "something was written beside the user's Makefile"
    assert main(["generate", FOUR_BAR, "--target", "c", "-o", str(out), "--force"]) == 0
    assert (out / "Makefile").read_bytes() != mine
    assert sorted(contents(out)) == sorted([MANIFEST, "Makefile", "four_bar_solver.c", "four_bar_solver.h"])
    before = contents(out)
    # its own files it replaces without --force, also changed ones (another --set), and another target beside
    assert main(["generate", FOUR_BAR, "--target", "c", "-o", str(out), "--set", "L_crank=0.11"]) == 0
    assert contents(out)["four_bar_solver.h"] != before["four_bar_solver.h"]
    assert main(["generate", FOUR_BAR, "--target", "casadi", "-o", str(out)]) == 0
    assert main(["generate", FOUR_BAR, "--target", "casadi", "-o", str(out), "--set", "L_crank=0.12"]) == 0
    capsys.readouterr()


def old_and_new(out: Path) -> dict[str, bytes]:
    """Generate the four-bar's C into `out` (the old folder); its bytes."""
    assert main(["generate", FOUR_BAR, "--target", "c", "-o", str(out)]) == 0
    return contents(out)


NEW = ["generate", FOUR_BAR, "--target", "c", "--set", "L_crank=0.11"]  # every file differs from the old one's


@pytest.fixture
def tiny_disk(tmp_path):
    """A real file system of 1 MiB (tmpfs), unmounted after the test: root only."""
    if os.geteuid() != 0 or shutil.which("mount") is None:
        pytest.skip("mounting a tmpfs needs root")
    disk = tmp_path / "disk"
    disk.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=1m", "tmpfs", str(disk)]).returncode != 0:
        pytest.skip("cannot mount a tmpfs here")
    try:
        yield disk
    finally:
        subprocess.run(["umount", str(disk)], check=True)


def test_generate_onto_a_full_disk_leaves_the_old_folder_byte_for_byte(tiny_disk, capsys):
    out = tiny_disk / "fb"
    before = old_and_new(out)
    capsys.readouterr()
    # fill the disk but for room for the new header (13 KB), not the new source (54 KB): written
    # file by file, the old source stayed beside the new header (two solvers mixed)
    room = 24 << 10
    free = os.statvfs(tiny_disk).f_bavail * os.statvfs(tiny_disk).f_frsize
    (tiny_disk / "filler").write_bytes(b"\0" * (free - room))
    status, err = run([*NEW, "-o", str(out)], capsys)
    assert status == 2
    line = one_line(err)
    assert line.startswith(f"symid: {out}/") and line.endswith(f": cannot write: {os.strerror(errno.ENOSPC)}"), line
    assert ".symid-generate" not in line, "the line names the staging folder, not the output"
    assert contents(out) == before, "the old folder changed"
    (tiny_disk / "filler").unlink()
    assert main([*NEW, "-o", str(out)]) == 0  # with room, the new solver replaces it whole
    assert contents(out)["four_bar_solver.c"] != before["four_bar_solver.c"]


@pytest.mark.slow  # generates the four-bar twice, once in a child under the limit
def test_generate_over_a_file_size_limit_leaves_the_old_folder_byte_for_byte(tmp_path, capsys):
    out = tmp_path / "fb"
    before = old_and_new(out)
    capsys.readouterr()
    limit = 16 << 10  # the new header (13 KB) fits, the new source (54 KB) does not
    fresh = tmp_path / "fresh"  # a new folder that cannot be written whole is not left behind at all
    (status, err, _), (fresh_status, fresh_err, _) = symids([[*NEW, "-o", str(out)], [*NEW, "-o", str(fresh / "c")]],
                                                            tmp_path, limit)
    assert status == 2, err
    line = one_line(err)
    assert line.startswith(f"symid: {out}/") and line.endswith(f": cannot write: {os.strerror(errno.EFBIG)}"), line
    assert contents(out) == before, "the old folder changed"
    assert fresh_status == 2, fresh_err
    assert not fresh.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fb"]


# -- nothing in the current folder that nobody asked for -----------------------------------

@pytest.mark.slow  # every command in turn (78 s under load)
def test_no_command_leaves_a_file_in_the_current_folder(tmp_path):
    here = tmp_path / "here"
    here.mkdir()
    out = tmp_path / "out"
    out.mkdir()
    # what a command leaves does not depend on the table's length: 5 instants (the
    # GIF's 5 frames, not 21) and 2 variants take every command's writing path
    few = ["--steps", "5"]
    commands = [
        ["solve", CRANK, *few, "-o", str(out / "run.csv"), "--plot"],
        ["solve", CRANK, *few, "-o", str(out / "run.npz"), "--backend", "casadi"],
        ["sweep", CRANK, "--grid", "L_rod=0.25:0.4:2", *few, "--backend", "numpy", "-o", str(out / "sweep.parquet"),
         "--plot"],
        ["plot", str(out / "run.csv"), "--mechanism", CRANK, "-o", str(out / "figures"), "--gif"],
        ["optimize", CRANK, "--minimize", "motor.effort_rms", "--vary", "L_rod=0.25:0.4", *few, "--backend", "numpy",
         "-o", str(out / "best.toml")],
        ["generate", FOUR_BAR, "--target", "casadi", "-o", str(out / "fb")],
        ["sweep", CRANK, "--grid", "L_rod=0.25:0.4:2", *few, "--gradients", "-o", str(out / "g.csv")],
    ]
    # one interpreter runs them in turn (symids): the imports of sympy, numpy, matplotlib and casadi once
    for command, (status, err, left) in zip(commands, symids(commands, here)):
        assert status == 0, (command, err)
        assert left == [], f"{command[0]} left {left}"
    assert list(here.iterdir()) == [], f"the process's exit left {[p.name for p in here.iterdir()]}"
    assert not [p for p in out.rglob("*") if ".tmp" in p.name or p.name.startswith(".symid-generate.")]


# slow: a child writing to a FIFO and its figures; tests/io/test_machine_faults.py keeps a FIFO in the quick
# tier
@pytest.mark.slow
@pytest.mark.parametrize("command, stem", first_quick([(SOLVE, "slider_crank"), (SWEEP, "slider_crank_sweep")],
                                                     ids=["solve", "sweep"]))
def test_plots_of_a_table_sent_to_a_fifo_go_to_the_current_folder_named_after_the_mechanism(tmp_path, command, stem):
    """`-o PIPE --plot`: the pictures cannot go beside a stream (they were
    written as /dev/null_figures.png); they go to the current folder, named
    after the mechanism, and nothing lands beside the FIFO."""
    (tmp_path / "pipes").mkdir()
    fifo = tmp_path / "pipes" / "table.csv"
    os.mkfifo(fifo)
    (tmp_path / "run").mkdir()
    received: list[bytes] = []
    reader = threading.Thread(target=lambda: received.append(fifo.read_bytes()))
    reader.start()
    done = symid([*command, "-o", str(fifo), "--plot"], tmp_path / "run")
    reader.join(TIMEOUT)
    assert done.returncode == 0, done.stderr
    assert received and received[0].startswith(b"variant," if command is SWEEP else b"t,")
    assert sorted(p.name for p in (tmp_path / "pipes").iterdir()) == ["table.csv"], "a picture beside the FIFO"
    pictures = sorted(p.name for p in (tmp_path / "run").iterdir())
    assert pictures and all(name.startswith(stem + "_") and name.endswith(".png") for name in pictures), pictures
