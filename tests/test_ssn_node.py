"""The SoftShadowSSN node with the shipped weights: range, determinism, softness
really widens the penumbra, and it runs in a cached graph with the weights loaded
once."""
import pathlib

import numpy as np
import pytest

from pixgraph.session import Session
from pixgraph_nodes import ssn_soft_shadow

GRAPH = pathlib.Path(__file__).resolve().parents[1] / "graphs" / "ssn_wall_corner.yaml"


@pytest.fixture(scope="module")
def session():
    return Session(disk_cache=None)


def test_weights_are_shipped_with_their_provenance():
    w = ssn_soft_shadow.WEIGHTS / "ssnpp.pt"
    assert w.exists() and w.stat().st_size < 4_000_000
    meta = w.with_suffix(".json").read_text()
    assert '"seed"' in meta and '"train_data"' in meta


def test_range_determinism_and_softness_widens_the_penumbra(session):
    g = session.graph(GRAPH)
    run = lambda r: session.run(g, outputs=["shadow.darkness"], params={"light.radius": r})["shadow.darkness"]
    small, large = run(0.05), run(0.8)
    for d in (small, large):
        assert d.dtype == np.float32 and np.isfinite(d).all()
        assert d.min() >= 0.0 and d.max() <= 1.0
    assert np.array_equal(run(0.05), small)
    mask = session.run(g, outputs=["cutout.alpha"])["cutout.alpha"] > 0.5
    penumbra = lambda d: int(((d > 0.05) & (d < 0.6) & ~mask).sum())
    # a light 16x larger spreads the shadow's edge over many more pixels
    assert penumbra(large) > 1.5 * penumbra(small)


def test_graph_caching_and_weights_loaded_once(session):
    ssn_soft_shadow._load.cache_clear()
    g = session.graph(GRAPH)
    for az in (-25, -10, 5):
        session.run(g, outputs=["comp.image"], params={"light.azimuth": az})
    assert ssn_soft_shadow._load.cache_info().misses == 1
    assert ssn_soft_shadow._load.cache_info().hits == 2
    events = []
    session.run(g, outputs=["comp.image"], params={"light.azimuth": 5}, on_event=events.append)
    ran = [e for e in events if type(e).__name__ == "NodeFinished"]
    assert not ran  # everything served from the memory cache
