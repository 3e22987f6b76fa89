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
graph's folder and the roots given in code count. What this does and does not
guard is in ``docs/security.md``.
"""
from __future__ import annotations

import os
import pathlib
import stat
from typing import Iterable, Sequence

from .errors import GraphError, PathError  # noqa: F401 (PathError is re-exported)

PathLike = str | os.PathLike
ENV_ALLOW = "PIXGRAPH_ALLOW_PATHS"
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
