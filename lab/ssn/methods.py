"""SSN++ models as methods of the evaluation CLI (``module:function`` specs).

    python -m pixgraph_lab.evaluate --data data/wall_test \
        --method pixgraph_lab.ssn.methods:shipped \
        --method pixgraph_lab.ssn.methods:run_ssg --method pixgraph_lab.ssn.methods:run_ssnpp

``shipped`` is the model in ``pixgraph_nodes/weights/ssnpp.pt`` (what the
SoftShadowSSN node uses); ``run_<name>`` is ``$PIXGRAPH_SSN_RUNS/<name>/model.pt``
(default folder ``runs``), written by ``pixgraph_lab.ssn.train --out runs/<name>``:
any run folder works (``run_ssnpp_b4`` reads ``runs/ssnpp_b4/model.pt``; the
ablation's are ``run_ssg``, ``run_sparse``, ``run_reldist``, ``run_ssnpp``).
Each call computes the buffer channels with our tracer, exactly as the node does,
and times the whole prediction.
"""
from __future__ import annotations

import functools
import os
import pathlib

from pixgraph_nodes.ops import ssn

from .prepare import sample_inputs


@functools.lru_cache(maxsize=8)
def _model(path: str):
    return ssn.load_model(path)


def _predict(model_path: str, sample: dict):
    buffers, softness, _ = sample_inputs(sample["device"], sample)
    return ssn.predict(_model(model_path), buffers, softness)


def _run(variant: str):
    root = pathlib.Path(os.environ.get("PIXGRAPH_SSN_RUNS", "runs"))
    return str(root / variant / "model.pt")


def shipped(sample):
    from pixgraph_nodes.ssn_soft_shadow import WEIGHTS
    return _predict(str(WEIGHTS / "ssnpp.pt"), sample)


def __getattr__(name: str):
    """``run_<folder>``: the model in ``$PIXGRAPH_SSN_RUNS/<folder>/model.pt`` on the
    whole 256² frame; ``node_run_<folder>``: that model the way the node runs it
    (window at the trained scale + reach gate, ``_node``)."""
    if name.startswith("node_run_") and len(name) > 9:
        folder = name[9:]

        def node_run(sample):
            return _node(sample, model=_model(_run(folder)))
        node_run.__name__ = name
        return node_run
    if name.startswith("run_") and len(name) > 4:
        folder = name[4:]

        def run(sample):
            return _predict(_run(folder), sample)
        run.__name__ = name
        return run
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def _node(sample, gate=True, model=None):
    from pixgraph_nodes.ops import ssn_crop
    from pixgraph_nodes.ops.lights import disk_extremes, light_point
    from pixgraph_nodes.ssn_soft_shadow import load_shipped
    light, cam = sample["light"], sample["camera"]
    mask = sample["mask"].astype("float32")
    softness = ssn.softness_of(light, cam, mask, sample["fg_height"])
    model = load_shipped("ssnpp") if model is None else model
    d, _ = ssn_crop.render(sample["device"], model, mask, sample["fg_height"],
                           sample["bg_height"], light_point(light, cam), disk_extremes(light, cam),
                           softness, 1.0, gate=gate)
    return d


def node(sample):
    """What the SoftShadowSSN node computes: SSN++ on a window at the trained scale
    (``ops.ssn_crop.render``), shipped weights, the node's softness."""
    return _node(sample)


def node_ungated(sample):
    """``node`` without the shadow-reach gate (for the ablation in docs/ssn.md)."""
    return _node(sample, gate=False)
