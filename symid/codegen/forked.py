"""One pure computation in a forked child process while this one works on.

A cold C build is Python work from end to end (derive, sample the plan,
print, render) before the compiler runs; on two cores the plan's sample (a
Newton solve through the lambdified reference evaluator, with the imports it
needs) runs beside the rest of the build (compiling the templates) instead of before it. The child is
a fork: it has the parent's modules and objects already, computes one value
and sends it back pickled through a pipe (floats exactly).

Forking is used only where it is safe: on Linux, with no other thread than
symid's own status line (a forked child has no threads; one that needed a
lock another thread held would hang). Anywhere else, and whenever the child
fails for any reason, the value is computed here, so the result never
depends on whether a child ran.
"""

from __future__ import annotations

import gc
import os
import pickle
import select
import signal
import sys
import threading
import warnings
from typing import Callable, Generic, TypeVar

V = TypeVar("V")

ENABLED = True  # tests compare both paths
_HARMLESS_THREADS = ("symid-status",)  # waits on an event, writes only to the parent's stderr


def usable() -> bool:
    """Whether this process may fork a child for a computation now."""
    if not ENABLED or not sys.platform.startswith("linux") or not hasattr(os, "fork"):
        return False
    me = threading.current_thread()
    return me is threading.main_thread() and all(
        t is me or t.name in _HARMLESS_THREADS for t in threading.enumerate())


class Pending(Generic[V]):
    """`compute()` under way in a child (or, if none could start, to be done by `result`)."""

    def __init__(self, compute: Callable[[], V], fork: bool = True) -> None:
        """fork: start a child if `usable` (False: `result` computes here, when asked)."""
        self._compute = compute
        self._pid = 0
        self._read = -1
        if fork and usable():
            self._start()

    def _start(self) -> None:
        read, write = os.pipe()
        try:
            with warnings.catch_warnings():  # Python 3.12 warns of threads; the status line's is harmless
                warnings.simplefilter("ignore", DeprecationWarning)
                pid = os.fork()
        except OSError:  # no memory or process slots for a child: compute here
            os.close(read)
            os.close(write)
            return
        if pid == 0:  # the child: never returns into the caller's code
            _child(self._compute, read, write)
        os.close(write)
        self._pid, self._read = pid, read

    def ready(self) -> bool:
        """Whether `result` would return without waiting for the child."""
        if self._read < 0:
            return self._pid == 0
        poll = select.poll()  # not select.select: it refuses descriptors past 1023
        poll.register(self._read, select.POLLIN)
        return bool(poll.poll(0))

    def result(self) -> V:
        """The value: the child's, or computed here if no child ran or it failed."""
        if self._pid:
            try:
                with os.fdopen(self._read, "rb") as pipe:
                    self._read = -1
                    data = pipe.read()
                _, status = os.waitpid(self._pid, 0)
            except BaseException:  # Ctrl-C while waiting: the child goes too
                _end(self._pid)
                raise
            finally:
                self._pid = 0
            if os.waitstatus_to_exitcode(status) == 0 and data:
                tag, value = pickle.loads(data)
                if tag == "ok":
                    return value  # type: ignore[no-any-return]
        return self._compute()  # no child, or it failed: here, where a failure is reported as usual

    def __del__(self) -> None:
        if self._pid:  # never collected: the caller stopped before asking (an error, Ctrl-C)
            _end(self._pid)
            os.close(self._read)


def _end(pid: int) -> None:
    try:
        os.kill(pid, signal.SIGKILL)
        os.waitpid(pid, 0)
    except OSError:
        pass


def _child(compute: Callable[[], object], read: int, write: int) -> None:
    """Compute, send ("ok", value) or ("failed", None), and exit without running
    any of the parent's exit handlers or flushing its buffers."""
    code = 1
    try:
        gc.disable()  # a collection would walk (and copy) every page shared with the parent
        os.close(read)
        for signum in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
            signal.signal(signum, signal.SIG_DFL)  # Ctrl-C ends the child at once
        sys.stdout = sys.stderr = open(os.devnull, "w")  # never the parent's streams (their locks)
        warnings.simplefilter("ignore")
        try:
            data = pickle.dumps(("ok", compute()))
        except Exception:  # the parent computes it again and reports the failure
            data = pickle.dumps(("failed", None))
        with os.fdopen(write, "wb") as pipe:
            pipe.write(data)
        code = 0
    finally:
        os._exit(code)
