"""Full-size array work a band of rows at a time, on the machine's cores.

numpy releases the interpreter lock inside its loops, so the bands of a banded
computation (decoding a photo through a table, compositing, enlarging a proxy
shadow) can run on several threads at once: each band reads shared inputs and
writes its own rows of a preallocated output, so the result is the same numbers
as one thread's, band for band. ``PIXGRAPH_THREADS`` sets how many threads
(default: the CPUs this process may run on, at most 8); 1 runs every band in the caller.
A band's function that itself calls :func:`for_bands` runs those bands in line
(no pool inside the pool: a full pool waiting on itself would never finish).
"""
from __future__ import annotations

import os
import threading
from concurrent.futures import ThreadPoolExecutor

_POOL: ThreadPoolExecutor | None = None
_LOCK = threading.Lock()
_IN_BAND = threading.local()


#: the default's cap: each band in flight holds its own temporaries (a 50 MP image's
#: band of 64 rows: about 8 MB per float plane), and memory bandwidth, not cores, bounds
#: these loops well before 8 threads
DEFAULT_MAX = 8


def usable_cpus() -> int:
    """The CPUs this process may run on (its affinity; the machine's count elsewhere)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):   # not on Linux
        return max(1, os.cpu_count() or 1)


def threads_from_env(name: str, default: int) -> int:
    """The thread count in the environment variable ``name``: a whole number, at
    least 1 (else ``ValueError`` naming the variable), or ``default`` when unset."""
    raw = os.environ.get(name, "").strip()
    if not raw:
        return default
    try:
        n = int(raw)
    except ValueError:
        n = 0
    if n < 1:
        raise ValueError(f"{name} must be a whole number of threads, at least 1, got {raw!r}")
    return n


def workers() -> int:
    """Threads for banded work: ``PIXGRAPH_THREADS`` or the CPUs this process may use,
    at most ``DEFAULT_MAX``."""
    return threads_from_env("PIXGRAPH_THREADS", min(usable_cpus(), DEFAULT_MAX))


def _forget_pool_in_child() -> None:
    # a forked child has none of the pool's threads but would believe it had (its
    # bands would wait forever): it starts a pool of its own
    global _POOL, _LOCK
    _POOL, _LOCK = None, threading.Lock()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forget_pool_in_child)


def _pool(n: int) -> ThreadPoolExecutor:
    global _POOL
    with _LOCK:
        if _POOL is None or _POOL._max_workers != n:
            _POOL = ThreadPoolExecutor(max_workers=n, thread_name_prefix="pixgraph-band")
        return _POOL


def _run(fn, r0: int, r1: int) -> None:
    _IN_BAND.on = True
    try:
        fn(r0, r1)
    finally:
        _IN_BAND.on = False


def for_bands(fn, start: int, stop: int, band: int, min_bands: int = 2) -> None:
    """``fn(r0, r1)`` for the consecutive bands ``[r0, r1)`` of ``band`` rows covering
    ``[start, stop)``, on up to :func:`workers` threads; returns when every band is
    done and re-raises the first band's error. Fewer than ``min_bands`` bands, one
    worker, or a call from inside a band: in the caller's thread, in order."""
    band = max(1, int(band))
    bands = [(r0, min(stop, r0 + band)) for r0 in range(start, stop, band)]
    n = workers()
    if n == 1 or len(bands) < min_bands or getattr(_IN_BAND, "on", False):
        for r0, r1 in bands:
            fn(r0, r1)
        return
    futures = [_pool(n).submit(_run, fn, r0, r1) for r0, r1 in bands]
    error = None
    for f in futures:               # wait for all, even after an error: no band still writing on return
        try:
            f.result()
        except BaseException as e:  # noqa: BLE001 - re-raised below
            error = error or e
    if error is not None:
        raise error
