"""The user's own files in the page: build a graph from a template around an opened
photo and cutout, and save a graph with the files it reads beside it.

The server knows no node types here either: a *template* is a YAML graph shipped by
a node pack (a ``templates/`` folder next to the module its ``pixgraph.nodes``
entry point names) in which a string ``"$photo"``, ``"$cutout"`` or ``"$mask"``
stands for a file the user opened, and a string ``"=EXPR"`` for a number computed
from the photo's size ``W`` x ``H`` and the cutout's ``w`` x ``h`` [px] (numbers,
``+ - * /`` and parentheses only). Which template: ``own_photo`` for an RGBA
cutout, ``own_photo_mask`` for an RGB cutout with a mask file.

Opened files arrive through ``PUT /api/uploads/NAME`` (the upload folder, an
allowed root) and are named here by the paths that call returned, so they pass
the same path rules as any graph's paths.
"""
from __future__ import annotations

import ast
import importlib.metadata
import os
import re
import shutil
import stat
from importlib import resources
from typing import Any

import yaml

from pixgraph.paths import PathError, open_write_folder

from .errors import ServeError, serve_error
from .state import ServeState

ENTRY_POINT_GROUP = "pixgraph.nodes"
FILE_ROLES = ("photo", "cutout", "mask")


def template_text(name: str) -> str:
    """The text of template ``name`` from the first installed node pack that ships it."""
    for ep in importlib.metadata.entry_points(group=ENTRY_POINT_GROUP):
        module = ep.value.split(":", 1)[0].strip()
        try:
            f = resources.files(module) / "templates" / f"{name}.yaml"
            if f.is_file():
                return f.read_text(encoding="utf-8")
        except (ModuleNotFoundError, TypeError):
            continue
    raise ServeError(404, f"no node pack ships a graph template {name!r} (templates/{name}.yaml)")


def _number(expr: str, env: dict[str, float], where: str) -> float:
    """Evaluate ``expr`` (numbers, names from ``env``, + - * / and parentheses)."""
    def ev(n):
        if isinstance(n, ast.Expression):
            return ev(n.body)
        if isinstance(n, ast.Constant) and isinstance(n.value, (int, float)) and not isinstance(n.value, bool):
            return float(n.value)
        if isinstance(n, ast.Name) and n.id in env:
            return float(env[n.id])
        if isinstance(n, ast.UnaryOp) and isinstance(n.op, (ast.USub, ast.UAdd)):
            v = ev(n.operand)
            return -v if isinstance(n.op, ast.USub) else v
        if isinstance(n, ast.BinOp) and isinstance(n.op, (ast.Add, ast.Sub, ast.Mult, ast.Div)):
            a, b = ev(n.left), ev(n.right)
            if isinstance(n.op, ast.Div):
                if b == 0:
                    raise ServeError(500, f"template {where}: {expr!r} divides by zero")
                return a / b
            return a + b if isinstance(n.op, ast.Add) else a - b if isinstance(n.op, ast.Sub) else a * b
        raise ServeError(500, f"template {where}: {expr!r} is not a number expression of {', '.join(env)}")

    try:
        tree = ast.parse(expr, mode="eval")
    except SyntaxError:
        raise ServeError(500, f"template {where}: {expr!r} is not an expression") from None
    return round(ev(tree), 2)


def fill(template: str, files: dict[str, str], sizes: dict[str, float]) -> str:
    """The graph YAML of ``template`` with ``$role`` strings replaced by ``files[role]``
    and ``=EXPR`` strings by their values; raises ServeError for a file it needs
    and was not given."""
    doc = yaml.safe_load(template)

    def sub(v, where):
        if isinstance(v, str) and v.startswith("$"):
            role = v[1:]
            if role not in files:
                raise ServeError(400, f"this graph needs a {role} file", field=role)
            return files[role]
        if isinstance(v, str) and v.startswith("="):
            return _number(v[1:], sizes, where)
        if isinstance(v, list):
            return [sub(x, where) for x in v]
        if isinstance(v, dict):
            return {k: sub(x, f"{where}.{k}") for k, x in v.items()}
        return v

    for nid, node in (doc.get("nodes") or {}).items():
        if isinstance(node, dict) and isinstance(node.get("params"), dict):
            node["params"] = sub(node["params"], nid)
    return yaml.safe_dump(doc, sort_keys=False)


def _size(path: str) -> tuple[int, int]:
    import OpenImageIO as oiio

    inp = oiio.ImageInput.open(path)
    if inp is None:
        raise ServeError(400, f"cannot read image {os.path.basename(path)}: {oiio.geterror()}")
    spec = inp.spec()
    inp.close()
    return int(spec.width), int(spec.height)


def open_files(state: ServeState, data: dict) -> dict:
    """``{"photo": path, "cutout": path, "mask": path?}`` (paths from the upload API,
    or relative to the served graph's folder) -> the served graph becomes the
    template filled in with them, unless the nodes' checks from the files' headers
    refuse it (then the served graph stays). Returns ``{"template", "yaml", "notes",
    "save_as"}`` (``save_name_for``)."""
    files = {}
    for role in FILE_ROLES:
        v = data.get(role)
        if v is None or v == "":
            continue
        if not isinstance(v, str):
            raise ServeError(400, f"{role} must be a path", field=role)
        files[role] = v
    for role in ("photo", "cutout"):
        if role not in files:
            raise ServeError(400, f"open needs a {role} file", field=role)
    resolved = {}
    policy = state.session.paths.with_roots([state.root])
    for role, v in files.items():
        path = os.path.normpath(os.path.join(state.root, os.path.expanduser(v)))
        try:
            policy.check_read(path, node=role, param="path")   # the same rule as any graph path
        except PathError as e:
            raise ServeError(403, str(e), field=role) from None
        if not os.path.isfile(path):
            raise ServeError(404, f"{role}: no file {os.path.basename(path)}", field=role)
        resolved[role] = path
    W, H = _size(resolved["photo"])
    w, h = _size(resolved["cutout"])
    name = "own_photo_mask" if "mask" in resolved else "own_photo"
    text = fill(template_text(name), resolved, {"W": W, "H": H, "w": w, "h": h})
    previous = state.graph
    state.load_text(text)
    try:
        found = notes(state)   # the nodes' own checks from the files' headers: an RGB cutout without a mask...
    except ServeError:
        state.graph = previous
        raise
    # a new graph, not the served file's: the page proposes the photo's name to save it under
    state.save_name = save_name_for(resolved["photo"], state.graph_path)
    return {"template": name, "yaml": state.yaml(), "notes": found, "save_as": state.save_name}


def save_name_for(photo: str, served: str) -> str:
    """The file name proposed for saving the graph of an opened photo: the photo's
    name with anything but letters, digits, ``_ . -`` made ``_`` and ``.yaml``; never
    the served graph's own name (the photo ``own_photo.jpg`` beside ``own_photo.yaml``
    would otherwise propose to write over the graph the server was started with)."""
    stem = re.sub(r"[^A-Za-z0-9_.-]", "_", os.path.splitext(os.path.basename(photo))[0]) or "photo"
    name = stem + ".yaml"
    k = 1
    while name.lower() == os.path.basename(served).lower():
        name = f"{stem}_{k}.yaml"
        k += 1
    return name


def notes(state: ServeState) -> list[str]:
    """The graph's check before running (file headers only): its warnings, e.g. a
    horizon that does not fit the cutout's placement; a problem is a ServeError."""
    from pixgraph.graph import GraphError

    found: list[str] = []
    if not state.graph.outputs:
        return found
    try:
        state.session.check(state.graph, notes=found)
    except GraphError as e:
        raise serve_error(e) from None
    return [n.replace(state.root + os.sep, "") for n in found]


def _beside(src: str, folder, shown: str) -> str:
    """Copy ``src`` into ``folder`` (a ``pixgraph.paths.Folder``, held open; ``shown``:
    its path as the graph names it) under its own name (or name_2, name_3, ... when
    another file of that name is there); a regular file with the same bytes is reused.
    Each copy is created with ``O_EXCL | O_NOFOLLOW``: a symlink planted at a name (even
    a dangling one) is skipped, never written through nor reused."""
    base, ext = os.path.splitext(os.path.basename(src))
    for k in range(1, 1000):
        name = f"{base}{'' if k == 1 else f'_{k}'}{ext}"
        try:
            fd = folder.open(name, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
        except FileExistsError:
            if _same_regular_file(src, folder, name):
                return os.path.join(shown, name)
            continue
        try:
            with open(src, "rb") as fin, os.fdopen(fd, "wb") as fout:
                shutil.copyfileobj(fin, fout, 1 << 20)
        except BaseException:
            folder.unlink(name)
            raise
        return os.path.join(shown, name)
    raise ServeError(409, f"save: too many files named {base}*{ext} in {shown}")


def _same_regular_file(src: str, folder, name: str) -> bool:
    """Whether ``name`` in ``folder`` is a regular file (not a symlink) with the bytes of ``src``."""
    try:
        fd = folder.open(name, os.O_RDONLY)
    except OSError:             # a symlink (ELOOP), a folder...
        return False
    with os.fdopen(fd, "rb") as a, open(src, "rb") as b:
        if not stat.S_ISREG(os.fstat(a.fileno()).st_mode) or os.fstat(a.fileno()).st_size != os.fstat(b.fileno()).st_size:
            return False
        while True:
            x, y = a.read(1 << 20), b.read(1 << 20)
            if x != y:
                return False
            if not x:
                return True


def save_with_files(state: ServeState, path: str | None) -> dict:
    """Save the graph to ``path`` (relative to the served graph's folder) with every
    file it reads from the upload folder copied beside it; the saved graph names
    them relative to itself, and the served graph then reads the copies.
    Returns ``{"path", "copied": [names], "yaml"}``."""
    target = state.save_target(path)   # checked before anything is copied
    shown = os.path.dirname(target)
    try:            # the checked folder, made if missing, no symlink followed on the way
        folder, _ = open_write_folder(target)
    except PathError as e:
        raise ServeError(403, f"save: {e.message}", field="path") from None
    uploads = os.path.realpath(state.upload_dir)
    live: dict[str, Any] = {}
    copied = []
    try:
        for nid, inst in state.graph.nodes.items():
            spec = state.registry.get(inst.type)
            for p in spec.params:
                if p.kind != "path" or p.writes or not inst.params.get(p.name):
                    continue
                src = os.path.realpath(state.graph.resolve_path(os.fspath(inst.params[p.name])))
                if os.path.commonpath([src, uploads]) != uploads:
                    continue
                dest = _beside(src, folder, shown)
                copied.append(os.path.basename(dest))
                inside = os.path.commonpath([dest, state.root]) == state.root
                live[f"{nid}.{p.name}"] = os.path.relpath(dest, state.root) if inside else dest
    finally:
        folder.close()
    if live:
        state.set_params(live)   # the served graph reads the copies from now on
    target = state.save(path)    # relative paths rebased; written atomically
    with open(target, encoding="utf-8") as f:
        return {"path": target, "copied": copied, "yaml": f.read()}


def routes(locked, json_body):
    """Starlette routes of this module: ``POST /api/open``, ``POST /api/save_files``
    and ``GET /api/notes`` (the check's warnings, and what the nodes of the last final
    logged: ``logs``). ``locked(request, fn, *args)``
    and ``json_body(request)`` are app.py's; the state is ``request.app.state.serve``."""
    from starlette.responses import JSONResponse
    from starlette.routing import Route

    def serve(request) -> ServeState:
        return request.app.state.serve

    async def open_route(request):
        data = await json_body(request)
        state = serve(request)
        # one undo step: undo goes back to the graph before the photo was opened
        return JSONResponse(await locked(request, lambda: state.edit(lambda: open_files(state, data), step=True)))

    async def save_route(request):
        data = await json_body(request)
        p = data.get("path")
        if p is not None and not isinstance(p, str):
            raise ServeError(400, "path must be a string", field="path")
        return JSONResponse(await locked(request, save_with_files, serve(request), p))

    async def notes_route(request):
        def both(state):
            return {"notes": notes(state), "logs": state.log_lines()}
        return JSONResponse(await locked(request, both, serve(request)))

    return [Route("/api/open", open_route, methods=["POST"]),
            Route("/api/save_files", save_route, methods=["POST"]),
            Route("/api/notes", notes_route, methods=["GET"])]
