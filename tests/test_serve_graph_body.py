"""A posted graph's body is read up to the graph format's own limit
(``fileio.MAX_FILE_BYTES``, 4 MiB) and no further: 413 over it, before it is decoded
or parsed. Before, the whole body up to ``Limits.max_body_bytes`` (256 MiB: an
uploaded photo's limit) was read, decoded, token-scanned and parsed by libyaml, and
only then refused by the graph loader's size check (200 MB of YAML comments: seconds,
and hundreds of megabytes of the server's memory)."""
import httpx

from pixgraph.fileio import MAX_FILE_BYTES
from serve_helpers import copy_scene, running_server


def test_a_posted_graph_over_the_format_limit_is_413_before_parsing(tmp_path):
    with running_server(copy_scene(str(tmp_path / "scene"))) as (url, _):
        graph = httpx.get(url + "/api/graph.yaml", timeout=60).text
        big = graph + "#" * 99 + "\n" + ("#" + "x" * 99 + "\n") * (MAX_FILE_BYTES // 100 + 1)
        assert len(big) > MAX_FILE_BYTES
        yaml = {"Content-Type": "application/yaml"}
        r = httpx.post(url + "/api/graph", content=big, headers=yaml, timeout=120)
        assert r.status_code == 413 and str(MAX_FILE_BYTES) in r.json()["error"], r.text[:300]
        r = httpx.post(url + "/api/graph", content=iter([big[i:i + 65536].encode() for i in range(0, len(big), 65536)]),
                       headers=yaml, timeout=120)          # chunked: counted while it arrives
        assert r.status_code == 413, r.text[:300]
        r = httpx.post(url + "/api/graph", content=graph + "# a comment\n", headers=yaml, timeout=120)
        assert r.status_code == 200, r.text[:300]           # a graph within the limit is taken
