"""Executors: where a batch's groups of items run.

- ``inprocess``: the caller's ``Session`` (one device, one memory cache);
- ``processes``: a pool of spawned local processes, one ``Session`` and OpenCL
  context each; the parent hands each idle worker the next group;
- ``dask``: ``distributed`` (a scheduler address, a ``Client``, a cluster object or a
  ``LocalCluster``); a worker plugin opens one ``Session`` per worker process. The
  ``LocalCluster`` speaks TLS with certificates made for it alone
  (``Security.temporary``): its scheduler listens on a port of 127.0.0.1, and over
  plain TCP any process of any user of the machine could connect and run code in
  the batch's workers. Its HTTP servers (the scheduler's and each worker's, plain
  HTTP on 127.0.0.1) serve no routes: their /info pages showed the workers' logs
  and call stacks to anyone.

Local workers die with their parent: on Linux the kernel kills them when the
batch process dies (``PR_SET_PDEATHSIG``, kill -9 included), and everywhere a
watchdog thread in each worker exits when its parent's pid changes. Workers
ignore SIGINT: Ctrl-C stops the parent, which kills its workers before exiting.
"""
from __future__ import annotations

import dataclasses
import os
import queue as queue_mod
import signal
import sys
import threading
import time
from typing import Any, Callable, Sequence

from .items import Item
from .rows import BatchError
from .work import ItemResult, failed, run_group, worker_name

EXECUTORS = ("inprocess", "processes", "dask")


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
    #: pid of the batch process a local worker must not outlive (None: a remote worker)
    parent_pid: int | None = None
    #: write a row's files on a writer thread while the next row computes (``work.run_group``)
    overlap: bool = True


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


def die_with_parent(parent_pid: int | None) -> None:
    """Make this process exit when ``parent_pid`` dies: the kernel's parent-death
    signal on Linux, and a watchdog thread (every 0.5 s) everywhere."""
    if parent_pid is None:
        return
    if sys.platform.startswith("linux"):
        try:
            import ctypes

            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(1, int(signal.SIGKILL), 0, 0, 0)  # PR_SET_PDEATHSIG
        except (OSError, AttributeError):
            pass
    if os.getppid() != parent_pid:  # the parent died before the signal was armed
        os._exit(1)

    def watch():
        while True:
            time.sleep(0.5)
            if os.getppid() != parent_pid:
                os._exit(1)

    threading.Thread(target=watch, name="pixgraph-parent-watchdog", daemon=True).start()


def init_worker(config: WorkerConfig) -> None:
    """Open this process's ``Session`` (and its device) once; later groups reuse it."""
    with _WORKER_LOCK:
        if _WORKER.get("config") == config and "session" in _WORKER:
            return
        die_with_parent(config.parent_pid)
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


def worker_run_group(config: WorkerConfig, graph_file: str, items: Sequence[Item], force: bool = False,
                     on_result: Callable[[ItemResult], None] | None = None) -> list[ItemResult]:
    """Run one group in a worker process (pool or Dask), opening the session on first use."""
    init_worker(config)
    with _WORKER_LOCK:  # one Session per process: groups run one at a time in it
        s = _WORKER["session"]
        graphs = _WORKER["graphs"]
        try:
            st = os.stat(graph_file)
            sig = (st.st_mtime_ns, st.st_size)
            if graphs.get(graph_file, (None,))[0] != sig:
                graphs[graph_file] = (sig, s.load(graph_file))
            graph = graphs[graph_file][1]
        except Exception as e:
            results = [failed(it, str(e), worker=worker_name()) for it in items]
            for r in results:
                if on_result is not None:
                    on_result(r)
            return results
        return run_group(s, graph, items, force, on_result, overlap=config.overlap)


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


# -- the process pool --------------------------------------------------------------------


def _pool_worker(config: WorkerConfig, gfile: str, force: bool, tasks, results) -> None:
    """A pool worker's main loop: take a group, report each item as it finishes."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's to handle
    init_worker(config)
    while True:
        group = tasks.get()
        if group is None:
            return
        worker_run_group(config, gfile, group, force, on_result=lambda r: results.put((os.getpid(), r)))
        results.put((os.getpid(), None))  # idle: ready for the next group


def run_pool(config: WorkerConfig, gfile: str, groups: Sequence[Sequence[Item]], workers: int, force: bool,
             record: Callable[[ItemResult], None]) -> int:
    """Run groups on ``workers`` spawned processes. A worker that dies (killed, out of
    memory) fails the unfinished items of its group; the others go on."""
    import multiprocessing

    # spawn, not fork: a forked child would inherit the parent's OpenCL context and
    # torch thread pools, which are not fork-safe
    ctx = multiprocessing.get_context("spawn")
    config = dataclasses.replace(config, parent_pid=os.getpid())
    todo = [list(g) for g in groups if g]
    n = max(1, min(workers, len(todo)))
    results = ctx.Queue()
    procs, inboxes, assigned = {}, {}, {}

    def dispatch(pid):
        if todo:
            assigned[pid] = {it.index: it for it in todo.pop(0)}
            inboxes[pid].put(list(assigned[pid].values()))
        else:
            inboxes[pid].put(None)  # nothing left: the worker exits

    def handle(pid, r):
        if r is not None:
            assigned.get(pid, {}).pop(r.index, None)
            record(r)
        else:  # the worker finished its group
            assigned.pop(pid, None)
            if pid in procs:
                dispatch(pid)

    try:
        for _ in range(n):
            inbox = ctx.Queue()
            p = ctx.Process(target=_pool_worker, args=(config, gfile, force, inbox, results), daemon=True)
            p.start()
            procs[p.pid], inboxes[p.pid] = p, inbox
        for pid in procs:
            dispatch(pid)
        while assigned or (todo and procs):
            try:
                handle(*results.get(timeout=0.2))
                continue
            except queue_mod.Empty:
                pass
            for pid, p in list(procs.items()):
                if not p.is_alive():
                    del procs[pid]
                    while True:  # what it (or another worker) sent before it died
                        try:
                            handle(*results.get_nowait())
                        except queue_mod.Empty:
                            break
                    for it in assigned.pop(pid, {}).values():
                        record(failed(it, f"worker lost: process {pid} exited with code {p.exitcode}"))
            if not procs:
                for g in todo:
                    for it in g:
                        record(failed(it, "worker lost: no worker process left"))
                todo.clear()
        for p in procs.values():
            p.join(timeout=5)
    finally:  # Ctrl-C or an error here: no worker outlives the batch
        for p in procs.values():
            if p.is_alive():
                p.kill()
        for p in procs.values():
            p.join(timeout=5)
    return n


# -- Dask --------------------------------------------------------------------------------


def _temporary_security():
    """TLS certificates for one LocalCluster (a new CA, clients must present its
    certificate): no other process can connect to its scheduler or workers."""
    try:
        from distributed.security import Security

        return Security.temporary()
    except ImportError:
        raise BatchError("the dask executor's local cluster needs the 'cryptography' package for TLS "
                         "(without it any local user could run code in its workers): "
                         "pip install 'pixgraph[batch]'") from None


def run_dask(config: WorkerConfig, gfile: str, groups: Sequence[Sequence[Item]], workers: int, scheduler,
             force: bool, record: Callable[[ItemResult], None]) -> int:
    """Run groups as Dask tasks (one task per group)."""
    try:
        import dask
        from distributed import Client, LocalCluster, as_completed
    except ImportError:
        raise BatchError("the dask executor needs dask.distributed: pip install 'pixgraph[batch]'") from None
    cluster, own_client = None, True
    if hasattr(scheduler, "submit"):  # a Client the caller made (e.g. on a dask-jobqueue cluster)
        client, own_client = scheduler, False
    elif scheduler:  # an address or a cluster object
        client = Client(scheduler)
    else:
        # one thread per worker process: a worker runs one composite at a time on
        # its own device; spawn-started processes (the nanny's default)
        security = _temporary_security()
        # their HTTP servers (plain HTTP on 127.0.0.1 whatever dashboard_address says)
        # serve no routes: /info gave any local user the workers' logs and call stacks
        with dask.config.set({"distributed.scheduler.http.routes": [], "distributed.worker.http.routes": []}):
            cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                   dashboard_address=None, protocol="tls", security=security)
        client = Client(cluster, security=security)
        config = dataclasses.replace(config, parent_pid=os.getpid())
    try:
        client.register_plugin(PixgraphWorkerPlugin(config), name=PixgraphWorkerPlugin.name)
        n = len(client.scheduler_info().get("workers", {}))
        groups = [list(g) for g in groups if g]
        futures = client.map(worker_run_group, [config] * len(groups), [gfile] * len(groups), groups,
                             [force] * len(groups), pure=False)
        by_key = {f.key: g for f, g in zip(futures, groups)}
        for fut in as_completed(futures):
            try:
                for r in fut.result():
                    record(r)
            except Exception as e:  # the worker died (killed, out of memory): its rows failed
                for it in by_key[fut.key]:
                    record(failed(it, f"worker lost: {type(e).__name__}: {e}"))
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
