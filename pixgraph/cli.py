"""``pixgraph`` command line: a thin shell over ``Session``.

Exit codes: 0 success; 2 bad input (graph file, params, options: one line on
stderr naming file, line, node and field); 1 internal failure (a node raised, a
device failed); 130 cancelled by Ctrl-C. ``--debug`` adds tracebacks.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import traceback
from typing import Any


from . import errors
from .errors import EXIT_BAD_INPUT, EXIT_CANCELLED, EXIT_INTERNAL, EXIT_OK, UsageError  # noqa: F401
from .options import parse_output_options, parse_sets  # noqa: F401 (part of the CLI's API)
from .registry import Registry


def default_disk_cache() -> str:
    """``PIXGRAPH_DISK_CACHE``, else ``$XDG_CACHE_HOME/pixgraph`` (``~/.cache/pixgraph``)."""
    env = os.environ.get("PIXGRAPH_DISK_CACHE")
    if env:
        return env
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return os.path.join(base, "pixgraph")


def _common(default) -> argparse.ArgumentParser:
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--debug", action="store_true", default=default, help="show tracebacks")
    common.add_argument("--quiet", "-q", action="store_true", default=default,
                        help="no progress bar or summaries")
    return common


def _parser() -> argparse.ArgumentParser:
    # --debug and --quiet go before or after the command: a command's own default
    # is SUPPRESS, so ``pixgraph --debug run`` keeps the flag the top level read
    top = _common(False)
    common = _common(argparse.SUPPRESS)

    graph_opts = argparse.ArgumentParser(add_help=False)
    graph_opts.add_argument("graph", help="graph file (YAML)")
    graph_opts.add_argument("--set", action="append", default=[], metavar="NODE.PARAM=VALUE",
                            help="override a param; VALUE is a YAML scalar or list")

    graph_opts.add_argument("--allow-path", action="append", default=[], metavar="DIR",
                            help="let the graph read and write files under DIR too (repeatable; "
                                 "also PIXGRAPH_ALLOW_PATHS, separated by os.pathsep)")

    cache_opts = argparse.ArgumentParser(add_help=False)
    cache_opts.add_argument("--disk-cache", metavar="DIR", default=None,
                            help="disk cache folder (default PIXGRAPH_DISK_CACHE or ~/.cache/pixgraph)")
    cache_opts.add_argument("--no-disk-cache", action="store_true", help="memory cache only")

    p = argparse.ArgumentParser(prog="pixgraph", description="Node-graph compositing with pixel-height light effects.",
                                parents=[top])
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")

    r = sub.add_parser("run", parents=[common, graph_opts, cache_opts], help="run a graph")
    r.add_argument("-o", "--output", action="append", default=[], metavar="NAME=PATH",
                   help="write graph output NAME (or any node output, NODE.OUTPUT) to a file PATH "
                        "(png, tif, jpg, exr, npy); masks and pixel heights are written as data "
                        "(no gamma, never clipped: 16-bit PNG for 0..1, else npy/exr/tif)")
    r.add_argument("--device", default=None, help="OpenCL device spec (see 'pixgraph devices')")
    r.add_argument("--cache-bytes", type=int, default=None, help="memory cache limit in bytes")
    r.add_argument("--workers", type=int, default=None, metavar="N",
                   help="compute up to N independent branches at once (default PIXGRAPH_WORKERS, else 1; "
                        "OpenCL nodes still take turns on the device)")

    sub.add_parser("validate", parents=[common, graph_opts],
                   help="check a graph file and its input files' headers without running it")
    sub.add_parser("explain", parents=[common, graph_opts, cache_opts],
                   help="show what a run would compute or take from cache, and why")

    gr = sub.add_parser("graph", parents=[common, graph_opts],
                        help="draw a graph: Graphviz DOT text (--dot, the default) or an SVG picture (--svg)")
    fmt = gr.add_mutually_exclusive_group()
    fmt.add_argument("--dot", action="store_true", help="print DOT text (render with Graphviz: dot -Tpng)")
    fmt.add_argument("--svg", action="store_true", help="an SVG picture, drawn without Graphviz")
    gr.add_argument("-o", "--output", metavar="PATH", default=None, help="write to PATH instead of stdout")

    n = sub.add_parser("nodes", parents=[common], help="list node types, or show one")
    n.add_argument("name", nargs="?", help="node type id")
    n.add_argument("--errors", action="store_true", help="show plugins that failed to load")
    n.add_argument("--markdown", action="store_true", help="print the node reference as Markdown")
    n.add_argument("--json", action="store_true", help="print the node declarations as JSON")

    sub.add_parser("schema", parents=[common], help="print the JSON Schema of graph files")
    sub.add_parser("devices", parents=[common], help="list OpenCL platforms and devices")

    sv = sub.add_parser("serve", parents=[common],
                        help="serve a graph: browser UI (drag the light) and a local HTTP API")
    from pixgraph_serve.cli import add_arguments as _serve_arguments

    _serve_arguments(sv)

    b = sub.add_parser("batch", parents=[common, graph_opts, cache_opts],
                       help="run a graph over a manifest's rows or a sweep (see docs/batch.md)")
    from pixgraph_batch import add_arguments as _batch_arguments

    _batch_arguments(b)

    c = sub.add_parser("cache", parents=[common, cache_opts], help="disk cache statistics or clearing")
    c.add_argument("action", choices=["stats", "clear"])
    return p


def main(argv: list[str] | None = None, registry: Registry | None = None) -> int:
    """Entry point; returns the exit code. ``registry`` replaces discovery (tests, hosts)."""
    parser = _parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as e:  # argparse prints its own one-line usage error
        return EXIT_BAD_INPUT if e.code else EXIT_OK
    try:
        return _COMMANDS[args.command](args, registry)
    except KeyboardInterrupt:
        print("pixgraph: cancelled", file=sys.stderr)
        if argv is None:
            _exit_now(EXIT_CANCELLED)
        return EXIT_CANCELLED
    except Exception as e:  # one table: pixgraph.errors
        code = errors.exit_code(e)
        if code == EXIT_CANCELLED:
            print("pixgraph: cancelled", file=sys.stderr)
            return code
        # a graph or usage error names its own file/flag; anything else says "error:"
        _fail(args, e, prefix="" if errors.names_its_input(e) else "error: ")
        return code


def _exit_now(code: int) -> None:
    """End the process at once after Ctrl-C on the command line. Nothing is left to
    save: the interrupted node stored nothing, and every finished node's cache
    entry was written atomically when it finished. Python's normal teardown would
    first finalise torch, PoCL and every module (torch alone: 1.7 s on a loaded
    2-core machine), delaying the exit the user asked for (benchmarks/cancel_bench.py)."""
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


def _fail(args, e: BaseException, prefix: str = "") -> None:
    print(errors.one_line(f"{prefix}{errors.message(e)}"), file=sys.stderr)
    if getattr(args, "debug", False):
        traceback.print_exception(e, file=sys.stderr)


def _session(args, registry, disk: bool = True):
    from .session import Session


    disk_dir = None
    if disk and not getattr(args, "no_disk_cache", False):
        disk_dir = args.disk_cache or default_disk_cache()
        try:
            os.makedirs(disk_dir, exist_ok=True)
            if not os.access(disk_dir, os.W_OK):
                raise PermissionError(disk_dir)
        except OSError:
            if not args.quiet:
                print(f"pixgraph: disk cache {disk_dir} is not writable; using memory only", file=sys.stderr)
            disk_dir = None
    if getattr(args, "device", None):
        from .device import DeviceError, choose

        try:
            choose(args.device)  # a bad spec is bad input, found before any node runs
        except DeviceError as e:
            raise UsageError(str(e)) from None
    workers = getattr(args, "workers", None)
    if workers is not None and workers < 1:
        raise UsageError(f"--workers {workers}: must be 1 or more")
    return Session(device=getattr(args, "device", None), cache_bytes=getattr(args, "cache_bytes", None),
                   disk_cache=disk_dir, registry=registry, allow_paths=getattr(args, "allow_path", []),
                   workers=workers)


def _cmd_run(args, registry) -> int:
    from .events import NodeCached, NodeFinished, NodeProgress, RunStarted

    targets = parse_output_options(args.output)
    s = _session(args, registry)
    sets = parse_sets(args.set)
    graph = s.graph(args.graph, sets)
    _allow_typed_paths(s, graph, sets)
    _check_output_paths(s, graph, targets)
    # unknown names or node outputs are reported by the engine's plan (exit 2)
    bar = None
    show_bar = not args.quiet and sys.stderr.isatty()

    def on_event(ev):
        nonlocal bar
        if not show_bar:
            return
        if isinstance(ev, RunStarted):
            from tqdm import tqdm

            bar = tqdm(total=ev.to_run + ev.cached, file=sys.stderr, unit="node", leave=False)
        elif isinstance(ev, (NodeFinished, NodeCached)):
            bar.set_postfix_str(ev.node_id)
            bar.update(1)
        elif isinstance(ev, NodeProgress):
            bar.set_postfix_str(f"{ev.node_id} {ev.fraction:.0%} {ev.message}".strip())

    try:
        res = s.run(graph, outputs=list(targets) or None, on_event=on_event)
    finally:
        if bar is not None:
            bar.close()
    values = res.outputs
    for name, path in targets.items():
        _write_output(s, graph, name, values[name], path)
    if not args.quiet:
        print(f"ran {len(res.ran)} node(s), {len(res.cached)} from cache, "
              f"{sum(res.timings.values()):.3f} s compute", file=sys.stderr)
        for nid, messages in res.logs.items():
            for m in messages:
                print(f"{nid}: {m}", file=sys.stderr)
        for name, v in values.items():
            where = f" -> {targets[name]}" if name in targets else ""
            print(f"{name}: {_describe(v)}{where}")
    return EXIT_OK


def _allow_typed_paths(s, graph, sets: dict[str, Any]) -> None:
    """A path given with ``--set`` is the user's own, like ``-o``: allow that one file."""
    files = []
    for name, value in sets.items():
        nid, _, pname = name.partition(".")
        inst = graph.nodes.get(nid)
        p = s.registry.get(inst.type).param(pname) if inst is not None else None
        if p is not None and p.kind == "path" and isinstance(value, str) and value:
            from .paths import bad_characters

            if not bad_characters(value):
                files.append(graph.resolve_path(value))
    if files:
        s.allow_files(files)


def _check_output_paths(s, graph, targets: dict[str, str]) -> None:
    """``-o`` paths are the user's own (any folder), but never hold control
    characters and never overwrite a file this graph reads."""
    from .paths import PathError

    try:
        s.check_output_paths(graph, targets)
    except PathError as e:
        raise UsageError(f"-o {e.message}") from None


def _write_output(s, graph, name: str, value, path: str) -> None:
    try:
        s.write_output(graph, name, value, path)
    except ValueError as e:
        raise UsageError(f"-o {name}={path}: {e}") from None


def _describe(v) -> str:
    import numpy as np

    if isinstance(v, np.ndarray):
        return f"array {v.dtype} {tuple(v.shape)}"
    return repr(v) if len(repr(v)) < 80 else type(v).__name__


def _cmd_validate(args, registry) -> int:
    reg = registry if registry is not None else Registry.discover()
    from .session import Session

    s = Session(registry=reg, allow_paths=args.allow_path)
    sets = parse_sets(args.set)
    g = s.graph(args.graph, sets)
    _allow_typed_paths(s, g, sets)
    s.check_paths(g)
    notes: list[str] = []
    if g.outputs:
        s.check(g, notes=notes)  # file headers: sizes, alpha, placements (reads no pixels)
    for note in notes:
        print(f"warning: {note}", file=sys.stderr)
    if not args.quiet:
        print(f"{args.graph}: ok ({len(g.nodes)} nodes, outputs: {', '.join(g.outputs) or 'none'})")
    return EXIT_OK


def _cmd_explain(args, registry) -> int:
    s = _session(args, registry)
    sets = parse_sets(args.set)
    graph = s.graph(args.graph, sets)
    _allow_typed_paths(s, graph, sets)
    print(s.explain(graph))
    return EXIT_OK


def _cmd_graph(args, registry) -> int:
    from . import drawing
    from .session import Session

    s = Session(registry=registry if registry is not None else Registry.discover(), allow_paths=args.allow_path)
    g = s.graph(args.graph, parse_sets(args.set))
    title = os.path.basename(args.graph)
    text = drawing.to_svg(g, s.registry, title) if args.svg else drawing.to_dot(g, s.registry)
    if args.output is None:
        sys.stdout.write(text)
        return EXIT_OK
    try:
        with open(args.output, "w", encoding="utf-8") as f:
            f.write(text)
    except OSError as e:
        raise UsageError(f"-o {args.output}: {e.strerror or e}") from None
    if not args.quiet:
        print(f"{args.graph}: {len(g.nodes)} nodes drawn to {args.output}", file=sys.stderr)
    return EXIT_OK


def _cmd_nodes(args, registry) -> int:
    from . import reference

    reg = registry if registry is not None else Registry.discover()
    if args.errors:
        for e in reg.errors:
            print(str(e))
            if args.debug and e.detail:
                print(e.detail, end="")
        if not reg.errors:
            print("no plugin errors")
        return EXIT_OK if not reg.errors else EXIT_INTERNAL
    if args.markdown:
        sys.stdout.write(reference.markdown(reg))
        return EXIT_OK
    if args.json and not args.name:
        print(json.dumps([reference.as_dict(s) for s in reg.specs()], indent=1))
        return EXIT_OK
    if args.name:
        if args.name not in reg:
            hint = reg.suggest(args.name)
            raise UsageError(f"unknown node type {args.name!r}" + (f" (did you mean {hint!r}?)" if hint else ""))
        if args.json:
            print(json.dumps(reference.as_dict(reg.get(args.name)), indent=1))
        else:
            sys.stdout.write(reference.text(reg.get(args.name), reg.source(args.name)))
        return EXIT_OK
    width = max((len(s.type_id) for s in reg.specs()), default=0)
    for spec in reg.specs():
        print(f"{spec.type_id.ljust(width)}  v{spec.version}  {spec.summary}")
    if reg.errors and not args.quiet:
        print(f"pixgraph: {len(reg.errors)} plugin error(s); see 'pixgraph nodes --errors'", file=sys.stderr)
    return EXIT_OK


def _cmd_schema(args, registry) -> int:
    from .fileio import schema_text

    sys.stdout.write(schema_text(registry if registry is not None else Registry.discover()))
    return EXIT_OK


def _cmd_devices(args, registry) -> int:
    from .device import DeviceError, build_problem, choose, list_devices, no_device_hint

    devices = list_devices()
    if not devices:
        print(f"no OpenCL device found: {no_device_hint()}", file=sys.stderr)
        return EXIT_INTERNAL
    try:
        default = choose().spec
    except DeviceError:
        default = None
    for d in devices:
        mark = "*" if d.spec == default else " "
        problem = build_problem(d)
        print(f"{mark} {d.describe()}" + (f"  [cannot build kernels: {problem}]" if problem else ""))
    if not args.quiet:
        print("(* = default; choose with --device SPEC or PIXGRAPH_DEVICE)", file=sys.stderr)
    return EXIT_OK


def _cmd_cache(args, registry) -> int:
    from .cache import DiskCache

    if args.no_disk_cache:
        raise UsageError(f"cache {args.action}: --no-disk-cache leaves no disk cache to {args.action}")
    root = args.disk_cache or default_disk_cache()
    if not os.path.isdir(root):
        print(json.dumps({"root": root, "entries": 0, "bytes": 0}) if args.action == "stats"
              else f"removed 0 entries from {root} (no such folder)")
        return EXIT_OK
    from .session import DEFAULT_DISK_CACHE_BYTES, env_bytes

    d = DiskCache(root, env_bytes("PIXGRAPH_DISK_CACHE_BYTES", DEFAULT_DISK_CACHE_BYTES))
    if args.action == "clear":
        n = d.clear()
        print(f"removed {n} entr{'y' if n == 1 else 'ies'} from {root}")
    else:
        print(json.dumps(d.stats(), sort_keys=True))
    return EXIT_OK


def _cmd_batch(args, registry) -> int:
    from pixgraph_batch import cli_batch

    return cli_batch(args, _session(args, registry), parse_sets(args.set), UsageError)


def _cmd_serve(args, registry) -> int:
    from pixgraph_serve.cli import cli_serve

    return cli_serve(args, registry, UsageError)


_COMMANDS = {"run": _cmd_run, "graph": _cmd_graph, "batch": _cmd_batch, "serve": _cmd_serve, "validate": _cmd_validate,
             "explain": _cmd_explain, "nodes": _cmd_nodes, "schema": _cmd_schema, "devices": _cmd_devices,
             "cache": _cmd_cache}
