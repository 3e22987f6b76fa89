"""Limits set in the environment (PIXGRAPH_*_BYTES, PIXGRAPH_MAX_PIXELS,
PIXGRAPH_MAX_FILE_BYTES, PIXGRAPH_WORKERS) that are no finite number: ``inf`` or
``1e400`` reached ``int(float(...))``, whose OverflowError stopped ``pixgraph run``
with exit 1 and "cannot convert float infinity to integer", naming no variable."""
import pytest

from pixgraph.cli import main

GRAPH = ("pixgraph: 1\nnodes:\n  c: {type: pixgraph.Constant, params: {width: 4, height: 4}}\n"
         "  s: {type: pixgraph.SaveImage, inputs: {image: c.image}, params: {path: PATH}}\n"
         "outputs: {final: c.image}\n")


@pytest.mark.parametrize("value", ["inf", "1e400", "-inf"])
@pytest.mark.parametrize("name", ["PIXGRAPH_CACHE_BYTES", "PIXGRAPH_DISK_CACHE_BYTES", "PIXGRAPH_MAX_FILE_BYTES",
                                  "PIXGRAPH_WORKERS"])
def test_an_infinite_limit_names_its_variable(tmp_path, monkeypatch, capsys, name, value):
    graph = tmp_path / "g.yaml"
    graph.write_text(GRAPH.replace("PATH", str(tmp_path / "saved.png")))
    monkeypatch.setenv(name, value)
    code = main(["run", str(graph), "--disk-cache", str(tmp_path / "cache"), "-o", f"final={tmp_path}/x.png"])
    err = capsys.readouterr().err
    assert code in (1, 2) and name in err and "cannot convert" not in err, (code, err)


@pytest.mark.parametrize("value", ["inf", "1e400"])
def test_an_infinite_pixel_limit_names_its_variable(monkeypatch, value):
    from pixgraph_nodes.ops import imageio
    monkeypatch.setenv("PIXGRAPH_MAX_PIXELS", value)
    with pytest.raises(imageio.ImageFileError, match="PIXGRAPH_MAX_PIXELS must be a number"):
        imageio.max_pixels()
