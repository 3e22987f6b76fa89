"""What ``pixgraph serve`` holds: one ``Session``, the edited graph, and the limits.

No HTTP here: ``app.py`` turns requests into calls on a ``ServeState`` and its
errors into JSON responses (``errors.py``). Every method that runs the engine or
edits the graph must be called by one thread at a time (``app.py`` holds a lock
around them); edits build a new immutable ``Graph`` and swap it in, so a run in
progress keeps the graph it started with, and an edit that fails anywhere leaves
the graph as it was (``edit`` is all or nothing).

**Undo.** An edit made through ``edit(..., step=True)`` keeps the graph's state before
it in the undo history (``history.py``: params, no pixels); ``undo`` and ``redo`` move
through it. One history per server, shared by its clients as the graph is (two
clients' actions that overlap in time are one step: ``history.py``).

The session keeps its memory cache across requests: a light drag changes one
param of the light node, so only the nodes downstream of it run again. Runs at a
working resolution below full size (the page's previews) have a session and cache
of their own (``session_for``), so a full-size final does not push them out.

Nothing here names a node type: a node declares its cheap preview stand-in
(``preview = "type id"``) and what the page may draw and drag (``handles``, read
by ``scene.py``); both are class attributes read through the registry's spec.
"""
from __future__ import annotations

import dataclasses
import os
import tempfile
import threading
import time
from typing import Any, Mapping

from pixgraph import fileio
from pixgraph.events import Cancelled, CancelToken
from pixgraph.graph import Graph, GraphError, NodeInstance, split_param, validate
from pixgraph.paths import PathError, WritePath
from pixgraph.session import Session

from .errors import RunTimeout, ServeError, serve_error
from .images import header_pixels, store_upload
from .history import History, Step

#: image file extensions whose header is checked against the pixel limit
IMAGE_EXTENSIONS = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".exr", ".hdr")
#: deepest nesting of lists/objects accepted in an edit's values
MAX_DEPTH = 32


@dataclasses.dataclass(frozen=True)
class Limits:
    """Request, image and time limits of the server."""

    #: largest request body (a posted graph, params, an uploaded image: a 50 MP photo's
    #: JPEG is 10-40 MB, its 8-bit PNG 60-150 MB) [bytes]
    max_body_bytes: int = 256 << 20
    #: largest JSON body (an edit, a save, an undo: a few kilobytes; 24 MB of a
    #: 2-million-point list held the event loop, every client, 8.6 s at load 3.4:
    #: benchmarks/serve_bytes_bench.py) [bytes]
    max_json_bytes: int = 1 << 20
    #: largest image a graph may load or make, width x height [pixels]: 8192^2 (67 MP)
    #: takes the 12-50 MP photos people bring
    max_pixels: int = 8192 * 8192
    #: previews are sent downscaled by this integer factor
    preview_scale: int = 2
    #: wall-clock limit of one run; a run still going is cancelled (503) [s]
    run_timeout: float = 120.0
    #: memory cache of the runs at a working resolution below 1 (the page's previews), kept
    #: apart from the full-size runs' so a final of a large photo cannot evict them [bytes]
    scaled_cache_bytes: int = 512 << 20
    #: graph states kept to undo (each a reference to an immutable graph: params, no pixels)
    undo_steps: int = 100
    #: bytes the undo history may hold, estimated by ``history.graph_bytes`` (a step of an
    #: 8,000-node graph is ~13 MB: fewer steps of such graphs), the newest step kept [bytes]
    undo_bytes: int = 64 << 20


class Deadlines:
    """Cancel runs that pass their deadline, from one watchdog thread (started on first
    use) rather than a timer thread per run."""

    def __init__(self):
        self._cv = threading.Condition()
        self._items: dict[CancelToken, tuple[float, threading.Event]] = {}
        self._thread: threading.Thread | None = None

    def add(self, token: CancelToken, seconds: float) -> threading.Event:
        """Cancel ``token`` after ``seconds``; the returned event is set when it did."""
        expired = threading.Event()
        with self._cv:
            self._items[token] = (time.monotonic() + seconds, expired)
            if self._thread is None:
                self._thread = threading.Thread(target=self._watch, name="pixgraph-run-deadlines", daemon=True)
                self._thread.start()
            self._cv.notify()
        return expired

    def remove(self, token: CancelToken) -> None:
        with self._cv:
            self._items.pop(token, None)

    def _watch(self) -> None:
        with self._cv:
            while True:
                now = time.monotonic()
                for token, (deadline, expired) in list(self._items.items()):
                    if deadline <= now:
                        expired.set()
                        token.cancel()
                        del self._items[token]
                nearest = min((d for d, _ in self._items.values()), default=None)
                self._cv.wait(None if nearest is None else max(0.0, nearest - now))


def _graph_errors(fn):
    """Run ``fn()``; a GraphError (a PathError is one) becomes its ServeError."""
    try:
        return fn()
    except GraphError as e:
        raise serve_error(e) from None


class ServeState:
    """The served graph and the session that runs it.

    graph_path: the YAML file served; its folder is the root the graph may read
        and write in. allow: more folders the graph may use. upload_dir: where
        uploaded images go (made when None; always allowed). device, registry:
        as for ``Session``, which is made here in the strict path form.
    """

    def __init__(self, graph_path: str | os.PathLike, *, allow: list[str] | tuple[str, ...] = (),
                 limits: Limits | None = None, upload_dir: str | None = None, device=None, registry=None):
        self.graph_path = os.path.abspath(graph_path)
        self.root = os.path.dirname(self.graph_path)
        self.limits = limits or Limits()
        #: True when the upload folder was made here (``remove_uploads`` deletes it)
        self.own_uploads = upload_dir is None
        self.upload_dir = upload_dir or tempfile.mkdtemp(prefix="pixgraph-uploads-")
        roots = [self.root, self.upload_dir, *(os.path.abspath(a) for a in allow)]
        self._roots = roots
        self.session = Session(device=device, registry=registry, allow_paths=roots, strict_paths=True)
        self._scaled: Session | None = None
        self.registry = self.session.registry
        self._stash: dict[tuple[str, str], dict] = {}   # (node, type) -> its params before a type swap
        self._preview: tuple[Graph, Graph] | None = None
        self._pixels: dict[tuple[str, int], int] = {}
        #: runs of the graph made so far (each ``session.run``), e.g. to count a drag's
        self.runs = 0
        self._active: set[CancelToken] = set()
        self._active_lock = threading.Lock()
        self._closing = False
        self._deadlines = Deadlines()
        #: scene.py's cache of what the handles are anchored to (see scene.Anchors)
        self.anchors = None
        #: what the nodes of the last final said (``RunResult.said``: cached nodes included)
        self.final_said: dict[str, list[str]] = {}
        #: the name the page proposes to save under (``info()["save_as"]``): the last file
        #: saved, or after ``/api/open`` the photo's name; None: the served file
        self.save_name: str | None = None
        self.steps = History(self.limits.undo_steps, self.limits.undo_bytes)
        try:
            self.graph = self._checked(_graph_errors(lambda: self.session.load(self.graph_path)))
        except BaseException:
            self.remove_uploads()
            raise

    # -- graph ------------------------------------------------------------------

    def _checked(self, graph: Graph) -> Graph:
        """``graph`` after the session's path policy and the image limits; raises ServeError."""
        _graph_errors(lambda: self.session.check_paths(graph))
        for nid, inst in graph.nodes.items():
            spec = self.registry.get(inst.type)
            for p in spec.params:
                if p.kind == "path" and not p.writes and p.name in inst.params:
                    # every file's header, whatever its name: a .bmp, .gif or a PNG named
                    # x.data is read by content as well
                    path = graph.resolve_path(inst.params[p.name])
                    self._check_pixels(self.image_pixels(path), nid, p.name)
            values = spec.coerce_params(inst.params)
            if isinstance(values.get("width"), int) and isinstance(values.get("height"), int):
                self._check_pixels(values["width"] * values["height"], nid, "width")
        return graph

    def _paths_first(self, base_dir: str, nodes) -> None:
        """Check path params against the policy before the graph is validated, so a
        path outside the roots is refused (403) whether or not the file exists there:
        "file not found" would tell a client which files exist outside."""
        policy = self.session.paths.with_roots([base_dir])
        for nid, type_id, params in nodes:
            if type_id not in self.registry:
                continue
            spec = self.registry.get(type_id)
            for pname, value in params.items():
                p = spec.param(str(pname))
                if p is None or p.kind != "path" or not isinstance(value, str) or not value:
                    continue
                path = os.path.normpath(os.path.join(base_dir, os.path.expanduser(value)))
                try:
                    (policy.check_write if p.writes else policy.check_read)(path, node=str(nid), param=p.name)
                except PathError as e:
                    raise serve_error(e) from None

    def _check_pixels(self, n: int, nid: str, pname: str) -> None:
        if n > self.limits.max_pixels:
            raise ServeError(413, f"node {nid!r}: param {pname!r}: image of {n} pixels is over the "
                                  f"server's limit of {self.limits.max_pixels} (pixgraph serve --max-pixels N raises it)", node=nid, field=f"params.{pname}")

    def image_pixels(self, path: str) -> int:
        """Pixel count from the file's header (not decoded), cached by path and mtime:
        an image in any format the image reader knows, whatever its name, or a ``.npy``
        array (its first two dimensions); 0 for a missing file (the graph's own
        validation reports it) and for a file that is neither (the node reports it),
        unless it is named as an image (``IMAGE_EXTENSIONS``): then a 400."""
        try:
            key = (path, os.stat(path).st_mtime_ns)
        except OSError:
            return 0
        if key not in self._pixels:
            self._pixels[key] = header_pixels(path, strict=path.lower().endswith(IMAGE_EXTENSIONS))
        return self._pixels[key]

    def store_upload(self, name: str, raw: bytes) -> tuple[str, int]:
        """Write an uploaded image (``name`` already checked) into the upload folder,
        after checking its header against the pixel limit; returns (path, pixels)
        (``images.store_upload``)."""
        return store_upload(self.upload_dir, name, raw, self.limits.max_pixels)

    def remove_uploads(self) -> None:
        """Delete the upload folder with the files in it, when this state made it (the
        server stopping: the user's photos do not stay in the temporary folder; a graph
        saved from the page reads copies beside it)."""
        if self.own_uploads:
            import shutil

            shutil.rmtree(self.upload_dir, ignore_errors=True)

    def info(self) -> dict:
        """The graph as the UI and API clients see it: nodes in file order with the
        params set and their effective values, inputs, outputs, and node types (those
        used, and those a node may be switched to: ``alternatives``); ``save_as``: the
        name the page proposes to save under (``save_name``); ``history``: the undo and
        redo steps there are (``history()``)."""
        from pixgraph.reference import as_dict

        g = self.graph
        nodes = []
        for nid, inst in g.nodes.items():
            spec = self.registry.get(inst.type)
            values = spec.coerce_params(inst.params)
            nodes.append({"id": nid, "type": inst.type,
                          "params": _jsonable(dict(inst.params)), "values": _jsonable(values),
                          "inputs": {k: str(v) for k, v in inst.inputs.items()}})
        used = {inst.type for inst in g.nodes.values()}
        for t in list(used):
            used.update(self.alternatives(t))
        return {"file": self.graph_path, "save_as": self.save_name or os.path.basename(self.graph_path), "nodes": nodes,
                "outputs": {k: str(v) for k, v in g.outputs.items()},
                "types": {t: as_dict(self.registry.get(t)) for t in sorted(used)},
                "limits": dataclasses.asdict(self.limits), "history": self.history()}

    def handles(self, type_id: str) -> dict | None:
        """The ``handles`` a node type declares (a dict with a ``kind``), or None."""
        h = getattr(self.registry.get(type_id).cls, "handles", None)
        return h if isinstance(h, Mapping) and "kind" in h else None

    def alternatives(self, type_id: str) -> list[str]:
        """Registered types a node of ``type_id`` may be switched to: those declaring the
        same handles ``kind`` with the same input port names (e.g. the shadow methods)."""
        h = self.handles(type_id)
        if h is None:
            return []
        ports = [p.name for p in self.registry.get(type_id).inputs]
        return sorted(t for t in self.registry
                      if (self.handles(t) or {}).get("kind") == h["kind"]
                      and [p.name for p in self.registry.get(t).inputs] == ports)

    # -- edits (all or nothing) ---------------------------------------------------

    def edit(self, apply, keep_on: tuple = (), step: bool = False, action: str | None = None,
             client: str | None = None):
        """Call ``apply()`` (any number of ``set_*`` calls, and a run of the edited graph)
        and return what it returns; if it raises, the graph, the stashed params and the
        undo history are restored and the error propagates: nothing is half-applied. An
        exception of a class in ``keep_on`` keeps the edits (a render cancelled by a newer
        one of the page: the newer one carries only its own edits).

        step: the edit is a user's (``undo`` can take it back): when it changed the graph,
        the state before it becomes an undo step and the redo steps are dropped, unless
        ``action`` (the page's id of one user action, e.g. a whole drag) of ``client``
        (the page that sent it) already has a step: then it continues that step (joined
        with any newer steps of other clients: ``history.py``, "Two clients")."""
        History.check_action(action, client)
        before, saved = Step(self.graph, dict(self._stash)), self.steps.save()
        try:
            out = apply()
        except keep_on:
            if step:
                self.steps.record(before, self.graph, action, client)
            raise
        except BaseException:
            self.graph, self._stash = before.graph, dict(before.stash)
            self.steps.restore(saved)
            raise
        if step:
            self.steps.record(before, self.graph, action, client)
        return out

    def history(self) -> dict:
        """``{"undo": steps, "redo": steps, "limit": Limits.undo_steps}``."""
        return self.steps.counts()

    def undo(self) -> Graph:
        """Go back to the state before the newest step (its graph and stashed params);
        the state left can be redone. 409 when there is nothing to undo."""
        return self._go("undo")

    def redo(self) -> Graph:
        """Go forward to the state the newest undo left; 409 when there is nothing to redo."""
        return self._go("redo")

    def _go(self, what: str) -> Graph:
        target = self.steps.peek(what)
        graph = self._checked(target.graph)   # the path and pixel rules again: files change
        self.steps.moved(what, Step(self.graph, dict(self._stash)))
        self.graph, self._stash = graph, dict(target.stash)
        return self.graph

    def set_params(self, params: Mapping[str, Any]) -> Graph:
        """Apply ``{"node.param": value}`` (or ``{"node": {"param": value}}``) edits."""
        if not isinstance(params, Mapping):
            raise ServeError(400, "params must be an object of 'node.param': value", field="params")
        check_depth(params)
        edits = []
        for name, value in params.items():
            if isinstance(value, Mapping) and "." not in str(name):
                edits += [(str(name), k, v) for k, v in value.items()]
            else:
                try:                         # the engine's parser; its error named no field
                    nid, pname = split_param(name, "param override")
                except GraphError as e:
                    raise ServeError(400, e.message, field=f"params.{name}") from None
                edits.append((nid, pname, value))
        self._paths_first(self.graph.base_dir, [(nid, self.graph.nodes[nid].type, {pname: v})
                                                for nid, pname, v in edits if nid in self.graph.nodes])
        try:
            graph = self.session.graph(self.graph, dict(params))
        except GraphError as e:
            raise serve_error(e) from None
        except (TypeError, ValueError, OverflowError) as e:  # e.g. a number too large for a float
            raise ServeError(400, f"bad params: {e}", field="params") from None
        self.graph = self._checked(graph)
        return self.graph

    def set_type(self, node_id: str, type_id: str) -> Graph:
        """Switch a node to another type with the same inputs (e.g. the shadow method),
        keeping the params the new type declares of the same kind and unit (a length in
        image pixels does not carry over to one in another unit: the new type's default
        applies) and those it had last time."""
        inst = self.graph.nodes.get(node_id)
        if inst is None:
            raise ServeError(404, f"no node {node_id!r} in the graph", node=node_id)
        if type_id not in self.registry:
            raise ServeError(400, f"unknown node type {type_id!r}", node=node_id, field="type")
        if type_id == inst.type:
            return self.graph
        self._stash[(node_id, inst.type)] = dict(inst.params)
        spec, old = self.registry.get(type_id), self.registry.get(inst.type)

        def carries(name):
            new, was = spec.param(name), old.param(name)
            return new is not None and (was is None or (new.kind, new.unit) == (was.kind, was.unit))
        params = {k: v for k, v in inst.params.items() if carries(k)}
        params.update(self._stash.get((node_id, type_id), {}))
        nodes = dict(self.graph.nodes)
        nodes[node_id] = NodeInstance(node_id, type_id, params, inst.inputs)
        graph = _graph_errors(lambda: validate(dataclasses.replace(self.graph, nodes=nodes), self.registry))
        self.graph = self._checked(graph)
        return self.graph

    def load_text(self, text: str) -> Graph:
        """Replace the served graph by posted YAML; its paths resolve in the graph's folder."""
        import yaml

        _precheck_yaml(text)
        try:
            doc = yaml.load(text, Loader=getattr(yaml, "CSafeLoader", yaml.SafeLoader))
        except (yaml.YAMLError, ValueError):     # ValueError: an int over Python's 4300 digits
            doc = None  # the loader below reports it with its line
        if isinstance(doc, dict) and isinstance(doc.get("nodes"), dict):
            self._paths_first(self.root, [(nid, n.get("type"), n.get("params")) for nid, n in doc["nodes"].items()
                                          if isinstance(n, dict) and isinstance(n.get("params"), dict)])
        graph = _graph_errors(lambda: fileio.loads(text, self.registry, file="<posted graph>", base_dir=self.root))
        self.graph = self._checked(graph)
        return self.graph

    def yaml(self) -> str:
        return fileio.dumps(self.graph)

    def save_target(self, path: str | None = None) -> WritePath:
        """The file ``save(path)`` writes (relative to the served graph's folder; default
        the served file), checked: a YAML name the path policy lets this graph write.
        A ``WritePath``: writers keep to the folder that was checked."""
        target = self.graph_path if not path else os.path.normpath(os.path.join(self.root, path))
        if not target.endswith((".yaml", ".yml")):
            raise ServeError(400, f"save: {path!r} must end in .yaml or .yml", field="path")
        try:
            real = self.session.policy_for(self.graph).check_write(target)
        except PathError as e:
            raise ServeError(403, str(e), field="path") from None
        return WritePath(target, real)

    def save(self, path: str | None = None) -> str:
        """Write the edited graph as canonical YAML (default: over the served file),
        through a temporary renamed into place (a reader, or a killed server, never sees
        half a file), never through a symlink planted in the folder (``fileio.dump``)."""
        target = self.save_target(path)
        try:
            fileio.dump(self.graph, target, self.registry)
        except PathError as e:
            raise ServeError(403, f"save: {e.message}", field="path") from None
        except OSError as e:
            raise ServeError(400, f"save: cannot write {path or target}: {e.strerror or e}", field="path") from None
        target = str(target)
        inside = os.path.commonpath([target, self.root]) == self.root
        self.save_name = os.path.relpath(target, self.root) if inside else target
        return target

    # -- run ----------------------------------------------------------------------

    def preview_graph(self, graph: Graph | None = None) -> Graph:
        """``graph`` (default the current one) with every node whose type declares a
        ``preview`` stand-in swapped for it (cached for the current graph): the stand-in
        gets the node's params it declares, then the type's ``preview_params`` (the
        values that say how the node's params map onto the stand-in's)."""
        graph = self.graph if graph is None else graph
        if self._preview is not None and self._preview[0] is graph:
            return self._preview[1]
        nodes = dict(graph.nodes)
        for nid, inst in nodes.items():
            cls = self.registry.get(inst.type).cls
            cheap = getattr(cls, "preview", None)
            if isinstance(cheap, str) and cheap in self.registry:
                spec = self.registry.get(cheap)
                keep = {k: v for k, v in inst.params.items() if spec.param(k) is not None}
                # set last, unfiltered: a name the stand-in lacks fails the preview's validation
                keep.update(getattr(cls, "preview_params", None) or {})
                nodes[nid] = NodeInstance(nid, cheap, keep, inst.inputs)
        preview = _graph_errors(lambda: validate(dataclasses.replace(graph, nodes=nodes), self.registry))
        if graph is self.graph:
            self._preview = (graph, preview)
        return preview

    def graph_for(self, mode: str, graph: Graph | None = None) -> Graph:
        if mode not in ("final", "preview"):
            raise ServeError(400, f"mode must be 'final' or 'preview', got {mode!r}", field="mode")
        graph = self.graph if graph is None else graph
        return graph if mode == "final" else self.preview_graph(graph)

    def run(self, outputs: list[str] | None = None, mode: str = "final", cancel: CancelToken | None = None,
            graph: Graph | None = None, scale: float = 1.0):
        """Run ``graph`` (default the current one; its preview for ``mode="preview"``)
        for ``outputs`` within the time limit. Returns the session's ``RunResult``.
        Raises ServeError (the table in errors.py); a run cancelled through ``cancel``
        raises ``Cancelled``, one over the time limit ``RunTimeout``. ``scale``: the
        working resolution in (0, 1] (``Session.run``), e.g. a screen-sized preview."""
        graph = self.graph_for(mode, graph)
        token = cancel or CancelToken()
        with self._active_lock:
            if self._closing:
                raise Cancelled("the server is shutting down")
            self._active.add(token)
        timed_out = self._deadlines.add(token, self.limits.run_timeout)
        try:
            self.runs += 1
            return self.session_for(scale).run(graph, outputs=outputs, cancel=token, scale=scale)
        except Cancelled:
            if timed_out.is_set():
                raise RunTimeout(f"the run was stopped after the server's limit of {self.limits.run_timeout:g} s "
                                 "(pixgraph serve --run-timeout)") from None
            if self._closing:
                raise Cancelled("the server is shutting down") from None
            raise
        except Exception as e:
            se = serve_error(e)
            if se.status == 500:
                raise
            raise se from None
        finally:
            self._deadlines.remove(token)
            with self._active_lock:
                self._active.discard(token)

    def log_lines(self) -> list[str]:
        """``node: message`` of the last final (``final_said``), the served graph's nodes in
        order, at most the last 5 lines of 400 characters a node, paths under the graph's
        folder shown relative to it."""
        return [f"{nid}: {str(m)[:400]}".replace(self.root + os.sep, "") for nid in self.graph.nodes
                for m in self.final_said.get(nid, [])[-5:]]

    def session_for(self, scale: float = 1.0) -> Session:
        """The session that runs at working resolution ``scale``: full size in ``session``;
        below 1 (the page's previews) in a second one on the same device, registry and
        path rules, whose memory cache (``Limits.scaled_cache_bytes``) the large values of a
        full-size final never evict: a drag after a release finds its upstream cached."""
        if scale >= 1.0:
            return self.session
        with self._active_lock:  # runs start on several threads: make one, never two
            if self._scaled is None:
                self._scaled = Session(device=self.session.device, registry=self.registry, allow_paths=self._roots,
                                       strict_paths=True, cache_bytes=self.limits.scaled_cache_bytes)
            return self._scaled

    def running(self) -> int:
        """How many runs are in progress."""
        with self._active_lock:
            return len(self._active)

    def cancel_all(self) -> int:
        """Cancel every run in progress and refuse new ones (the server is stopping);
        returns how many were running."""
        with self._active_lock:
            self._closing = True
            tokens = list(self._active)
        for t in tokens:
            t.cancel()
        return len(tokens)


def check_depth(value: Any, limit: int = MAX_DEPTH) -> None:
    """Refuse values nested deeper than ``limit`` (checked without recursion)."""
    stack = [(value, 1)]
    while stack:
        v, d = stack.pop()
        if isinstance(v, Mapping):
            children = v.values()
        elif isinstance(v, (list, tuple)):
            children = v
        else:
            continue
        if d > limit:
            raise ServeError(400, f"request nested deeper than {limit} levels")
        stack.extend((c, d + 1) for c in children)


def _precheck_yaml(text: str) -> None:
    """Refuse, in linear time and before the (pure-Python, line-recording) graph loader
    sees it, posted YAML that uses anchors or aliases (a few hundred bytes of nested
    aliases expand to gigabytes, the "billion laughs"; graphs never need them), nests
    deeper than ``MAX_DEPTH`` (``[`` x 100000 would take that loader minutes) or holds
    more values than the format allows (``fileio.MAX_YAML_NODES``: that loader took
    30 s to build 20,000 nodes before refusing them).
    Uses libyaml when PyYAML has it; a YAML syntax error is left to the loader."""
    import yaml

    fast = getattr(yaml, "CSafeLoader", None)
    loader = fast(text) if fast is not None else yaml.SafeLoader(text)
    depth = values = 0
    starts = (yaml.ScalarToken, yaml.FlowSequenceStartToken, yaml.FlowMappingStartToken,
              yaml.BlockSequenceStartToken, yaml.BlockMappingStartToken)
    try:
        while loader.check_token():
            token = loader.get_token()
            if isinstance(token, starts):
                values += 1
                if values > fileio.MAX_YAML_NODES:   # the graph format's own limit, found before any loader builds it
                    line = token.start_mark.line + 1
                    raise ServeError(400, f"<posted graph>:{line}: more than {fileio.MAX_YAML_NODES} values", line=line)
            if isinstance(token, (yaml.AliasToken, yaml.AnchorToken)):
                line = token.start_mark.line + 1
                raise ServeError(400, f"<posted graph>:{line}: YAML anchors and aliases are not accepted "
                                      "by the server", line=line)
            if isinstance(token, (yaml.FlowSequenceStartToken, yaml.FlowMappingStartToken,
                                  yaml.BlockSequenceStartToken, yaml.BlockMappingStartToken)):
                depth += 1
            elif isinstance(token, (yaml.FlowSequenceEndToken, yaml.FlowMappingEndToken, yaml.BlockEndToken)):
                depth -= 1
            if depth > MAX_DEPTH:
                line = token.start_mark.line + 1
                raise ServeError(400, f"<posted graph>:{line}: nested deeper than {MAX_DEPTH} levels", line=line)
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        line = mark.line + 1 if mark is not None else None
        raise ServeError(400, f"<posted graph>{f':{line}' if line else ''}: not valid YAML: "
                              f"{getattr(e, 'problem', None) or e}", line=line) from None
    finally:
        loader.dispose()


def _jsonable(v: Any) -> Any:
    if isinstance(v, Mapping):
        return {k: _jsonable(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_jsonable(x) for x in v]
    return v
