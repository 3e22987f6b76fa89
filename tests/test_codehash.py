"""The code hash in cache keys: editing a node's code (its module, an op module it
imports from the same package, a kernel or header it loads) changes its key, so a
disk cache never serves a result of the old code; editing code it does not use
changes nothing."""
import json
import os
import subprocess
import sys
import textwrap

import pytest

from pixgraph import codehash

PLUGIN = {
    "plug/__init__.py": "",
    "plug/glow.py": textwrap.dedent('''
        import numpy as np
        from pixgraph_nodes import types as T
        from pixgraph.node import node, port

        @node("plug.Glow", version=1)
        class Glow:
            """A constant from the plug's op."""
            class Outputs:
                out: T.Image = port()
            impl_version = "1"

            def compute(self, ctx, inputs, params):
                from .ops.shade import level   # imported inside compute, as nodes often do
                ctx.log("computed")
                return {"out": np.full((4, 4), level(), np.float32)}
        '''),
    "plug/ops/__init__.py": "",
    "plug/ops/shade.py": textwrap.dedent('''
        KERNEL = "shade.cl"

        def level():
            return 1.0
        '''),
    "plug/ops/shade.cl": '#include "common.h"\n__kernel void k() {}\n',
    "plug/ops/common.h": "#define GAIN 1\n",
    "plug/ops/unused.py": "def other():\n    return 5\n",
}

RUN = textwrap.dedent("""
    import json, sys
    sys.path.insert(0, {root!r})
    from pixgraph.registry import Registry
    from pixgraph.session import Session
    import plug.glow
    reg = Registry()
    reg.add(plug.glow.Glow, source="plug")
    s = Session(registry=reg, disk_cache={disk!r})
    b = s.builder()
    b.add("plug.Glow", "g")
    b.output("o", "g.out")
    g = b.build()
    plan = s.plan(g)
    out = s.run(g)["o"]
    print(json.dumps({{"key": plan.keys["g"], "impl": plan.parts["g"].impl_version, "status": plan.steps[0].status,
                       "value": float(out[0, 0]), "ran": list(s.last_run.ran)}}))
""")


@pytest.fixture
def plugin(tmp_path):
    root = tmp_path / "src"
    for rel, text in PLUGIN.items():
        p = root / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(text)
    return root


def _run(root, disk):
    p = subprocess.run([sys.executable, "-c", RUN.format(root=str(root), disk=str(disk))],
                       capture_output=True, text=True, timeout=120, env={**os.environ, "PYTHONDONTWRITEBYTECODE": "1"})
    assert p.returncode == 0, p.stderr
    return json.loads(p.stdout)


def test_editing_an_op_reruns_the_node_instead_of_serving_the_old_result(plugin, tmp_path):
    disk = tmp_path / "disk"
    first = _run(plugin, disk)
    assert first["ran"] == ["g"] and first["value"] == 1.0 and first["impl"].startswith("1+code.")
    again = _run(plugin, disk)
    assert again["key"] == first["key"] and again["status"] == "disk" and again["ran"] == []
    # the op changes, impl_version is not bumped: a new key, the new number
    (plugin / "plug/ops/shade.py").write_text(PLUGIN["plug/ops/shade.py"].replace("1.0", "2.0"))
    edited = _run(plugin, disk)
    assert edited["key"] != first["key"] and edited["status"] == "run" and edited["value"] == 2.0


@pytest.mark.parametrize("rel, edit, changes", [
    ("plug/glow.py", lambda t: t.replace('"""A constant', '"""The constant'), True),
    ("plug/ops/shade.py", lambda t: t + "\n# a comment\n", True),
    ("plug/ops/shade.cl", lambda t: t.replace("{}", "{ }"), True),
    ("plug/ops/common.h", lambda t: t.replace("1", "2"), True),   # only reached through #include
    ("plug/ops/unused.py", lambda t: t.replace("5", "6"), False),  # not imported by the node
])
def test_what_is_in_the_code_of_a_node(plugin, tmp_path, rel, edit, changes):
    before = _run(plugin, tmp_path / "d1")["key"]
    (plugin / rel).write_text(edit((plugin / rel).read_text()))
    after = _run(plugin, tmp_path / "d2")["key"]
    assert (after != before) == changes


def test_code_files_of_a_builtin_node():
    import pixgraph_nodes.soft_shadow  # noqa: F401

    files = codehash.code_files("pixgraph_nodes.soft_shadow")
    for want in ("pixgraph_nodes.soft_shadow", "pixgraph_nodes.ops.shadow", "pixgraph_nodes._checks",
                 "data:ops/shadow.cl", "data:ops/march.h"):
        assert want in files, want
    assert "pixgraph_nodes.ops.reflection" not in files and "pixgraph_nodes" not in files
    assert not any(k.startswith(("numpy", "pixgraph.")) for k in files)
    h = codehash.code_hash("pixgraph_nodes.soft_shadow")
    assert len(h) == 16 and h == codehash.code_hash("pixgraph_nodes.soft_shadow")


def test_a_node_without_a_source_file_keeps_its_declared_impl_version():
    from pixgraph_nodes import types as T
    from pixgraph.node import node, port

    ns = {"node": node, "port": port, "T": T, "__name__": "not_a_module_anywhere"}
    exec(textwrap.dedent('''
        @node("x.NoFile", version=1)
        class NoFile:
            class Outputs:
                out: T.Image = port()
            impl_version = "7"
            def compute(self, ctx, inputs, params):
                return {}
    '''), ns)
    assert ns["NoFile"].__module__ == "not_a_module_anywhere"
    assert codehash.impl_version(ns["NoFile"].spec) == "7"
