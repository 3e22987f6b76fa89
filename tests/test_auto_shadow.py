"""pixgraph.Shadow with method auto (ops/choose.py, lab/auto_table.py): the choice
follows the measured table, the node computes exactly the chosen method, and
explain / the run's log say what was chosen and why."""
import pathlib

import numpy as np
import pytest

from _shadow_scenes import figure
from pixgraph.session import Session
from pixgraph_lab import auto_table
from pixgraph_nodes.ops import choose as C

GRAPH = pathlib.Path(__file__).resolve().parents[1] / "graphs" / "auto_shadow.yaml"


def _table(cell):
    """A one-bin-per-receiver table with the given {method: (mean, p90)} and 10 samples."""
    st = {m: {"n": 10, "mean": a, "p90": b} for m, (a, b) in cell.items()}
    rec = {"bins": [st], "all": st}
    return {"methods": list(cell), "softness_edges": [0.0, 10.0], "cells": {"wall": rec, "ground": rec},
            "ms_256": {"hard": 5.0, "soft:4": 10.0, "soft:16": 40.0, "ssn": 30.0}}


def test_choose_takes_the_cheapest_method_that_meets_the_target():
    t = _table({"hard": (0.09, 0.20), "soft:4": (0.06, 0.12), "soft:16": (0.05, 0.09), "ssn": (0.045, 0.08)})
    assert C.choose(t, 0.1, "wall", 256 * 256, 0.15).method == "soft:4"
    # soft:16 and ssn qualify; ssn is cheaper at 256^2 ...
    assert C.choose(t, 0.1, "wall", 256 * 256, 0.09).method == "ssn"
    # ... but not on a tiny image, where the classical cost shrinks with the pixels and ssn's does not
    assert C.choose(t, 0.1, "wall", 64 * 64, 0.09).method == "soft:16"
    c = C.choose(t, 0.1, "wall", 256 * 256, 0.01)           # nothing qualifies: the most accurate
    assert c.method == "ssn" and not c.met and "no method" in c.reason
    assert C.choose(t, 0.1, "wall", 256 * 256, 1.0).method == "hard"


def test_a_thin_cell_falls_back_to_the_receivers_pooled_row():
    t = _table({"hard": (0.09, 0.20), "ssn": (0.045, 0.08)})
    thin = {m: dict(v, n=2, p90=0.01) for m, v in t["cells"]["wall"]["bins"][0].items()}
    t["cells"]["wall"] = {"bins": [thin], "all": t["cells"]["wall"]["all"]}
    c = C.choose(t, 0.1, "wall", 256 * 256, 0.05)
    assert c.method == "ssn" and "too few samples" in c.cell     # the thin cell would have said hard


def test_fit_builds_percentiles_per_receiver_and_softness_bin():
    rng = np.random.default_rng(0)
    recs = []
    for i in range(200):
        s = float(rng.uniform(0.015, 0.45))
        recs.append({"index": i, "softness": s, "receiver": "wall" if i % 3 else "ground", "feature_ms": 1.0,
                     "rmse": {m: float(rng.gamma(2, 0.02)) for m in auto_table.CANDIDATES},
                     "ms": {m: float(k + 1) for k, m in enumerate(auto_table.CANDIDATES)}})
    t = auto_table.fit(recs)
    edges = t["softness_edges"]
    sel = [r["rmse"]["soft:16"] for r in recs if r["receiver"] == "wall" and edges[1] <= r["softness"] < edges[2]]
    cell = t["cells"]["wall"]["bins"][1]["soft:16"]
    assert cell["n"] == len(sel) and cell["p90"] == pytest.approx(float(np.percentile(sel, 90)))
    assert t["ms_256"]["hard"] == 1.0 and t["ms_256"]["ssn"] == 7.0


def test_the_shipped_table_is_complete_and_says_how_it_was_made():
    t = C.load_table()
    assert t["methods"] == list(auto_table.CANDIDATES)
    assert t["provenance"]["command"].startswith("python -m pixgraph_lab.auto_table")
    n = sum(t["provenance"]["data"].values())
    for rec in ("wall", "ground"):
        assert sum(b["hard"]["n"] for b in t["cells"][rec]["bins"]) == t["cells"][rec]["all"]["hard"]["n"]
        for b in t["cells"][rec]["bins"]:
            for m in t["methods"]:
                assert 0 < b[m]["mean"] <= b[m]["p90"] < 1
    assert t["cells"]["wall"]["all"]["hard"]["n"] + t["cells"]["ground"]["all"]["hard"]["n"] == n


def test_receiver_kind(device):
    m, fg, bg = figure(128, 128)
    shadow = np.zeros_like(m, bool)
    shadow[20:60, 80:120] = True                     # above the wall's foot row (0.45 H): on the wall
    assert C.receiver_kind(shadow, m, bg) == "wall"
    assert C.receiver_kind(shadow, m, np.zeros_like(bg)) == "ground"
    assert C.receiver_kind(np.zeros_like(shadow), m, bg) == "ground"


@pytest.fixture(scope="module")
def session(device):
    return Session(device=device, disk_cache=None)


@pytest.mark.parametrize("target", [1.0, 0.1, 0.0])
def test_the_node_computes_exactly_the_method_it_logs(session, target):
    g = session.graph(GRAPH)
    events = []
    auto = session.run(g, outputs=["shadow.darkness"], params={"shadow.max_rmse": target},
                       on_event=events.append)["shadow.darkness"]
    logs = [e.message for e in events if type(e).__name__ == "NodeLog"]
    chosen = logs[0].split()[2].rstrip(":")
    assert logs[0].startswith("auto chose ")
    if target == 1.0:
        assert chosen == "hard"                         # everything qualifies: the cheapest
    if target == 0.0:
        assert any(m.startswith("warning: no method") for m in logs)
    method, _, n = chosen.partition(":")
    forced = {"shadow.method": method, **({"shadow.samples": int(n)} if n else {})}
    again = session.run(g, outputs=["shadow.darkness"], params=forced)["shadow.darkness"]
    assert np.array_equal(auto, again)


def test_explain_says_what_auto_will_do_and_what_it_chose(session):
    g = session.graph(GRAPH)
    before = session.explain(g, outputs=["shadow.darkness"]).splitlines()
    row = next(r for r in before if r.startswith("shadow"))
    assert "method auto: at run time, the cheapest of hard" in row and "<= 0.1" in row
    session.run(g, outputs=["shadow.darkness"])
    row = next(r for r in session.explain(g, outputs=["shadow.darkness"]).splitlines() if r.startswith("shadow"))
    assert "its run logged: auto chose" in row and "memory" in row


def test_the_docs_example_runs(capsys):
    import re
    text = (pathlib.Path(__file__).resolve().parents[1] / "docs" / "auto.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, re.S)
    assert len(blocks) == 1
    exec(compile(blocks[0], "auto.md", "exec"), {})
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 2 and all(ln.split()[1] in C.load_table()["methods"] for ln in lines)


def test_new_ssn_weights_or_table_invalidate_cached_shadow_results():
    # method ssn (and auto choosing it) runs the shipped SSN++ weights: a Shadow result cached
    # with other weights or another table must not be served, so the node's version carries both
    from pixgraph_nodes.shadow import Shadow
    from pixgraph_nodes.ssn_soft_shadow import SoftShadowSSN
    assert Shadow.impl_version.endswith("+ssn." + SoftShadowSSN.impl_version)
    assert "table." + C.table_digest() in Shadow.impl_version


def test_the_docs_printed_choice_is_what_the_graph_logs(device):
    # docs/auto.md shows `pixgraph run graphs/auto_shadow.yaml`'s log line; it must be today's
    import re
    text = (pathlib.Path(__file__).resolve().parents[1] / "docs" / "auto.md").read_text()
    shown = re.search(r"\$ pixgraph run graphs/auto_shadow\.yaml[^\n]*\n(shadow: [^\n]*)\n", text).group(1)
    events = []
    fresh = Session(device=device, disk_cache=None)          # nothing cached: the node runs and logs
    fresh.run(fresh.graph(GRAPH), outputs=["shadow.darkness"], on_event=events.append)
    logs = [e.message for e in events if type(e).__name__ == "NodeLog"]
    assert shown == "shadow: " + logs[0]


def test_a_cached_run_says_what_the_node_logged_when_it_ran(device):
    # RunResult.said: a node that ran says this run's lines; served from the cache, the lines
    # it logged when it made that result (the page shows them under the image)
    session = Session(device=device, disk_cache=None)
    g = session.graph(GRAPH)
    first = session.run(g, outputs=["shadow.darkness"])
    assert "shadow" in first.ran and first.said["shadow"] == first.logs["shadow"]
    assert first.said["shadow"][0].startswith("auto chose ")
    other = session.run(g, outputs=["shadow.darkness"], params={"shadow.method": "hard"})
    assert "shadow" in other.ran and "shadow" not in other.said    # a forced method logs nothing
    again = session.run(g, outputs=["shadow.darkness"])
    assert "shadow" in again.cached and "shadow" not in again.logs
    assert again.said["shadow"] == first.said["shadow"]
