"""The disk cache's entry format: one file holds the key, a JSON manifest of the
value's structure (dicts, lists, tuples, numbers, strings, and frozen dataclasses of
those), the raw bytes of its numeric arrays, and a sha256 of all of it; no pickle,
and decoding never imports a module or runs code named by the entry. ``misfit``
checks a decoded entry against what its node's ports declare before it is served.
Also the names both caches share: ``MISS``, ``CacheError``, ``Unstorable``.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import struct
import sys
from typing import Any, Mapping

import numpy as np

from .errors import EXIT_BAD_INPUT, PixgraphError

#: what a cache lookup returns for a key it does not hold
MISS = object()


class CacheError(PixgraphError, ValueError):
    """A cache the user configured that cannot be used as asked (a negative limit, a
    folder that is not pixgraph's): bad input, the CLI exits 2 with this one line."""

    exit_code = EXIT_BAD_INPUT
    http_status = 500  # the server's own configuration, not the request


class Unstorable(TypeError):
    """A value the disk store cannot represent without pickle."""


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
DIGEST_BYTES = 32
#: dtypes an entry may hold: numbers and bools only (never objects or records)
_DTYPE_KINDS = "biufc"


def entry_parts(key: str, value: Any) -> tuple[bytes, list]:
    """The bytes before the arrays (magic, length, header) and the arrays' buffers."""
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
    return MAGIC + struct.pack("<Q", len(header)) + header, blobs


def pack_entry(key: str, value: Any) -> bytes:
    """The bytes of one disk entry: the key, the value's manifest and arrays, a checksum."""
    head, blobs = entry_parts(key, value)
    body = b"".join([head, *blobs])
    return body + hashlib.sha256(body).digest()


def unpack_entry(key: str, data: bytes) -> Any:
    """The value of an entry's bytes; ``ValueError`` saying why when the entry is
    damaged (checksum), is another key's entry (swapped), or is malformed."""
    if len(data) < len(MAGIC) + 8 + DIGEST_BYTES or not data.startswith(MAGIC):
        raise ValueError("not a pixgraph cache entry (truncated or foreign)")
    body, digest = memoryview(data)[:-DIGEST_BYTES], data[-DIGEST_BYTES:]
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
        if not a.flags.aligned:
            # the entry's bytes put it at an offset its dtype does not divide: OpenImageIO
            # refuses such a buffer ("buffer is wrong size": a cached float image could
            # not be written as EXR); an aligned copy, read-only like the rest
            a = a.copy()
            a.flags.writeable = False
        arrays[name] = a
    return decode(header.get("value"), arrays)


# -- checking a value against a node's declared outputs ------------------------------

def _port_arrays(port_type, name: str, value) -> list[tuple[str, np.ndarray]]:
    """The pixel arrays of a port whose type declares its values finite
    (``PortType.finite``: images, masks, pixel heights, buffers), labelled for messages."""
    if not getattr(port_type, "finite", False):
        return []
    if isinstance(value, np.ndarray):
        return [(repr(name), value)]
    if isinstance(value, dict):
        return [(f"{name!r} channel {k!r}", v) for k, v in value.items() if isinstance(v, np.ndarray)]
    return []


def _non_finite(a: np.ndarray, chunk: int = 1 << 22) -> int:
    """How many NaN or infinite values ``a`` holds, counted in slices of ``chunk``
    values (no temporary the size of the array)."""
    if a.dtype.kind not in "fc" or a.size == 0:
        return 0
    flat = a.reshape(-1)
    return int(sum(int(flat[i:i + chunk].size - np.count_nonzero(np.isfinite(flat[i:i + chunk])))
                   for i in range(0, flat.size, chunk)))


def misfit(outputs, value: Any, expected: Mapping[str, Any] | None = None) -> str | None:
    """Why ``value`` is not a valid output dict for ``outputs`` (``(name, port
    type)`` pairs), or None. Checked: the output names; each port type's
    ``validate`` (array, dimensions, dtype); that the arrays of ports whose type
    declares ``finite`` (Image, Mask, PixelHeight, Buffers) are all finite; and, where ``expected``
    holds a ``types.Shape`` for an output (the engine's check from file headers),
    that its arrays have that height and width."""
    from . import types as T

    outputs = [(n, t) for n, t in outputs]
    names = [n for n, _ in outputs]
    if not isinstance(value, dict) or sorted(value) != sorted(names):
        return f"holds outputs {sorted(value)[:8] if isinstance(value, dict) else type(value).__name__}, " \
               f"not {names}"
    for name, port_type in outputs:
        v = value[name]
        try:
            port_type.validate(v)
        except TypeError as e:
            return f"output {name!r} is not a valid {port_type.type_name()}: {e}"[:200]
        arrays = _port_arrays(port_type, name, v)
        for label, a in arrays:
            bad = _non_finite(a)
            if bad:
                return f"output {label} holds {bad} NaN or infinite value(s)"
        want = (expected or {}).get(name)
        if isinstance(want, T.Shape):
            for label, a in arrays:
                if a.ndim >= 2 and tuple(a.shape[:2]) != (want.height, want.width):
                    return f"output {label} is {a.shape[1]}x{a.shape[0]}, but its inputs make it {want.size}"
    return None


# -- the disk store ------------------------------------------------------------------

#: the file that makes a folder pixgraph's disk cache; written when pixgraph creates
#: (or adopts) the folder, checked every time it opens it
