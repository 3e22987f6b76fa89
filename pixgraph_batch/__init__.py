"""``pixgraph batch``: one graph over many rows (a manifest or sweeps), in this process,
in spawned processes or on a Dask cluster, resumable. A shell over ``pixgraph.Session``;
install with ``pip install 'pixgraph[batch]'`` (Dask only for the dask executor).
"""
from .runner import *  # noqa: F401,F403
from .runner import batch, cli_batch, add_arguments  # noqa: F401
