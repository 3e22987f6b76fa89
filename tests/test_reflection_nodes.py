"""The Reflection, Refraction, ReflectionComposite and Sphere nodes, and the example
graphs glossy_floor.yaml and crystal_ball.yaml run through a Session."""
import os

import numpy as np
import pytest

from pixgraph.session import Session
from pixgraph_nodes.ops import reflection as R
from pixgraph_nodes.reflection_composite import ReflectionComposite

GRAPHS = os.path.join(os.path.dirname(__file__), "..", "graphs")


class _Ctx:
    device = None

    def progress(self, f, msg=""):
        pass

    def check_cancelled(self):
        pass


class _NS(dict):
    __getattr__ = dict.__getitem__


def test_reflection_composite_exact_numbers():
    H, W = 2, 3
    bg = np.full((H, W, 3), 0.5, np.float32)
    cut = np.zeros((H, W, 4), np.float32)
    cut[0, 0] = (0.2, 0.4, 0.6, 1.0)
    alpha = cut[..., 3].copy()
    refl = np.zeros((H, W, 4), np.float32)
    refl[1, 1] = (0.1, 0.05, 0.0, 0.2)
    shadow = np.zeros((H, W), np.float32)
    shadow[1, 1] = 1.0
    refr = np.zeros((H, W, 4), np.float32)
    refr[0, 2] = (0.3, 0.3, 0.3, 0.5)
    node = ReflectionComposite()
    out = node.compute(_Ctx(), _NS(background=bg, cutout=cut, alpha=alpha, reflection=refl, shadow=shadow,
                                   refraction=refr),
                       _NS(opacity=0.5, tint=[0.0, 0.0, 0.0]))["image"]
    # shadowed bg 0.25, then the reflection over it: 0.1 + 0.25 * 0.8
    np.testing.assert_allclose(out[1, 1], [0.3, 0.25, 0.2], atol=1e-7)
    np.testing.assert_allclose(out[0, 0], [0.2, 0.4, 0.6], atol=1e-7)     # opaque cutout on top
    np.testing.assert_allclose(out[0, 2], [0.3 + 0.25, 0.55, 0.55], atol=1e-7)
    np.testing.assert_allclose(out[0, 1], [0.5, 0.5, 0.5], atol=1e-7)


@pytest.fixture(scope="module")
def session():
    return Session(cache_bytes=1 << 28)


def test_glossy_floor_graph(session):
    path = os.path.join(GRAPHS, "glossy_floor.yaml")
    out = session.run(path, params={"shadow.samples": 4, "refl.max_spp": 32})
    final, refl = out["final"], out["reflection"]
    assert final.shape == (512, 512, 3) and refl.shape == (512, 512, 4)
    assert np.isfinite(final).all() and np.isfinite(refl).all()
    # the figure stands at row ~440: its reflection lies below its feet, none above the horizon
    assert refl[445:, 200:320, 3].max() > 0.03
    assert refl[:120].max() == 0
    assert refl[..., 3].max() <= 1.0


def test_glossy_floor_mirror_uses_closed_form(session):
    path = os.path.join(GRAPHS, "glossy_floor.yaml")
    out = session.run(path, outputs=["reflection", "refl.stats"],
                      params={"refl.roughness": 0.0, "shadow.samples": 1})
    stats = out["refl.stats"]
    below = np.arange(512) + 0.5 > 120
    assert np.all(stats["spp"][below] == 1) and np.all(stats["spp"][~below] == 0)
    assert np.all(stats["steps"] == 0)                # flat floor: no march at all


def test_crystal_ball_graph(session):
    out = session.run(os.path.join(GRAPHS, "crystal_ball.yaml"))
    final, refr = out["final"], out["refraction"]
    assert final.shape == (512, 512, 3) and np.isfinite(final).all()
    a = refr[..., 3]
    assert a.max() == 1.0 and (a > 0).sum() > 3000
    assert np.all(refr[a == 0] == 0)


def test_refraction_node_proxy_param(session):
    """Refraction's ``proxy``: 0 (or at least the image's size) is the full trace; a
    smaller one traces a proxy and stays close to it inside the glass."""
    path = os.path.join(GRAPHS, "crystal_ball.yaml")
    full = session.run(path, outputs=["refr.layer"], params={"refr.proxy": 0})["refr.layer"]
    same = session.run(path, outputs=["refr.layer"], params={"refr.proxy": 512})["refr.layer"]
    assert np.array_equal(full, same)
    half = session.run(path, outputs=["refr.layer"], params={"refr.proxy": 256})["refr.layer"]
    on = full[..., 3] > 0
    assert not np.array_equal(half, full)
    np.testing.assert_array_equal(half[..., 3], full[..., 3])          # coverage stays full resolution
    rmse = float(np.sqrt(np.mean((half - full)[on] ** 2)))
    assert rmse < 0.03                                                   # measured 0.011
