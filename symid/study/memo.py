"""What a study computes once per mechanism object and reuses for every chunk.

A sweep calls the engine once per chunk of variants (a local chunk, or a Dask
task on a worker that keeps its mechanism), always with the same Mechanism
object. Checking it, assembling it and finding its solver in the cache
(whose key prints every expression) cost about 0.1 s a call: as much as
solving a chunk of a hundred thousand instants. Mechanisms hold dicts and are
not hashable, so the memo is by identity, guarded by a weak reference (an id
can be reused once its object is gone).
"""

from __future__ import annotations

import threading
import weakref
from typing import Callable, Generic, TypeVar

V = TypeVar("V")

SIZE = 8  # objects remembered: a process runs one study at a time, a test many


class ByIdentity(Generic[V]):
    """make(obj, key) computed once per live object and key (oldest dropped past SIZE)."""

    def __init__(self) -> None:
        self._items: dict[tuple[int, str], tuple[weakref.ref[object], V]] = {}
        self._lock = threading.Lock()

    def get(self, obj: object, key: str, make: Callable[[], V]) -> V:
        slot = (id(obj), key)
        with self._lock:
            hit = self._items.get(slot)
        if hit is not None and hit[0]() is obj:
            return hit[1]
        value = make()  # outside the lock: a build may take seconds; two racing threads build twice
        with self._lock:
            self._items.pop(slot, None)
            while len(self._items) >= SIZE:
                self._items.pop(next(iter(self._items)))
            self._items[slot] = (weakref.ref(obj), value)
        return value
