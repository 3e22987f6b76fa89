"""tools/house_check.py measures issue 21's goals; the engine itself meets them."""
import importlib.util
import os

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
spec = importlib.util.spec_from_file_location("house_check", os.path.join(ROOT, "tools", "house_check.py"))
house_check = importlib.util.module_from_spec(spec)
spec.loader.exec_module(house_check)


def test_it_finds_each_kind_of_offender(tmp_path):
    pkg = tmp_path / "pixgraph_serve"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "a.py").write_text(
        '"""Mentions pixgraph.HardShadow in a docstring: not code."""\n'
        "from . import b\n"
        "PREVIEW = 'pixgraph.SoftShadow'\n"
        "def f(session, state):\n"
        "    from pixgraph_nodes.ops import imageio\n"
        "    session.engine.plan(None)\n"
        "    import os\n"
        "    os._exit(0)\n"
        "    return state._pixels, self_like._x if False else None\n")
    (pkg / "b.py").write_text("from .a import PREVIEW\nfrom pixgraph.session import _env_bytes\n" + "x = 1\n" * 600)
    report = house_check.check(["pixgraph_serve"], root=str(tmp_path))
    assert report["type ids"] == ["pixgraph_serve/a.py:3: 'pixgraph.SoftShadow'"]
    assert report["plugin imports"] == ["pixgraph_serve/a.py:5: pixgraph_nodes.ops"]
    assert report["reaches"] == ["pixgraph_serve/a.py:6: session.engine", "pixgraph_serve/a.py:9: self_like._x",
                                 "pixgraph_serve/a.py:9: state._pixels",
                                 "pixgraph_serve/b.py:2: from pixgraph.session import _env_bytes"]
    assert report["import cycles"] in (["pixgraph_serve.a -> pixgraph_serve.b -> pixgraph_serve.a"],
                                       ["pixgraph_serve.b -> pixgraph_serve.a -> pixgraph_serve.b"])
    assert report["long files"] == ["pixgraph_serve/b.py: 602 lines"]


def test_the_engine_and_its_shells_meet_the_goals():
    report = house_check.check(["pixgraph", "pixgraph_serve", "pixgraph_batch"])
    assert report["type ids"] == [] and report["plugin imports"] == [] and report["reaches"] == []
    assert report["import cycles"] == []
    assert report["long files"] == []
