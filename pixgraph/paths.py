"""The path policy: which files a graph may read and write.

A graph file is data handed over by other people (a shared workflow, a render
farm, the HTTP server), so its ``path`` params are confined to *roots*: the
graph file's folder (for a graph built in Python, its ``base_dir``, by default
the current directory), plus folders the user allows (``Session(allow_paths=)``,
``pixgraph run --allow-path DIR``, ``PIXGRAPH_ALLOW_PATHS``). Symlinks are
resolved before the check, so neither a symlinked file nor a symlinked folder
leads out of a root. NUL and other control characters are refused everywhere.

    policy = PathPolicy(["/data/plates"])
    policy.check_read("/data/plates/a.png", node="load", param="path")  # -> Path
    policy.check_write("/etc/passwd", node="save", param="path")       # PathError

``strict=True`` (the HTTP server) ignores ``PIXGRAPH_ALLOW_PATHS``: only the
graph's folder and the roots given in code count. A path a node writes is
handed to it as a ``WritePath`` that remembers the folder checked, and the image
writers open that folder with ``open_write_folder`` (no symlink followed), so a
folder swapped for a symlink after the check cannot redirect the write. What this
does and does not guard is in ``docs/security.md``.
"""
from __future__ import annotations

import errno
import hashlib
import os
import pathlib
import stat
from typing import Iterable, Sequence

from .errors import GraphError, PathError  # noqa: F401 (PathError is re-exported)

PathLike = str | os.PathLike
ENV_ALLOW = "PIXGRAPH_ALLOW_PATHS"
#: the most bytes of one file name (Linux's NAME_MAX, and that of most file systems)
NAME_MAX = 255
#: bytes a temporary's tail may take: ``.tmp-`` PID (up to 10 digits) ``-`` 8 hex digits
TMP_TAIL = 24
#: longest path text quoted in an error, in characters
_QUOTE = 100


def env_roots() -> list[str]:
    """The folders listed in ``PIXGRAPH_ALLOW_PATHS`` (``os.pathsep``-separated)."""
    raw = os.environ.get(ENV_ALLOW, "")
    return [r for r in raw.split(os.pathsep) if r.strip()]


def quote(path) -> str:
    """``repr`` of a path, cut to a readable length."""
    text = repr(os.fspath(path) if isinstance(path, os.PathLike) else path)
    return text if len(text) <= _QUOTE else text[:_QUOTE - 5] + "...'"


def bad_characters(path: str) -> str | None:
    """Why ``path`` is refused for its characters (NUL, control), or None."""
    for ch in path:
        if ch == "\0":
            return "contains a NUL byte"
        if ord(ch) < 32 or ord(ch) == 127:
            return f"contains a control character ({ch!r})"
    return None


class PathPolicy:
    """Allowed roots for file reads and writes; see the module docstring.

    roots: allowed folders (made absolute and symlink-resolved now).
    strict: only these roots and the graph's folder; ``PIXGRAPH_ALLOW_PATHS`` is ignored.
    """

    def __init__(self, roots: Sequence[PathLike] = (), *, strict: bool = False):
        self.strict = bool(strict)
        given = [os.fspath(r) for r in roots]
        if not strict:
            given += env_roots()
        self.roots: tuple[str, ...] = tuple(dict.fromkeys(self._root(r) for r in given))
        #: single files allowed wherever they are (paths the user typed, e.g. ``--set``)
        self.files: frozenset[str] = frozenset()

    @staticmethod
    def _root(root: str) -> str:
        why = bad_characters(root)
        if why:
            raise PathError(f"allowed folder {quote(root)} {why}")
        return os.path.realpath(os.path.abspath(os.path.expanduser(root)))

    def with_roots(self, roots: Iterable[PathLike]) -> "PathPolicy":
        """A copy that also allows ``roots`` (e.g. a graph's folder)."""
        out = PathPolicy.__new__(PathPolicy)
        out.strict = self.strict
        extra = [self._root(os.fspath(r)) for r in roots]
        out.roots = tuple(dict.fromkeys(self.roots + tuple(extra)))
        out.files = self.files
        return out

    def with_files(self, files: Iterable[PathLike]) -> "PathPolicy":
        """A copy that also allows these exact files (resolved), e.g. paths the user
        gave on the command line rather than ones written in the graph file."""
        out = self.with_roots(())
        out.files = self.files | {self._root(os.fspath(f)) for f in files}
        return out

    def allows(self, resolved: str) -> bool:
        if resolved in self.files:
            return True
        return any(resolved == r or resolved.startswith(r.rstrip(os.sep) + os.sep) for r in self.roots)

    def _resolve(self, path, node, param, verb) -> pathlib.Path:
        if isinstance(path, bytes):
            path = os.fsdecode(path)
        path = os.fspath(path)
        field = f"params.{param}" if param else None
        why = bad_characters(path)
        if why:
            raise PathError(f"path {quote(path)} {why}", node=node, field=field)
        resolved = os.path.realpath(os.path.abspath(path))
        if not self.allows(resolved):
            shown = quote(path) + (f" -> {quote(resolved)}" if resolved != os.path.abspath(path) else "")
            raise PathError(f"outside the allowed folders (allow one with --allow-path DIR): {verb} {shown}",
                            node=node, field=field)
        return pathlib.Path(resolved)

    def check_read(self, path: PathLike, *, node: str | None = None, param: str | None = None) -> pathlib.Path:
        """The resolved path of a file a node reads, or ``PathError``.

        Besides the roots: an existing path must be a regular file (no FIFOs or
        devices, which would hang or never end)."""
        p = self._resolve(path, node, param, "read")
        try:
            st = os.stat(p)
        except OSError:
            return p  # missing: the caller says "file not found" with the errno
        if not stat.S_ISREG(st.st_mode):
            raise PathError(f"cannot read {quote(path)}: not a regular file", node=node,
                            field=f"params.{param}" if param else None)
        return p

    def check_write(self, path: PathLike, *, node: str | None = None, param: str | None = None) -> pathlib.Path:
        """The resolved path of a file a node writes, or ``PathError``.

        An existing target must be a regular file (never a folder or a device)."""
        p = self._resolve(path, node, param, "write")
        try:
            st = os.stat(p)
        except OSError:
            return p
        if not stat.S_ISREG(st.st_mode):
            raise PathError(f"cannot write {quote(path)}: exists and is not a regular file", node=node,
                            field=f"params.{param}" if param else None)
        return p

    def __repr__(self) -> str:
        return f"PathPolicy({list(self.roots)!r}, strict={self.strict})"


# -- writing without following symlinks ------------------------------------------------

_DIR_FLAGS = os.O_RDONLY | getattr(os, "O_DIRECTORY", 0)
_NOFOLLOW = getattr(os, "O_NOFOLLOW", 0)
#: a folder opened only to look names up in it (Linux ``O_PATH``: needs search
#: permission only, like a path walk; a folder one may enter but not list works)
_SEARCH_FLAGS = (os.O_PATH | getattr(os, "O_DIRECTORY", 0)) if hasattr(os, "O_PATH") else _DIR_FLAGS
#: the platform opens files relative to a folder descriptor (POSIX ``*at`` calls)
AT_CALLS = hasattr(os, "O_DIRECTORY") and all(
    f in os.supports_dir_fd for f in (os.open, os.unlink, os.mkdir, os.rmdir, os.rename, os.stat))


class Folder:
    """A folder held open: a descriptor where the platform has ``*at`` calls
    (Linux, macOS), so names are looked up in *this* folder whatever happens to its
    path meanwhile, and no symlink is followed (``O_NOFOLLOW``); elsewhere (Windows)
    its path, with each step checked to be a folder and not a link just before use.
    Use as a context manager, or ``close()``."""

    def __init__(self, path: str, fd: int | None):
        self.path, self.fd = path, fd

    @classmethod
    def at(cls, path: str) -> "Folder":
        """Open a folder by its path (symlinks in ``path`` itself are followed)."""
        return cls(path, os.open(path, _DIR_FLAGS) if AT_CALLS else None)

    def sub(self, name: str, create: bool = False) -> "Folder":
        """The child folder ``name`` (created when missing and ``create``); an
        ``OSError`` (``ELOOP``/``ENOTDIR``) when it is a symlink or not a folder."""
        if create:
            try:
                self.mkdir(name)
            except FileExistsError:
                pass
        path = os.path.join(self.path, name)
        if self.fd is not None:
            fd = os.open(name, _SEARCH_FLAGS | _NOFOLLOW, dir_fd=self.fd)
            if not stat.S_ISDIR(os.fstat(fd).st_mode):  # O_PATH may hand out a link itself
                os.close(fd)
                raise NotADirectoryError(errno.ENOTDIR, "a symlink or not a folder", path)
            return Folder(path, fd)
        if not os.path.lexists(path):
            raise FileNotFoundError(errno.ENOENT, "no such folder", path)
        if os.path.islink(path) or not os.path.isdir(path):
            raise NotADirectoryError(errno.ENOTDIR, "a symlink or not a folder", path)
        return Folder(path, None)

    def _name(self, name: str) -> str:
        return name if self.fd is not None else os.path.join(self.path, name)

    def _at(self) -> dict:
        return {"dir_fd": self.fd} if self.fd is not None else {}

    def open(self, name: str, flags: int, mode: int = 0o644) -> int:
        """``os.open`` of a file in this folder, never through a symlink."""
        return os.open(self._name(name), flags | _NOFOLLOW, mode, **self._at())

    def mkdir(self, name: str, mode: int = 0o777) -> None:
        os.mkdir(self._name(name), mode, **self._at())

    def unlink(self, name: str) -> None:
        os.unlink(self._name(name), **self._at())

    def rmdir(self, name: str) -> None:
        os.rmdir(self._name(name), **self._at())

    def lstat(self, name: str) -> os.stat_result:
        return os.stat(self._name(name), follow_symlinks=False, **self._at())

    def replace(self, src: str, dst: str) -> None:
        """Rename ``src`` over ``dst``, both in this folder."""
        if self.fd is not None:
            os.replace(src, dst, src_dir_fd=self.fd, dst_dir_fd=self.fd)
        else:
            os.replace(self._name(src), self._name(dst))

    def write_replace(self, name: str, data: bytes, tmp: str, mode: int = 0o644, check=None) -> None:
        """Write ``data`` into a new file ``tmp`` of this folder (``O_EXCL``, never through
        a symlink), call ``check(tmp)`` when given (it raises to refuse the file), then
        rename it over ``name``; the temporary is removed when anything fails."""
        fd = self.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, mode)
        try:
            with os.fdopen(fd, "wb") as f:
                f.write(data)
            if check is not None:
                check(tmp)
            self.replace(tmp, name)
        except BaseException:
            try:
                self.unlink(tmp)
            except OSError:
                pass
            raise

    def listdir(self) -> list[str]:
        if self.fd is None:
            return os.listdir(self.path)
        fd = os.open(".", _DIR_FLAGS, dir_fd=self.fd)  # readable, whatever ``self.fd`` was opened for
        try:
            return os.listdir(fd)
        finally:
            os.close(fd)

    def close(self) -> None:
        if self.fd is not None:
            os.close(self.fd)
            self.fd = None

    def __enter__(self) -> "Folder":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class WritePath(str):
    """A path a node writes, as the graph names it (made absolute: messages name
    the user's path), carrying ``real``: the symlink-free path the policy allowed
    when the run was planned. ``open_write_folder`` writes there and nowhere else,
    even if a folder on the way has been swapped for a symlink since."""

    def __new__(cls, named: str, real: str):
        obj = str.__new__(cls, named)
        obj.real = os.fspath(real)
        return obj

    def __reduce__(self):
        return (WritePath, (str(self), self.real))


def open_write_folder(path: PathLike) -> tuple[Folder, str]:
    """``(folder, file name)`` for writing ``path``: the folder opened one component
    at a time from the root without following any symlink (missing folders are
    created). The folder is the one the path policy checked (``WritePath.real``),
    or for any other path its real folder now (the user's own ``-o`` paths).
    Raises ``PathError`` (nothing written) when a component is now a symlink or not
    a folder; the caller closes the folder."""
    named = os.fspath(path)
    real = getattr(path, "real", None) or os.path.realpath(os.path.abspath(named))
    folder, name = os.path.split(real)
    if not name or name in (os.curdir, os.pardir):
        raise PathError(f"cannot write {quote(named)}: not a file name")
    drive, rest = os.path.splitdrive(folder)
    walked = drive + os.sep
    current = Folder.at(walked)
    try:
        for part in rest.split(os.sep):
            if not part:
                continue
            walked = os.path.join(walked, part)
            try:
                child = current.sub(part, create=True)
            except OSError as e:
                raise _swapped(named, walked, e) from None
            current.close()
            current = child
        return current, name
    except BaseException:
        current.close()
        raise


def _swapped(named: str, walked: str, e: OSError) -> PathError:
    if e.errno in (errno.ELOOP, errno.ENOTDIR, errno.EMLINK):
        why = "is now a symlink or not a folder (changed since the path was checked)"
    else:
        why = f"cannot be opened ({e.strerror})"
    return PathError(f"cannot write {quote(named)}: {quote(walked)} {why}; nothing was written")


def temp_stem(stem: str, extra: int = 0) -> str:
    """``stem`` as the start of a temporary's name ``.STEM.tmp-PID-RANDOM`` followed by
    ``extra`` more bytes (an extension, or room a writer's own temporary on top of
    this one needs): unchanged when that fits in ``NAME_MAX`` bytes, else its start
    and ``~`` and 8 hex digits of its sha256 (the same stem always gives the same
    name, so leftover temporaries can be recognised). Before, a long output name made
    a temporary name over NAME_MAX, and its write failed (ENAMETOOLONG)."""
    raw = stem.encode("utf-8", "surrogateescape")
    room = NAME_MAX - 1 - TMP_TAIL - extra
    if len(raw) <= room:
        return stem
    start = raw[:max(0, room - 9)].decode("utf-8", "ignore")     # a character cut in two is dropped
    return f"{start}~{hashlib.sha256(raw).hexdigest()[:8]}"
