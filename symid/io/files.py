"""Reading and writing the user's files so that no machine fault costs a traceback.

Every output of every command (tables, plots, the optimum's snippet, generated
code) goes through `atomic_write`, its format chosen by `output_format` (the
suffix, or refused); `symid.io.folder` writes a generated folder as a whole.
Every input a user names (mechanism file, motion table) goes through
`read_at_most`, so a device or an endless stream (`/dev/zero`) is never read
past its size limit.
"""

from __future__ import annotations

import errno
import os
import shutil
import stat
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any, Callable, Iterator, Sequence

from symid.errors import InputError
from symid.io.limits import MAX_FILE_BYTES


def read_at_most(path: str | Path, limit: int) -> bytes:
    """The file's bytes, or its first limit + 1 bytes when it is longer.

    A caller compares the length with `limit`; `stat().st_size` alone would
    let a device or a pipe (size 0) be read without end.

    Raises:
        OSError: the file cannot be opened or read.
    """
    with open(path, "rb") as f:
        return f.read(limit + 1)


def read_text(path: str | Path, fail: Callable[[str], InputError] | None = None) -> str:
    """An input file (mechanism, motion table, claims, variants) as UTF-8 text, read
    no further than MAX_FILE_BYTES (a device or endless stream is refused). A
    leading byte-order mark (spreadsheets write one before CSV text) is dropped:
    it is no part of the first name.

    Raises:
        InputError: `fail(reason)`, by default "PATH: reason".
    """
    def default(reason: str) -> InputError:
        return InputError(f"{path}: {reason}")

    fail = fail or default
    try:
        data = read_at_most(path, MAX_FILE_BYTES)
        if len(data) > MAX_FILE_BYTES:
            raise fail(f"file is longer than the {MAX_FILE_BYTES} bytes allowed")
        return data.decode("utf-8-sig")
    except OSError as exc:
        raise fail(f"cannot read: {exc.strerror or exc}") from None
    except UnicodeDecodeError:
        raise fail("not UTF-8 text") from None


def cannot_write(path: str | Path, exc: OSError) -> InputError:
    """The one line for a failed write: the path and the system's reason (exit 2)."""
    return InputError(f"{path}: cannot write: {exc.strerror or exc}")


def new_file_mode() -> int:
    """The mode an ordinary new file gets under the current umask (mkstemp makes 0600)."""
    umask = os.umask(0)
    os.umask(umask)
    return 0o666 & ~umask


def check_target(path: str | Path) -> None:
    """Refuse, before any work, an output path that is a directory, in no
    folder, under a file, or in a folder this process cannot write (a
    read-only folder or file system: the new file is made beside its name and
    renamed over it, so the folder must take it; a device or FIFO is written
    into and needs no such folder).

    Raises:
        InputError: one line naming the path.
    """
    path = Path(path)
    if path.is_dir():
        raise InputError(f"{path}: cannot write: is a directory")
    if not path.parent.is_dir():
        check_folder(path.parent, path)
        raise InputError(f"{path}: cannot write: no folder {path.parent} ({os.strerror(errno.ENOENT)})")
    land = _landing(path)
    if land.exists() and not land.is_file():
        return
    folder = land.parent
    if folder.is_dir() and not os.access(folder, os.W_OK | os.X_OK,
                                         effective_ids=os.access in os.supports_effective_ids):
        try:
            read_only = bool(os.statvfs(folder).f_flag & os.ST_RDONLY)
        except OSError:
            read_only = False
        why = "is on a read-only file system" if read_only else "is not writable by this user"
        raise InputError(f"{path}: cannot write: the folder {folder} {why}")


def check_folder(folder: str | Path, named: str | Path | None = None) -> None:
    """Refuse a folder that a file stands in the way of (`folder` itself or one
    above it), before any work, naming that file and `named` (default `folder`).

    Raises:
        InputError: one line, "NAMED: cannot write: FILE is a file, not a folder".
    """
    folder = Path(folder)
    blocker = next((p for p in (folder, *folder.parents) if p.exists() and not p.is_dir()), None)
    if blocker is not None:
        raise InputError(f"{named or folder}: cannot write: {blocker} is a file, not a folder")


def make_folder(path: str | Path) -> Path:
    """mkdir -p for an output folder (of plots), one line when it cannot be one.

    Raises:
        InputError: `path` or a folder above it is a file, or cannot be made
            (permission, read-only file system): naming the path.
    """
    path = Path(path)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except (FileExistsError, NotADirectoryError):
        check_folder(path)
        raise InputError(f"{path}: cannot write: {path} is a file, not a folder") from None
    except OSError as exc:
        raise cannot_write(path, exc) from None
    return path


def output_format(path: str | Path, suffixes: Sequence[str], what: str) -> str:
    """The format of an output, by its suffix: one of `suffixes` (".csv", ...).

    An existing device or FIFO (`/dev/null`, `/dev/stdout`, a named pipe)
    whose name has none of them gets the first, the command's default: it is
    written into, never replaced, so its name is not the user's choice of format.

    Raises:
        InputError: any other suffix (or none), one line naming it and those accepted.
    """
    suffix = Path(path).suffix.lower()
    if suffix in suffixes:
        return suffix
    try:
        mode = os.stat(path).st_mode
    except OSError:
        mode = stat.S_IFREG  # absent (or unreachable: the write names that): the suffix decides
    if not stat.S_ISREG(mode) and not stat.S_ISDIR(mode):
        return suffixes[0]
    given = f"suffix {Path(path).suffix!r}" if suffix else "no suffix"
    accepted = suffixes[0] if len(suffixes) == 1 else f"{', '.join(suffixes[:-1])} or {suffixes[-1]}"
    raise InputError(f"{path}: {given}: {what} is written as {accepted} (the suffix chooses the format)")


def beside(out: str | Path, name: str) -> tuple[Path, str]:
    """The folder and stem of the pictures that go with the table `out`: its
    folder and stem, or, when `out` is a device or FIFO (`-o /dev/null`, a named
    pipe), the current folder and the mechanism's `name` (not /dev/null_figures.png)."""
    out = Path(out)
    try:
        streamed = not stat.S_ISREG(os.stat(out).st_mode)
    except OSError:
        streamed = False  # absent: a file to be written there
    return (Path("."), name) if streamed else (out.parent, out.stem)


def _landing(path: Path) -> Path:
    """Where a regular file's new bytes land: a symbolic link's target (the link is kept), else `path`."""
    return Path(os.path.realpath(path)) if path.is_symlink() else path


@contextmanager
def atomic_write(path: str | Path, binary: bool = False) -> Iterator[IO[Any]]:
    """Open `path` for writing so that it is either complete or untouched.

    A regular (or new) file is written to a temporary name in its folder,
    synced and renamed over `path` when the block ends without an exception;
    on any exception, a signal turned into one included, the temporary file is
    removed. An existing non-regular file (a character device such as
    /dev/null or /dev/full, a FIFO), or a link to one, is written into
    directly and never replaced; a link to a regular file is kept and its
    target replaced.

    Raises:
        InputError: `path` is a directory, or a write failed (disk full,
            file-size limit, permission, read-only file system, name too
            long): one line naming the path and the system's reason.
    """
    path = Path(path)
    mode = "wb" if binary else "w"
    newline = None if binary else ""
    try:
        st: os.stat_result | None = os.stat(path)
    except FileNotFoundError:
        st = None
    except OSError as exc:
        raise cannot_write(path, exc) from None
    if st is not None and stat.S_ISDIR(st.st_mode):
        raise InputError(f"{path}: cannot write: is a directory")
    if st is not None and not stat.S_ISREG(st.st_mode):
        try:
            with open(path, mode, newline=newline) as out:
                yield out
        except BrokenPipeError:  # `-o /dev/stdout | head`: the reader has enough, as for stdout
            raise
        except OSError as exc:
            raise cannot_write(path, exc) from None
        return
    with atomic_path(path) as tmp:
        with open(tmp, mode, newline=newline) as out:
            yield out
            out.flush()
            os.fsync(out.fileno())  # the rename must not publish data still in the page cache


@contextmanager
def atomic_path(path: Path, suffix: str = ".tmp") -> Iterator[Path]:
    """A temporary name beside `path`, for a writer that needs a file name
    (Pillow's GIF writer): renamed over `path` when the block ends (a device
    or FIFO is written into instead, a link kept), removed on any exception
    (a signal turned into one included).

    Raises:
        InputError: the folder cannot take the file, or the rename failed.
    """
    shown, path = path, _landing(Path(path))
    into = path.exists() and not path.is_file() and not path.is_dir()  # a device or FIFO: its folder may be /dev
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=suffix, dir=None if into else path.parent)
    except OSError as exc:
        raise cannot_write(shown, exc) from None
    os.close(fd)
    try:
        yield Path(tmp)
        if into:
            with open(tmp, "rb") as made, open(path, "wb") as out:
                shutil.copyfileobj(made, out)
            os.unlink(tmp)
            return
        os.chmod(tmp, new_file_mode())
        os.replace(tmp, path)
    except OSError as exc:
        Path(tmp).unlink(missing_ok=True)
        raise cannot_write(shown, exc) from None
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
