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

A folder is pixgraph's cache only if it carries the ``PIXGRAPH_CACHE.json``
marker; pixgraph deletes only files it names itself, and a write that fails
(full disk, read-only folder) means "not cached", never a failed run. What this
does and does not protect: docs/security.md.
"""
from __future__ import annotations

import errno
import hashlib
import json
import logging
import os
import re
import stat
import time
import uuid
from typing import Any, Callable

from .cache_entry import MISS, CacheError, Unstorable, DIGEST_BYTES, entry_parts, decode, encode, misfit, pack_entry, unpack_entry  # noqa: F401 (re-exported)
from .memory_cache import MemoryCache  # noqa: F401 (re-exported)
from .paths import Folder

DISK_SUFFIX = ".pxc"
TMP_PREFIX = ".tmp-"
_log = logging.getLogger("pixgraph.cache")


MARKER = "PIXGRAPH_CACHE.json"
#: layout version the marker records; another version is refused, never rewritten
MARKER_VERSION = 1
LOCK_NAME = ".lock"
RECORDS = "records"
_HH = re.compile(r"^[0-9a-f]{2}$")
_ENTRY = re.compile(r"^[0-9a-f]{3,128}\.pxc$")
_ENTRY_TMP = re.compile(r"^\.tmp-[0-9a-f]{3,128}-[0-9a-f]{32}\.(pxc|npz)$")  # .npz: the older format's
_LEGACY = re.compile(r"^[0-9a-f]{3,128}\.npz$")   # entries of the format before .pxc
_RECORD_NAME = re.compile(r"^[a-z][a-z0-9_-]{0,63}-[0-9a-f]{64}$")
_RECORD = re.compile(r"^[a-z][a-z0-9_-]{0,63}-[0-9a-f]{64}\.json$")
_RECORD_TMP = re.compile(r"^\.tmp-[a-z][a-z0-9_-]{0,63}-[0-9a-f]{64}-[0-9a-f]{32}\.json$")
_MAX_MARKER = 64 << 10
_NOFOLLOW = getattr(os, "O_NOFOLLOW", 0)


class CacheFolderError(CacheError):
    """A disk cache folder pixgraph must not use: it holds files pixgraph did not
    write and no ``PIXGRAPH_CACHE.json`` marker, its marker is of another version,
    or it is not a folder. Nothing in it was changed."""


def pixgraph_owns(folder: str, name: str) -> bool:
    """True when ``<folder>/<name>`` (inside a cache root) is a name pixgraph writes:
    an entry or an entry's temporary in its ``<key[:2]>`` folder, a record or a
    record's temporary in ``records``. Everything else is never deleted."""
    if folder == RECORDS:
        return bool(_RECORD.match(name) or _RECORD_TMP.match(name))
    if not _HH.match(folder):
        return False
    if _ENTRY.match(name) or _LEGACY.match(name):
        return name.startswith(folder)
    return bool(_ENTRY_TMP.match(name)) and name[5:7] == folder


def _mine(st: os.stat_result) -> bool:
    """True when this user owns the file (always where the platform has no uids): an
    entry another user wrote is never read, whatever its key and checksum say."""
    return not hasattr(os, "geteuid") or st.st_uid == os.geteuid()


def _is_temporary(folder: str, name: str) -> bool:
    return (folder == RECORDS and bool(_RECORD_TMP.match(name))) or \
        (_HH.match(folder) is not None and bool(_ENTRY_TMP.match(name)) and name[5:7] == folder)


def foreign_items(root: str, limit: int = 3) -> list[str]:
    """Up to ``limit`` paths under ``root`` (relative) that a pixgraph cache would not
    hold (read-only scan; symlinks are never followed). ``[]``: only pixgraph's files."""
    foreign: list[str] = []
    with os.scandir(root) as top:
        for e in top:
            if len(foreign) >= limit:
                break
            if e.name in (MARKER, LOCK_NAME) and e.is_file(follow_symlinks=False):
                continue
            if (_HH.match(e.name) or e.name == RECORDS) and e.is_dir(follow_symlinks=False):
                with os.scandir(e.path) as inner:
                    for f in inner:
                        if not (f.is_file(follow_symlinks=False) and pixgraph_owns(e.name, f.name)):
                            foreign.append(f"{e.name}/{f.name}" + ("/" if f.is_dir(follow_symlinks=False) else ""))
                            if len(foreign) >= limit:
                                break
                continue
            foreign.append(e.name + ("/" if e.is_dir(follow_symlinks=False) else ""))
    return foreign


def _write_failure(e: OSError) -> str:
    """A disk write failure in words, one per kind (each is warned about once)."""
    n = e.errno
    if n in (errno.ENOSPC, errno.EDQUOT, errno.EFBIG):
        return f"the disk is full ({e.strerror})"
    if n in (errno.EROFS, errno.EACCES, errno.EPERM):
        return f"the folder is read-only ({e.strerror})"
    if n in (errno.EISDIR, errno.ENOTEMPTY, errno.ENOTDIR, errno.ELOOP, errno.EEXIST):
        return f"something that is not a cache entry is in an entry's place ({e.strerror})"
    return f"cannot write ({type(e).__name__}: {e.strerror or e})"


class DiskCache:
    """Content-addressed, size-bounded store of entries under ``root``.

    **Ownership.** A folder is pixgraph's only if it holds ``PIXGRAPH_CACHE.json``
    (written when pixgraph creates the folder, or finds it empty, or finds only
    files named as pixgraph names them: a cache from before the marker). A folder
    holding anything else and no marker raises ``CacheFolderError`` and is left
    untouched. Even in its own folder pixgraph only ever deletes or replaces files
    with the names it writes (``pixgraph_owns``), never follows a symlink inside the
    folder (every file is opened relative to a folder descriptor with
    ``O_NOFOLLOW``), and never removes a folder that is not empty.

    **Reads** check each entry's sha256 and key: a damaged, truncated or swapped
    entry is deleted and is a miss, and the reason is kept in ``discarded`` (the
    engine shows it in events and ``explain``; the engine then checks the value
    against the node's declared outputs with ``misfit``).

    **Writes** go to a temporary file, fsynced and renamed into place; temporaries
    older than ``tmp_max_age_s`` (a killed writer's) are swept when the store opens.
    A write that fails (a full disk, a read-only folder, a folder or other file in
    an entry's place, a value too large for memory) is not an error: ``put``
    returns False, ``last_skip`` says why, and each kind of failure is logged once
    as a ``pixgraph.cache`` warning. A folder that cannot even take the marker
    (read-only, full) gives a store that caches nothing (``unwritable`` says why).

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
        if int(limit_bytes) < 0:
            raise CacheError(f"disk cache limit must be >= 0 bytes (PIXGRAPH_DISK_CACHE_BYTES), got {limit_bytes}")
        self.limit_bytes = int(limit_bytes)
        self.before_commit = before_commit
        #: key -> why its entry was discarded (damaged, swapped), newest last
        self.discarded: dict[str, str] = {}
        #: why nothing can be written here (the marker could not be written), or None
        self.unwritable: str | None = None
        #: why the last ``put`` stored nothing ("" after a stored entry)
        self.last_skip = ""
        self._warned: set[str] = set()
        self.owned = self._open_root()
        if self.owned:
            self._sweep_temporaries(tmp_max_age_s)

    # -- the folder ---------------------------------------------------------------

    def _open_root(self) -> bool:
        """True when the folder is pixgraph's (marker present or just written)."""
        shown = repr(self.root)
        try:
            os.makedirs(self.root, exist_ok=True)
        except FileExistsError:
            raise CacheFolderError(f"disk cache {shown} exists and is not a folder") from None
        except OSError as e:
            self._unwritable(_write_failure(e))
            return False
        if not os.path.isdir(self.root):
            raise CacheFolderError(f"disk cache {shown} exists and is not a folder")
        marker = os.path.join(self.root, MARKER)
        try:
            st = os.lstat(marker)
        except FileNotFoundError:
            st = None
        if st is not None and not (stat.S_ISREG(st.st_mode) and st.st_size == 0):
            self._check_marker(marker, st)
            return True
        try:
            foreign = foreign_items(self.root, limit=4)
        except OSError as e:
            raise CacheFolderError(f"disk cache {shown} cannot be listed: {e.strerror}") from None
        if foreign:
            listing = ", ".join(foreign[:3]) + (", ..." if len(foreign) > 3 else "")
            raise CacheFolderError(
                f"disk cache folder {shown} is not pixgraph's: it holds {listing} and no {MARKER}; "
                f"nothing in it was changed (use a new or empty folder with --disk-cache or "
                f"PIXGRAPH_DISK_CACHE, or --no-disk-cache)")
        try:
            self._write_marker(marker)
        except OSError as e:
            self._unwritable(_write_failure(e))
            return False
        return True

    def _check_marker(self, marker: str, st: os.stat_result) -> None:
        shown = repr(self.root)
        if not stat.S_ISREG(st.st_mode) or st.st_size > _MAX_MARKER:
            raise CacheFolderError(f"disk cache {shown}: {MARKER} is not pixgraph's marker (not a small file)")
        try:
            fd = os.open(marker, os.O_RDONLY | _NOFOLLOW)
            with os.fdopen(fd, "rb") as f:
                doc = json.loads(f.read(_MAX_MARKER).decode("utf-8"))
        except (OSError, ValueError) as e:
            raise CacheFolderError(f"disk cache {shown}: cannot read its {MARKER} ({type(e).__name__}); "
                                   "nothing in it was changed") from None
        version = doc.get("pixgraph_cache") if isinstance(doc, dict) else None
        if version != MARKER_VERSION:
            raise CacheFolderError(f"disk cache {shown}: its {MARKER} says version {version!r}, this pixgraph "
                                   f"uses version {MARKER_VERSION}; nothing in it was changed (use another folder)")

    @staticmethod
    def _write_marker(marker: str) -> None:
        # one small write: a killed writer leaves at worst an empty marker, which is rewritten
        doc = json.dumps({"pixgraph_cache": MARKER_VERSION, "entries": "<key[:2]>/<key>.pxc",
                          "about": "pixgraph's disk cache: 'pixgraph cache clear' deletes only the files "
                                   "pixgraph wrote here"}, sort_keys=True).encode()
        fd = os.open(marker, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | _NOFOLLOW, 0o644)
        try:
            os.write(fd, doc)
            os.fsync(fd)
        finally:
            os.close(fd)

    def _unwritable(self, why: str) -> None:
        self.unwritable = why
        self._warn(f"{why}: nothing is cached on disk")

    def _warn(self, why: str) -> None:
        if why not in self._warned:
            self._warned.add(why)
            _log.warning("disk cache %s: %s; runs go on without it", self.root, why)

    def _skip(self, why: str, warn: bool = True) -> bool:
        self.last_skip = why
        if warn:
            self._warn(why)
        return False

    def _subdir(self, name: str, create: bool = False) -> Folder:
        """``<root>/<name>`` held open, never through a symlink there."""
        with Folder.at(self.root) as root:
            return root.sub(name, create)

    def _unlink(self, folder: str, name: str) -> bool:
        """Delete ``<root>/<folder>/<name>`` if pixgraph owns that name (never a folder,
        never through a symlink); True when something was deleted."""
        if not pixgraph_owns(folder, name):
            return False
        try:
            d = self._subdir(folder)
        except OSError:
            return False
        try:
            d.unlink(name)
            return True
        except OSError:
            return False
        finally:
            d.close()

    def _files(self, want: Callable[[str, str], bool]) -> list[tuple[str, str, os.stat_result]]:
        """(folder, name, lstat) of regular files in pixgraph's subfolders for which ``want``."""
        out = []
        try:
            top = os.scandir(self.root)
        except OSError:
            return out
        with top:
            folders = [e.name for e in top if (_HH.match(e.name) or e.name == RECORDS)
                       and e.is_dir(follow_symlinks=False)]
        for folder in folders:
            try:
                inner = os.scandir(os.path.join(self.root, folder))
            except OSError:
                continue
            with inner:
                for f in inner:
                    if want(folder, f.name):
                        try:
                            st = f.stat(follow_symlinks=False)
                        except OSError:
                            continue
                        if stat.S_ISREG(st.st_mode):
                            out.append((folder, f.name, st))
        return out

    # -- entries ------------------------------------------------------------------

    def path(self, key: str) -> str:
        if not all(c in "0123456789abcdef" for c in key) or not 3 <= len(key) <= 128:
            raise ValueError(f"bad cache key {key[:80]!r}")
        return os.path.join(self.root, key[:2], key + DISK_SUFFIX)

    def __contains__(self, key: str) -> bool:
        """True when ``get(key)`` will read a file: this user's (``_mine``), as ``get`` asks."""
        try:
            st = os.lstat(self.path(key))
            return self.owned and stat.S_ISREG(st.st_mode) and _mine(st)
        except OSError:
            return False

    def get(self, key: str) -> Any:
        """The entry, or ``MISS``; a damaged or foreign entry is deleted and is a miss."""
        self.path(key)
        if not self.owned:
            return MISS
        try:
            d = self._subdir(key[:2])
        except FileNotFoundError:
            return MISS
        except OSError as e:  # a symlink or a file in the entry folder's place: not ours to touch
            self._note(key, f"entry folder {key[:2]!r} is not a plain folder ({e.strerror})")
            return MISS
        try:
            try:
                fd = d.open(key + DISK_SUFFIX, os.O_RDONLY)
            except FileNotFoundError:
                return MISS
            if not stat.S_ISREG(os.fstat(fd).st_mode):  # a folder in the entry's place: not ours, left alone
                os.close(fd)
                return MISS
            with os.fdopen(fd, "rb") as f:
                st = os.fstat(f.fileno())
                if not _mine(st):
                    # another user wrote it (a shared or planted cache folder): its key and
                    # checksum are computable by anyone, so it is never read; not ours to delete
                    self._note(key, f"written by another user (uid {st.st_uid}): not read")
                    return MISS
                if st.st_size > max(self.limit_bytes, 1 << 20):
                    raise ValueError(f"entry of {st.st_size} bytes exceeds the cache limit")
                data = f.read()
                value = unpack_entry(key, data)
                try:
                    os.utime(f.fileno())  # least recently *used* eviction
                except OSError:
                    pass
            return value
        except Exception as e:  # noqa: BLE001 - any failure to decode means: not a usable entry
            self._discard(key, None, f"{type(e).__name__}: {e}"[:200])
            return MISS
        finally:
            d.close()

    def _note(self, key: str, why: str) -> None:
        self.discarded.pop(key, None)
        self.discarded[key] = why
        while len(self.discarded) > 1000:
            self.discarded.pop(next(iter(self.discarded)))
        _log.warning("disk cache entry %s discarded: %s", key[:12], why)

    def _discard(self, key: str, p: str | None, why: str) -> None:
        """Delete the entry of ``key`` (only a file of its own name) and remember why."""
        self._unlink(key[:2], key + DISK_SUFFIX)
        self._note(key, why)

    def discard(self, key: str, why: str) -> None:
        """The engine found a well-formed entry that is not this node's outputs."""
        self._discard(key, None, why)

    def put(self, key: str, value: Any) -> bool:
        """Store atomically; True when stored. Raises ``Unstorable`` for values without
        a disk form. Every other reason not to store (larger than the limit, a full
        disk, a read-only folder, something in the entry's place, out of memory) returns
        False with the reason in ``last_skip`` (logged once per kind)."""
        self.path(key)
        if not self.owned:
            return self._skip(self.unwritable or "the folder is not pixgraph's", warn=False)
        try:
            head, blobs = entry_parts(key, value)
        except MemoryError:
            return self._skip("a result too large for memory is not cached on disk")
        size = len(head) + sum(len(b) for b in blobs) + DIGEST_BYTES
        if size > self.limit_bytes:
            return self._skip("larger than the disk cache limit", warn=False)
        name = key + DISK_SUFFIX
        tmp = f"{TMP_PREFIX}{key}-{uuid.uuid4().hex}{DISK_SUFFIX}"
        d = None
        pending = False
        try:
            d = self._subdir(key[:2], create=True)
            fd = d.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL)
            pending = True
            with os.fdopen(fd, "wb") as f:
                h = hashlib.sha256()
                for part in (head, *blobs):  # streamed: the entry is never copied whole in memory
                    h.update(part)
                    f.write(part)
                f.write(h.digest())
                f.flush()
                os.fsync(f.fileno())
            if self.before_commit is not None:
                self.before_commit(os.path.join(self.root, key[:2], tmp), self.path(key))
            with self._lock():
                d.replace(tmp, name)
                pending = False
                self._evict_locked()
        except OSError as e:
            return self._skip(_write_failure(e))
        finally:
            _release(d, tmp if pending else None)
        self.last_skip = ""
        self.discarded.pop(key, None)
        return True

    def _lock(self):
        return _FileLock(self.root)

    def save_record(self, name: str, data: dict) -> None:
        """Keep a small JSON document (e.g. last-run key parts) next to the entries;
        ``name`` is ``<word>-<64 hex digits>``. Never fails a run."""
        if not _RECORD_NAME.match(name):
            raise ValueError(f"record name {name[:80]!r} is not <word>-<sha256 hex>")
        if not self.owned:
            return
        tmp = f"{TMP_PREFIX}{name}-{uuid.uuid4().hex}.json"
        d = None
        try:
            text = json.dumps(data, sort_keys=True).encode("utf-8")
            d = self._subdir(RECORDS, create=True)
            d.write_replace(name + ".json", text, tmp)
        except (OSError, ValueError, TypeError):
            pass  # records only serve explanations: never fail a run for one
        finally:
            _release(d, None)

    def load_record(self, name: str) -> dict | None:
        if not _RECORD_NAME.match(name) or not self.owned:
            return None
        try:
            d = self._subdir(RECORDS)
        except OSError:
            return None
        try:
            fd = d.open(name + ".json", os.O_RDONLY)
            with os.fdopen(fd, "rb") as f:
                st = os.fstat(f.fileno())
                if st.st_size > 64 << 20 or not _mine(st):
                    return None
                data = json.loads(f.read().decode("utf-8"))
        except (OSError, ValueError, RecursionError):
            return None
        finally:
            d.close()
        return data if isinstance(data, dict) else None

    def entries(self) -> list[tuple[str, int, float]]:
        """(path, bytes, mtime) of every committed entry, oldest first."""
        found = self._files(lambda folder, n: folder != RECORDS and bool(_ENTRY.match(n)) and n.startswith(folder))
        out = [(os.path.join(self.root, folder, n), st.st_size, st.st_mtime) for folder, n, st in found]
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
            folder, name = os.path.split(os.path.relpath(p, self.root))
            self._unlink(folder, name)
            total -= size
            removed += 1
        return removed

    def stats(self) -> dict:
        entries = self.entries()
        out = {"root": self.root, "entries": len(entries), "bytes": sum(e[1] for e in entries),
               "limit_bytes": self.limit_bytes, "temporaries": len(self.temporaries())}
        if self.unwritable:
            out["unwritable"] = self.unwritable
        return out

    def temporaries(self) -> list[str]:
        return [os.path.join(self.root, folder, n) for folder, n, _ in self._files(_is_temporary)]

    def clear(self) -> int:
        """Delete every file pixgraph wrote here (entries, temporaries, records), and
        the entry folders left empty; nothing else. Returns how many entries went."""
        if not self.owned:
            return 0
        n = 0
        with self._lock():
            for folder, name, _ in self._files(pixgraph_owns):
                if self._unlink(folder, name) and _ENTRY.match(name):
                    n += 1
            try:
                root = Folder.at(self.root)
            except OSError:
                return n
            with root:
                for folder in root.listdir():
                    if _HH.match(folder) or folder == RECORDS:
                        try:
                            root.rmdir(folder)  # only when empty (and never a symlink's target)
                        except OSError:
                            pass
        return n

    def _sweep_temporaries(self, older_than_s: float = 600.0) -> int:
        # a temp file is only ever half an entry: the writer was killed, or is
        # still writing (hence the age threshold); .npz entries are of the format
        # before .pxc and never read again
        now, removed = time.time(), 0
        for folder, name, st in self._files(lambda f, n: _is_temporary(f, n) or
                                            (_LEGACY.match(n) is not None and n.startswith(f))):
            if _LEGACY.match(name) or now - st.st_mtime > older_than_s:
                removed += self._unlink(folder, name)
        return removed


def _release(folder, tmp: str | None) -> None:
    """Close a folder opened for a write, removing the temporary ``tmp`` left in it
    by a write that did not reach its rename (None: nothing left)."""
    if folder is None:
        return
    if tmp is not None:
        try:
            folder.unlink(tmp)
        except OSError:
            pass
    folder.close()


class _FileLock:
    """An exclusive ``flock`` on ``<root>/.lock``, held for a ``with`` block (no-op without fcntl)."""

    def __init__(self, root: str):
        self.root = root
        self._fd = None

    def __enter__(self):
        try:
            import fcntl
        except ImportError:  # not POSIX: the bound then holds per process only
            return self
        self._fd = os.open(os.path.join(self.root, LOCK_NAME), os.O_RDWR | os.O_CREAT | _NOFOLLOW, 0o644)
        fcntl.flock(self._fd, fcntl.LOCK_EX)
        return self

    def __exit__(self, *exc):
        if self._fd is not None:
            import fcntl

            fcntl.flock(self._fd, fcntl.LOCK_UN)
            os.close(self._fd)
            self._fd = None
