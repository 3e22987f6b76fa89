"""Value caches keyed by cache key: a byte-bounded memory LRU and a disk store.

An entry is a node's whole output dict (``{output name: value}``).

The disk store is content-addressed (``<root>/<key[:2]>/<key>.pxc``) and needs no
pickle: one file holds the key, a JSON manifest of the value's structure (dicts,
lists, tuples, numbers, strings, and frozen dataclasses of those, such as
``Camera``), the raw bytes of its numeric arrays, and a sha256 of all of it. A
value outside that set raises ``Unstorable`` and stays memory-only. Reads verify
the checksum and the key, and decoding never imports a module or runs code
named by the entry. Writes go to a temporary file in the same folder, are fsynced
and renamed, so a killed process never leaves a half entry; stale temporaries are
swept on open. The store is bounded in bytes across processes (a lock file) and
evicts least recently used entries (reads touch the file's mtime).
"""
from __future__ import annotations

import collections
import dataclasses
import hashlib
import json
import logging
import math
import os
import shutil
import struct
import sys
import time
import uuid
from typing import Any, Callable

import numpy as np

from .types import nbytes

MISS = object()
DISK_SUFFIX = ".pxc"
TMP_PREFIX = ".tmp-"
_log = logging.getLogger("pixgraph.cache")


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


def decode(desc: Any, arrays: dict[str, np.ndarray], depth: int = 0) -> Any:
    """The value described by ``desc``. Never imports a module: a dataclass is
    looked up among modules already loaded, must be a frozen dataclass with
    exactly the fields given, and is filled in without running any of its code.
    Anything else raises ``ValueError`` (the entry is then discarded)."""
    if depth > 64:
        raise ValueError("manifest nested too deeply")
    if not isinstance(desc, dict):
        if desc is None or isinstance(desc, (bool, int, float, str)):
            return desc
        raise ValueError(f"unexpected manifest value of type {type(desc).__name__}")
    if len(desc) > 2 and "__dataclass__" not in desc:
        raise ValueError(f"unknown manifest entry {sorted(desc)[:4]}")
    if "__float__" in desc:
        if desc["__float__"] not in ("nan", "inf", "-inf"):
            raise ValueError("bad non-finite float")
        return float(desc["__float__"])
    if "__array__" in desc:
        a = arrays[desc["__array__"]]
        return a[()] if desc.get("scalar") else a
    if "__dict__" in desc:
        return {str(k): decode(v, arrays, depth + 1) for k, v in _mapping(desc["__dict__"]).items()}
    if "__list__" in desc:
        return [decode(v, arrays, depth + 1) for v in _sequence(desc["__list__"])]
    if "__tuple__" in desc:
        return tuple(decode(v, arrays, depth + 1) for v in _sequence(desc["__tuple__"]))
    if "__dataclass__" in desc:
        cls = _loaded_dataclass(desc["__dataclass__"])
        fields = _mapping(desc.get("fields"))
        if set(fields) != {f.name for f in dataclasses.fields(cls)}:
            raise ValueError(f"fields of {desc['__dataclass__']} do not match")
        obj = object.__new__(cls)
        for k, v in fields.items():  # frozen: bypass __setattr__, as dataclasses itself does
            object.__setattr__(obj, k, decode(v, arrays, depth + 1))
        return obj
    raise ValueError(f"unknown manifest entry {sorted(desc)[:4]}")


def _mapping(x) -> dict:
    if not isinstance(x, dict):
        raise ValueError("expected a mapping in the manifest")
    return x


def _sequence(x) -> list:
    if not isinstance(x, list):
        raise ValueError("expected a list in the manifest")
    return x


def _loaded_dataclass(name: Any) -> type:
    if not isinstance(name, str):
        raise ValueError("bad dataclass name")
    module_name, _, qualname = name.partition(":")
    obj: Any = sys.modules.get(module_name)
    if obj is None:
        raise ValueError(f"module {module_name!r} is not loaded (never imported from cache data)")
    for part in qualname.split("."):
        if part.startswith("_"):
            raise ValueError(f"{name} is not a public dataclass")
        obj = getattr(obj, part, None)
    if not (isinstance(obj, type) and dataclasses.is_dataclass(obj) and obj.__dataclass_params__.frozen):
        raise ValueError(f"{name} is not a frozen dataclass")
    return obj


#: entry layout: MAGIC, header length (u64 LE), header JSON, array bytes, sha256 of all before
MAGIC = b"PXGCACH1"
_DIGEST = 32
#: dtypes an entry may hold: numbers and bools only (never objects or records)
_DTYPE_KINDS = "biufc"


def pack_entry(key: str, value: Any) -> bytes:
    """The bytes of one disk entry: the key, the value's manifest and arrays, a checksum."""
    arrays: dict[str, np.ndarray] = {}
    manifest = encode(value, arrays)
    layout, offset, blobs = {}, 0, []
    for name, a in arrays.items():
        a = np.ascontiguousarray(a)
        layout[name] = {"dtype": a.dtype.str, "shape": list(a.shape), "offset": offset, "nbytes": a.nbytes}
        blobs.append(memoryview(a).cast("B") if a.nbytes else b"")
        offset += a.nbytes
    header = json.dumps({"key": key, "value": manifest, "arrays": layout}, allow_nan=False,
                        separators=(",", ":")).encode("utf-8")
    body = b"".join([MAGIC, struct.pack("<Q", len(header)), header, *blobs])
    return body + hashlib.sha256(body).digest()


def unpack_entry(key: str, data: bytes) -> Any:
    """The value of an entry's bytes; ``ValueError`` saying why when the entry is
    damaged (checksum), is another key's entry (swapped), or is malformed."""
    if len(data) < len(MAGIC) + 8 + _DIGEST or not data.startswith(MAGIC):
        raise ValueError("not a pixgraph cache entry (truncated or foreign)")
    body, digest = memoryview(data)[:-_DIGEST], data[-_DIGEST:]
    if hashlib.sha256(body).digest() != digest:
        raise ValueError("checksum mismatch (damaged)")
    (hlen,) = struct.unpack_from("<Q", data, len(MAGIC))
    start = len(MAGIC) + 8
    if hlen > len(body) - start:
        raise ValueError("header runs past the end")
    header = json.loads(bytes(body[start:start + hlen]).decode("utf-8"))
    if not isinstance(header, dict) or header.get("key") != key:
        raise ValueError("entry holds another key (swapped or renamed)")
    payload = body[start + hlen:]
    arrays = {}
    for name, d in _mapping(header.get("arrays")).items():
        d = _mapping(d)
        dtype = np.dtype(str(d["dtype"]))
        if dtype.kind not in _DTYPE_KINDS or dtype.hasobject or dtype.fields is not None:
            raise ValueError(f"array dtype {d['dtype']!r} is not numeric")
        shape = tuple(int(n) for n in _sequence(d["shape"]))
        off, n = int(d["offset"]), int(d["nbytes"])
        if min(shape, default=0) < 0 or math.prod(shape) * dtype.itemsize != n or off < 0 or off + n > len(payload):
            raise ValueError(f"array {name!r} does not fit the entry")
        a = np.frombuffer(payload[off:off + n], dtype=dtype).reshape(shape) if n else np.zeros(shape, dtype)
        arrays[name] = a
    return decode(header.get("value"), arrays)


class DiskCache:
    """Content-addressed, size-bounded store of entries under ``root``.

    Each entry records its key and a sha256 of its bytes, checked on every read:
    a damaged, truncated or swapped entry is deleted and is a miss, and the
    reason is kept in ``discarded`` (the engine shows it in events and ``explain``).
    Writes go to a temporary file that is renamed into place; temporaries older
    than ``tmp_max_age_s`` (a killed writer's) are swept when the store opens.
    The byte bound is kept across processes: every commit takes an exclusive
    lock on ``<root>/.lock`` and re-scans the store before evicting, so committed
    entries never exceed ``limit_bytes`` once a put returns; files being written
    (one entry per writing process) are not counted until committed.

    ``before_commit(tmp_path, final_path)`` is called between writing the
    temporary file and renaming it (tests use it to kill the process there).
    """

    def __init__(self, root: str | os.PathLike, limit_bytes: int,
                 before_commit: Callable[[str, str], None] | None = None, tmp_max_age_s: float = 600.0):
        self.root = os.path.abspath(os.fspath(root))
        self.limit_bytes = int(limit_bytes)
        self.before_commit = before_commit
        #: key -> why its entry was discarded (damaged, swapped), newest last
        self.discarded: dict[str, str] = {}
        os.makedirs(self.root, exist_ok=True)
        self._sweep_temporaries(tmp_max_age_s)

    def path(self, key: str) -> str:
        if not all(c in "0123456789abcdef" for c in key) or len(key) < 3:
            raise ValueError(f"bad cache key {key[:80]!r}")
        return os.path.join(self.root, key[:2], key + DISK_SUFFIX)

    def __contains__(self, key: str) -> bool:
        return os.path.isfile(self.path(key))

    def get(self, key: str) -> Any:
        """The entry, or ``MISS``; a damaged or foreign entry is deleted and is a miss."""
        p = self.path(key)
        try:
            with open(p, "rb") as f:
                size = os.fstat(f.fileno()).st_size
                if size > max(self.limit_bytes, 1 << 20):
                    raise ValueError(f"entry of {size} bytes exceeds the cache limit")
                data = f.read()
            value = unpack_entry(key, data)
        except FileNotFoundError:
            return MISS
        except Exception as e:  # noqa: BLE001 - any failure to decode means: not a usable entry
            self._discard(key, p, f"{type(e).__name__}: {e}"[:200])
            return MISS
        try:
            os.utime(p)  # least recently *used* eviction
        except OSError:
            pass
        return value

    def _discard(self, key: str, p: str, why: str) -> None:
        self._remove(p)
        self.discarded.pop(key, None)
        self.discarded[key] = why
        while len(self.discarded) > 1000:
            self.discarded.pop(next(iter(self.discarded)))
        _log.warning("disk cache entry %s discarded: %s", key[:12], why)

    def put(self, key: str, value: Any) -> None:
        """Store atomically. Raises ``Unstorable`` for values without a disk form."""
        data = pack_entry(key, value)
        if len(data) > self.limit_bytes:
            return  # would be evicted at once
        final = self.path(key)
        folder = os.path.dirname(final)
        os.makedirs(folder, exist_ok=True)
        tmp = os.path.join(folder, f"{TMP_PREFIX}{key}-{uuid.uuid4().hex}{DISK_SUFFIX}")
        try:
            with open(tmp, "wb") as f:
                f.write(data)
                f.flush()
                os.fsync(f.fileno())
            if self.before_commit is not None:
                self.before_commit(tmp, final)
            with self._lock():
                os.replace(tmp, final)
                self._evict_locked()
        except BaseException:
            self._remove(tmp)
            raise
        self.discarded.pop(key, None)

    def _lock(self):
        return _FileLock(os.path.join(self.root, ".lock"))

    def save_record(self, name: str, data: dict) -> None:
        """Keep a small JSON document (e.g. last-run key parts) next to the entries."""
        folder = os.path.join(self.root, "records")
        os.makedirs(folder, exist_ok=True)
        tmp = os.path.join(folder, f"{TMP_PREFIX}{name}-{uuid.uuid4().hex}.json")
        try:
            with open(tmp, "w", encoding="utf-8") as f:
                json.dump(data, f, sort_keys=True)
            os.replace(tmp, os.path.join(folder, name + ".json"))
        except (OSError, ValueError):
            self._remove(tmp)  # records only serve explanations: never fail a run for one

    def load_record(self, name: str) -> dict | None:
        try:
            p = os.path.join(self.root, "records", name + ".json")
            if os.path.getsize(p) > 64 << 20:
                return None
            with open(p, encoding="utf-8") as f:
                data = json.load(f)
        except (OSError, ValueError, RecursionError):
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
        with self._lock():
            return self._evict_locked()

    def _evict_locked(self) -> int:
        entries = self.entries()
        total = sum(e[1] for e in entries)
        removed = 0
        for p, size, _ in entries:
            if total <= self.limit_bytes:
                break
            self._remove(p)
            total -= size
            removed += 1
        return removed

    def stats(self) -> dict:
        entries = self.entries()
        return {"root": self.root, "entries": len(entries), "bytes": sum(e[1] for e in entries),
                "limit_bytes": self.limit_bytes, "temporaries": len(self.temporaries())}

    def temporaries(self) -> list[str]:
        return [os.path.join(d, n) for d, _, files in os.walk(self.root) for n in files if n.startswith(TMP_PREFIX)]

    def clear(self) -> int:
        n = len(self.entries())
        for name in os.listdir(self.root):
            p = os.path.join(self.root, name)
            if os.path.isdir(p) and (len(name) == 2 or name == "records"):
                shutil.rmtree(p, ignore_errors=True)
        return n

    def _sweep_temporaries(self, older_than_s: float = 600.0) -> int:
        # a temp file is only ever half an entry: the writer was killed, or is
        # still writing (hence the age threshold)
        now, removed = time.time(), 0
        for d, _, files in os.walk(self.root):  # entries of the older .npz format: never read again
            for n in files:
                if n.endswith(".npz") and len(os.path.basename(d)) == 2:
                    self._remove(os.path.join(d, n))
        for p in self.temporaries():
            try:
                if now - os.stat(p).st_mtime > older_than_s:
                    os.remove(p)
                    removed += 1
            except OSError:
                pass
        return removed

    @staticmethod
    def _remove(p: str) -> None:
        try:
            os.remove(p)
        except OSError:
            pass


class _FileLock:
    """An exclusive ``flock`` on a file, held for a ``with`` block (no-op without fcntl)."""

    def __init__(self, path: str):
        self.path = path
        self._fd = None

    def __enter__(self):
        try:
            import fcntl
        except ImportError:  # not POSIX: the bound then holds per process only
            return self
        self._fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
        fcntl.flock(self._fd, fcntl.LOCK_EX)
        return self

    def __exit__(self, *exc):
        if self._fd is not None:
            import fcntl

            fcntl.flock(self._fd, fcntl.LOCK_UN)
            os.close(self._fd)
            self._fd = None
