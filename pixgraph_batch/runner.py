"""Batch runs: one graph over many rows of inputs and params, on one or many machines.

A *row* binds ``node.param`` overrides (input files are ``LoadImage.path``
params) and names its output files by template, e.g. ``out/{row}_{name}.png``.
Rows come from a manifest (CSV or YAML), from sweeps (``light.azimuth=0:360:15``)
or both (every manifest row crossed with every sweep value); see ``rows``.

Each item is planned, and its *content key* is the engine's cache key of each
requested output plus the output path: an output whose provenance sidecar
(``PATH.json``) records the same key, and whose file still has the sha256 the
batch wrote, is done and skipped, so a killed batch resumes where it stopped and
a changed input, param or graph re-renders only the rows it touches (``files``).

Items that differ only downstream form groups that one executor runs together,
sharing their upstream results (``work``). Executors: ``inprocess``,
``processes`` and ``dask`` (``executors``). A row that fails is reported in the
result and does not stop the others.

This module holds the entry points: ``batch`` (rows or a manifest, sweeps ->
``BatchResult``) and ``run_batch`` (items -> ``BatchResult``).
"""
from __future__ import annotations

import dataclasses
import os
import sys
import time
from typing import Any, Callable, Iterable, Mapping, Sequence

from pixgraph.graph import Graph

from .files import FolderLock, remove_temporaries
from .executors import EXECUTORS, PixgraphWorkerPlugin, WorkerConfig, init_worker, limit_threads, run_dask, run_pool
from .items import DEFAULT_TEMPLATE, Item, make_items, output_folders, parse_output_options, user_files
from .rows import (DEFAULT_MAX_MANIFEST_BYTES, DEFAULT_MAX_ROWS, BatchError, Row, make_row,
                   parse_sweep, read_manifest, sweep_rows)
from .work import ItemResult, group_items, run_group, run_item, split_groups

__all__ = ["batch", "run_batch", "BatchResult", "BatchError", "Row", "Item", "ItemResult", "read_manifest",
           "parse_sweep", "sweep_rows", "make_items", "parse_output_options", "run_item", "run_group",
           "WorkerConfig", "PixgraphWorkerPlugin", "init_worker", "limit_threads", "EXECUTORS",
           "DEFAULT_TEMPLATE", "DEFAULT_MAX_ROWS", "DEFAULT_MAX_MANIFEST_BYTES"]


@dataclasses.dataclass
class BatchResult:
    results: list[ItemResult]
    seconds: float
    executor: str
    workers: int
    #: how many groups of items that share upstream work the batch ran
    groups: int = 0

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
              workers: int = 2, scheduler=None, force: bool = False, threads: int = 1,
              progress: bool = False, on_result: Callable[[ItemResult], None] | None = None,
              device=None, wait_lock: float | None = 0.0, share: bool = True,
              overlap: bool = True) -> BatchResult:
    """Run ``items`` with one executor.

    The output folders are locked for the whole batch (another batch on one of them:
    ``BatchError`` at once, or after ``wait_lock`` seconds; ``None`` waits as long as
    it takes); leftover temporaries of the items' files are removed first.
    share: group items that differ only downstream and run each group in one
        session, its upstream results held in memory (``work.group_items``).
    overlap: write each row's files on a writer thread while the next row of its
        group computes (``work.run_group``); False writes them before the next row
        starts (one row's outputs in memory at a time).
    """
    if executor not in EXECUTORS:
        raise BatchError(f"executor {executor!r}: choose one of {', '.join(EXECUTORS)}")
    if executor != "inprocess" and not isinstance(graph, (str, os.PathLike)):
        if getattr(graph, "file", None) is None:
            raise BatchError(f"the {executor} executor needs a graph file: worker processes load it themselves")
        graph = graph.file
    g = graph if isinstance(graph, Graph) else session.load(graph)
    groups = group_items(g, items) if share else [[it] for it in items]
    bar = None
    results: list[ItemResult] = []

    def record(r: ItemResult):
        results.append(r)
        if bar is not None:
            bar.update(1)
            bar.set_postfix_str(f"{sum(x.status == 'skipped' for x in results)} skipped, "
                                f"{sum(x.status == 'failed' for x in results)} failed")
        if on_result is not None:
            on_result(r)

    t0 = time.perf_counter()
    with FolderLock(output_folders(items), wait=wait_lock):
        remove_temporaries(p for it in items for p in it.outputs.values())
        if progress:
            from tqdm import tqdm

            bar = tqdm(total=len(items), unit="composite", desc="batch", file=sys.stderr, dynamic_ncols=True)
        try:
            if executor == "inprocess":
                for group in groups:
                    run_group(session, g, group, force, record, pin=share, overlap=overlap)
                n = 1
            else:
                if device is None and isinstance(session.device_spec, str):
                    device = session.device_spec  # a Device value cannot cross processes: workers open their own
                config = WorkerConfig(device=device, cache_bytes=session.memory.limit_bytes,
                                      disk_cache=session.disk.root if session.disk is not None else None,
                                      threads=threads, allow_paths=tuple(session.paths.roots),
                                      allow_files=tuple(sorted(session.paths.files)),
                                      strict_paths=session.paths.strict, overlap=overlap)
                gfile = os.path.abspath(os.fspath(graph))
                groups = split_groups(groups, workers)
                if executor == "processes":
                    n = run_pool(config, gfile, groups, workers, force, record)
                else:
                    n = run_dask(config, gfile, groups, workers, scheduler, force, record)
        finally:
            if bar is not None:
                bar.close()
            if executor != "dask" or not scheduler:
                # local writers are all gone now (workers killed on Ctrl-C): none of
                # their temporaries may stay behind
                remove_temporaries(p for it in items for p in it.outputs.values())
    results.sort(key=lambda r: r.index)
    return BatchResult(results, time.perf_counter() - t0, executor, n, len(groups))


def batch(session, graph, rows: Iterable[Row | Mapping[str, Any]] | str | os.PathLike | None = None, outputs=None,
          template: str = DEFAULT_TEMPLATE, sweeps: Sequence[tuple[str, Sequence[Any]] | str] = (),
          params: Mapping[str, Any] | None = None, manifest_dir: str | None = None,
          max_rows: int = DEFAULT_MAX_ROWS, max_manifest_bytes: int = DEFAULT_MAX_MANIFEST_BYTES,
          **run_kw) -> BatchResult:
    """Run ``graph`` over rows (``Row`` values, mappings of ``node.param``/field
    values, or a manifest path) crossed with sweeps (``"node.param=VALUES"`` or
    ``(name, values)``); ``outputs`` is ``{name: template}``, a list of names, or
    None (every image output, ``template``); ``params`` apply to every row.
    ``run_kw`` go to ``run_batch`` (executor, workers, scheduler, force, threads,
    progress, on_result, device, wait_lock, share, overlap). Bad input raises ``BatchError``
    before anything runs; a failing row is reported in the result."""
    g = graph if isinstance(graph, Graph) else session.load(graph)
    if isinstance(rows, (str, os.PathLike)):
        manifest_dir = manifest_dir or os.path.dirname(os.path.abspath(rows))
        rows = read_manifest(rows, max_rows=max_rows, max_bytes=max_manifest_bytes)
    rows = [r if isinstance(r, Row) else make_row(dict(r), f"row {i}") for i, r in enumerate(rows or [])]
    sweeps = [parse_sweep(s, max_rows) if isinstance(s, str) else (s[0], list(s[1])) for s in sweeps]
    rows = sweep_rows(sweeps, rows, max_rows)  # counts first: too many rows raise before any is made
    items = make_items(g, rows, session.registry, outputs, template, manifest_dir, params)
    files = user_files(g, session.registry, items)
    if files:
        session.allow_files(files)
    return run_batch(session, g, items, **run_kw)
