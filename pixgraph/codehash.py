"""Code hashes: a node's cache key covers the code that computes it.

A node's ``impl_version`` is a promise its author must remember to keep ("bump
it when the numbers change"); an edit that forgets it would be served the old
results from a disk cache. So the engine adds a hash of the node's code to
the key: ``impl_version`` becomes ``"<declared>+code.<16 hex digits>"``.

The code of a node is:

- the source file of the module that defines its class;
- transitively, every module *of the same top-level package* that one of those
  modules imports (``from .ops.shadow import soft_shadow``, ``import
  pixgraph_nodes.ops.camera``, imports inside functions included), read from
  the module's file, whether or not it was imported yet; a package's
  ``__init__`` counts only when a name is imported from it;
- the data files those modules name in string literals: ``"shadow.cl"`` next to
  the module, a file of that name anywhere in the package's folder (such as
  ``weights/shadow_methods.json``), or every file of a folder named next to the
  module (``pathlib.Path(__file__).parent / "weights"``), with the ``#include
  "x.h"`` files of text kernels. Files over 64 MiB are left out.

Third-party libraries (numpy, pyopencl, torch) and pixgraph itself are not
hashed: upgrading them is not detected (their versions are the environment's
business). A module with no source file (built in a test function, ``__main__``
without a file, a frozen module) has no code hash: its ``impl_version`` is used
as declared. Hashes are computed once per process per module (a long-running
server does not see edits until restarted, nor does Python run them).
"""
from __future__ import annotations

import ast
import hashlib
import importlib.util
import os
import sys
import threading

#: longest data file hashed (larger ones are left out: trusted like the code's environment)
MAX_DATA_BYTES = 64 << 20
#: text kernels whose ``#include "..."`` lines are followed
_TEXT_KERNELS = (".cl", ".h", ".cuh", ".cu", ".glsl", ".hlsl", ".metal", ".wgsl", ".c", ".cpp", ".hpp")

_lock = threading.Lock()
_by_module: dict[str, str] = {}
_by_class: dict[type, str] = {}


def impl_version(spec) -> str:
    """The ``impl_version`` that goes into the cache key of a node type: the declared
    one plus ``+code.<hash>`` of its code (once per process per class)."""
    cls = spec.cls
    with _lock:
        hit = _by_class.get(cls)
    if hit is None:
        h = node_code_hash(cls)
        hit = f"{spec.impl_version}+code.{h}" if h else str(spec.impl_version)
        with _lock:
            _by_class[cls] = hit
    return hit


def node_code_hash(cls: type) -> str:
    """16 hex digits over the code of the module defining ``cls`` (see the module
    docstring), or ``""`` when that module has no source file."""
    module = getattr(cls, "__module__", None)
    if not module or module == "__main__" and not getattr(sys.modules.get("__main__"), "__file__", None):
        return ""
    return code_hash(module)


def code_hash(module: str) -> str:
    """The code hash of a module name (memoised per process)."""
    with _lock:
        hit = _by_module.get(module)
    if hit is not None:
        return hit
    files = code_files(module)
    if not files:
        digest = ""
    else:
        h = hashlib.sha256()
        for label, path in sorted(files.items()):
            h.update(label.encode("utf-8") + b"\0" + _file_digest(path) + b"\0")
        digest = h.hexdigest()[:16]
    with _lock:
        _by_module[module] = digest
    return digest


def code_files(module: str) -> dict[str, str]:
    """``{label: path}`` of every file in the code of ``module``: labels are module
    names for modules and paths relative to the package folder for data files."""
    top = module.split(".")[0]
    origin = _origin(module)
    if origin is None:
        return {}
    top_origin = _origin(top)
    package_dir = os.path.dirname(top_origin) if top_origin and _is_package(top, top_origin) else None
    by_name = _package_files(package_dir) if package_dir else {}
    files: dict[str, str] = {}
    queue, seen = [module], set()
    while queue:
        mod = queue.pop()
        if mod in seen:
            continue
        seen.add(mod)
        path = _origin(mod)
        if path is None:
            continue
        files[mod] = path
        if path.endswith(".py"):
            imported, data = _direct(mod, path, top, package_dir, by_name)
            queue.extend(imported)
            for d in data:
                _add_data(files, d, package_dir or os.path.dirname(origin))
    return files


_directs: dict[tuple, tuple[list, list]] = {}


def _direct(mod: str, path: str, top: str, package_dir, by_name) -> tuple[list, list]:
    """The modules of package ``top`` that ``mod`` imports and the data files its
    string literals name; worked out once per process per file version (every
    node of a pack reaches the same shared modules)."""
    st = os.stat(path)
    sig = (mod, path, st.st_mtime_ns, st.st_size, package_dir)
    hit = _directs.get(sig)
    if hit is not None:
        return hit
    is_pkg = _is_package(mod, path)
    imports, strings = _scan(path)
    imported, data = [], []
    for level, name, aliases in imports:
        base = _absolute(mod, is_pkg, level, name) if level else name
        if base is None or base.split(".")[0] != top:
            continue
        if aliases is None:  # import a.b.c
            imported.append(base)
            continue
        for alias in aliases:
            sub = f"{base}.{alias}"
            if alias != "*" and _origin(sub) is not None:
                imported.append(sub)  # a submodule: not the package it sits in
            else:
                imported.append(base)  # a name defined in ``base``
    for text in dict.fromkeys(strings):
        data += _data_files(text, os.path.dirname(path), by_name)
    _directs[sig] = (imported, data)
    return imported, data


_digests: dict[tuple[str, int, int], bytes] = {}


def _file_digest(path: str) -> bytes:
    """sha256 of a file's bytes, once per process per file version."""
    st = os.stat(path)
    sig = (path, st.st_mtime_ns, st.st_size)
    hit = _digests.get(sig)
    if hit is None:
        h = hashlib.sha256()
        with open(path, "rb") as f:
            for chunk in iter(lambda: f.read(1 << 20), b""):
                h.update(chunk)
        hit = _digests[sig] = h.digest()
    return hit


def _scan(path: str) -> tuple[list, list]:
    """The imports ``(level, module, names or None)`` and string literals of a
    source file (``_direct`` remembers what they give per file version)."""
    imports, strings = [], []
    try:
        with open(path, "rb") as f:
            tree = ast.parse(f.read(), filename=path)
    except (OSError, SyntaxError, ValueError):
        tree = None
    for node in ast.walk(tree) if tree is not None else ():
        if isinstance(node, ast.Import):
            imports += [(0, alias.name, None) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            imports.append((node.level, node.module, [alias.name for alias in node.names]))
        elif isinstance(node, ast.Constant) and isinstance(node.value, str):
            strings.append(node.value)
    return imports, strings


def _absolute(mod: str, is_pkg: bool, level: int, name: str | None) -> str | None:
    if level == 0:
        return name
    parts = mod.split(".") if is_pkg else mod.split(".")[:-1]
    if level - 1 > len(parts) - 1:
        return None
    parts = parts[: len(parts) - (level - 1)]
    return ".".join(parts + ([name] if name else []))


_origins: dict[str, str | None] = {}


def _origin(module: str) -> str | None:
    """The file of a module, without importing it (its parent packages may be);
    looked up once per process per name."""
    if module in _origins:
        return _origins[module]
    _origins[module] = found = _find_origin(module)
    return found


def _find_origin(module: str) -> str | None:
    loaded = sys.modules.get(module)
    f = getattr(loaded, "__file__", None) if loaded is not None else None
    if f is None:
        try:
            spec = importlib.util.find_spec(module)
        except (ImportError, ValueError, AttributeError):
            return None
        f = getattr(spec, "origin", None) if spec is not None else None
    if not f or not os.path.isfile(f):
        return None
    return os.path.abspath(f)


def _is_package(module: str, path: str) -> bool:
    return os.path.basename(path).startswith("__init__.")


def _package_files(package_dir: str) -> dict[str, list[str]]:
    """Non-Python files under a package's folder, by base name."""
    out: dict[str, list[str]] = {}
    for d, dirs, names in os.walk(package_dir):
        dirs[:] = sorted(x for x in dirs if not x.startswith((".", "__pycache__")))
        for n in names:
            if not n.endswith((".py", ".pyc", ".pyo")):
                out.setdefault(n, []).append(os.path.join(d, n))
    return out


def _data_files(text: str, module_dir: str, by_name: dict[str, list[str]]) -> list[str]:
    """Files a string literal names: a path next to the module, or a file of that
    base name in the package's folder."""
    if not text or len(text) > 200 or "\0" in text or "\n" in text or os.path.isabs(text):
        return []
    if "." not in text:  # a folder next to the module (``WEIGHTS = here / "weights"``): its files
        near = os.path.join(module_dir, text)
        if text in (os.curdir, os.pardir) or not os.path.isdir(near):
            return []
        return sorted(os.path.join(near, n) for n in os.listdir(near)
                      if not n.endswith((".py", ".pyc")) and os.path.isfile(os.path.join(near, n)))
    if text.endswith((".py", ".pyc")):
        return []
    found = []
    near = os.path.join(module_dir, text)
    if not os.path.isabs(text) and os.path.isfile(near):
        found.append(os.path.abspath(near))
    found += by_name.get(os.path.basename(text), [])
    return found


def _add_data(files: dict[str, str], path: str, root: str) -> None:
    try:
        if os.path.getsize(path) > MAX_DATA_BYTES:
            return
    except OSError:
        return
    label = "data:" + os.path.relpath(path, root)
    if label in files:
        return
    files[label] = path
    if path.endswith(_TEXT_KERNELS):
        try:
            with open(path, encoding="utf-8", errors="replace") as f:
                lines = f.read().splitlines()
        except OSError:
            return
        for line in lines:
            s = line.strip()
            if s.startswith("#include") and '"' in s:
                inc = os.path.join(os.path.dirname(path), s.split('"')[1])
                if os.path.isfile(inc):
                    _add_data(files, os.path.abspath(inc), root)


def clear() -> None:
    """Forget the hashes computed so far (tests that edit code in one process)."""
    with _lock:
        _by_module.clear()
        _by_class.clear()
        _origins.clear()
