"""Where generated solvers are kept between runs, keyed by what they depend on.

The key hashes the mechanism's structure (parameter values excluded: they
are run-time inputs), the generation options and symid's own code and
templates, so a change to any of them regenerates and nothing stale is used.

The cache is an optimization, never trusted blindly (as pip's and ccache's):

- An entry is built in a private staging folder and renamed into place only
  when complete; its `complete` file then lists the sha256 of every file in
  it. Before anything is loaded the entry is checked against that list; a
  damaged or incomplete entry is set aside and rebuilt, with one warning
  line. A build that leaves an artifact missing or empty is never complete.
- Code is loaded only from folders owned by the current user that group
  and others cannot write: the entry, `plans/` and the cache root. A root
  that fails this (a shared folder with mode 1777, another user's folder),
  or that cannot be used (a file, read-only, full), is not used at all:
  symid warns once and builds in a private temporary cache removed at exit.
  Only if that too cannot be written does the run stop (exit 2, one line).
- The cache and its entries are created 0700 and their files lose group
  and other write permission, whatever the umask.
"""

from __future__ import annotations

import atexit
import dataclasses
import errno
import hashlib
import json
import os
import shutil
import stat
import sys
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING, Callable, Sequence

from symid.errors import InputError
from symid.codegen.sources import code_version

if TYPE_CHECKING:  # a cached run (symid.tools.plan) finds its solver here without sympy
    from symid.codegen.flat import Options
    from symid.model.mechanism import Mechanism

MANIFEST = "complete"
FORMAT = 1
# Errors that make a cache folder unusable rather than reveal a bug: the
# build moves to the private temporary cache.
UNUSABLE = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EPERM, errno.EFBIG})

_fallback: dict[Path, Path] = {}  # chosen root -> private temporary cache used instead, this process


def cache_root() -> Path:
    """The chosen cache: $SYMID_CACHE, else $XDG_CACHE_HOME/symid, else ~/.cache/symid.

    An empty variable counts as unset (never the current folder).
    """
    chosen = os.environ.get("SYMID_CACHE")
    if chosen:
        return Path(chosen)
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "symid"


def root() -> Path:
    """The cache to use: the chosen one, created 0700 if absent, when it is a
    private folder of the current user; else a private temporary cache (one
    warning line, once per process)."""
    chosen = cache_root()
    if chosen in _fallback:
        return _fallback[chosen]
    problem = _prepare(chosen)
    return chosen if problem is None else fall_back(chosen, problem)


def fall_back(chosen: Path, problem: str, warn: bool = True) -> Path:
    """Use a private temporary cache instead of `chosen` for the rest of this process.

    Args:
        warn: say so now (else the caller does, once the private cache served).
    """
    if chosen not in _fallback:
        try:
            private = Path(tempfile.mkdtemp(prefix="symid-cache-"))
        except OSError as exc:
            raise InputError(f"cache {chosen}: {problem}, and no temporary cache can be made "
                             f"({exc.strerror})") from None
        atexit.register(shutil.rmtree, private, True)
        _fallback[chosen] = private
        if warn:
            _warn(_falling_back(chosen, problem))
    return _fallback[chosen]


def _falling_back(chosen: Path, problem: str) -> str:
    return f"cache {chosen}: {problem}; using a private temporary cache for this run"


def _warn(message: str) -> None:
    print(f"symid: warning: {message}", file=sys.stderr)


def _prepare(chosen: Path) -> str | None:
    """Create `chosen` (and missing parents) 0700 if absent; why it cannot be used, or None."""
    if not os.path.lexists(chosen):
        try:
            make_private_dirs(chosen)
        except OSError as exc:
            return f"cannot be created ({exc.strerror})"
    problem = distrust(chosen, follow=True)
    if problem is None and not os.access(chosen, os.W_OK | os.X_OK):
        problem = "is not writable"
    return problem


def make_private_dirs(path: Path) -> None:
    """mkdir -p with mode 0700 for every folder created, whatever the umask."""
    missing = []
    while not os.path.lexists(path):
        missing.append(path)
        if path.parent == path:
            break
        path = path.parent
    for folder in reversed(missing):
        try:
            folder.mkdir(mode=0o700)
        except FileExistsError:  # made meanwhile by another run
            continue
        os.chmod(folder, 0o700)  # the umask can only remove bits, but it can remove ours


def distrust(path: Path, follow: bool = False) -> str | None:
    """Why the folder `path` must not be trusted with code, or None.

    Args:
        follow: follow a symbolic link (the root the user chose may be one;
            nothing inside the cache may).
    """
    try:
        st = os.stat(path, follow_symlinks=follow)
    except OSError as exc:
        return f"cannot be read ({exc.strerror})"
    if not stat.S_ISDIR(st.st_mode):
        return "is not a folder"
    return _distrust_owner(st)


def _distrust_owner(st: os.stat_result) -> str | None:
    if st.st_uid != os.geteuid():
        return f"is owned by another user (uid {st.st_uid})"
    if st.st_mode & 0o022:
        return f"is writable by group or others (mode {stat.S_IMODE(st.st_mode):o})"
    return None


def key(mech: Mechanism, options: Options, target: str) -> str:
    """The cache key of one generated solver."""
    from symid.model.params import is_derived  # sympy: only once a mechanism is at hand

    # base parameters are run-time inputs; a derived one's definition is compiled in
    parameters = {n: (str(e) if is_derived(e) else None) for n, e in mech.parameters.items()}
    structure = dataclasses.replace(mech, parameters=parameters, source="", analysis=None,  # type: ignore[arg-type]
                                    sizing=None)  # post-processing: a motor changed builds nothing
    text = repr((structure, options, target, code_version()))
    return hashlib.sha256(text.encode()).hexdigest()[:24]


def verify(folder: Path) -> str | None:
    """Why the entry `folder` must not be loaded, or None when every file
    listed in its manifest is there with its recorded sha256 and the entry
    and its files are private to the current user."""
    problem = distrust(folder)
    if problem is not None:
        return problem
    try:
        with open(folder / MANIFEST, "rb") as f:
            if _distrust_owner(os.fstat(f.fileno())) is not None:
                return "has a manifest others can write"
            manifest = json.loads(f.read())
        files = manifest["files"] if manifest.get("format") == FORMAT else None
        if not isinstance(files, dict) or not files:
            return "has no valid manifest"
    except FileNotFoundError:
        return "is incomplete"
    except (OSError, ValueError, AttributeError, KeyError, TypeError):
        return "has no valid manifest"
    for name, digest in files.items():
        if Path(name).is_absolute() or ".." in Path(name).parts:
            return "has no valid manifest"
        path = folder / name
        try:
            fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW)
        except OSError:
            return f"lacks {name}"
        with os.fdopen(fd, "rb") as f:
            st = os.fstat(fd)
            why = _distrust_owner(st) if stat.S_ISREG(st.st_mode) else "is not a regular file"
            if why is not None:
                return f"{name} {why}"
            if hashlib.sha256(f.read()).hexdigest() != digest:
                return f"{name} does not match its recorded sha256 (damaged)"
    return None


def inside(path: Path) -> bool:
    """Whether `path` is an entry of the cache in use (a run plan's solver must be)."""
    try:
        return Path(path).resolve().parent == root().resolve()
    except OSError:
        return False


def _seal(staging: Path, artifacts: Sequence[str], what: str) -> None:
    """Check a finished build and write its manifest (sha256 of every file).

    Raises:
        InputError: an artifact is missing or a file is empty (a broken tool).
    """
    for name in artifacts:
        if not (staging / name).is_file():
            raise InputError(f"{what}: the build left no {name}")
    files = {}
    for path in sorted(staging.rglob("*")):
        mode = path.lstat().st_mode
        os.chmod(path, stat.S_IMODE(mode) & ~0o022)
        if stat.S_ISREG(mode):
            data = path.read_bytes()
            if not data:
                raise InputError(f"{what}: the build left {path.name} empty")
            files[path.relative_to(staging).as_posix()] = hashlib.sha256(data).hexdigest()
    text = json.dumps({"format": FORMAT, "files": files}, indent=1, sort_keys=True)
    (staging / MANIFEST).write_text(text)
    os.chmod(staging / MANIFEST, 0o644)


def _discard(folder: Path) -> None:
    """Set a damaged entry aside (a rename: atomic for concurrent runs) and delete it."""
    aside = folder.with_name(f".discard-{folder.name}-{os.getpid()}")
    try:
        folder.rename(aside)
    except OSError:  # already set aside by another run, or not ours to move
        return
    if aside.is_dir() and not aside.is_symlink():
        shutil.rmtree(aside, ignore_errors=True)
    else:
        aside.unlink(missing_ok=True)


def staged_entry(staging: Path) -> Path:
    """The path the staging folder of `cached`'s `make` will have once complete."""
    return staging.with_name(staging.name.rsplit(".", 1)[0])


def cached(mech: Mechanism, options: Options, target: str, make: Callable[[Path], None],
           artifacts: Sequence[str] = (), what: str = "") -> Path:
    """The verified cache folder of one generated solver (`cached_entry`, keyed by `key`)."""
    return cached_entry(f"{target}-{mech.name}-{key(mech, options, target)}", make, artifacts,
                        what or f"{target} solver of {mech.name}")


def cached_entry(entry: str, make: Callable[[Path], None], artifacts: Sequence[str] = (), what: str = "") -> Path:
    """The verified cache folder of one generated artefact, made by `make(folder)` if
    absent or damaged.

    `make` writes into a private staging folder that is renamed into place
    only when complete, so concurrent runs and failures never leave a
    half-built entry.

    Args:
        entry: the folder's name in the cache (a key of what it depends on in it).
        artifacts: files `make` must leave (besides, no file may be empty).
        what: names the build in errors (e.g. the compiler used).
    """
    where = root()
    try:
        return _cached(where, entry, make, artifacts, what)
    except OSError as exc:
        if exc.errno not in UNUSABLE:
            raise
        if where in _fallback.values():  # already the private cache: nowhere else to build
            raise InputError(f"cache {where}: {exc.strerror}") from None
        problem = f"cannot be written ({exc.strerror})"
    chosen = cache_root()
    private = fall_back(chosen, problem, warn=False)
    try:
        folder = _cached(private, entry, make, artifacts, what)
    except OSError as exc:
        if exc.errno not in UNUSABLE:
            raise
        raise InputError(f"cache {chosen}: {problem}, nor the private temporary cache {private} "
                         f"({exc.strerror})") from None
    _warn(_falling_back(chosen, problem))  # only now: one line either way
    return folder


def _cached(base: Path, entry: str, make: Callable[[Path], None], artifacts: Sequence[str], what: str) -> Path:
    folder = base / entry
    if os.path.lexists(folder):
        problem = verify(folder)
        if problem is None:
            return folder
        _warn(f"cache entry {folder} {problem}; rebuilding it")
        _discard(folder)
    staging = Path(tempfile.mkdtemp(prefix=folder.name + ".", dir=base))
    try:
        make(staging)
        _seal(staging, artifacts, what or entry)
        try:
            staging.rename(folder)
        except OSError:  # built meanwhile by another process, or a damaged folder
            if verify(folder) is None:
                shutil.rmtree(staging, ignore_errors=True)
            else:
                _discard(folder)
                staging.rename(folder)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    return folder


def loadable(entry: Path) -> str | None:
    """Why a run plan's solver folder must not be loaded (outside the cache in
    use, or failing `verify`), or None."""
    if not inside(entry):
        return "lies outside the cache"
    return verify(entry)
