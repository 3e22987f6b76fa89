"""Output files of a batch: atomic writes, provenance sidecars, temporaries, the folder lock.

- An output is written to a temporary file in its own folder
  (``.STEM.tmp-PID-RANDOM.EXT``), hashed, and renamed over the target; its
  sidecar ``PATH.json`` is written the same way, last. The sidecar's
  ``file_sha256`` is the hash of the bytes this batch wrote, never of whatever
  is on disk later, so a file changed behind the batch's back no longer matches
  its sidecar and is rendered again on resume.
- Leftover temporaries of a batch's outputs (a killed run's) are removed when
  the next batch on that folder starts, and by the writer itself when a write
  fails or is interrupted.
- A batch holds a lock on each of its output folders (``.pixgraph-batch.lock``,
  an advisory ``flock`` the kernel drops when the process dies, kill -9
  included): a second batch on the same folder refuses to start (exit 2, naming
  the folder and the other batch's pid) or, with ``wait``, waits for it.
"""
from __future__ import annotations

import errno
import hashlib
import json
import os
import secrets
import socket
import time
from typing import Any, Callable, Iterable

from pixgraph.hashing import canonical_json
from pixgraph.paths import TMP_TAIL, WritePath, temp_stem

from .rows import BatchError

SIDECAR_SUFFIX = ".json"
LOCK_NAME = ".pixgraph-batch.lock"
#: a temporary whose writer's pid cannot be checked (another host) is removed once this old
STALE_TMP_SECONDS = 3600.0


def content_key(node_key: str, output: str, path: str) -> str:
    """Key of one output file: the engine's key of the node that makes it, the
    output port and the absolute path it is written to."""
    return hashlib.sha256(canonical_json({"node_key": node_key, "output": output,
                                          "path": os.path.abspath(path)}).encode()).hexdigest()


def sidecar_path(path: str) -> str:
    return path + SIDECAR_SUFFIX


def file_sha256(path: str) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def read_sidecar(path: str) -> dict | None:
    try:
        with open(sidecar_path(path), encoding="utf-8") as f:
            meta = json.load(f)
        return meta if isinstance(meta, dict) else None
    except (OSError, ValueError):
        return None


def is_done(path: str, key: str) -> bool:
    """True when ``path``'s sidecar records ``key`` and the file still has the
    sha256 the batch wrote."""
    meta = read_sidecar(path)
    if meta is None or meta.get("content_key") != key:
        return False
    try:
        return meta.get("file_sha256") == file_sha256(path)
    except OSError:
        return False


def _temp_stem(name: str, suffix: str = "") -> str:
    """The STEM of ``name``'s temporaries (``paths.temp_stem``): an image's leaves room
    for the image writer's own temporary on top of it (``..STEM.tmp-PID-R.tmp-PID-R.EXT``),
    so both fit in NAME_MAX bytes whatever the length of ``name``."""
    stem, ext = os.path.splitext(name)
    if suffix:
        return temp_stem(name, len(suffix.encode("utf-8", "surrogateescape")))
    return temp_stem(stem, len(ext.encode("utf-8", "surrogateescape")) + 1 + TMP_TAIL)


def temporary_name(path: str, suffix: str = "") -> str:
    """``DIR/.STEM.tmp-PID-RANDOM.EXT`` next to ``path`` (same file system: the rename is
    atomic), within NAME_MAX bytes (a long STEM is shortened: ``_temp_stem``)."""
    folder, name = os.path.split(os.path.abspath(path))
    ext = suffix or os.path.splitext(name)[1]
    return os.path.join(folder, f".{_temp_stem(name, suffix)}.tmp-{os.getpid()}-{secrets.token_hex(4)}{ext}")


def open_folder(path: str):
    """``(folder, name)``: the folder of ``path`` held open without following symlinks
    (``pixgraph.paths.open_write_folder``): names are looked up in that very folder,
    whatever happens to its path meanwhile. The caller closes the folder."""
    from pixgraph.paths import PathError, open_write_folder

    try:
        return open_write_folder(path)
    except PathError as e:
        raise BatchError(e.message) from None


def write_atomic(path: str, write: Callable[[str], Any], folder=None) -> str:
    """Write through ``write(tmp)`` to a temporary next to ``path``, hash what was
    written, rename it over ``path``; returns the sha256 of the bytes written. The
    hash is read from, and the rename made in, ``folder`` (from ``open_folder``,
    opened before the write: no symlink swapped in meanwhile can redirect either);
    ``tmp`` is a ``pixgraph.paths.WritePath`` of that folder's real path, which the
    image writers open without following symlinks (a swapped folder gets nothing).
    The temporary is removed when anything fails (an error, Ctrl-C)."""
    own = folder is None
    if own:
        folder, _ = open_folder(path)
    name = os.path.basename(path)
    try:
        tmp_name = os.path.basename(temporary_name(path))
        try:
            # a WritePath of the folder held open: the image writers open that very path
            # from / without following symlinks, so a folder swapped for a symlink since
            # receives nothing (the write fails instead)
            tmp = os.path.join(folder.path, tmp_name)
            write(WritePath(tmp, tmp))
            fd = folder.open(tmp_name, os.O_RDONLY)
            h = hashlib.sha256()
            with os.fdopen(fd, "rb") as f:
                for chunk in iter(lambda: f.read(1 << 20), b""):
                    h.update(chunk)
            folder.replace(tmp_name, name)
        except BaseException:
            _unlink_in(folder, tmp_name)
            raise
        return h.hexdigest()
    finally:
        if own:
            folder.close()


def write_json_atomic(path: str, data: dict, folder=None) -> None:
    """Write ``data`` as JSON to ``path`` through a temporary in ``folder`` (see ``write_atomic``)."""
    own = folder is None
    if own:
        folder, _ = open_folder(path)
    name = os.path.basename(path)
    try:
        text = json.dumps(data, indent=1, sort_keys=True, default=str)
        folder.write_replace(name, text.encode("utf-8"), os.path.basename(temporary_name(path, suffix=".tmp")))
    finally:
        if own:
            folder.close()


def _unlink_in(folder, name: str) -> None:
    try:
        folder.unlink(name)
    except OSError:
        pass


# -- leftover temporaries ------------------------------------------------------------


def _tmp_owner(name: str, bases: set[str]) -> str | None:
    """The pid text of a temporary of one of ``bases`` (``.BASE.tmp-PID...``,
    the image writer's ``..BASE.tmp-...`` and sidecar ``BASE.json.tmp-PID``), or None."""
    stripped = name.lstrip(".")
    base, sep, rest = stripped.partition(".tmp-")
    if not sep:
        return None
    candidates = {base}
    stem, ext = os.path.splitext(base)
    if ext:
        candidates.add(stem)  # .STEM.EXT.tmp-PID.npy (data writer)
    if not candidates & bases:
        return None
    if not name.startswith(".") and not base.endswith(SIDECAR_SUFFIX):
        return None
    digits = ""
    for ch in rest:
        if not ("0" <= ch <= "9"):      # not isdigit: '²' is one, and int() refuses it
            break
        digits += ch
    # a pid is below 2^31 (10 digits, TMP_TAIL): a larger one is no process's, and
    # os.kill of it raised OverflowError, stopping the batch (int() of the digits of a
    # file name, at most 255, is safe; the length is checked first all the same)
    return digits if 0 < len(digits) <= 10 and int(digits) < 2 ** 31 else None


def _pid_alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OSError):
        return True
    return True


def remove_temporaries(paths: Iterable[str]) -> list[str]:
    """Remove leftover temporaries of these output files (a killed batch's):
    only names this batch's writers make for exactly these files, and only when
    their writer (the pid in the name) is no longer running. Returns what was removed."""
    by_folder: dict[str, set[str]] = {}
    for p in paths:
        folder, name = os.path.split(os.path.abspath(p))
        stem = os.path.splitext(name)[0]
        by_folder.setdefault(folder, set()).update({stem, name, name + SIDECAR_SUFFIX, _temp_stem(name),
                                                   _temp_stem(name + SIDECAR_SUFFIX, ".tmp")})
    removed = []
    now = time.time()
    for folder, bases in by_folder.items():
        try:
            entries = list(os.scandir(folder))
        except OSError:
            continue
        for e in entries:
            if ".tmp-" not in e.name:
                continue
            pid = _tmp_owner(e.name, bases)
            if pid is None:
                continue
            try:
                if not e.is_file(follow_symlinks=False):
                    continue
                old = now - e.stat(follow_symlinks=False).st_mtime > STALE_TMP_SECONDS
            except OSError:
                continue
            if old or not _pid_alive(int(pid)):
                try:
                    os.unlink(e.path)
                    removed.append(e.path)
                except OSError:
                    pass
    return removed


# -- the output-folder lock ----------------------------------------------------------


class FolderLock:
    """An exclusive lock on output folders for one batch (``.pixgraph-batch.lock``
    in each, holding ``pid host``). ``wait``: seconds to wait for another batch
    (0: refuse at once; ``None``: wait as long as it takes)."""

    def __init__(self, folders: Iterable[str], wait: float | None = 0.0):
        self.folders = sorted(set(folders))
        self.wait = wait
        self._held: list[tuple[str, int]] = []

    def __enter__(self):
        try:
            for folder in self.folders:  # sorted: two batches never wait on each other in a cycle
                self._held.append((folder, self._acquire(folder)))
        except BaseException:
            self.release()
            raise
        return self

    def __exit__(self, *exc):
        self.release()

    def _acquire(self, folder: str) -> int:
        try:
            os.makedirs(folder, exist_ok=True)
        except OSError as e:
            raise BatchError(f"output folder {folder}: cannot create it: {e.strerror}") from None
        path = os.path.join(folder, LOCK_NAME)
        deadline = None if self.wait is None else time.monotonic() + self.wait
        while True:
            try:
                fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
            except OSError as e:
                raise BatchError(f"output folder {folder}: cannot create its lock file: {e.strerror}") from None
            if _try_lock(fd):
                try:
                    same = os.fstat(fd).st_ino == os.stat(path).st_ino
                except OSError:
                    same = False
                if same:  # not a file the previous holder unlinked while we waited
                    os.ftruncate(fd, 0)
                    os.write(fd, f"{os.getpid()} {socket.gethostname()}\n".encode())
                    return fd
                os.close(fd)
                continue
            holder = _read_holder(path)
            os.close(fd)
            if deadline is not None and time.monotonic() >= deadline:
                raise BatchError(f"output folder {folder} is in use by another batch ({holder}): wait for it "
                                 f"to finish or write elsewhere (--wait-lock waits)")
            time.sleep(0.1)

    def release(self) -> None:
        while self._held:
            folder, fd = self._held.pop()
            try:
                os.unlink(os.path.join(folder, LOCK_NAME))  # still locked: a waiter re-checks the inode
            except OSError:
                pass
            os.close(fd)


def _read_holder(path: str) -> str:
    try:
        with open(path, encoding="utf-8") as f:
            pid, _, host = f.read(200).strip().partition(" ")
        return f"pid {pid} on {host}" if pid else "pid unknown"
    except OSError:
        return "pid unknown"


try:
    import fcntl

    def _try_lock(fd: int) -> bool:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            return True
        except OSError as e:
            if e.errno in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                return False
            raise
except ImportError:  # Windows: a byte-range lock the OS drops with the process
    import msvcrt

    def _try_lock(fd: int) -> bool:
        try:
            msvcrt.locking(fd, msvcrt.LK_NBLCK, 1)
            return True
        except OSError:
            return False
