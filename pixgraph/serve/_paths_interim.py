"""Interim path policy with the API of the hardening branch's pixgraph.paths (strict form only);
used only until that module is merged, then deleted."""
import os
class PathError(ValueError):
    pass
class PathPolicy:
    def __init__(self, roots=(), *, strict=False):
        self.roots = [os.path.realpath(r) for r in roots]
        self.strict = strict
    def _check(self, path, node=None, param=None, what="read"):
        real = os.path.realpath(path)
        if self.strict and not any(real == r or real.startswith(r + os.sep) for r in self.roots):
            where = (f"node {node!r}: param {param!r}: " if node else "")
            raise PathError(f"{where}{path} is outside the allowed folders")
        return real
    def check_read(self, path, node=None, param=None):
        return self._check(path, node, param)
    def check_write(self, path, node=None, param=None):
        return self._check(path, node, param, "write")
