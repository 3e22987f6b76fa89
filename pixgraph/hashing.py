"""Cache keys: computed from the graph alone, before anything runs.

``key(node) = sha256(canonical JSON of KeyParts)`` where ``KeyParts`` holds the
type id, node version, impl_version, the cache-relevant params after defaults and
coercion (a read path contributes the sha256 of the file's *content*, a written
path its absolute path), and the key of each input by port name. Keys never use
object identity, so two identical nodes share one cache entry, and the parts can
be compared to say *why* a node must run again (``explain_change``).
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import os
from typing import Any, Mapping

import numpy as np


def canonical_json(obj: Any) -> str:
    """JSON with sorted keys, no spaces, tuples as lists; NaN and infinities refused."""
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), ensure_ascii=False, allow_nan=False)


def sha256_text(text: str) -> str:
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def array_key(array: np.ndarray) -> str:
    """Key of a host array handed in with ``bind``: its dtype, shape and bytes."""
    a = np.ascontiguousarray(array)
    h = hashlib.sha256()
    h.update(f"bind:{a.dtype.str}:{a.shape}".encode())
    h.update(memoryview(a).cast("B"))
    return h.hexdigest()


class FileHasher:
    """sha256 of file contents, remembered per path and stat signature (size,
    mtime, ctime, inode) so an unchanged file is not read again on every plan.
    A file rewritten in place with the same size within one timestamp tick is
    not noticed (as with make); replacing it by rename changes the inode."""

    def __init__(self):
        self._seen: dict[str, tuple[tuple, str]] = {}

    def __call__(self, path: str) -> str:
        st = os.stat(path)
        sig = (st.st_size, st.st_mtime_ns, st.st_ctime_ns, st.st_ino)
        hit = self._seen.get(path)
        if hit is not None and hit[0] == sig:
            return hit[1]
        return self.fresh(path)

    def fresh(self, path: str) -> str:
        """Hash the file now, streaming it in 1 MiB chunks (never the whole file in
        memory); the engine calls this after a node read the file, so a file edited
        during the run is caught even within one timestamp tick."""
        with open(path, "rb") as f:
            st = os.fstat(f.fileno())
            h = hashlib.sha256()
            for chunk in iter(lambda: f.read(1 << 20), b""):
                h.update(chunk)
        digest = h.hexdigest()
        self._seen[path] = ((st.st_size, st.st_mtime_ns, st.st_ctime_ns, st.st_ino), digest)
        return digest


@dataclasses.dataclass(frozen=True)
class KeyParts:
    """Everything a node's cache key is made of, decodable for 'why did this run?'."""

    type_id: str
    version: int
    impl_version: str
    #: cache-relevant params; a read path is ``{"file_sha256": ...}``
    params: Mapping[str, Any]
    #: ``"<upstream key>:<output name>"`` by input port
    inputs: Mapping[str, str]

    def to_dict(self) -> dict:
        return {"type": self.type_id, "version": self.version, "impl_version": self.impl_version,
                "params": dict(self.params), "inputs": dict(self.inputs)}

    @classmethod
    def from_dict(cls, d: Mapping) -> "KeyParts":
        return cls(d["type"], d["version"], d["impl_version"], dict(d["params"]), dict(d["inputs"]))

    def to_json(self) -> str:
        return canonical_json(self.to_dict())

    def key(self) -> str:
        return sha256_text(self.to_json())


def explain_change(old: KeyParts | None, new: KeyParts) -> list[str]:
    """What differs between the last run of a node id and now, in words.

    ``["new"]`` when there is no last run; ``[]`` when the key is the same.
    """
    if old is None:
        return ["new"]
    why = []
    if old.type_id != new.type_id:
        why.append("type changed")
    if old.version != new.version:
        why.append("version changed")
    if old.impl_version != new.impl_version:
        why.append("impl_version changed")
    for name in sorted(set(old.params) | set(new.params)):
        a, b = old.params.get(name), new.params.get(name)
        if a != b:
            if isinstance(a, dict) and isinstance(b, dict) and "file_sha256" in a and "file_sha256" in b:
                why.append(f"file content changed (params.{name})")
            else:
                why.append(f"params.{name} changed")
    for port in sorted(set(old.inputs) | set(new.inputs)):
        if old.inputs.get(port) != new.inputs.get(port):
            why.append(f"input {port} changed")
    return why
