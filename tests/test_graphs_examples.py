"""Every example graph in graphs/ runs end to end and makes a plausible composite."""
import pathlib
import subprocess
import sys

import numpy as np
import pytest

from pixgraph.session import Session

GRAPHS = pathlib.Path(__file__).resolve().parents[1] / "graphs"
EXAMPLES = ["ground_shadow", "wall_corner_shadow", "steps_shadow"]


@pytest.fixture(scope="module")
def session(device):
    return Session(device=device, disk_cache=None)


@pytest.mark.parametrize("name", EXAMPLES)
def test_example_graph_runs_and_casts_a_shadow(session, name):
    path = GRAPHS / f"{name}.yaml"
    out = session.run(path, outputs=["final", "shadow.darkness", "bg_h.height", "cutout.alpha", "photo.image"])
    img = out["final"]
    assert img.shape == (512, 512, 3) and img.dtype == np.float32
    assert np.all(np.isfinite(img)) and img.min() >= 0.0 and img.max() <= 1.0
    dark, bg_h, alpha, photo = (out[k] for k in ("shadow.darkness", "bg_h.height", "cutout.alpha", "photo.image"))
    free = alpha == 0
    # a real shadow: a sizeable fully dark core and a soft rim, off the cutout
    assert (dark[free] > 0.9).sum() > 500
    assert ((dark[free] > 0.05) & (dark[free] < 0.95)).sum() > 500
    # where there is no cutout the composite is the photo darkened by the shadow, never brightened
    assert np.all(img[free] <= photo[free] + 1e-6)
    shaded = free & (dark > 0.9)
    assert np.all(img[shaded].mean(-1) < 0.5 * photo[shaded].mean(-1) + 1e-3)
    lit = free & (dark == 0)
    np.testing.assert_allclose(img[lit], photo[lit], atol=1e-6)
    if name != "ground_shadow":
        # the shadow climbs the wall / the risers: shadowed background pixels above the floor
        assert ((dark > 0.5) & (bg_h > 2.0) & free).sum() > 300


def test_readme_job_through_the_cli(tmp_path):
    """`pixgraph run graphs/wall_corner_shadow.yaml -o final=...` writes a PNG (its time:
    benchmarks/example_graph_bench.py)."""
    out = tmp_path / "wall_corner.png"
    cmd = ["run", str(GRAPHS / "wall_corner_shadow.yaml"), "-o", f"final={out}", "--no-disk-cache", "-q"]
    r = subprocess.run([sys.executable, "-c", "import sys; from pixgraph.cli import main; sys.exit(main())", *cmd],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    from pixgraph_nodes.ops.imageio import read_image
    img, _ = read_image(out)
    assert img.shape[:2] == (512, 512) and np.all(np.isfinite(img))
