"""Cached results equal uncached results over random graphs and random param edits.

A long-lived session (tiny memory cache plus a disk cache, so entries are evicted,
re-read from disk and recomputed) is compared after every edit with a fresh
session that computes everything from scratch.
"""
import random

import numpy as np

from engine_testnodes import make_registry
from pixgraph.events import NodeCached
from pixgraph.session import Session

N_GRAPHS = 200
EDITS_PER_GRAPH = 3


def random_graph(rng: random.Random, session):
    b = session.builder()
    ids = []
    size = rng.choice([2, 3])
    for i in range(rng.randint(2, 9)):
        nid = f"n{i}"
        kind = "t.Source" if not ids or rng.random() < 0.25 else rng.choice(["t.Add", "t.Scale", "t.Add"])
        if kind == "t.Source":
            b.add(kind, nid, value=rng.choice([0.0, 1.0, 2.5, -3.0]), size=size)
        elif kind == "t.Add":
            b.add(kind, nid, k=float(rng.randint(-2, 2)))
            b.connect(f"{rng.choice(ids)}.out", f"{nid}.a")
            if rng.random() < 0.6:
                b.connect(f"{rng.choice(ids)}.out", f"{nid}.b")
        else:
            b.add(kind, nid, factor=rng.choice([0.5, 1.0, 2.0]))
            b.connect(f"{rng.choice(ids)}.out", f"{nid}.x")
        ids.append(nid)
    for j, nid in enumerate(rng.sample(ids, rng.randint(1, len(ids)))):
        b.output(f"o{j}", f"{nid}.out")
    return b.build()


def random_edit(rng: random.Random, graph):
    nid = rng.choice(sorted(graph.nodes))
    t = graph.nodes[nid].type
    if t == "t.Source":
        return {f"{nid}.value": rng.choice([0.0, 1.0, 4.0, -1.5])}
    if t == "t.Add":
        return {f"{nid}.k": float(rng.randint(-3, 3))}
    return {f"{nid}.factor": rng.choice([0.0, 0.5, 3.0])}


def test_cached_equals_uncached(tmp_path):
    rng = random.Random(20260)
    cached = Session(registry=make_registry(), cache_bytes=600, disk_cache=tmp_path / "disk")
    where = {"memory": 0, "disk": 0}

    def count(ev):
        if isinstance(ev, NodeCached):
            where[ev.where] += 1
    for _ in range(N_GRAPHS):
        graph = random_graph(rng, cached)
        params = {}
        for _ in range(EDITS_PER_GRAPH + 1):
            got = cached.run(graph, params=params, on_event=count)
            fresh = Session(registry=make_registry(), cache_bytes=1 << 20).run(graph, params=params)
            assert got.keys() == fresh.keys()
            for k in got:
                np.testing.assert_array_equal(got[k], fresh[k])
            params = {**params, **random_edit(rng, graph)}
    # the cached session really served results from both of its caches
    assert where["memory"] > 100 and where["disk"] > 100, where
