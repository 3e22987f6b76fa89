"""The working resolution of a whole graph (``Session.run(..., scale=s)``): loaders
read at that size, params in pixels are scaled, and the result is the full run
downsampled, up to the error of tracing at the smaller size. Also: nodes that
declare ``disk_cache = False`` stay off the disk cache."""
import pathlib

import numpy as np
import pytest

from pixgraph.graph import GraphError
from pixgraph.session import Session
from pixgraph_nodes.ops.resample import at_scale, scaled_size

GRAPHS = pathlib.Path(__file__).resolve().parents[1] / "graphs"


@pytest.fixture(scope="module")
def runs(device):
    s = Session(device=device, disk_cache=None)
    g = s.graph(GRAPHS / "ground_shadow.yaml")
    want = ["shadow.darkness", "cutout.alpha", "final"]
    return s, g, {sc: s.run(g, outputs=want, scale=sc) for sc in (1.0, 0.5, 0.25)}


@pytest.mark.parametrize("sc", [0.5, 0.25])
def test_a_scaled_run_is_the_full_run_downsampled(runs, sc):
    _, _, out = runs
    full, lo = out[1.0], out[sc]
    assert lo["final"].shape[:2] == scaled_size(512, 512, sc) == lo["shadow.darkness"].shape
    ref = at_scale(full["shadow.darkness"], sc)
    background = at_scale(full["cutout.alpha"], sc) < 0.5
    assert (ref[background] > 0.3).sum() > 300 * sc * sc        # a real shadow is compared
    rmse = float(np.sqrt(np.mean((lo["shadow.darkness"] - ref)[background] ** 2)))
    # measured 0.016 at 0.5 and 0.018 at 0.25 (the trace at the smaller size; 48 samples)
    assert rmse < 0.03
    final = float(np.sqrt(np.mean((lo["final"] - at_scale(full["final"], sc)) ** 2)))
    assert final < 0.006                                          # measured 0.0025 and 0.0032
    # the mask is the file's alpha at that size, not a thresholded copy
    assert np.allclose(lo["cutout.alpha"], at_scale(full["cutout.alpha"], sc), atol=1e-6)


def test_params_in_pixels_scale_and_keys_stay_at_full_size(runs):
    s, g, _ = runs
    p1, p0 = s.plan(g, outputs=["final"]), s.plan(g, outputs=["final"], scale=1.0)
    assert p1.keys == p0.keys and p1.scale == 1.0
    ph = s.plan(g, outputs=["final"], scale=0.25)
    assert ph.params["cam"]["width"] == 128 and ph.params["cam"]["horizon"] == 30.0
    assert ph.params["cam"]["hfov"] == 50.0                        # degrees: not scaled
    assert ph.params["shadow"]["thickness"] == 1.5 and ph.params["shadow"]["samples"] == 48
    # a proxy side is a resolution cap, not a length in the picture: a preview traces at
    # the final's proxy size, so it shows what the final will
    assert ph.params["shadow"]["proxy"] == 1024
    assert ph.params["light"]["distance"] == 4.0                   # world units: not scaled
    assert ph.parts["cutout"].params["@scale"] == 0.25             # a loader declares uses_scale
    assert "@scale" not in ph.parts["comp"].params
    assert all(ph.keys[n] != p1.keys[n] for n in ("cutout", "cam", "shadow", "comp"))


@pytest.mark.parametrize("bad", [0, -0.5, 1.5, "x"])
def test_a_scale_outside_0_1_is_refused(runs, bad):
    s, g, _ = runs
    with pytest.raises(GraphError, match="scale"):
        s.plan(g, outputs=["final"], scale=bad)


def test_nodes_off_the_disk_cache(device, tmp_path):
    s = Session(device=device, disk_cache=tmp_path / "cache")
    g = s.graph(GRAPHS / "ground_shadow.yaml")
    s.run(g, outputs=["final"])
    keys = s.last_run.plan.keys
    on_disk = {n for n in keys if keys[n] in s.disk}
    # loaders, templates and composites are remade faster than read back; the shadow is kept
    assert {"shadow", "light", "fg_h", "cam"} <= on_disk
    assert not on_disk & {"cutout", "photo", "bg_h", "comp"}
    s2 = Session(device=device, disk_cache=tmp_path / "cache")
    s2.run(g, outputs=["final"])
    assert "shadow" not in s2.last_run.ran and "comp" in s2.last_run.ran
