"""``pixgraph batch``: the subcommand's options and its run (the graph, ``--set`` and
cache options, and the session, come from ``pixgraph.cli``)."""
from __future__ import annotations

import dataclasses
import json
import sys
from typing import Any, Mapping

from .items import DEFAULT_TEMPLATE, parse_output_options
from .rows import DEFAULT_MAX_MANIFEST_BYTES, DEFAULT_MAX_ROWS, BatchError
from .runner import batch


def add_arguments(p) -> None:
    """The ``pixgraph batch`` options."""
    p.add_argument("manifest", nargs="?", help="rows: a CSV or YAML manifest (columns NODE.PARAM, id, ...)")
    p.add_argument("--sweep", action="append", default=[], metavar="NODE.PARAM=VALUES",
                   help="sweep a param: START:STOP:STEP (stop excluded), A,B,C or a file glob; "
                        "several sweeps (and a manifest) are crossed")
    p.add_argument("-o", "--output", action="append", default=[], metavar="NAME=TEMPLATE",
                   help="write output NAME (or NODE.OUTPUT) to TEMPLATE, e.g. 'out/{row}_{name}.png'; "
                        "fields: row, index, name, stem, node_param, manifest columns; every file stays "
                        "inside the template's folder")
    p.add_argument("--template", default=DEFAULT_TEMPLATE,
                   help=f"template of every image output when no -o is given (default {DEFAULT_TEMPLATE})")
    ex = p.add_mutually_exclusive_group()
    ex.add_argument("--processes", type=int, metavar="N", help="run on N local worker processes (spawned)")
    ex.add_argument("--dask-local", type=int, metavar="N", help="run on a Dask LocalCluster of N worker processes")
    ex.add_argument("--scheduler", metavar="ADDRESS", help="run on a Dask cluster (e.g. tcp://host:8786)")
    p.add_argument("--threads", type=int, default=1, help="threads per worker process (default 1)")
    p.add_argument("--force", action="store_true", help="re-render rows whose outputs are already done")
    p.add_argument("--no-overlap", action="store_true",
                   help="write each row's files before the next row starts (default: on a writer thread while "
                        "the next row computes; this holds one row's outputs in memory instead of two)")
    p.add_argument("--report", metavar="JSON", help="also write every row's result to this JSON file")
    p.add_argument("--device", default=None, help="OpenCL device spec (see 'pixgraph devices')")
    p.add_argument("--cache-bytes", type=_bytes, default=None, help="memory cache limit in bytes (per process)")
    p.add_argument("--max-rows", type=int, default=DEFAULT_MAX_ROWS,
                   help=f"refuse batches of more rows, counted before any is made (default {DEFAULT_MAX_ROWS})")
    p.add_argument("--max-manifest-bytes", type=int, default=DEFAULT_MAX_MANIFEST_BYTES,
                   help=f"refuse larger manifest files (default {DEFAULT_MAX_MANIFEST_BYTES})")
    p.add_argument("--wait-lock", type=float, default=0.0, metavar="SECONDS",
                   help="wait this long for another batch writing the same output folder (default 0: "
                        "refuse at once; -1: wait as long as it takes)")


def _bytes(text: str) -> int:
    """A byte count >= 0 (checked while parsing: the session is made before the batch runs)."""
    import argparse

    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number of bytes") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"{value}: must be >= 0")
    return value


def cli_batch(args, session, shared_params: Mapping[str, Any], usage_error) -> int:
    """``pixgraph batch``: exit 0 when every row is done or skipped, 1 when a row
    failed, 2 (``usage_error``) for bad input found before anything runs."""
    try:
        if not args.manifest and not args.sweep:
            raise BatchError("batch: give a MANIFEST, one or more --sweep, or both")
        for flag, value in (("--max-rows", args.max_rows), ("--max-manifest-bytes", args.max_manifest_bytes)):
            if value < 1:
                raise BatchError(f"{flag} {value}: must be >= 1")
        outputs = parse_output_options(args.output)
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
                       max_rows=args.max_rows, max_manifest_bytes=args.max_manifest_bytes,
                       executor=executor, workers=workers, scheduler=args.scheduler, force=args.force,
                       progress=show, threads=args.threads, device=args.device,
                       wait_lock=None if args.wait_lock < 0 else args.wait_lock, overlap=not args.no_overlap)
    except BatchError as e:
        raise usage_error(str(e)) from None
    if args.report:
        with open(args.report, "w", encoding="utf-8") as f:
            json.dump({"summary": {"done": result.count("done"), "skipped": result.count("skipped"),
                                   "failed": result.count("failed"), "seconds": result.seconds,
                                   "executor": result.executor, "workers": result.workers,
                                   "groups": result.groups},
                       "rows": [dataclasses.asdict(r) for r in result.results]}, f, indent=1)
    if not args.quiet:
        table = result.table()
        if table:
            print(table)
        print(result.summary())
    return 0 if not result.failed else 1
