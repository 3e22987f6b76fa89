"""``pixgraph batch``: one graph over many rows (a manifest or sweeps), in this process,
in spawned processes or on a Dask cluster, resumable. A shell over ``pixgraph.Session``;
install with ``pip install 'pixgraph[batch]'`` (Dask only for the dask executor).

Modules: ``rows`` (manifests, sweeps, their bounds), ``items`` (rows bound to a graph
and to output files), ``files`` (atomic writes, sidecars, the folder lock),
``work`` (running items and groups), ``executors`` (in-process, processes, Dask),
``runner`` (``batch``, ``run_batch``), ``cli`` (the subcommand).
"""
from .cli import add_arguments, cli_batch
from .runner import *  # noqa: F401,F403
from .runner import BatchError, BatchResult, batch, run_batch  # noqa: F401
