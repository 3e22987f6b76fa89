"""The memory cache: an LRU of node results bounded by their total size in bytes."""
from __future__ import annotations

import collections
from typing import Any

from .cache_entry import MISS, CacheError
from .types import nbytes


class MemoryCache:
    """LRU of entries bounded by their total size in bytes (``types.nbytes``)."""

    def __init__(self, limit_bytes: int):
        if limit_bytes < 0:
            raise CacheError(f"memory cache limit must be >= 0 bytes (--cache-bytes, PIXGRAPH_CACHE_BYTES), "
                             f"got {limit_bytes}")
        self.limit_bytes = int(limit_bytes)
        self._entries: collections.OrderedDict[str, tuple[Any, int]] = collections.OrderedDict()
        self.bytes = 0

    def __contains__(self, key: str) -> bool:
        return key in self._entries

    def __len__(self) -> int:
        return len(self._entries)

    def get(self, key: str) -> Any:
        hit = self._entries.get(key)
        if hit is None:
            return MISS
        self._entries.move_to_end(key)
        return hit[0]

    def put(self, key: str, value: Any, size: int | None = None) -> bool:
        """Store ``value``; False when it alone exceeds the limit (not stored)."""
        size = nbytes(value) if size is None else size
        if key in self._entries:
            self.bytes -= self._entries.pop(key)[1]
        if size > self.limit_bytes:
            return False
        self._entries[key] = (value, size)
        self.bytes += size
        while self.bytes > self.limit_bytes:
            _, (_, s) = self._entries.popitem(last=False)
            self.bytes -= s
        return True

    def clear(self) -> None:
        self._entries.clear()
        self.bytes = 0

    def stats(self) -> dict:
        return {"entries": len(self._entries), "bytes": self.bytes, "limit_bytes": self.limit_bytes}


# -- value <-> (manifest, arrays) ---------------------------------------------------
