"""Results remembered for frozen (read-only) input arrays.

The engine freezes every node output it hands on (``writeable = False`` on the
array and its bases), so a frozen array's numbers never change while it lives.
A batch's rows, and a page's light drags, feed the *same* upstream arrays (a
20-megapixel mask, its pixel heights) to every run of a node whose light
changes; what a node derives from those arrays alone (a shrunken proxy scene,
a cutout's bounding box) is the same each time. :class:`FrozenMemo` keeps a few
such results, keyed by the arrays' identities and checked by weak references:
an entry is used only while every one of its arrays is still the same live,
frozen object, so a new array (even at a reused address) or a writable one is
always computed afresh.
"""
from __future__ import annotations

import threading
import weakref
from collections import OrderedDict

import numpy as np


def frozen(a) -> bool:
    """True when no one can write ``a``'s numbers: it and every array it views are
    read-only (the engine freezes every node output it hands on)."""
    while isinstance(a, np.ndarray):
        if a.flags.writeable:
            return False
        a = a.base
    return a is None


class FrozenMemo:
    """At most ``size`` results, each for a tuple of frozen arrays and a hashable
    ``extra`` (sizes, params); least recently used dropped first."""

    def __init__(self, size: int = 4):
        self.size = size
        self._items: OrderedDict = OrderedDict()
        self._lock = threading.Lock()

    def get(self, arrays: tuple, extra=None):
        """The remembered result for these arrays and ``extra``, or None."""
        key = (tuple(id(a) for a in arrays), extra)
        with self._lock:
            hit = self._items.get(key)
            if hit is None:
                return None
            refs, value = hit
            if all(r() is a for r, a in zip(refs, arrays)) and all(frozen(a) for a in arrays):
                self._items.move_to_end(key)
                return value
            del self._items[key]
            return None

    def put(self, arrays: tuple, extra, value) -> None:
        """Remember ``value`` when every array is frozen (else nothing: it could change)."""
        if not all(isinstance(a, np.ndarray) and frozen(a) for a in arrays):
            return
        key = (tuple(id(a) for a in arrays), extra)
        with self._lock:
            self._items[key] = (tuple(weakref.ref(a) for a in arrays), value)
            self._items.move_to_end(key)
            while len(self._items) > self.size:
                self._items.popitem(last=False)
