"""``pixgraph serve``'s command line: ``add_arguments`` (called by ``pixgraph.cli``) and
``cli_serve``. Imports no web server until the command runs."""
from __future__ import annotations

import dataclasses
import os


def add_arguments(sv) -> None:
    """The ``serve`` subcommand's options, on an argparse parser."""
    sv.add_argument("graph", help="graph file (YAML); it may read and write only in its folder and --allow folders")
    sv.add_argument("--host", default="127.0.0.1", help="address to bind (default 127.0.0.1: this machine only)")
    sv.add_argument("--port", type=int, default=8765, help="port (default 8765; 0 picks a free one)")
    sv.add_argument("--allow-path", action="append", default=[], metavar="DIR",
                    help="another folder the graph may read and write (repeatable)")
    sv.add_argument("--device", default=None, help="OpenCL device spec (see 'pixgraph devices')")
    sv.add_argument("--max-pixels", type=int, default=None, help="largest image, width x height (default 8192^2)")
    sv.add_argument("--max-body", type=int, default=None, metavar="BYTES",
                    help="largest request body (default 256 MiB)")
    sv.add_argument("--run-timeout", type=float, default=None, metavar="SECONDS",
                    help="wall-clock limit of one run; a run still going is cancelled (default 120)")
    sv.add_argument("--no-token", action="store_true",
                    help="accept requests without the per-launch token (for scripts on a machine you alone use; "
                         "other web pages are still refused by their Host and Origin)")


def cli_serve(args, registry, usage_error) -> int:
    """Run ``pixgraph serve`` from parsed ``args``; bad input raises ``usage_error`` (exit 2)."""
    try:
        from .server import new_token, serve
        from .state import Limits, ServeState
        from .errors import ServeError
    except ImportError as e:
        raise usage_error(f"pixgraph serve needs the 'serve' extra ({e.name} is missing): "
                          "pip install 'pixgraph[serve]'") from None
    limits = Limits()
    for flag, field, value in (("--max-pixels", "max_pixels", args.max_pixels),
                               ("--max-body", "max_body_bytes", args.max_body),
                               ("--run-timeout", "run_timeout", args.run_timeout)):
        if value is None:
            continue
        if not value > 0 or value != value or value == float("inf"):
            raise usage_error(f"{flag} must be a positive number, got {value}")
        limits = dataclasses.replace(limits, **{field: value})
    for d in args.allow_path:
        if not os.path.isdir(d):
            raise usage_error(f"--allow-path {d}: no such folder")
    if args.device:
        from pixgraph.device import DeviceError, choose

        try:
            choose(args.device)
        except DeviceError as e:
            raise usage_error(str(e)) from None
    try:
        state = ServeState(args.graph, allow=args.allow_path, limits=limits, device=args.device, registry=registry)
    except ServeError as e:
        raise usage_error(e.message) from None

    def ready(url):
        print(f"pixgraph: serving {args.graph} at {url}", flush=True)

    # the engine checks every image it decodes against PIXGRAPH_MAX_PIXELS, from the header
    # the node opens: with the server's limit there, a file swapped for a larger one after
    # the server's own check (state.py) is refused too (a lower limit already set is kept)
    engine_limit = (os.environ.get("PIXGRAPH_MAX_PIXELS") or "").strip()
    if not (engine_limit.isascii() and engine_limit.isdigit() and int(engine_limit) < limits.max_pixels):
        os.environ["PIXGRAPH_MAX_PIXELS"] = str(limits.max_pixels)

    try:
        serve(state, args.host, args.port, on_ready=ready, token=None if args.no_token else new_token())
    except OSError as e:
        raise usage_error(f"cannot listen on {args.host}:{args.port}: {e.strerror or e}") from None
    finally:
        state.remove_uploads()
        if engine_limit is None:   # as it was (a server run in process, e.g. by tests)
            os.environ.pop("PIXGRAPH_MAX_PIXELS", None)
        else:
            os.environ["PIXGRAPH_MAX_PIXELS"] = engine_limit
    return 0
