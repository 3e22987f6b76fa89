"""Batch runs: one graph over many rows of inputs and params, on one or many machines.

A *row* binds ``node.param`` overrides (input files are ``LoadImage.path``
params) and names its output files by template, e.g. ``out/{row}_{name}.png``.
Rows come from a manifest (CSV or YAML), from sweeps (``light.azimuth=0:360:15``)
or both (every manifest row crossed with every sweep value).

Each item is planned, and its *content key* is the engine's cache key of each
requested output plus the output path: an output whose provenance sidecar
(``PATH.json``) records the same key, and whose file still has the recorded
sha256, is done and skipped, so a killed batch resumes where it stopped and a
changed input, param or graph re-renders only the rows it touches.

Executors: ``inprocess`` (the caller's ``Session``: one device, one shared memory
cache), ``processes`` (a local pool of spawned processes, one ``Session`` and
OpenCL context each) and ``dask`` (``distributed``: a scheduler address or a
``LocalCluster``; a worker plugin opens one ``Session`` per worker process).
A row that fails is reported in the result and does not stop the others.
"""
from __future__ import annotations

import csv
import dataclasses
import glob
import hashlib
import itertools
import json
import math
import os
import socket
import string
import sys
import threading
import time
from typing import Any, Callable, Iterable, Mapping, Sequence

import yaml

from pixgraph import __version__
from pixgraph.graph import Graph, GraphError
from pixgraph.hashing import canonical_json

DEFAULT_TEMPLATE = "out/{row}_{name}.png"
EXECUTORS = ("inprocess", "processes", "dask")
SIDECAR_SUFFIX = ".json"


class BatchError(ValueError):
    """A manifest, sweep or template that cannot make a batch (bad input, exit 2)."""


# -- rows: manifests and sweeps ----------------------------------------------------


@dataclasses.dataclass(frozen=True)
class Row:
    """One manifest or sweep row: ``params`` are ``node.param`` overrides, ``fields``
    the other columns (usable in output templates), ``source`` where it came from."""

    id: str
    params: Mapping[str, Any]
    fields: Mapping[str, Any] = dataclasses.field(default_factory=dict)
    source: str = ""


def read_manifest(path: str | os.PathLike) -> list[Row]:
    """Rows of a CSV or YAML manifest.

    CSV: a header row; columns named ``node.param`` are overrides (cells are YAML
    scalars or lists, an empty cell leaves the graph's value), other columns are
    fields for templates (``id`` names the row). YAML: a list of mappings, or a
    mapping with ``rows:``, each mapping like a CSV row. Relative paths of path
    params are resolved against the manifest's folder when the batch is planned.
    """
    path = os.fspath(path)
    try:
        with open(path, newline="", encoding="utf-8") as f:
            text = f.read()
    except OSError as e:
        raise BatchError(f"{path}: cannot read manifest: {e.strerror}") from None
    if path.lower().endswith((".yaml", ".yml")):
        return _yaml_rows(path, text)
    if path.lower().endswith((".csv", ".tsv")):
        return _csv_rows(path, text)
    raise BatchError(f"{path}: a manifest is .csv, .tsv, .yaml or .yml")


def _csv_rows(path: str, text: str) -> list[Row]:
    dialect = csv.excel_tab if path.lower().endswith(".tsv") else csv.excel
    reader = csv.reader(text.splitlines(), dialect)
    rows = list(reader)
    if not rows:
        raise BatchError(f"{path}: empty manifest (expected a header row)")
    header = [h.strip() for h in rows[0]]
    if len(set(header)) != len(header) or "" in header:
        raise BatchError(f"{path}:1: header has an empty or repeated column name")
    out = []
    for lineno, cells in enumerate(rows[1:], start=2):
        if not any(c.strip() for c in cells):
            continue
        if len(cells) != len(header):
            raise BatchError(f"{path}:{lineno}: {len(cells)} cells, the header has {len(header)}")
        values = {}
        for name, cell in zip(header, cells):
            if cell.strip() == "":
                continue
            if "." in name:
                try:
                    values[name] = yaml.safe_load(cell)
                except yaml.YAMLError as e:
                    raise BatchError(f"{path}:{lineno}: column {name!r}: not a YAML value: "
                                     f"{str(e).splitlines()[0]}") from None
            else:
                values[name] = cell
        out.append(_row(values, len(out), f"{path}:{lineno}"))
    return out


def _yaml_rows(path: str, text: str) -> list[Row]:
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as e:
        raise BatchError(f"{path}: not valid YAML: {str(e).splitlines()[0]}") from None
    if isinstance(data, Mapping) and "rows" in data:
        data = data["rows"]
    if not isinstance(data, list):
        raise BatchError(f"{path}: a YAML manifest is a list of rows (or a mapping with 'rows:')")
    out = []
    for i, item in enumerate(data):
        if not isinstance(item, Mapping):
            raise BatchError(f"{path}: row {i}: expected a mapping of column: value")
        values = {}
        for name, value in item.items():
            if isinstance(value, Mapping) and "." not in str(name):  # {node: {param: value}}
                values.update({f"{name}.{k}": v for k, v in value.items()})
            else:
                values[str(name)] = value
        out.append(_row(values, i, f"{path}: row {i}"))
    return out


def _row(values: Mapping[str, Any], index: int, source: str) -> Row:
    params = {k: v for k, v in values.items() if "." in k}
    fields = {k: v for k, v in values.items() if "." not in k}
    rid = str(fields["id"]) if "id" in fields else None
    return Row(rid if rid is not None else "", params, fields, source)


def parse_sweep(spec: str) -> tuple[str, list[Any]]:
    """``NODE.PARAM=VALUES`` -> (name, values). VALUES is ``start:stop:step``
    (stop excluded, like ``range``: ``0:360:15`` is 0, 15, .., 345), a
    comma-separated list of YAML values, or a file glob (``cutouts/*.png``)."""
    name, eq, raw = spec.partition("=")
    name, raw = name.strip(), raw.strip()
    if not eq or "." not in name or not raw:
        raise BatchError(f"--sweep {spec}: expected NODE.PARAM=START:STOP:STEP, A,B,C or a file glob")
    if any(ch in raw for ch in "*?["):
        files = sorted(glob.glob(raw))
        if not files:
            raise BatchError(f"--sweep {spec}: no file matches {raw!r}")
        return name, [os.path.abspath(f) for f in files]
    if raw.count(":") == 2:
        try:
            start, stop, step = (float(x) for x in raw.split(":"))
        except ValueError:
            raise BatchError(f"--sweep {spec}: START:STOP:STEP must be numbers") from None
        if step == 0 or (stop - start) / step <= 0:
            raise BatchError(f"--sweep {spec}: the range is empty (step 0 or pointing away from stop)")
        n = math.ceil((stop - start) / step - 1e-9)
        values = [start + i * step for i in range(n)]
        if all(float(x).is_integer() for x in (start, step)):
            values = [int(round(v)) for v in values]
        return name, values
    try:
        return name, [yaml.safe_load(x) for x in raw.split(",")]
    except yaml.YAMLError as e:
        raise BatchError(f"--sweep {spec}: not a YAML value: {str(e).splitlines()[0]}") from None


def sweep_rows(sweeps: Sequence[tuple[str, Sequence[Any]]], base: Sequence[Row] | None = None) -> list[Row]:
    """Every base row (one empty row when none) crossed with every combination of sweep values."""
    base = list(base) if base else [Row("", {}, {}, "")]
    if not sweeps:
        return base
    names = [n for n, _ in sweeps]
    out = []
    for row in base:
        for combo in itertools.product(*(v for _, v in sweeps)):
            params = dict(row.params)
            params.update(zip(names, combo))
            label = " ".join(f"{n}={_short(v)}" for n, v in zip(names, combo))
            out.append(Row(row.id, params, dict(row.fields), f"{row.source} {label}".strip()))
    return out


def _short(v) -> str:
    return os.path.basename(v) if isinstance(v, str) and os.path.isabs(v) else str(v)


# -- items: rows bound to a graph and output files ---------------------------------


@dataclasses.dataclass(frozen=True)
class Item:
    """One unit of work: a row's overrides (paths absolute) and its output files."""

    index: int
    row: str
    params: Mapping[str, Any]
    #: output name (graph output or NODE.OUTPUT) -> absolute file path
    outputs: Mapping[str, str]
    source: str = ""


def make_items(graph: Graph, rows: Sequence[Row], registry, outputs: Mapping[str, str] | Sequence[str] | None = None,
               template: str = DEFAULT_TEMPLATE, manifest_dir: str | None = None,
               params: Mapping[str, Any] | None = None) -> list[Item]:
    """Bind rows to ``graph``: check the override columns name real node params,
    resolve relative path params against ``manifest_dir`` and fill in the output
    templates (fields: ``row``, ``index``, ``name``, ``stem`` = the file stem of the
    row's first path param, each override as ``node_param`` and each extra column).

    outputs: ``{name: template}``, a list of names (all with ``template``), or
        ``None`` for every image-valued graph output.
    params: overrides shared by every row (applied first).
    """
    if outputs is None:
        outputs = _image_outputs(graph, registry)
        if not outputs:
            raise BatchError("the graph has no image outputs: name outputs with -o NAME=TEMPLATE")
    if not isinstance(outputs, Mapping):
        outputs = {name: template for name in outputs}
    shared = dict(params or {})
    width = max(4, len(str(len(rows) - 1)))
    items, seen = [], {}
    for i, row in enumerate(rows):
        merged = dict(shared)
        for name, value in row.params.items():
            merged[name] = _resolve_param(graph, registry, name, value, manifest_dir, row.source)
        rid = row.id or f"{i:0{width}d}"
        fields = {k: v for k, v in row.fields.items()}
        fields.update({name.replace(".", "_"): _short(v) for name, v in row.params.items()})
        stem = next((os.path.splitext(os.path.basename(v))[0] for n, v in merged.items()
                     if _is_path_param(graph, registry, n) and isinstance(v, str) and n in row.params), rid)
        fields.update(row=rid, index=i, stem=stem)
        files = {}
        for name, tmpl in outputs.items():
            try:
                path = string.Formatter().vformat(tmpl, (), {**fields, "name": name.replace(".", "_")})
            except (KeyError, IndexError, ValueError) as e:
                raise BatchError(f"output template {tmpl!r}: {type(e).__name__} {e}; fields: "
                                 f"{', '.join(sorted({*fields, 'name'}))}") from None
            path = os.path.abspath(path)
            if path in seen:
                raise BatchError(f"rows {seen[path]} and {rid} both write {path}: put {{row}} or {{stem}} "
                                 f"in the output template")
            seen[path] = rid
            files[name] = path
        items.append(Item(i, rid, merged, files, row.source))
    return items


def _image_outputs(graph: Graph, registry) -> list[str]:
    """The graph outputs that can be written to a file (their port type has ``write``)."""
    names = []
    for name, ref in graph.outputs.items():
        port = registry.get(graph.nodes[ref.node].type).output(ref.output)
        if port is not None and getattr(port.type, "write", None) is not None:
            names.append(name)
    return names


def _is_path_param(graph: Graph, registry, name: str) -> bool:
    node, _, pname = name.partition(".")
    inst = graph.nodes.get(node)
    if inst is None:
        return False
    p = next((p for p in registry.get(inst.type).params if p.name == pname), None)
    return p is not None and p.kind == "path"


def _resolve_param(graph, registry, name, value, manifest_dir, source):
    node, _, pname = name.partition(".")
    if node not in graph.nodes:
        raise BatchError(f"{source}: column {name!r}: no node {node!r} in the graph "
                         f"(nodes: {', '.join(graph.nodes)})")
    spec = registry.get(graph.nodes[node].type)
    if not any(p.name == pname for p in spec.params):
        raise BatchError(f"{source}: column {name!r}: node {node!r} ({spec.type_id}) has no param {pname!r}")
    if _is_path_param(graph, registry, name) and isinstance(value, str) and not os.path.isabs(value):
        return os.path.abspath(os.path.join(manifest_dir or os.getcwd(), value))
    return value


# -- one item: plan, skip or run, write, sidecar -----------------------------------


@dataclasses.dataclass
class ItemResult:
    index: int
    row: str
    #: "done" (rendered now), "skipped" (already done) or "failed"
    status: str
    outputs: dict[str, str]
    seconds: float = 0.0
    error: str = ""
    worker: str = ""


def content_key(node_key: str, output: str, path: str) -> str:
    """Key of one output file: the engine's key of the node that makes it, the
    output port and the absolute path it is written to."""
    return hashlib.sha256(canonical_json({"node_key": node_key, "output": output,
                                          "path": os.path.abspath(path)}).encode()).hexdigest()


def sidecar_path(path: str) -> str:
    return path + SIDECAR_SUFFIX


def _file_sha256(path: str) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def _is_done(path: str, key: str) -> bool:
    try:
        with open(sidecar_path(path), encoding="utf-8") as f:
            meta = json.load(f)
        return meta.get("content_key") == key and meta.get("file_sha256") == _file_sha256(path)
    except (OSError, ValueError):
        return False


def _graph_sha256(graph: Graph) -> str | None:
    if graph.file is None:
        return None
    try:
        return _file_sha256(graph.file)
    except OSError:
        return None


def run_item(session, graph: Graph, item: Item, force: bool = False) -> ItemResult:
    """Plan ``item``; skip it when every output is done, else run it and write its
    files and sidecars. Never raises for a failure of the row: it is returned."""
    t0 = time.perf_counter()
    worker = f"{socket.gethostname()}:{os.getpid()}"
    try:
        g = session.graph(graph, item.params)
        plan = session.plan(g, list(item.outputs))
        keys = {name: content_key(plan.keys[ref.node], ref.output, item.outputs[name])
                for name, ref in plan.outputs.items()}
        if not force and all(_is_done(item.outputs[n], k) for n, k in keys.items()):
            return ItemResult(item.index, item.row, "skipped", dict(item.outputs), time.perf_counter() - t0,
                              worker=worker)
        _check_outputs(session, g, item)
        res = session.run_plan(plan)
        for name, path in item.outputs.items():
            _write_output(session, g, name, res.outputs[name], path)
        seconds = time.perf_counter() - t0
        for name, path in item.outputs.items():
            _write_sidecar(session, g, plan, res, item, name, path, keys[name], seconds)
        return ItemResult(item.index, item.row, "done", dict(item.outputs), seconds, worker=worker)
    except Exception as e:  # one row's failure is reported, the batch goes on
        msg = str(e).replace("\n", " ") if isinstance(e, (GraphError, BatchError)) else \
            f"{type(e).__name__}: {e}".replace("\n", " ")
        return ItemResult(item.index, item.row, "failed", dict(item.outputs), time.perf_counter() - t0,
                          error=msg, worker=worker)


def _check_outputs(session, graph: Graph, item: Item) -> None:
    """Output paths are the user's own (any folder, like ``pixgraph run -o``), but
    never hold control characters and never overwrite a file this row reads."""
    from pixgraph.paths import PathError

    try:
        session.check_output_paths(graph, item.outputs)
    except PathError as e:
        raise BatchError(e.message) from None


def _write_output(session, graph: Graph, name: str, value, path: str) -> None:
    """Write like ``pixgraph run -o``: images as colour, mattes and heights as data."""
    try:
        session.write_output(graph, name, value, path)
    except ValueError as e:
        raise BatchError(str(e)) from None


def user_files(graph: Graph, registry, items: Sequence[Item]) -> list[str]:
    """The files that rows' path overrides name: the user's own (from a manifest,
    a sweep or ``--set``), allowed by the path policy like ``pixgraph run --set``."""
    from pixgraph.paths import bad_characters

    files = set()
    for item in items:
        for name, value in item.params.items():
            if isinstance(value, str) and value and _is_path_param(graph, registry, name) \
                    and not bad_characters(value):
                files.add(graph.resolve_path(value))
    return sorted(files)


def _write_sidecar(session, graph, plan, res, item, name, path, key, seconds) -> None:
    ref = plan.outputs[name]
    steps = {s.node_id: s for s in plan.steps}
    methods = {}
    for nid, s in steps.items():
        p = plan.params.get(nid, {})
        chosen = {k: p[k] for k in ("method", "kind", "mode", "material") if k in p}
        methods[nid] = {"type": s.type_id, **chosen}
    device = None
    if session.device_opened:
        dev = session.device
        device = str(getattr(dev, "name", None) or dev)
    meta = {
        "pixgraph": __version__,
        "graph": os.path.abspath(graph.file) if graph.file else None,
        "graph_sha256": _graph_sha256(graph),
        "row": item.row,
        "source": item.source,
        "params": {k: v for k, v in item.params.items()},
        "output": name,
        "ref": f"{ref.node}.{ref.output}",
        "path": path,
        "node_key": plan.keys[ref.node],
        "content_key": key,
        "file_sha256": _file_sha256(path),
        "methods": methods,
        "ran": list(res.ran),
        "cached": list(res.cached),
        "device": device,
        "seconds": round(seconds, 6),
        "host": socket.gethostname(),
        "pid": os.getpid(),
        "time": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
    }
    side = sidecar_path(path)
    tmp = f"{side}.tmp-{os.getpid()}"
    with open(tmp, "w", encoding="utf-8") as f:
        json.dump(meta, f, indent=1, sort_keys=True, default=str)
    os.replace(tmp, side)


# -- worker processes (pool and Dask) ----------------------------------------------


@dataclasses.dataclass(frozen=True)
class WorkerConfig:
    """How a worker process opens its ``Session``: the same for every worker."""

    device: Any = None
    cache_bytes: int | None = None
    disk_cache: str | None = None
    #: threads one worker may use (torch, OpenMP, PoCL); 1 = one composite per core
    threads: int = 1
    open_device: bool = True
    #: the path policy of the batch's session: allowed folders and files, strict or not
    allow_paths: tuple = ()
    allow_files: tuple = ()
    strict_paths: bool = False


_WORKER: dict[str, Any] = {}
_WORKER_LOCK = threading.Lock()


def limit_threads(threads: int) -> None:
    """Cap the threads of the numeric libraries in this process (before they start
    their pools): torch/OpenMP/BLAS and PoCL's CPU driver, which otherwise each
    use every core, so N workers would run N x cores threads."""
    n = str(max(1, int(threads)))
    for var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS",
                "POCL_CPU_MAX_CU_COUNT", "POCL_MAX_PTHREAD_COUNT"):
        os.environ[var] = n
    if "torch" in sys.modules:
        import torch

        torch.set_num_threads(int(n))


def init_worker(config: WorkerConfig) -> None:
    """Open this process's ``Session`` (and its device) once; later items reuse it."""
    with _WORKER_LOCK:
        if _WORKER.get("config") == config and "session" in _WORKER:
            return
        limit_threads(config.threads)
        from pixgraph.session import Session

        s = Session(device=config.device, cache_bytes=config.cache_bytes, disk_cache=config.disk_cache,
                    allow_paths=config.allow_paths, strict_paths=config.strict_paths)
        if config.allow_files:
            s.allow_files(config.allow_files)
        if config.open_device:
            try:
                s.device  # noqa: B018 - open the OpenCL context now, once per process
            except Exception:
                pass  # graphs without OpenCL nodes still run; the others report the error per row
        _WORKER.update(config=config, session=s, graphs={})


def worker_run(config: WorkerConfig, graph_file: str, item: Item, force: bool = False) -> ItemResult:
    """Run one item in a worker process (pool or Dask), opening the session on first use."""
    init_worker(config)
    with _WORKER_LOCK:  # one Session per process: items run one at a time in it
        s = _WORKER["session"]
        graphs = _WORKER["graphs"]
        try:
            st = os.stat(graph_file)
            sig = (st.st_mtime_ns, st.st_size)
            if graphs.get(graph_file, (None,))[0] != sig:
                graphs[graph_file] = (sig, s.load(graph_file))
            graph = graphs[graph_file][1]
        except Exception as e:
            return ItemResult(item.index, item.row, "failed", dict(item.outputs),
                              error=str(e).replace("\n", " "), worker=f"{socket.gethostname()}:{os.getpid()}")
        return run_item(s, graph, item, force)


try:
    from distributed.diagnostics.plugin import WorkerPlugin as _WorkerPluginBase
except ImportError:  # dask is an extra: the plugin is only made when it is installed
    _WorkerPluginBase = object


class PixgraphWorkerPlugin(_WorkerPluginBase):
    """Dask worker plugin: on each worker, cap its threads and open one ``Session``
    (and OpenCL device) when the worker starts, not per task."""

    name = "pixgraph-session"

    def __init__(self, config: WorkerConfig):
        self.config = config

    def setup(self, worker=None):
        init_worker(self.config)


# -- the batch ---------------------------------------------------------------------


@dataclasses.dataclass
class BatchResult:
    results: list[ItemResult]
    seconds: float
    executor: str
    workers: int

    def count(self, status: str) -> int:
        return sum(r.status == status for r in self.results)

    @property
    def failed(self) -> list[ItemResult]:
        return [r for r in self.results if r.status == "failed"]

    @property
    def throughput(self) -> float:
        """Rendered composites per second of wall time (skipped rows not counted)."""
        return self.count("done") / self.seconds if self.seconds > 0 else 0.0

    def summary(self) -> str:
        return (f"batch: {self.count('done')} done, {self.count('skipped')} skipped (already done), "
                f"{self.count('failed')} failed, in {self.seconds:.2f} s "
                f"({self.throughput:.2f} composites/s, {self.executor}, {self.workers} worker(s))")

    def table(self) -> str:
        """The failed rows as a text table (empty when none failed)."""
        if not self.failed:
            return ""
        rows = [("row", "status", "error")] + [(r.row, r.status, r.error) for r in self.failed]
        w = [max(len(r[i]) for r in rows) for i in range(2)]
        return "\n".join(f"{r[0].ljust(w[0])}  {r[1].ljust(w[1])}  {r[2]}" for r in rows)


def run_batch(session, graph: Graph | str | os.PathLike, items: Sequence[Item], executor: str = "inprocess",
              workers: int = 2, scheduler: str | None = None, force: bool = False, threads: int = 1,
              progress: bool = False, on_result: Callable[[ItemResult], None] | None = None,
              device=None) -> BatchResult:
    """Run ``items`` with one executor; see ``Session.batch``."""
    if executor not in EXECUTORS:
        raise BatchError(f"executor {executor!r}: choose one of {', '.join(EXECUTORS)}")
    if executor != "inprocess" and not isinstance(graph, (str, os.PathLike)):
        if getattr(graph, "file", None) is None:
            raise BatchError(f"the {executor} executor needs a graph file: worker processes load it themselves")
        graph = graph.file
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=len(items), unit="composite", desc="batch", file=sys.stderr, dynamic_ncols=True)
    results: list[ItemResult] = []

    def record(r: ItemResult):
        results.append(r)
        if bar is not None:
            bar.update(1)
            nfail = sum(x.status == "failed" for x in results)
            nskip = sum(x.status == "skipped" for x in results)
            bar.set_postfix_str(f"{nskip} skipped, {nfail} failed")
        if on_result is not None:
            on_result(r)

    t0 = time.perf_counter()
    try:
        if executor == "inprocess":
            g = graph if isinstance(graph, Graph) else session.load(graph)
            for item in items:
                record(run_item(session, g, item, force))
            n = 1
        else:
            if device is None and isinstance(session.device_spec, str):
                device = session.device_spec  # a Device value cannot cross processes: workers open their own
            config = WorkerConfig(device=device, cache_bytes=session.memory.limit_bytes,
                                  disk_cache=session.disk.root if session.disk is not None else None,
                                  threads=threads, allow_paths=tuple(session.paths.roots),
                                  allow_files=tuple(sorted(session.paths.files)),
                                  strict_paths=session.paths.strict)
            gfile = os.path.abspath(os.fspath(graph))
            if executor == "processes":
                n = _run_pool(config, gfile, items, workers, force, record)
            else:
                n = _run_dask(config, gfile, items, workers, scheduler, force, record)
    finally:
        if bar is not None:
            bar.close()
    results.sort(key=lambda r: r.index)
    return BatchResult(results, time.perf_counter() - t0, executor, n)


def _run_pool(config, gfile, items, workers, force, record) -> int:
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor, as_completed

    # spawn, not fork: a forked child would inherit the parent's OpenCL context and
    # torch thread pools, which are not fork-safe
    ctx = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=init_worker,
                             initargs=(config,)) as pool:
        futures = {pool.submit(worker_run, config, gfile, it, force): it for it in items}
        try:
            for fut in as_completed(futures):
                record(_future_result(fut, futures[fut]))
        except BaseException:  # Ctrl-C or an error in a callback: do not run the rest
            pool.shutdown(wait=False, cancel_futures=True)
            raise
    return workers


def _future_result(fut, item: Item) -> ItemResult:
    try:
        return fut.result()
    except Exception as e:  # the worker died (killed, out of memory): the row failed
        return ItemResult(item.index, item.row, "failed", dict(item.outputs),
                          error=f"worker lost: {type(e).__name__}: {e}".replace("\n", " "))


def _run_dask(config, gfile, items, workers, scheduler, force, record) -> int:
    try:
        from distributed import Client, LocalCluster, as_completed
    except ImportError:
        raise BatchError("the dask executor needs dask.distributed: pip install 'pixgraph[batch]'") from None
    cluster, own_client = None, True
    if hasattr(scheduler, "submit"):  # a Client the caller made (e.g. on a dask-jobqueue cluster)
        client, own_client = scheduler, False
    elif scheduler is not None and hasattr(scheduler, "scheduler_address"):  # a cluster object
        client = Client(scheduler)
    elif scheduler:
        client = Client(scheduler)
    else:
        # one thread per worker process: a worker runs one composite at a time on
        # its own device; spawn-started processes (the nanny's default)
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                               dashboard_address=None)
        client = Client(cluster)
    try:
        client.register_plugin(PixgraphWorkerPlugin(config), name=PixgraphWorkerPlugin.name)
        n = len(client.scheduler_info().get("workers", {}))
        futures = client.map(worker_run, [config] * len(items), [gfile] * len(items), list(items),
                             [force] * len(items), pure=False)
        by_key = {f.key: it for f, it in zip(futures, items)}
        for fut in as_completed(futures):
            record(_future_result(fut, by_key[fut.key]))
        return n
    finally:
        if own_client:
            client.close()
        if cluster is not None:
            import logging

            # a worker holding an OpenCL context can take a few seconds to exit; the
            # nanny then kills it and warns: expected at shutdown, not worth a line
            nanny = logging.getLogger("distributed.nanny")
            level = nanny.level
            nanny.setLevel(logging.ERROR)
            try:
                cluster.close()
            finally:
                nanny.setLevel(level)


def batch(session, graph, rows: Iterable[Row | Mapping[str, Any]] | None = None, outputs=None,
          template: str = DEFAULT_TEMPLATE, sweeps: Sequence[tuple[str, Sequence[Any]] | str] = (),
          params: Mapping[str, Any] | None = None, manifest_dir: str | None = None, **run_kw) -> BatchResult:
    """``Session.batch``: rows (``Row`` values, or mappings of ``node.param``/field
    values, or a manifest path) crossed with sweeps, bound to ``graph``, run."""
    g = graph if isinstance(graph, Graph) else session.load(graph)
    if isinstance(rows, (str, os.PathLike)):
        manifest_dir = manifest_dir or os.path.dirname(os.path.abspath(rows))
        rows = read_manifest(rows)
    rows = [r if isinstance(r, Row) else _row(dict(r), i, f"row {i}") for i, r in enumerate(rows or [])]
    sweeps = [parse_sweep(s) if isinstance(s, str) else (s[0], list(s[1])) for s in sweeps]
    rows = sweep_rows(sweeps, rows)
    items = make_items(g, rows, session.registry, outputs, template, manifest_dir, params)
    files = user_files(g, session.registry, items)
    if files:
        session.allow_files(files)
    return run_batch(session, g, items, **run_kw)


# -- command line ------------------------------------------------------------------


def add_arguments(p) -> None:
    """The ``pixgraph batch`` options (the graph, --set and cache options come from the CLI)."""
    p.add_argument("manifest", nargs="?", help="rows: a CSV or YAML manifest (columns NODE.PARAM, id, ...)")
    p.add_argument("--sweep", action="append", default=[], metavar="NODE.PARAM=VALUES",
                   help="sweep a param: START:STOP:STEP (stop excluded), A,B,C or a file glob; "
                        "several sweeps (and a manifest) are crossed")
    p.add_argument("-o", "--output", action="append", default=[], metavar="NAME=TEMPLATE",
                   help="write output NAME (or NODE.OUTPUT) to TEMPLATE, e.g. 'out/{row}_{name}.png'; "
                        "fields: row, index, name, stem, node_param, manifest columns")
    p.add_argument("--template", default=DEFAULT_TEMPLATE,
                   help=f"template of every image output when no -o is given (default {DEFAULT_TEMPLATE})")
    ex = p.add_mutually_exclusive_group()
    ex.add_argument("--processes", type=int, metavar="N", help="run on N local worker processes (spawned)")
    ex.add_argument("--dask-local", type=int, metavar="N", help="run on a Dask LocalCluster of N worker processes")
    ex.add_argument("--scheduler", metavar="ADDRESS", help="run on a Dask cluster (e.g. tcp://host:8786)")
    p.add_argument("--threads", type=int, default=1, help="threads per worker process (default 1)")
    p.add_argument("--force", action="store_true", help="re-render rows whose outputs are already done")
    p.add_argument("--report", metavar="JSON", help="also write every row's result to this JSON file")
    p.add_argument("--device", default=None, help="OpenCL device spec (see 'pixgraph devices')")
    p.add_argument("--cache-bytes", type=int, default=None, help="memory cache limit in bytes (per process)")


def cli_batch(args, session, shared_params: Mapping[str, Any], usage_error) -> int:
    """``pixgraph batch``: exit 0 when every row is done or skipped, 1 when a row failed."""
    try:
        if not args.manifest and not args.sweep:
            raise BatchError("batch: give a MANIFEST, one or more --sweep, or both")
        outputs = None
        if args.output:
            outputs = {}
            for item in args.output:
                name, eq, tmpl = item.partition("=")
                if not eq or not name or not tmpl:
                    raise BatchError(f"-o {item}: expected NAME=TEMPLATE")
                outputs[name] = tmpl
        executor, workers = "inprocess", 1
        if args.processes is not None:
            executor, workers = "processes", args.processes
        elif args.dask_local is not None:
            executor, workers = "dask", args.dask_local
        elif args.scheduler:
            executor = "dask"
        if workers < 1:
            raise BatchError("the number of workers must be >= 1")
        show = not args.quiet and sys.stderr.isatty()
        result = batch(session, args.graph, args.manifest, outputs, args.template, args.sweep, shared_params,
                               executor=executor, workers=workers, scheduler=args.scheduler, force=args.force,
                               progress=show, threads=args.threads, device=args.device)
    except BatchError as e:
        raise usage_error(str(e)) from None
    if args.report:
        with open(args.report, "w", encoding="utf-8") as f:
            json.dump({"summary": {"done": result.count("done"), "skipped": result.count("skipped"),
                                   "failed": result.count("failed"), "seconds": result.seconds,
                                   "executor": result.executor, "workers": result.workers},
                       "rows": [dataclasses.asdict(r) for r in result.results]}, f, indent=1)
    if not args.quiet:
        table = result.table()
        if table:
            print(table)
        print(result.summary())
    return 0 if not result.failed else 1
