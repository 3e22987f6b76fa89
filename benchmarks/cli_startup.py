"""CLI start-up of a graph without SSN++: wall time of a whole ``pixgraph run``
process, and whether torch got imported, here and (optionally) at another commit.

    python benchmarks/cli_startup.py                       # this tree
    python benchmarks/cli_startup.py --before 4580722      # also that commit, interleaved

``--before REV`` checks REV out into a temporary git worktree with a throw-away
venv (system site packages + that tree editable, no deps) and times both trees
alternately, so a busy neighbour slows both alike. The graph is
``graphs/blur_over.yaml`` (two loads, a blur on OpenCL, a merge; no disk cache),
so most of the time is start-up: imports, node discovery, OpenCL device.
Reports medians over ``--runs`` processes each.
"""
from __future__ import annotations

import argparse
import pathlib
import statistics
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from _machine import cpu_model  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[1]
GRAPH = "graphs/blur_over.yaml"
_PROBE = ("import sys\n"
          "from pixgraph.cli import main\n"
          "try:\n    main(sys.argv[1:])\nexcept SystemExit as e:\n    assert not e.code, e.code\n"
          "print('torch imported:', 'torch' in sys.modules)\n")


def one_run(python: str, tree: pathlib.Path, out: pathlib.Path) -> tuple[float, bool]:
    cmd = [python, "-c", _PROBE, "run", GRAPH, "-o", f"final={out}", "--no-disk-cache"]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, cwd=tree, capture_output=True, text=True)
    dt = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(proc.stderr[-2000:])
    return dt, "torch imported: True" in proc.stdout


def before_tree(rev: str, tmp: pathlib.Path) -> tuple[str, pathlib.Path]:
    tree = tmp / "before"
    subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", "-q", str(tree), rev], check=True)
    subprocess.run([sys.executable, "-m", "venv", "--system-site-packages", str(tmp / "venv")], check=True)
    py = str(tmp / "venv" / "bin" / "python")
    subprocess.run([py, "-m", "pip", "install", "-q", "--no-deps", "-e", str(tree)], check=True,
                   capture_output=True)
    return py, tree


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--before", help="also time this git revision")
    ap.add_argument("--runs", type=int, default=7)
    args = ap.parse_args(argv)
    trees = {"this tree": (sys.executable, ROOT)}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        try:
            if args.before:
                trees = {f"before ({args.before})": before_tree(args.before, tmp), **trees}
            times = {name: [] for name in trees}
            torch = {}
            for name, (py, tree) in trees.items():       # warm-up: OS file cache, PoCL kernel cache
                one_run(py, tree, tmp / "warm.png")
            for _ in range(args.runs):
                for name, (py, tree) in trees.items():
                    dt, torch[name] = one_run(py, tree, tmp / "o.png")
                    times[name].append(dt)
        finally:
            if args.before:
                subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(tmp / "before")],
                               capture_output=True)
    print(f"machine: {cpu_model()}, Python {sys.version.split()[0]}")
    print(f"`pixgraph run {GRAPH}` as a new process, median of {args.runs} (min-max):")
    for name, ts in times.items():
        print(f"  {name:24s} {statistics.median(ts):6.2f} s  ({min(ts):.2f}-{max(ts):.2f})  "
              f"torch imported: {torch[name]}")


if __name__ == "__main__":
    main()
