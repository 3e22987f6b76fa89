"""Value caches keyed by cache key: a byte-bounded memory LRU and a disk store.

An entry is a node's whole output dict (``{output name: value}``).

The disk store is content-addressed (``<root>/<key[:2]>/<key>.npz``) and needs no
pickle: arrays go into an ``.npz`` next to a JSON manifest of the value's
structure (dicts, lists, tuples, numbers, strings, and frozen dataclasses of
those, such as ``Camera``). A value outside that set raises ``Unstorable`` and
stays memory-only. Writes go to a temporary file in the same folder, are fsynced
and renamed, so a killed process never leaves a half entry; stray temporary files
are swept on open. The store is bounded in bytes and evicts least recently used
entries (reads touch the file's mtime).
"""
from __future__ import annotations

import collections
import dataclasses
import importlib
import json
import math
import os
import shutil
import time
import uuid
from typing import Any, Callable

import numpy as np

from .types import nbytes

MISS = object()
DISK_SUFFIX = ".npz"
TMP_PREFIX = ".tmp-"


class Unstorable(TypeError):
    """A value the disk store cannot represent without pickle."""


class MemoryCache:
    """LRU of entries bounded by their total size in bytes (``types.nbytes``)."""

    def __init__(self, limit_bytes: int):
        if limit_bytes < 0:
            raise ValueError("cache limit must be >= 0 bytes")
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

def encode(value: Any, arrays: dict[str, np.ndarray]) -> Any:
    """JSON-able description of ``value``; its arrays are added to ``arrays``."""
    if value is None or isinstance(value, (bool, str)):
        return value
    if isinstance(value, int):
        return value
    if isinstance(value, float):
        return value if math.isfinite(value) else {"__float__": repr(value)}
    if isinstance(value, (np.ndarray, np.generic)):
        a = np.asarray(value)
        if a.dtype.hasobject:
            raise Unstorable("numpy array of Python objects")
        name = f"a{len(arrays)}"
        arrays[name] = a
        return {"__array__": name, "scalar": isinstance(value, np.generic)}
    if isinstance(value, dict):
        if not all(isinstance(k, str) for k in value):
            raise Unstorable("dict with non-string keys")
        return {"__dict__": {k: encode(v, arrays) for k, v in value.items()}}
    if isinstance(value, (list, tuple)):
        return {"__list__" if isinstance(value, list) else "__tuple__": [encode(v, arrays) for v in value]}
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        cls = type(value)
        if not cls.__dataclass_params__.frozen or "<locals>" in cls.__qualname__:
            raise Unstorable(f"{cls.__name__} is not a frozen, importable dataclass")
        return {"__dataclass__": f"{cls.__module__}:{cls.__qualname__}",
                "fields": {f.name: encode(getattr(value, f.name), arrays) for f in dataclasses.fields(value)}}
    raise Unstorable(f"value of type {type(value).__name__}")


def decode(desc: Any, arrays: dict[str, np.ndarray]) -> Any:
    if not isinstance(desc, dict):
        return desc
    if "__float__" in desc:
        return float(desc["__float__"])
    if "__array__" in desc:
        a = arrays[desc["__array__"]]
        return a[()] if desc.get("scalar") else a
    if "__dict__" in desc:
        return {k: decode(v, arrays) for k, v in desc["__dict__"].items()}
    if "__list__" in desc:
        return [decode(v, arrays) for v in desc["__list__"]]
    if "__tuple__" in desc:
        return tuple(decode(v, arrays) for v in desc["__tuple__"])
    if "__dataclass__" in desc:
        module, _, qualname = desc["__dataclass__"].partition(":")
        cls: Any = importlib.import_module(module)
        for part in qualname.split("."):
            cls = getattr(cls, part)
        if not (isinstance(cls, type) and dataclasses.is_dataclass(cls)):
            raise ValueError(f"{desc['__dataclass__']} is not a dataclass")
        fields = {k: decode(v, arrays) for k, v in desc["fields"].items()}
        obj = object.__new__(cls)
        for k, v in fields.items():  # frozen: bypass __setattr__, as dataclasses itself does
            object.__setattr__(obj, k, v)
        return obj
    raise ValueError(f"unknown manifest entry {sorted(desc)}")


class DiskCache:
    """Content-addressed, size-bounded store of entries under ``root``.

    ``before_commit(tmp_path, final_path)`` is called between writing the
    temporary file and renaming it (tests use it to kill the process there).
    """

    def __init__(self, root: str | os.PathLike, limit_bytes: int,
                 before_commit: Callable[[str, str], None] | None = None):
        self.root = os.path.abspath(os.fspath(root))
        self.limit_bytes = int(limit_bytes)
        self.before_commit = before_commit
        #: running total of committed bytes; None until first needed (a scan)
        self._bytes: int | None = None
        os.makedirs(self.root, exist_ok=True)
        self._sweep_temporaries()

    def path(self, key: str) -> str:
        return os.path.join(self.root, key[:2], key + DISK_SUFFIX)

    def __contains__(self, key: str) -> bool:
        return os.path.isfile(self.path(key))

    def get(self, key: str) -> Any:
        """The entry, or ``MISS``; an unreadable entry is deleted and is a miss."""
        p = self.path(key)
        try:
            with np.load(p, allow_pickle=False) as z:
                arrays = {k: z[k] for k in z.files}
            manifest = json.loads(arrays.pop("__manifest__").tobytes().decode("utf-8"))
            value = decode(manifest, arrays)
        except FileNotFoundError:
            return MISS
        except Exception:
            self._remove(p)
            return MISS
        try:
            os.utime(p)  # least recently *used* eviction
        except OSError:
            pass
        return value

    def put(self, key: str, value: Any) -> None:
        """Store atomically. Raises ``Unstorable`` for values without a disk form."""
        arrays: dict[str, np.ndarray] = {}
        manifest = json.dumps(encode(value, arrays), allow_nan=False).encode("utf-8")
        arrays["__manifest__"] = np.frombuffer(manifest, dtype=np.uint8)
        final = self.path(key)
        folder = os.path.dirname(final)
        os.makedirs(folder, exist_ok=True)
        tmp = os.path.join(folder, f"{TMP_PREFIX}{key}-{uuid.uuid4().hex}{DISK_SUFFIX}")
        try:
            with open(tmp, "wb") as f:
                np.savez(f, **arrays)
                f.flush()
                os.fsync(f.fileno())
            if self.before_commit is not None:
                self.before_commit(tmp, final)
            size = os.path.getsize(tmp)
            os.replace(tmp, final)
        except BaseException:
            self._remove(tmp)
            raise
        # scan the folder only when the running total says the limit is passed
        self._bytes = (self._bytes + size) if self._bytes is not None else None
        if self._bytes is None or self._bytes > self.limit_bytes:
            self.evict()

    def save_record(self, name: str, data: dict) -> None:
        """Keep a small JSON document (e.g. last-run key parts) next to the entries."""
        folder = os.path.join(self.root, "records")
        os.makedirs(folder, exist_ok=True)
        tmp = os.path.join(folder, f"{TMP_PREFIX}{name}-{uuid.uuid4().hex}.json")
        try:
            with open(tmp, "w", encoding="utf-8") as f:
                json.dump(data, f, sort_keys=True)
            os.replace(tmp, os.path.join(folder, name + ".json"))
        except OSError:
            self._remove(tmp)  # records only serve explanations: never fail a run for one

    def load_record(self, name: str) -> dict | None:
        try:
            with open(os.path.join(self.root, "records", name + ".json"), encoding="utf-8") as f:
                data = json.load(f)
        except (OSError, ValueError):
            return None
        return data if isinstance(data, dict) else None

    def entries(self) -> list[tuple[str, int, float]]:
        """(path, bytes, mtime) of every committed entry, oldest first."""
        out = []
        for dirpath, _, files in os.walk(self.root):
            for name in files:
                if name.endswith(DISK_SUFFIX) and not name.startswith(TMP_PREFIX):
                    p = os.path.join(dirpath, name)
                    try:
                        st = os.stat(p)
                    except FileNotFoundError:
                        continue
                    out.append((p, st.st_size, st.st_mtime))
        out.sort(key=lambda e: e[2])
        return out

    def evict(self) -> int:
        """Delete least recently used entries until the store fits its limit; returns how many."""
        entries = self.entries()
        total = sum(e[1] for e in entries)
        removed = 0
        for p, size, _ in entries:
            if total <= self.limit_bytes:
                break
            self._remove(p)
            total -= size
            removed += 1
        self._bytes = total
        return removed

    def stats(self) -> dict:
        entries = self.entries()
        return {"root": self.root, "entries": len(entries), "bytes": sum(e[1] for e in entries),
                "limit_bytes": self.limit_bytes}

    def clear(self) -> int:
        n = len(self.entries())
        self._bytes = None
        for name in os.listdir(self.root):
            p = os.path.join(self.root, name)
            if os.path.isdir(p) and (len(name) == 2 or name == "records"):
                shutil.rmtree(p, ignore_errors=True)
        return n

    def _sweep_temporaries(self, older_than_s: float = 3600.0) -> None:
        # a temp file is only ever half an entry: the writer was killed, or is
        # still writing (hence the age threshold)
        now = time.time()
        for dirpath, _, files in os.walk(self.root):
            for name in files:
                if name.startswith(TMP_PREFIX):
                    p = os.path.join(dirpath, name)
                    try:
                        if now - os.stat(p).st_mtime > older_than_s:
                            os.remove(p)
                    except OSError:
                        pass

    @staticmethod
    def _remove(p: str) -> None:
        try:
            os.remove(p)
        except OSError:
            pass

