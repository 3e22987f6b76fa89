"""Interim path policy with the API of the hardening branch's pixgraph.paths (strict form only);
used only until that module is merged, then deleted."""
import os

from ..graph import GraphError


class PathError(GraphError):
    pass


class PathPolicy:
    def __init__(self, roots=(), *, strict=False):
        self.roots = [os.path.realpath(r) for r in roots]
        self.strict = strict
    def _check(self, path, node=None, param=None, what="read"):
        real = os.path.realpath(path)
        if self.strict and not any(real == r or real.startswith(r + os.sep) for r in self.roots):
            raise PathError(f"cannot {what} {path!r}: outside the allowed folders", node=node,
                            field=f"params.{param}" if param else None)
        return real
    def check_read(self, path, *, node=None, param=None):
        return self._check(path, node, param)
    def check_write(self, path, *, node=None, param=None):
        return self._check(path, node, param, "write")
