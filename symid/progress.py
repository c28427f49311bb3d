"""A progress bar for long solves: on a terminal only, silent in a pipe or under CI.

A few lines of our own rather than a dependency: one bar, one line on stderr,
redrawn at most every `INTERVAL` seconds, showing the rate in instants/s.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import sys
import threading
import time
from typing import Callable, Iterable, Iterator, Mapping, TextIO, TypeVar

Item = TypeVar("Item")

DELAY = 0.5     # s before the bar first shows, so that quick solves print nothing
INTERVAL = 0.1  # s between redraws: drawing stays a negligible cost per instant


def enabled(stream: TextIO, environ: Mapping[str, str] | None = None) -> bool:
    """True when `stream` is a terminal and the environment is not CI.

    `CI` counts as set unless empty, "0" or "false" (CI services set CI=true).
    """
    env = os.environ if environ is None else environ
    if env.get("CI", "").strip().lower() not in ("", "0", "false"):
        return False
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError, OSError):  # no isatty, or a closed stream
        return False


def _clock(seconds: float) -> str:
    seconds = int(round(seconds))
    return f"{seconds // 3600}:{seconds // 60 % 60:02d}:{seconds % 60:02d}" if seconds >= 3600 \
        else f"{seconds // 60}:{seconds % 60:02d}"


def render(label: str, done: int, total: int | None, elapsed: float, width: int, fill: str = "#",
           unit: str = "instants") -> str:
    """One line of the bar, at most `width` characters.

    Args:
        done: instants solved; total: instants in the run (None: unknown).
        elapsed: seconds since the start; fill: the bar's character; unit: what is counted.
    """
    rate = done / elapsed if elapsed > 0 else 0.0
    speed = f"{rate:.4g} {unit}/s"
    if not total:
        return f"{label} {done} {unit}  {speed}  {_clock(elapsed)}"[:width]
    left = _clock((total - done) / rate) if rate > 0 else "?"
    head = f"{label} {100 * done // total:3d}% "
    tail = f" {done}/{total}  {speed}  {left} left"
    room = max(width - len(head) - len(tail) - 2, 0)
    cells = min(room, 40)
    filled = cells * done // total
    return (head + "|" + fill * filled + " " * (cells - filled) + "|" + tail)[:width]


# Streams on which a bar's line is open (shown, not yet ended by a newline).
# A bar suspended at its `yield` when the consumer fails ends its line only
# when the generator is closed, which may be after the error is printed:
# `end_lines` ends them first, so the message starts on a line of its own.
_OPEN: list[TextIO] = []


def end_lines() -> None:
    """End the line of every bar still open (before a message on stderr)."""
    while _OPEN:
        stream = _OPEN.pop()
        try:
            stream.write("\n")
            stream.flush()
        except (OSError, ValueError):  # a closed or broken stream: nothing to end
            pass


def bar(items: Iterable[Item], total: int | None = None, label: str = "solve",
        stream: TextIO | None = None, environ: Mapping[str, str] | None = None,
        delay: float | None = None, clock: Callable[[], float] = time.monotonic,
        unit: str = "instants", size: Callable[[Item], int] | None = None) -> Iterator[Item]:
    """Yield `items` unchanged, showing their progress on `stream` (default stderr).

    `size(item)` is how many instants an item holds (default 1: a block of
    rows counts its rows).

    Nothing is written unless `enabled(stream)`, nor before `delay` seconds
    (default `DELAY`).
    Once shown, the bar's last state stays on its own line when the items
    end, also when they end by an exception (so an error message that follows
    starts on a fresh line).
    """
    out = sys.stderr if stream is None else stream
    wait = DELAY if delay is None else delay
    if not enabled(out, environ):
        yield from items
        return
    fill = "#"
    try:
        "█".encode(getattr(out, "encoding", None) or "ascii")
        fill = "█"
    except (UnicodeEncodeError, LookupError):
        pass
    width = max(shutil.get_terminal_size((80, 24)).columns - 1, 20)
    start = clock()
    last = -float("inf")
    done = 0
    shown = False
    try:
        for item in items:
            done += 1 if size is None else size(item)
            now = clock()
            if now - start >= wait and now - last >= INTERVAL:
                if not shown:  # open before its first write: a signal inside that write still ends the line
                    _OPEN.append(out)
                last, shown = now, True
                out.write("\r" + render(label, done, total, now - start, width, fill, unit).ljust(width))
                out.flush()
            yield item
    finally:
        if shown and out in _OPEN:  # not ended already by end_lines (an error's message)
            _OPEN.remove(out)
            out.write("\r" + render(label, done, total, clock() - start, width, fill, unit).ljust(width) + "\n")
            out.flush()


# -- a status line for setup (derive, generate, compile) -------------------

SETUP_DELAY = 1.0  # s: a setup faster than this prints nothing
_STAGE = ["preparing"]


def stage(name: str) -> None:
    """Name what setup does now ("deriving", "generating", "compiling"), for `status`."""
    _STAGE[0] = name


@contextlib.contextmanager
def status(label: str, stream: TextIO | None = None, environ: Mapping[str, str] | None = None,
           delay: float = SETUP_DELAY, interval: float = 0.2) -> Iterator[None]:
    """While the body runs, show `label: STAGE... 3.2 s` on a terminal's stderr once
    it has taken `delay` seconds; then one line with the total. Silent in a pipe or under CI."""
    out = sys.stderr if stream is None else stream
    if not enabled(out, environ):
        yield
        return
    _STAGE[0] = "preparing"
    width = max(shutil.get_terminal_size((80, 24)).columns - 1, 20)
    start = time.monotonic()
    done = threading.Event()
    shown = threading.Event()

    def show() -> None:
        if done.wait(delay):
            return
        while True:
            shown.set()
            out.write("\r" + f"{label}: {_STAGE[0]}... {time.monotonic() - start:.1f} s"[:width].ljust(width))
            out.flush()
            if done.wait(interval):
                return

    thread = threading.Thread(target=show, name="symid-status", daemon=True)
    thread.start()
    try:
        yield
    finally:
        done.set()
        thread.join()
        if shown.is_set():
            out.write("\r" + f"{label}: done in {time.monotonic() - start:.1f} s"[:width].ljust(width) + "\n")
            out.flush()
