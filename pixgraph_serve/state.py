"""What ``pixgraph serve`` holds: one ``Session``, the edited graph, and the limits.

No HTTP here: ``app.py`` turns requests into calls on a ``ServeState`` and its
``ServeError`` into JSON error responses. Every method that runs the engine must
be called by one thread at a time (``app.py`` holds a lock around them); edits
build a new immutable ``Graph`` and swap it in, so a run in progress keeps the
graph it started with.

The session keeps its memory cache across requests: a light drag changes one
param of the light node, so only the nodes downstream of it run again.
"""
from __future__ import annotations

import dataclasses
import os
import tempfile
from typing import Any, Mapping

import numpy as np

from pixgraph import fileio
from pixgraph.engine import NodeError, NodeInputError, RunResult
from pixgraph.events import CancelToken
from pixgraph.graph import Graph, GraphError, NodeInstance, validate
from pixgraph.paths import PathError
from pixgraph.session import Session

#: previews swap these node types for a cheaper one with the same ports
PREVIEW_TYPES = {"pixgraph.SoftShadow": "pixgraph.HardShadow",
                 "pixgraph.SoftShadowSSN": "pixgraph.HardShadow"}
#: image file extensions whose header is checked against the pixel limit
IMAGE_EXTENSIONS = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".exr", ".hdr")


class ServeError(Exception):
    """A request that cannot be served: HTTP ``status`` and a one-line message,
    with the node, field, file and line when known."""

    def __init__(self, status: int, message: str, **where: Any):
        super().__init__(message)
        self.status = status
        self.message = message
        self.where = {k: v for k, v in where.items() if v is not None}

    def to_json(self) -> dict:
        return {"error": self.message, **self.where}

    @classmethod
    def from_graph_error(cls, e: GraphError) -> "ServeError":
        """400, or 403 for a path the policy refuses (``PathError`` is a ``GraphError``)."""
        status = 403 if isinstance(e, PathError) else 400
        return cls(status, str(e), node=e.node, field=e.field, file=e.file, line=e.line)


@dataclasses.dataclass(frozen=True)
class Limits:
    """Request and image limits of the server."""

    #: largest request body (a posted graph, params, an uploaded image) [bytes]
    max_body_bytes: int = 32 << 20
    #: largest image a graph may load or make, width x height [pixels]
    max_pixels: int = 4096 * 4096
    #: previews are sent downscaled by this integer factor
    preview_scale: int = 2


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
        self.upload_dir = upload_dir or tempfile.mkdtemp(prefix="pixgraph-uploads-")
        roots = [self.root, self.upload_dir, *(os.path.abspath(a) for a in allow)]
        self.session = Session(device=device, registry=registry, allow_paths=roots, strict_paths=True)
        self.registry = self.session.registry
        self._stash: dict[tuple[str, str], dict] = {}   # (node, type) -> its params before a type swap
        self._preview: tuple[Graph, Graph] | None = None
        self._pixels: dict[tuple[str, int], int] = {}
        try:
            graph = self.session.load(self.graph_path)
        except GraphError as e:
            raise ServeError.from_graph_error(e) from None
        self.graph = self._checked(graph)

    # -- graph ------------------------------------------------------------------

    def _checked(self, graph: Graph) -> Graph:
        """``graph`` after the session's path policy and the image limits; raises ServeError."""
        try:
            self.session.check_paths(graph)
        except GraphError as e:
            raise ServeError.from_graph_error(e) from None
        for nid, inst in graph.nodes.items():
            spec = self.registry.get(inst.type)
            for p in spec.params:
                if p.kind == "path" and not p.writes and p.name in inst.params:
                    path = graph.resolve_path(inst.params[p.name])
                    if path.lower().endswith(IMAGE_EXTENSIONS):
                        self._check_pixels(self._image_pixels(path), nid, p.name)
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
                    raise ServeError.from_graph_error(e) from None

    def _check_pixels(self, n: int, nid: str, pname: str) -> None:
        if n > self.limits.max_pixels:
            raise ServeError(413, f"node {nid!r}: param {pname!r}: image of {n} pixels is over the "
                                  f"server's limit of {self.limits.max_pixels}", node=nid, field=f"params.{pname}")

    def _image_pixels(self, path: str) -> int:
        """Pixel count from the file's header (not decoded), cached by path and mtime."""
        try:
            key = (path, os.stat(path).st_mtime_ns)
        except OSError:
            return 0  # the graph's own validation reports a missing file
        if key not in self._pixels:
            import OpenImageIO as oiio

            inp = oiio.ImageInput.open(path)
            if inp is None:
                raise ServeError(400, f"cannot read image {os.path.basename(path)}: {oiio.geterror()}")
            spec = inp.spec()
            inp.close()
            self._pixels[key] = int(spec.width) * int(spec.height)
        return self._pixels[key]

    def info(self) -> dict:
        """The graph as the UI and API clients see it: nodes in file order with the
        params set and their effective values, inputs, outputs, and node types."""
        g = self.graph
        nodes = []
        for nid, inst in g.nodes.items():
            spec = self.registry.get(inst.type)
            values = spec.coerce_params(inst.params)
            nodes.append({"id": nid, "type": inst.type,
                          "params": _jsonable(dict(inst.params)), "values": _jsonable(values),
                          "inputs": {k: str(v) for k, v in inst.inputs.items()}})
        used = {inst.type for inst in g.nodes.values()}
        used |= {t for t in self.method_types() if t in self.registry}
        from pixgraph.reference import as_dict

        return {"file": self.graph_path, "nodes": nodes,
                "outputs": {k: str(v) for k, v in g.outputs.items()},
                "types": {t: as_dict(self.registry.get(t)) for t in sorted(used)},
                "limits": dataclasses.asdict(self.limits)}

    @staticmethod
    def method_types() -> tuple[str, ...]:
        """Node types a shadow node may be switched between (hard, classical soft, SSN++)."""
        return ("pixgraph.HardShadow", "pixgraph.SoftShadow", "pixgraph.SoftShadowSSN")

    def set_params(self, params: Mapping[str, Any]) -> Graph:
        """Apply ``{"node.param": value}`` (or ``{"node": {"param": value}}``) edits."""
        if not isinstance(params, Mapping):
            raise ServeError(400, "params must be an object of 'node.param': value")
        edits = []
        for name, value in params.items():
            if isinstance(value, Mapping) and "." not in str(name):
                edits += [(str(name), k, v) for k, v in value.items()]
            else:
                nid, _, pname = str(name).partition(".")
                edits.append((nid, pname, value))
        self._paths_first(self.graph.base_dir, [(nid, self.graph.nodes[nid].type, {pname: v})
                                                for nid, pname, v in edits if nid in self.graph.nodes])
        try:
            graph = self.session.graph(self.graph, dict(params))
        except GraphError as e:
            raise ServeError.from_graph_error(e) from None
        except (TypeError, ValueError, OverflowError) as e:  # e.g. a number too large for a float
            raise ServeError(400, f"bad params: {e}".splitlines()[0], field="params") from None
        self.graph = self._checked(graph)
        return self.graph

    def set_type(self, node_id: str, type_id: str) -> Graph:
        """Switch a node to another type with the same inputs (e.g. the shadow method),
        keeping the params the new type declares and those it had last time."""
        inst = self.graph.nodes.get(node_id)
        if inst is None:
            raise ServeError(404, f"no node {node_id!r} in the graph", node=node_id)
        if type_id not in self.registry:
            raise ServeError(400, f"unknown node type {type_id!r}", node=node_id, field="type")
        if type_id == inst.type:
            return self.graph
        self._stash[(node_id, inst.type)] = dict(inst.params)
        spec = self.registry.get(type_id)
        params = {k: v for k, v in inst.params.items() if spec.param(k) is not None}
        params.update(self._stash.get((node_id, type_id), {}))
        nodes = dict(self.graph.nodes)
        nodes[node_id] = NodeInstance(node_id, type_id, params, inst.inputs)
        try:
            graph = validate(dataclasses.replace(self.graph, nodes=nodes), self.registry)
        except GraphError as e:
            raise ServeError.from_graph_error(e) from None
        self.graph = self._checked(graph)
        return self.graph

    def load_text(self, text: str) -> Graph:
        """Replace the served graph by posted YAML; its paths resolve in the graph's folder."""
        _refuse_aliases(text)
        try:
            import yaml

            doc = yaml.safe_load(text)
        except yaml.YAMLError:
            doc = None  # the loader below reports it with its line
        if isinstance(doc, dict) and isinstance(doc.get("nodes"), dict):
            self._paths_first(self.root, [(nid, n.get("type"), n.get("params")) for nid, n in doc["nodes"].items()
                                          if isinstance(n, dict) and isinstance(n.get("params"), dict)])
        try:
            graph = fileio.loads(text, self.registry, file="<posted graph>", base_dir=self.root)
        except GraphError as e:
            raise ServeError.from_graph_error(e) from None
        self.graph = self._checked(graph)
        return self.graph

    def yaml(self) -> str:
        return fileio.dumps(self.graph)

    def save(self, path: str | None = None) -> str:
        """Write the edited graph as canonical YAML (default: over the served file)."""
        target = self.graph_path if not path else os.path.normpath(os.path.join(self.root, path))
        if not target.endswith((".yaml", ".yml")):
            raise ServeError(400, f"save: {path!r} must end in .yaml or .yml", field="path")
        try:
            self.session.policy_for(self.graph).check_write(target)
        except PathError as e:
            raise ServeError(403, str(e), field="path") from None
        try:
            fileio.dump(self.graph, target, self.registry)
        except OSError as e:
            raise ServeError(400, f"save: cannot write {path or target}: {e.strerror or e}", field="path") from None
        return target

    # -- run ----------------------------------------------------------------------

    def preview_graph(self) -> Graph:
        """The current graph with soft shadows swapped for hard ones (cached per graph)."""
        if self._preview is None or self._preview[0] is not self.graph:
            nodes = dict(self.graph.nodes)
            for nid, inst in nodes.items():
                cheap = PREVIEW_TYPES.get(inst.type)
                if cheap is not None and cheap in self.registry:
                    spec = self.registry.get(cheap)
                    keep = {k: v for k, v in inst.params.items() if spec.param(k) is not None}
                    nodes[nid] = NodeInstance(nid, cheap, keep, inst.inputs)
            self._preview = (self.graph, validate(dataclasses.replace(self.graph, nodes=nodes), self.registry))
        return self._preview[1]

    def run(self, outputs: list[str] | None = None, mode: str = "final",
            cancel: CancelToken | None = None) -> tuple[dict, RunResult]:
        """Run the current graph (or its preview) for ``outputs``; ``Cancelled``
        propagates. Returns ``(values, run result)``."""
        if mode not in ("final", "preview"):
            raise ServeError(400, f"mode must be 'final' or 'preview', got {mode!r}", field="mode")
        graph = self.graph if mode == "final" else self.preview_graph()
        try:
            res = self.session.run(graph, outputs=outputs, cancel=cancel)
        except GraphError as e:
            raise ServeError.from_graph_error(e) from None
        except PathError as e:
            raise ServeError(403, str(e)) from None
        except NodeInputError as e:
            raise ServeError(400, str(e), node=e.node_id) from None
        except NodeError as e:
            raise ServeError(422, str(e), node=e.node_id) from None
        return res.outputs, res


def _refuse_aliases(text: str) -> None:
    """Posted YAML may not use anchors or aliases: a few hundred bytes of nested
    aliases expand to gigabytes (the "billion laughs"), and graphs never need them."""
    import yaml

    try:
        for token in yaml.scan(text):
            if isinstance(token, (yaml.AliasToken, yaml.AnchorToken)):
                line = token.start_mark.line + 1
                raise ServeError(400, f"<posted graph>:{line}: YAML anchors and aliases are not accepted "
                                      "by the server", line=line)
    except yaml.YAMLError:
        pass  # the loader reports the syntax error with its line


def _jsonable(v: Any) -> Any:
    if isinstance(v, Mapping):
        return {k: _jsonable(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_jsonable(x) for x in v]
    return v


# -- encoding ---------------------------------------------------------------------

def _image(value: Any, name: str) -> np.ndarray:
    if not isinstance(value, np.ndarray) or value.ndim not in (2, 3) or value.dtype.kind != "f":
        raise ServeError(400, f"output {name!r} is a {type(value).__name__}, not an image", field="output")
    return value


def downscale(img: np.ndarray, s: int) -> np.ndarray:
    """Box-filter downscale by an integer factor, in linear light (edges cropped)."""
    if s <= 1:
        return img
    h, w = (img.shape[0] // s) * s, (img.shape[1] // s) * s
    x = img[:h, :w].reshape(h // s, s, w // s, s, *img.shape[2:])
    return x.mean(axis=(1, 3), dtype=np.float32)


def encode_png(value: Any, name: str = "image", scale: int = 1, compress: int = 1) -> bytes:
    """An 8-bit sRGB PNG of a linear (premultiplied) image or mask."""
    import io

    from PIL import Image

    from pixgraph_nodes.ops.imageio import linear_to_srgb

    img = downscale(_image(value, name), scale)
    if img.ndim == 3 and img.shape[2] == 1:
        img = img[:, :, 0]
    if img.ndim == 3 and img.shape[2] in (2, 4):
        a = np.clip(img[:, :, -1:], 0.0, 1.0)
        colour = np.where(a > 0, img[:, :, :-1] / np.where(a > 0, a, 1.0), 0.0)
        img = np.concatenate([linear_to_srgb(np.clip(colour, 0.0, 1.0)), a], axis=2)
    else:
        img = linear_to_srgb(np.clip(img, 0.0, 1.0))
    u8 = (img * 255.0 + 0.5).astype(np.uint8)
    if u8.ndim == 3 and u8.shape[2] == 2:
        mode = "LA"
    else:
        mode = {2: "L"}.get(u8.ndim) or {3: "RGB", 4: "RGBA"}[u8.shape[2]]
    buf = io.BytesIO()
    Image.fromarray(u8, mode).save(buf, format="PNG", compress_level=compress)
    return buf.getvalue()


def encode_exr(value: Any, name: str = "image") -> bytes:
    """A float EXR (linear, premultiplied) of an image or mask."""
    from pixgraph_nodes.ops.imageio import write_image

    img = _image(value, name)
    with tempfile.TemporaryDirectory(prefix="pixgraph-exr-") as d:
        path = write_image(os.path.join(d, "out.exr"), img)
        with open(path, "rb") as f:
            return f.read()
