"""pixgraph's built-in nodes, registered through the ``pixgraph.nodes`` entry point
exactly as a third-party node pack would be.

One node per module; the math of each effect lives in ``pixgraph_nodes.ops`` as
plain functions (numpy references next to their OpenCL kernels).
"""
from __future__ import annotations

import importlib
import pkgutil


def nodes(report=None) -> list[type]:
    """Every node class defined in this package's modules (the entry point).

    ``report(module_name, exception)``, when given (the registry passes it), is
    called for a module that fails to import, and the other modules still load;
    without it the first failure raises.
    """
    from pixgraph.node import is_node_class

    found = []
    for info in sorted(pkgutil.iter_modules(__path__), key=lambda i: i.name):
        if info.ispkg or info.name.startswith("_"):
            continue
        name = f"{__name__}.{info.name}"
        try:
            mod = importlib.import_module(name)
        except Exception as exc:
            if report is None:
                raise
            report(name, exc)
            continue
        found.extend(obj for obj in vars(mod).values()
                     if is_node_class(obj) and obj.__module__ == mod.__name__)
    return found
