"""Planning and lazy pull evaluation.

``Engine.plan(graph, outputs)`` computes every needed node's cache key from the
graph alone and says, per node, whether it will run or be served from memory,
disk or a bound host array, and which key part changed since the last run of that
node id. Only ancestors of the requested outputs are considered, and the inputs
of a node served from cache are not needed at all.

``Engine.run(plan)`` pulls the requested outputs: a node computes once its inputs
are available; its result goes to the memory cache (and the disk cache when one
is configured and the value has a disk form). Sinks (``side_effects = True``)
always run when requested and are never cached.
"""
from __future__ import annotations

import logging
import os
import threading
import time
from typing import Any, Callable, Mapping

import numpy as np

from . import codehash, events as E
from .device import DeviceError
from .cache import MISS, DiskCache, MemoryCache, Unstorable, misfit
from .errors import NodeError, NodeInputError, out_of_memory  # noqa: F401 (re-exported)
from .graph import Graph, GraphError, Ref, upstream
from .hashing import FileHasher, KeyParts, array_key, explain_change, sha256_text
from .node import InputError, Namespace, NodeSpec
from .options import env_int
from .paths import PathError, PathPolicy
from .plan import NodeContext, Plan, RunResult, Step, files_upstream  # noqa: F401 (re-exported)
from .registry import Registry
from .resolve import PlanMemo, check_overwrites, check_scale, checked_path, resolve_params, scale_params
from .scheduler import DeviceGate, execute
from .types import nbytes
from .unusable import refuse_unusable_inputs


DEFAULT_MAX_FILE_BYTES = 4 << 30
_log = logging.getLogger("pixgraph.engine")


def _env_int(name: str, default: int) -> int:
    try:
        return env_int(name, default)
    except ValueError as e:
        raise GraphError(str(e)) from None


class Engine:
    """Plans and runs graphs against one registry, cache set and device.

    It remembers the key parts of the last run of every node id, so a plan can say
    which part changed ("params.sigma changed", "input image changed").
    """

    def __init__(self, registry: Registry, memory: MemoryCache, disk: DiskCache | None = None,
                 device: Callable[[], Any] | None = None, hasher: FileHasher | None = None,
                 paths: PathPolicy | None = None):
        self.registry = registry
        #: where path params may point; the graph's own folder is added per graph
        self.paths = paths if paths is not None else PathPolicy()
        #: largest file a path param may read (hashing reads it all)
        self.max_file_bytes = _env_int("PIXGRAPH_MAX_FILE_BYTES", DEFAULT_MAX_FILE_BYTES)
        self.memory = memory
        self.disk = disk
        self._device = device or _no_device
        self._hash_file = hasher or FileHasher()
        #: graph file (None for built graphs) -> node id -> key parts of its last run
        self._last_parts: dict[str | None, dict[str, KeyParts]] = {}
        #: node types whose outputs had no disk form last time they ran
        self.memory_only: dict[str, str] = {}
        #: cache key -> what the node logged when it computed that key (this process)
        self._logs_by_key: dict[str, list[str]] = {}
        self._planned = PlanMemo()  # nodes that read no file, as planned before
        #: nodes computed at once on independent branches (``scheduler``); 1 = in order
        self.workers = _env_int("PIXGRAPH_WORKERS", 1)

    # -- plan -------------------------------------------------------------------

    def plan(self, graph: Graph, outputs=None, bind: Mapping[str, Any] | None = None,
             scale: float = 1.0) -> Plan:
        """The plan of a run. ``scale`` in (0, 1] is the working resolution: every
        param declared with ``unit="px"`` (a length in the picture; not a size cap
        such as ``unit="px, longer side"``) is multiplied by it (ints rounded, kept in
        the param's range) and nodes that declare ``uses_scale = True`` get it as
        ``ctx.scale`` and in their cache key. The engine knows no more of images than
        that; at 1 (the default) plans and keys are those of an unscaled run."""
        bind = dict(bind or {})
        scale = check_scale(scale)
        requested = self._requested(graph, outputs)
        for nid in bind:
            if nid not in graph.nodes:
                raise GraphError("cannot bind: no such node in the graph", node=nid)
        order = self._ancestors(graph, [r.node for r in requested.values()], bind)
        policy = self.policy_for(graph)
        keys, parts, params, bound = {}, {}, {}, {}
        for nid in order:
            inst = graph.nodes[nid]
            spec = self.registry.get(inst.type)
            if nid in bind:
                params[nid] = {}
                if "bind" in spec.hooks:
                    # a host input: its params (colour space, alpha...) say how to read the array
                    p, relevant = resolve_params(graph, nid, spec, inst.params, None, self._hash_file, self.max_file_bytes, read_paths=False)
                    params[nid] = p
                    bound[nid] = self._bind(graph, nid, spec, bind[nid], p)
                    parts[nid] = KeyParts(spec.type_id, spec.version, codehash.impl_version(spec), relevant,
                                          {"bind": array_key(bind[nid])})
                    keys[nid] = parts[nid].key()
                else:
                    keys[nid] = array_key(bind[nid])
                    parts[nid] = KeyParts("bind", 0, "", {"array": keys[nid]}, {})
                    bound[nid] = {spec.outputs[0].name: bind[nid]}
                continue
            inputs = {port: f"{keys[ref.node]}:{ref.output}" for port, ref in inst.inputs.items()}
            memo = self._planned.key(spec, inst, inputs, scale)
            if (hit := self._planned.get(memo)) is not None:  # as planned before: no checks again
                params[nid], parts[nid], keys[nid] = hit
                continue
            p, relevant = resolve_params(graph, nid, spec, inst.params, policy, self._hash_file, self.max_file_bytes)
            if scale != 1.0:
                scale_params(spec, p, relevant, scale)
            params[nid] = p
            if "affects" in spec.hooks:  # params and inputs ignored in this mode stay out of the key
                relevant, inputs = _affecting(nid, spec, p, relevant, inputs)
            parts[nid] = KeyParts(spec.type_id, spec.version, codehash.impl_version(spec), relevant, inputs)
            keys[nid] = parts[nid].key()
            self._planned.put(memo, p, parts[nid], keys[nid])
        check_overwrites(self.registry, graph, params, order, bind)
        refuse_unusable_inputs(graph, self.registry, order, params, bind)
        steps = self._steps(graph, requested, order, keys, parts, bind, params)
        return Plan(graph, requested, steps, keys, parts, params, bind, bound, scale)

    # -- check before running -----------------------------------------------------

    def check(self, graph: Graph, outputs=None, notes: list[str] | None = None) -> dict[str, dict[str, Any]]:
        """Check what the needed nodes will get, from file headers only, before anything
        runs: returns ``{node: {output: info}}`` (a ``types.Shape`` where known).

        Each node's ``infer`` hook (``node.Node.infer``) turns its inputs' infos into
        its outputs' (a loader reads its file's header) and raises ``InputError`` for
        inputs that cannot work; the first problem is a ``GraphError`` naming the
        node, its line and the files. What an infer hook logs (``ctx.log``: plausible
        but probably wrong) is appended to ``notes``, named like an error, when given.
        """
        requested = self._requested(graph, outputs)
        order = self._ancestors(graph, [r.node for r in requested.values()], {})
        policy = self.policy_for(graph)
        infos: dict[str, dict[str, Any]] = {}
        checked: dict[str, dict[str, Any]] = {}
        for nid in order:
            inst = graph.nodes[nid]
            spec = self.registry.get(inst.type)
            params = spec.coerce_params(inst.params)
            for p in spec.params:
                if p.kind == "path" and params[p.name] is not None:  # the policy before any header is read
                    params[p.name] = checked_path(graph, policy, nid, p, params[p.name])
            checked[nid] = params
            refuse_unusable_inputs(graph, self.registry, [nid], checked, {})
            ins = {p.name: None for p in spec.inputs}
            for port, ref in inst.inputs.items():
                ins[port] = infos[ref.node].get(ref.output)
            try:
                note = _ignore if notes is None else (
                    lambda ev, nid=nid: notes.append(str(graph.error(ev.message, node=nid)))
                    if isinstance(ev, E.NodeLog) else None)
                ctx = NodeContext(nid, graph.base_dir, _no_device, None, note)
                infos[nid] = dict(spec.cls().infer(ctx, Namespace(ins), Namespace(params)) or {})
            except InputError as e:
                raise graph.error(str(e).splitlines()[0], node=nid) from None
        return infos

    def _requested(self, graph: Graph, outputs) -> dict[str, Ref]:
        if outputs is None:
            if not graph.outputs:
                raise GraphError("the graph has no outputs: name one under 'outputs:' or request 'node.output'",
                                 file=graph.file)
            return dict(graph.outputs)
        if isinstance(outputs, str):
            outputs = [outputs]
        out = {}
        for name in outputs:
            if name in graph.outputs:
                out[name] = graph.outputs[name]
                continue
            try:
                ref = Ref.parse(name)
            except ValueError:
                raise GraphError(f"no output named {name!r} (outputs: {', '.join(graph.outputs) or 'none'})",
                                 file=graph.file) from None
            inst = graph.nodes.get(ref.node)
            if inst is None or self.registry.get(inst.type).output(ref.output) is None:
                raise GraphError(f"no such node output {name!r}", file=graph.file, node=ref.node)
            out[name] = ref
        return out

    @staticmethod
    def _ancestors(graph: Graph, roots: list[str], bind: Mapping[str, Any]) -> list[str]:
        """Ancestors of ``roots`` (inclusive) in dependency order; a bound node's
        inputs are not followed (``graph.upstream``, on networkx)."""
        return upstream(graph, list(dict.fromkeys(roots)), stop=bind)

    @staticmethod
    def _bind(graph: Graph, nid: str, spec: NodeSpec, value, params) -> dict[str, Any]:
        """A host input's outputs from the array bound to it (its ``bind`` hook),
        checked like computed outputs; a bad array is a ``GraphError`` naming the node."""
        try:
            out = spec.cls().bind(value, Namespace(params))
        except (InputError, TypeError, ValueError) as e:
            raise graph.error(f"bound value does not fit {spec.type_id}: {str(e).splitlines()[0]}",
                              node=nid) from None
        for p in spec.outputs:
            try:
                p.type.validate(out[p.name])
            except (KeyError, TypeError) as e:
                raise NodeError(nid, spec.type_id, f"bind gave no valid output {p.name!r}: {e}") from None
            _freeze(out[p.name])
        return out


    # -- paths ------------------------------------------------------------------

    def policy_for(self, graph: Graph) -> PathPolicy:
        """The path policy for one graph: the engine's roots plus the graph's folder."""
        return self.paths.with_roots([graph.base_dir])

    def check_paths(self, graph: Graph) -> None:
        """Check every path param of every node against the policy (``validate``)."""
        policy = self.policy_for(graph)
        params = {}
        for nid, inst in graph.nodes.items():
            spec = self.registry.get(inst.type)
            values = spec.coerce_params(inst.params)
            for p in spec.params:
                if p.kind == "path" and values.get(p.name) is not None:
                    values[p.name] = checked_path(graph, policy, nid, p, values[p.name])
            params[nid] = values
        check_overwrites(self.registry, graph, params, list(graph.nodes), {})

    def _steps(self, graph, requested, order, keys, parts, bind, params) -> tuple[Step, ...]:
        last = self._last_run_parts(graph.file)
        needed, status = set(), {}
        stack = [r.node for r in requested.values()]
        while stack:
            nid = stack.pop()
            if nid in needed:
                continue
            needed.add(nid)
            inst = graph.nodes[nid]
            side_effects = self.registry.get(inst.type).side_effects
            if nid in bind:
                status[nid] = "bound"
                continue
            if not side_effects and keys[nid] in self.memory:
                status[nid] = "memory"
                continue
            if not side_effects and self.disk is not None and keys[nid] in self.disk:
                status[nid] = "disk"
                continue
            status[nid] = "run"
            stack.extend(ref.node for ref in inst.inputs.values())
        steps = []
        for nid in order:
            if nid not in needed:
                continue
            type_id = graph.nodes[nid].type
            why = explain_change(last.get(nid), parts[nid])
            if status[nid] == "run":
                if self.registry.get(type_id).side_effects:
                    why.append("sink: always runs")
                elif not why:
                    why = ["not in cache"]
                if type_id in self.memory_only:
                    why.append(f"memory only: {self.memory_only[type_id]}")
                if self.disk is not None and keys[nid] in self.disk.discarded:
                    why.append(f"disk entry discarded: {self.disk.discarded[keys[nid]]}")
            elif not why:
                why = ["unchanged"]
            elif status[nid] in ("memory", "disk"):
                # changed since the last run, but an earlier run left this key cached
                why.append(f"an earlier result is in the {status[nid]} cache")
            # a node may say what it will do with these params (``describe(params)``),
            # and what it logged when it made the result now in the cache
            spec = self.registry.get(type_id)
            if "describe" in spec.hooks and nid not in bind:
                said = spec.cls().describe(Namespace(params[nid]))
                if said:
                    why.append(str(said))
            if status[nid] != "run" and keys[nid] in self._logs_by_key:
                why.append("its run logged: " + " | ".join(self._logs_by_key[keys[nid]]))
            steps.append(Step(nid, type_id, keys[nid], status[nid], "; ".join(why)))
        return tuple(steps)

    # -- run --------------------------------------------------------------------

    def run(self, plan: Plan, cancel: E.CancelToken | None = None,
            on_event: Callable[[Any], None] | None = None) -> RunResult:
        """Pull the plan's outputs: serve what the caches hold, then compute the
        rest in dependency order (``scheduler.execute``; ``self.workers`` > 1 runs
        independent branches concurrently)."""
        forward = on_event or _ignore
        logs: dict[str, list[str]] = {}
        lock = threading.RLock()

        def emit(ev):
            with lock:  # nodes of concurrent branches report from their threads
                if isinstance(ev, E.NodeLog):
                    logs.setdefault(ev.node_id, []).append(ev.message)
                forward(ev)
        graph = plan.graph
        results: dict[str, dict[str, Any]] = {}
        timings: dict[str, float] = {}
        ran, cached = [], []
        reasons = {s.node_id: s.reason for s in plan.steps}
        t_run = time.perf_counter()
        emit(E.RunStarted(sum(s.status == "run" for s in plan.steps),
                          sum(s.status != "run" for s in plan.steps)))
        # 1. resolve: what the caches hold, and which nodes must compute (inputs first)
        to_compute: list[str] = []
        first_of: dict[str, str] = {}  # key -> the node that computes it
        twins: dict[str, list[str]] = {}  # that node -> nodes of the same key
        resolved: set[str] = set()
        missed: set[str] = set()
        expected = _Expected(self, plan)
        # a stack: reversed, so outputs (and inputs, below) are pulled in the order given
        stack = list(reversed(dict.fromkeys(r.node for r in plan.outputs.values())))
        while stack:
            nid = stack[-1]
            if nid in resolved:
                stack.pop()
                continue
            if cancel is not None:
                cancel.raise_if_cancelled()
            inst = graph.nodes[nid]
            spec = self.registry.get(inst.type)
            key = plan.keys[nid]
            if nid in plan.bind:
                results[nid] = dict(plan.bound[nid])
                cached.append(nid)
                resolved.add(nid)
                emit(E.NodeCached(nid, "bound"))
                stack.pop()
                continue
            if not spec.side_effects and key in first_of and nid not in missed:
                twins.setdefault(first_of[key], []).append(nid)  # same key: served by that node's result
                resolved.add(nid)
                stack.pop()
                continue
            if not spec.side_effects and nid not in missed:
                value, where = self._fetch(key, spec, lambda: expected.of(nid))
                if value is not MISS:
                    results[nid] = value
                    cached.append(nid)
                    resolved.add(nid)
                    emit(E.NodeCached(nid, where))
                    stack.pop()
                    continue
                missed.add(nid)  # evicted (or discarded) since the plan: run it after its inputs
                why = self.disk.discarded.get(key) if self.disk is not None else None
                if why:
                    reasons[nid] = f"disk cache entry discarded ({why}); recomputing"
                    emit(E.NodeLog(nid, reasons[nid]))
            waiting = [ref.node for ref in inst.inputs.values() if ref.node not in resolved]
            if waiting:
                stack.extend(reversed(waiting))
                continue
            stack.pop()
            resolved.add(nid)
            to_compute.append(nid)
            if not spec.side_effects:
                first_of[key] = nid
        # 2. compute
        tainted: set[str] = set()
        workers = max(1, int(self.workers))
        gate = DeviceGate(self._device) if workers > 1 and len(to_compute) > 1 else None

        def work(nid: str) -> None:
            inst = graph.nodes[nid]
            spec = self.registry.get(inst.type)
            emit(E.NodeStarted(nid, spec.type_id, reasons.get(nid, "evicted since the plan")))
            t0 = time.perf_counter()
            try:
                value = self._compute(nid, spec, inst, plan, results, cancel, emit,
                                      gate.opener() if gate is not None else self._device)
            finally:
                if gate is not None:
                    gate.release()
            seconds = time.perf_counter() - t0
            changed = self._sources_changed(nid, spec, plan)
            with lock:
                timings[nid] = seconds
                results[nid] = value
                ran.append(nid)
                if changed or any(ref.node in tainted for ref in inst.inputs.values()):
                    # computed on bytes the key does not describe: never cache it, nor what uses it
                    tainted.add(nid)
                    stored = ("not cached: " + (f"file changed during the run ({', '.join(changed)})" if changed
                                                else "an input was computed from a file that changed during the run"))
                    emit(E.NodeLog(nid, stored))
                    _log.warning("node %r: %s", nid, stored)
                else:
                    stored = self._store(spec, plan.keys[nid], value)
                    if "not on disk:" in stored:
                        emit(E.NodeLog(nid, stored.split("; ", 1)[-1]))
                for twin in twins.get(nid, ()):
                    results[twin] = value
                    cached.append(twin)
            emit(E.NodeFinished(nid, seconds, stored))
            for twin in twins.get(nid, ()):
                emit(E.NodeCached(twin, "memory"))

        twin_of = {t: n for n, ts in twins.items() for t in ts}
        deps = {nid: [twin_of.get(ref.node, ref.node) for ref in graph.nodes[nid].inputs.values()]
                for nid in to_compute}
        execute(to_compute, deps, work, workers, cancel)
        last = self._last_run_parts(graph.file)
        for nid in results:
            last[nid] = plan.parts[nid]
        if self.disk is not None and graph.file is not None:
            self.disk.save_record(_record_name(graph.file), {n: p.to_dict() for n, p in last.items()})
        values = {name: results[ref.node][ref.output] for name, ref in plan.outputs.items()}
        for nid in ran:
            if nid in logs:
                self._logs_by_key[plan.keys[nid]] = logs[nid]
                if len(self._logs_by_key) > 4096:      # bounded: drop the oldest
                    self._logs_by_key.pop(next(iter(self._logs_by_key)))
            else:
                self._logs_by_key.pop(plan.keys[nid], None)
        said = {nid: self._logs_by_key[k] for nid, k in plan.keys.items() if k in self._logs_by_key}
        emit(E.RunFinished(time.perf_counter() - t_run, len(ran), len(cached)))
        return RunResult(values, timings, tuple(ran), tuple(cached), plan, logs, said)

    def _last_run_parts(self, file: str | None) -> dict[str, KeyParts]:
        """Last-run key parts by node id for a graph file; read from the disk
        cache's records on first use, so ``explain`` works across processes."""
        last = self._last_parts.get(file)
        if last is None:
            last = {}
            if self.disk is not None and file is not None:
                record = self.disk.load_record(_record_name(file)) or {}
                for nid, d in record.items():
                    try:
                        last[nid] = KeyParts.from_dict(d)
                    except (KeyError, TypeError):
                        pass  # a record from another pixgraph version: only explanations suffer
            self._last_parts[file] = last
        return last

    def _fetch(self, key: str, spec: NodeSpec, expect: Callable[[], Any] = dict):
        value = self.memory.get(key)
        if value is not MISS:
            return value, "memory"
        if self.disk is not None:
            value = self.disk.get(key)
            if value is not MISS:
                # a well-formed entry that is not this node's outputs: other names, types,
                # NaN pixels, or another size than the graph's files make it
                why = misfit([(p.name, p.type) for p in spec.outputs], value, expect())
                if why:
                    self.disk.discard(key, why)
                    return MISS, ""
                _freeze(value)
                self.memory.put(key, value)
                return value, "disk"
        return MISS, ""

    def _sources_changed(self, nid: str, spec: NodeSpec, plan: Plan) -> list[str]:
        """Read-path params whose file no longer has the content hashed into the
        key (it changed between planning and the end of the compute)."""
        changed = []
        for p in spec.params:
            if p.kind == "path" and not p.writes:
                expect = plan.parts[nid].params.get(p.name)
                try:
                    now = {"file_sha256": self._hash_file.fresh(plan.params[nid][p.name])}
                except OSError:
                    now = None
                if now != expect:
                    changed.append(f"params.{p.name}")
        return changed

    def _compute(self, nid, spec: NodeSpec, inst, plan: Plan, results, cancel, emit, device) -> dict[str, Any]:
        inputs = {p.name: None for p in spec.inputs}
        for port, ref in inst.inputs.items():
            inputs[port] = results[ref.node][ref.output]
        ctx = NodeContext(nid, plan.graph.base_dir, device, cancel, emit, plan.scale)
        try:
            out = spec.cls().compute(ctx, Namespace(inputs), Namespace(plan.params[nid]))
        except (E.Cancelled, DeviceError):
            raise  # not the node's fault: no device could be opened
        except InputError as exc:
            files = files_upstream(plan, nid)
            where = f" (inputs from {files})" if files else ""
            raise NodeInputError(nid, spec.type_id,
                                 (str(exc).splitlines() or [type(exc).__name__])[0] + where) from exc
        except MemoryError as exc:  # sizes from the user's graph, too large for this machine
            raise NodeInputError(nid, spec.type_id, out_of_memory()) from exc
        except Exception as exc:
            raise NodeError(nid, spec.type_id, (f"failed: {type(exc).__name__}: {exc}".splitlines() or [""])[0]) from exc
        if not isinstance(out, dict):
            raise NodeError(nid, spec.type_id, f"compute returned {type(out).__name__}, expected a dict of outputs")
        names = [p.name for p in spec.outputs]
        missing = [n for n in names if n not in out]
        extra = [n for n in out if n not in names]
        if missing or extra:
            raise NodeError(nid, spec.type_id, f"compute returned outputs {sorted(out)}, declared {names}")
        for p in spec.outputs:
            try:
                p.type.validate(out[p.name])
            except TypeError as e:
                raise NodeError(nid, spec.type_id, f"output {p.name!r} is not a valid {p.type.type_name()}: {e}") from None
            _freeze(out[p.name])
        return out

    def _store(self, spec: NodeSpec, key: str, value: dict) -> str:
        if spec.side_effects:
            return "not cached (sink)"
        size = nbytes(value)
        where = "memory" if self.memory.put(key, value, size) else "not cached (larger than the memory limit)"
        if self.disk is not None and not spec.disk_cache:
            where += "; not on disk (the node recomputes faster than the disk cache reads)"
        elif self.disk is not None:
            try:
                bad = misfit([(p.name, p.type) for p in spec.outputs], value)
                if bad:  # it would be discarded when read
                    where += f"; not on disk: {bad}"
                elif self.disk.put(key, value):
                    where = "memory+disk" if where == "memory" else "disk"
                    self.memory_only.pop(spec.type_id, None)
                else:  # a full disk, a read-only folder...: not cached, never a failed run
                    where += f"; not on disk: {self.disk.last_skip}"
            except Unstorable as e:
                self.memory_only[spec.type_id] = str(e)
                where += f"; memory only: {e}"
            except MemoryError:  # the result is computed: a run never fails for want of a cache entry
                where += "; not on disk: ran out of memory writing the entry"
            except OSError as e:
                where += f"; not on disk: {e.strerror or e}"
        return where


def _affecting(nid: str, spec: NodeSpec, params: Mapping[str, Any], relevant: dict, inputs: dict):
    """The key parts the node's ``affects`` hook keeps: it may only leave names out."""
    names = spec.cls().affects(Namespace(params))
    if names is None:
        return relevant, inputs
    names = set(names)
    unknown = names - {p.name for p in spec.params} - {p.name for p in spec.inputs}
    if unknown:
        raise NodeError(nid, spec.type_id, f"affects() names no param or input {sorted(unknown)}")
    return ({k: v for k, v in relevant.items() if k in names},
            {k: v for k, v in inputs.items() if k in names})


class _Expected:
    """What the graph's file headers say each node's outputs will be (``Engine.check``),
    worked out once per run on the first disk hit; ``{}`` when the check cannot say
    (values bound by a host, a graph the check refuses: the run then reports it)."""

    def __init__(self, engine: "Engine", plan: Plan):
        self._engine, self._plan, self._infos = engine, plan, None

    def of(self, nid: str) -> dict[str, Any]:
        if self._infos is None:
            self._infos = {}
            if not self._plan.bind:
                try:
                    self._infos = self._engine.check(self._plan.graph, list(self._plan.outputs))
                except Exception:  # noqa: BLE001 - only a stricter check of cached values is lost
                    pass
        return self._infos.get(nid, {})


def _freeze(value) -> None:
    """Make output arrays read-only: one cached value feeds every consumer, so a
    node that wrote into its input would silently change other nodes' results."""
    if isinstance(value, np.ndarray):
        value.flags.writeable = False
    elif isinstance(value, dict):
        for v in value.values():
            _freeze(v)
    elif isinstance(value, (list, tuple)):
        for v in value:
            _freeze(v)


def _record_name(file: str) -> str:
    return "last-run-" + sha256_text(os.path.abspath(file))


def _ignore(event) -> None:
    pass


def _no_device():
    raise RuntimeError("this engine has no OpenCL device")

