"""Measure issue 21's house goals over the engine and its shells.

    python tools/house_check.py [DIR ...]       # default: pixgraph pixgraph_serve pixgraph_batch
    python tools/house_check.py --json pixgraph  # the counts and offenders as JSON
    python tools/house_check.py --root OTHER_CHECKOUT  # measure another checkout (e.g. before)

For the Python files under each DIR it counts, and lists each offender of:

type ids       string constants that are a node type id (``"pixgraph.HardShadow"``:
               a registered id, or ``namespace.CapitalName`` with the built-in
               ``pixgraph`` namespace), i.e. code that names a node type
plugin imports imports of ``pixgraph_nodes`` (the built-in node pack), lazy ones too
reaches        ``x.engine`` on anything but ``self``, ``x._private`` on another
               object (not ``self``/``cls``, not a third-party module such as
               ``os._exit``), and ``from first_party import _private``
import cycles  cycles among first-party modules (every import counts, also one
               inside a function): each strongly connected group of modules
long files     files over 600 lines

Exit status 0 always (it measures); tests assert the counts they expect.
"""
from __future__ import annotations

import argparse
import ast
import json
import os
import re
import sys

FIRST_PARTY = ("pixgraph", "pixgraph_serve", "pixgraph_batch", "pixgraph_nodes", "pixgraph_lab")
MAX_LINES = 600
TYPE_ID = re.compile(r"^pixgraph\.[A-Z][A-Za-z0-9]+$")
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _registered_ids() -> set[str]:
    try:
        from pixgraph.registry import Registry

        return set(Registry.discover())
    except Exception:  # noqa: BLE001 - an uninstalled checkout: the pattern alone
        return set()


def _module_name(path: str, root: str) -> str:
    rel = os.path.relpath(path, root)[:-3].replace(os.sep, ".")
    return rel[: -len(".__init__")] if rel.endswith(".__init__") else rel


def _resolve(module: str, is_pkg: bool, level: int, name: str | None) -> str:
    """The absolute module a (possibly relative) import names."""
    if level == 0:
        return name or ""
    parts = module.split(".")
    base = parts if is_pkg else parts[:-1]
    base = base[: len(base) - (level - 1)]
    return ".".join(base + ([name] if name else []))


def _files(dirs: list[str]) -> list[str]:
    out = []
    for d in dirs:
        for folder, subdirs, names in os.walk(d):
            subdirs[:] = sorted(s for s in subdirs if s not in ("__pycache__", "static"))
            out += [os.path.join(folder, n) for n in sorted(names) if n.endswith(".py")]
    return out


def check(dirs: list[str], root: str = ROOT) -> dict:
    ids = _registered_ids()
    report = {"type ids": [], "plugin imports": [], "reaches": [], "import cycles": [], "long files": []}
    modules: dict[str, tuple[str, bool]] = {}
    trees = {}
    for path in _files([os.path.join(root, d) if not os.path.isabs(d) else d for d in dirs]):
        rel = os.path.relpath(path, root)
        text = open(path, encoding="utf-8").read()
        n_lines = text.count("\n") + (not text.endswith("\n") and bool(text))
        if n_lines > MAX_LINES:
            report["long files"].append(f"{rel}: {n_lines} lines")
        tree = ast.parse(text, rel)
        trees[rel] = tree
        modules[_module_name(path, root)] = (rel, path.endswith("__init__.py"))
    edges: dict[str, set[str]] = {m: set() for m in modules}
    for mod, (rel, is_pkg) in modules.items():
        tree = trees[rel]
        third_party = set()
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                for a in node.names:
                    if a.name.split(".")[0] not in FIRST_PARTY:
                        third_party.add((a.asname or a.name).split(".")[0])
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and \
                    (node.module or "").split(".")[0] not in FIRST_PARTY:
                third_party.update(a.asname or a.name for a in node.names)
        docstrings = {id(n.body[0].value) for n in ast.walk(tree)
                      if isinstance(n, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef))
                      and n.body and isinstance(n.body[0], ast.Expr) and isinstance(n.body[0].value, ast.Constant)}
        for node in ast.walk(tree):
            where = f"{rel}:{getattr(node, 'lineno', 0)}"
            if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docstrings:
                if node.value in ids or TYPE_ID.match(node.value):
                    report["type ids"].append(f"{where}: {node.value!r}")
            elif isinstance(node, (ast.Import, ast.ImportFrom)):
                if isinstance(node, ast.Import):
                    targets = [a.name for a in node.names]
                else:
                    base = _resolve(mod, is_pkg, node.level, node.module)
                    targets = [base] + [f"{base}.{a.name}" for a in node.names]
                    if base.split(".")[0] in FIRST_PARTY:
                        for a in node.names:
                            if a.name.startswith("_") and not a.name.startswith("__"):
                                report["reaches"].append(f"{where}: from {base} import {a.name}")
                for t in targets:
                    if t.split(".")[0] == "pixgraph_nodes" and t == targets[0]:
                        report["plugin imports"].append(f"{where}: {t}")
                    if t in modules and t != mod:
                        edges[mod].add(t)
            elif isinstance(node, ast.Attribute):
                owner = node.value
                own = isinstance(owner, ast.Name) and owner.id in ("self", "cls")
                if node.attr == "engine" and not own:
                    report["reaches"].append(f"{where}: {ast.unparse(node)}")
                elif node.attr.startswith("_") and not node.attr.startswith("__") and not own:
                    if isinstance(owner, ast.Name) and owner.id in third_party:
                        continue  # os._exit, sys._getframe: a library's documented names
                    report["reaches"].append(f"{where}: {ast.unparse(node)}")
    import networkx as nx

    g = nx.DiGraph()
    g.add_nodes_from(edges)
    g.add_edges_from((a, b) for a, bs in edges.items() for b in bs)
    for comp in nx.strongly_connected_components(g):
        if len(comp) > 1:
            cycle = nx.find_cycle(g.subgraph(comp))
            report["import cycles"].append(" -> ".join([a for a, _ in cycle] + [cycle[-1][1]]))
    for k in report:
        report[k] = sorted(report[k])
    return report


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dirs", nargs="*", default=["pixgraph", "pixgraph_serve", "pixgraph_batch"])
    ap.add_argument("--json", action="store_true", help="print the report as JSON")
    ap.add_argument("--root", default=ROOT, help="the checkout to measure (default: this tool's)")
    args = ap.parse_args(argv)
    report = check(args.dirs, root=args.root)
    if args.json:
        print(json.dumps(report, indent=1))
        return 0
    print(f"house check of {', '.join(args.dirs)}")
    for k, items in report.items():
        print(f"{k}: {len(items)}")
        for item in items:
            print(f"    {item}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
