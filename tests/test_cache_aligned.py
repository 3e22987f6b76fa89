"""Arrays read from a disk cache entry are aligned for their dtype: the entry's
manifest length put them at any byte offset, and OpenImageIO refused an unaligned
float buffer, so a cached image could not be written as EXR ('buffer is wrong
size'; found planting cache entries: the second ``pixgraph run -o final=x.exr`` of a
4 x 4 Constant failed with the default disk cache)."""
import numpy as np

from pixgraph.cache import pack_entry, unpack_entry
from pixgraph.cli import main
from pixgraph_nodes.ops.imageio import read_image

KEY = "ab" + "0" * 62


def test_unpacked_arrays_are_aligned_and_read_only():
    a = np.arange(64, dtype=np.float32).reshape(4, 4, 4)
    for pad in range(16):                 # every offset the manifest's length can give
        v = unpack_entry(KEY, pack_entry(KEY, {"image": a, "note": "x" * pad}))
        assert v["image"].flags.aligned and not v["image"].flags.writeable
        np.testing.assert_array_equal(v["image"], a)


def test_a_cached_image_is_written_as_exr(tmp_path, capsys):
    g = tmp_path / "g.yaml"
    g.write_text("pixgraph: 1\nnodes:\n  c: {type: pixgraph.Constant, params: {width: 4, height: 4, "
                 "color: [0.2, 0.3, 0.4, 1]}}\noutputs: {final: c.image}\n")
    for name in ("a.exr", "b.exr", "c.exr"):          # the first computes, the others read the disk cache
        assert main(["run", str(g), "--disk-cache", str(tmp_path / "cache"), "-o", f"final={tmp_path / name}"]) == 0, \
            capsys.readouterr().err
        np.testing.assert_allclose(read_image(tmp_path / name)[0][0, 0], [0.2, 0.3, 0.4, 1], atol=1e-6)
