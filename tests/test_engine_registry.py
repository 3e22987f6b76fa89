"""Registry: entry-point discovery, duplicate ids and broken plugins are reported, the rest keeps working."""
import os
import subprocess
import sys
import textwrap
import types

import numpy as np
import pytest

from engine_testnodes import T, make_nodes, make_registry
from pixgraph.node import node, port
from pixgraph.registry import Registry, UnknownNodeType
from pixgraph.session import Session


class FakeEntryPoint:
    def __init__(self, name, value, load):
        self.name, self.value, self._load = name, value, load

    def load(self):
        return self._load()


def _module_with(*classes):
    mod = types.ModuleType("fakepack")
    for c in classes:
        c.__module__ = "fakepack"
        setattr(mod, c.__name__, c)
    return mod


def test_injected_broken_and_duplicate_plugins_are_reported():
    good = make_nodes([])

    @node("t.Source", version=9)
    class Impostor:
        """Claims an id that is taken."""
        class Outputs:
            out: T.Image = port()

        def compute(self, ctx, inputs, params):
            return {"out": np.zeros((1, 1), np.float32)}

    def broken():
        raise ImportError("No module named 'missing_dependency'")

    eps = [FakeEntryPoint("a_good", "goodpack:nodes", lambda: lambda: good),
           FakeEntryPoint("b_broken", "brokenpack", broken),
           FakeEntryPoint("c_dup", "duppack", lambda: _module_with(Impostor)),
           FakeEntryPoint("d_notnodes", "weird:thing", lambda: 42)]
    reg = Registry.discover(entry_points=lambda group: eps if group == "pixgraph.nodes" else [])
    msgs = [str(e) for e in reg.errors]
    assert len(msgs) == 3, msgs
    assert "entry point 'b_broken' (brokenpack): failed to load: ImportError: No module named" in msgs[0]
    dup = msgs[1]
    assert "duplicate node type 't.Source'" in dup
    assert "duppack" in dup and "goodpack:nodes" in dup  # both sources are named
    assert "weird:thing" in msgs[2] and "expected a module or a callable" in msgs[2]
    assert reg.get("t.Source").version == 1  # the first registration keeps the id
    # everything else still works
    s = Session(registry=reg)
    b = s.builder()
    b.add("t.Source", "s", value=3.0)
    b.output("o", "s.out")
    assert s.run(b.build())["o"][0, 0] == 3.0


def test_pack_reports_a_broken_module_and_keeps_the_others():
    good = make_nodes([])

    def pack(report=None):
        report("fakepack.broken_node", SyntaxError("invalid syntax (broken_node.py, line 3)"))
        return good

    reg = Registry.discover(entry_points=lambda g: [FakeEntryPoint("pack", "fakepack:nodes", lambda: pack)])
    assert len(reg.errors) == 1
    assert str(reg.errors[0]).startswith("entry point 'pack' (fakepack:nodes): fakepack.broken_node: failed to load: "
                                         "SyntaxError")
    assert "t.Add" in reg and len(reg) == len(good)


def test_builtin_pack_loads_through_its_entry_point():
    reg = Registry.discover()
    for type_id in ("pixgraph.LoadImage", "pixgraph.SaveImage", "pixgraph.Constant", "pixgraph.Merge",
                    "pixgraph.GaussianBlur"):
        assert type_id in reg, [str(e) for e in reg.errors]
        assert reg.source(type_id).startswith("entry point 'builtin' (pixgraph_nodes:nodes)")
    with pytest.raises(UnknownNodeType):
        reg.get("pixgraph.Nope")


def test_add_rejects_non_nodes_and_ignores_re_adding_the_same_class():
    reg = make_registry()
    n = len(reg)
    with pytest.raises(TypeError):
        reg.add(int)
    assert reg.add(reg.get("t.Add").cls) is False
    assert len(reg) == n and reg.errors == []


PLUGINS = {
    "okpack/__init__.py": '''
        import numpy as np
        from pixgraph_nodes import types as T
        from pixgraph.node import node, param, port

        @node("ok.Double", version=1)
        class Double:
            """Twice the input."""
            class Inputs:
                image: T.Image = port()
            class Outputs:
                image: T.Image = port()
            def compute(self, ctx, inputs, params):
                return {"image": inputs.image * 2}
    ''',
    "brokenpack/__init__.py": '''
        import this_dependency_is_not_installed
    ''',
    "duppack/__init__.py": '''
        import numpy as np
        from pixgraph_nodes import types as T
        from pixgraph.node import node, port

        @node("pixgraph.Constant", version=7)
        class NotTheRealConstant:
            """A plugin claiming a built-in id."""
            class Outputs:
                image: T.Image = port()
            def compute(self, ctx, inputs, params):
                return {"image": np.zeros((1, 1), np.float32)}
    ''',
    "fakeplugins-0.1.dist-info/METADATA": '''
        Metadata-Version: 2.1
        Name: fakeplugins
        Version: 0.1
    ''',
    "fakeplugins-0.1.dist-info/entry_points.txt": '''
        [pixgraph.nodes]
        aaa_dup = duppack
        broken = brokenpack
        ok = okpack
    ''',
}


@pytest.fixture
def plugin_dir(tmp_path):
    for rel, text in PLUGINS.items():
        p = tmp_path / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(textwrap.dedent(text).lstrip())
    return tmp_path


def _cli(plugin_dir, *args):
    env = {**os.environ, "PYTHONPATH": f"{plugin_dir}{os.pathsep}{os.environ.get('PYTHONPATH', '')}"}
    return subprocess.run([sys.executable, "-m", "pixgraph", *args], capture_output=True, text=True,
                          timeout=120, env=env, cwd=plugin_dir)


def test_installed_broken_and_duplicate_plugins(plugin_dir):
    p = _cli(plugin_dir, "nodes", "--errors")
    assert p.returncode == 1
    lines = p.stdout.splitlines()
    assert any("entry point 'broken' (brokenpack): failed to load: ModuleNotFoundError" in ln for ln in lines)
    dup = [ln for ln in lines if "duplicate node type 'pixgraph.Constant'" in ln]
    assert len(dup) == 1 and "duppack" in dup[0] and "pixgraph_nodes" in dup[0]
    p = _cli(plugin_dir, "nodes")
    assert p.returncode == 0 and "ok.Double" in p.stdout and "pixgraph.Constant" in p.stdout
    assert "2 plugin error(s)" in p.stderr
    # a graph mixing the plugin's node and the real built-in runs
    (plugin_dir / "g.yaml").write_text(textwrap.dedent("""
        pixgraph: 1
        nodes:
          c: {type: pixgraph.Constant, params: {color: [0.5, 0.5, 0.5, 1.0], width: 3, height: 2}}
          d: {type: ok.Double, inputs: {image: c.image}}
        outputs: {final: d.image}
    """))
    p = _cli(plugin_dir, "run", "g.yaml", "--no-disk-cache", "-o", "final=out.exr")
    assert p.returncode == 0, p.stderr
    from pixgraph_nodes.ops.imageio import read_exr_channels

    ch = read_exr_channels(plugin_dir / "out.exr")
    assert [float(ch[c][0, 0]) for c in "RGBA"] == [1.0, 1.0, 1.0, 2.0]


def test_port_types_come_from_the_registered_nodes():
    """The name -> port type table is the engine's own types plus those of the
    registered nodes' ports (a Mask output brings the Image it may feed)."""
    reg = Registry()
    assert set(reg.port_types()) == {"Any", "Scalar"}
    reg = make_registry()
    table = reg.port_types()
    assert table["Image"] is T.Image and table["Mask"] is T.Mask and table["Scalar"] is T.Scalar
    assert "PortType" not in table and "Camera" not in table
    real = Registry.discover().port_types()
    assert {"Image", "Mask", "PixelHeight", "Camera", "Light", "Geometry", "Buffers"} <= set(real)
    assert real["Image"].__module__ == "pixgraph_nodes.types"
